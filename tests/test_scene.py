"""Scene validation: every bad input is one clear `file:line: path: problem` line."""

import re
from pathlib import Path

import pytest

from blobcli.scene.schema import (
    MAX_VERTICES,
    SceneError,
    load_scene,
    parse_scene,
    reference_markdown,
    resolved_toml,
)

ROOT = Path(__file__).resolve().parent.parent
GOOD_BLOB = "[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\n"


def problems(text: str) -> list[str]:
    with pytest.raises(SceneError) as e:
        parse_scene(text, "s.toml")
    return e.value.problems


def one_problem(text: str) -> str:
    p = problems(text)
    assert len(p) == 1, p
    return p[0]


@pytest.mark.parametrize("text, expected", [
    # unknown keys, with did-you-mean
    ("[scene]\ndurtion = 2.0\n" + GOOD_BLOB, "s.toml:2: scene.durtion: unknown key: not a key of scene; did you mean 'duration'?"),
    (GOOD_BLOB + "radus = 0.5\n", "s.toml:4: blob[0].radus: unknown key: not a key of blob[0]; did you mean 'radius'?"),
    ("[scen]\n" + GOOD_BLOB, "s.toml:1: scen: unknown table; did you mean 'scene'?"),
    # wrong types and vector lengths
    ("[scene]\ndt = \"fast\"\n" + GOOD_BLOB, "s.toml:2: scene.dt: must be a number (got 'fast')"),
    ("[scene]\nsubsteps = 2.5\n" + GOOD_BLOB, "s.toml:2: scene.substeps: must be an integer (got 2.5)"),
    ("[scene]\ngravity = [0.0, -9.81, 0.0]\n" + GOOD_BLOB, "s.toml:2: scene.gravity: must be a list of 2 numbers (got [0.0, -9.81, 0.0])"),
    ("[scene]\nsubsteps = true\n" + GOOD_BLOB, "s.toml:2: scene.substeps: must be an integer (got True)"),
    # nan and inf
    ("[scene]\ndt = nan\n" + GOOD_BLOB, "s.toml:2: scene.dt: must be finite (got nan)"),
    ("[scene]\ngravity = [0.0, -inf]\n" + GOOD_BLOB, "s.toml:2: scene.gravity: must be finite (got [0.0, -inf])"),
    # non-positive dt, radius, mass
    ("[scene]\ndt = 0.0\n" + GOOD_BLOB, "s.toml:2: scene.dt: must be > 0 (got 0.0)"),
    ("[scene]\ndt = -0.01\n" + GOOD_BLOB, "s.toml:2: scene.dt: must be > 0 (got -0.01)"),
    ("[[blob]]\ncenter = [0.0, 1.0]\nradius = -0.5\n", "s.toml:3: blob[0].radius: must be > 0 (got -0.5)"),
    (GOOD_BLOB + "mass = 0\n", "s.toml:4: blob[0].mass: must be > 0 (got 0)"),
    # too few vertices
    (GOOD_BLOB + "vertices = 2\n", "s.toml:4: blob[0].vertices: must be >= 3 (got 2)"),
    ("[[blob]]\npoints = [[0.0, 0.0], [1.0, 0.0]]\n", "s.toml:2: blob[0].points: must be a list of at least 3 [x, y] points (got [[0.0, 0.0], [1.0, 0.0]])"),
    # both shape forms, or neither
    (GOOD_BLOB + "points = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]\n",
     "s.toml:1: blob[0]: give either center + radius (+ vertices) or points, not both"),
    ("[[blob]]\nmass = 2.0\n", "s.toml:1: blob[0]: needs center + radius (missing center and radius), or points"),
    # self-intersecting points
    ("[[blob]]\npoints = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]\n",
     "s.toml:2: blob[0].points: polygon intersects itself (edges 0 and 2 cross) (got [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])"),
    # unknown kind, method
    (GOOD_BLOB + "[[static]]\nkind = \"plain\"\n", "s.toml:5: static[0].kind: must be one of plane, segment, box, circle, polygon; did you mean 'plane'? (got 'plain')"),
    ("[scene]\nmethod = \"kott\"\n" + GOOD_BLOB, "s.toml:2: scene.method: unknown method; one of kot, xpbd, gas, springs; did you mean 'kot'? (got 'kott')"),
    # kind-specific keys
    (GOOD_BLOB + "[[static]]\nkind = \"plane\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nradius = 1.0\n",
     "s.toml:8: static[0].radius: unknown key: not a key of kind 'plane'"),
    (GOOD_BLOB + "[[static]]\nkind = \"circle\"\ncenter = [0.0, 0.0]\n", "s.toml:4: static[0]: circle needs radius"),
    (GOOD_BLOB + "[[static]]\nkind = \"plane\"\npoint = [0.0, 0.0]\nnormal = [0.0, 0.0]\n",
     "s.toml:7: static[0].normal: must not be the zero vector (got [0.0, 0.0])"),
    # duration and steps together; grids
    ("[scene]\nduration = 1.0\nsteps = 10\n" + GOOD_BLOB, "s.toml:3: scene.steps: give duration or steps, not both"),
    (GOOD_BLOB + "grid = [3, 2]\n", "s.toml:4: blob[0].spacing: required with grid"),
    (GOOD_BLOB + "grid = [0, 2]\nspacing = [1.0, 1.0]\n", "s.toml:4: blob[0].grid: must be >= 1 (got [0, 2])"),
    # empty, no blob
    ("", "s.toml:1: blob: a scene needs at least one [[blob]]"),
    ("[scene]\ndt = 0.01\n", "s.toml:1: blob: a scene needs at least one [[blob]]"),
    ("blob = 3\n", "s.toml:1: blob: must be an array of tables: write [[blob]] (got 3)"),
    # static friction below kinetic
    (GOOD_BLOB + "friction = 0.8\nstatic_friction = 0.5\n", "s.toml:5: blob[0].static_friction: must be >= friction (0.8) (got 0.5)"),
])
def test_bad_input_gets_one_clear_line(text, expected):
    assert one_problem(text) == expected


def test_every_problem_is_reported_not_just_the_first():
    text = "[scene]\ndt = -1.0\nsubsteps = 0\n[[blob]]\ncenter = [0.0, 1.0]\nradius = -1.0\n"
    assert [p.split(":")[1] for p in problems(text)] == ["2", "3", "6"]


def test_line_numbers_follow_multiline_values_and_array_tables():
    text = GOOD_BLOB + "[[blob]]\npoints = [\n  [0.0, 0.0],\n  [1.0, 0.0],\n  [0.0, 1.0],\n]\nmass = -1.0\n"
    assert one_problem(text) == "s.toml:10: blob[1].mass: must be > 0 (got -1.0)"


def test_toml_syntax_error_has_line_and_column():
    assert re.fullmatch(r"s\.toml:2:\d+: TOML syntax error: .+", one_problem("[scene]\ndt = = 3\n"))


def test_absurdly_nested_file_is_refused_cleanly():
    text = "x = " + "[" * 100_000 + "]" * 100_000 + "\n"
    p = one_problem(text)
    assert p.startswith("s.toml:") and ("nested" in p or "syntax" in p)


def test_binary_and_non_utf8_files(tmp_path):
    binary = tmp_path / "b.toml"
    binary.write_bytes(b"\x00\x01\x02ELF")
    with pytest.raises(SceneError) as e:
        load_scene(binary)
    assert e.value.problems == [f"{binary}:1: not a text file (it contains NUL bytes)"]
    latin = tmp_path / "l.toml"
    latin.write_bytes(b"[scene]\nname = \"caf\xe9\"\n")
    with pytest.raises(SceneError) as e:
        load_scene(latin)
    assert e.value.problems == [f"{latin}:2: not UTF-8 text (byte 0xe9)"]


def test_missing_file(tmp_path):
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path / "nope.toml")
    assert e.value.problems == [f"{tmp_path / 'nope.toml'}: no such file"]


def test_memory_limit_is_checked_before_allocating():
    # 10^10 vertices would need ~2 TB; refused from the counts alone, instantly.
    text = "[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\nvertices = 100000\ngrid = [1000, 100]\nspacing = [1.0, 1.0]\n"
    p = problems(text)
    assert any(f"the limit is {MAX_VERTICES:,}" in x for x in p)


def test_grid_expands_with_suffixed_names():
    from blobcli import build
    sc = parse_scene("[[blob]]\nname = \"b\"\ncenter = [0.0, 1.0]\nradius = 0.2\ngrid = [3, 2]\nspacing = [1.0, 0.5]\n")
    model, state = build(sc)
    assert model.names == ("b_0_0", "b_0_1", "b_1_0", "b_1_1", "b_2_0", "b_2_1")
    assert sc.blob_count == 6 and model.vertex_count == 6 * 32


def test_resolved_scene_round_trips_through_the_validator():
    for path in sorted((ROOT / "scenes").glob("*.toml")):
        sc = load_scene(path)
        again = parse_scene(resolved_toml(sc), "resolved")
        assert again.settings.dt == sc.settings.dt and again.blobs == sc.blobs and again.statics == sc.statics


def test_docs_scene_reference_is_generated_from_the_dataclasses():
    docs = (ROOT / "docs" / "scenes.md").read_text()
    assert reference_markdown() in docs, "regenerate docs/scenes.md's reference: python -m blobcli.scene.schema"


def test_one_friction_given_is_also_the_static_friction():
    sc = parse_scene("[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\nfriction = 0.2\n"
                     "[[static]]\nkind = \"plane\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nfriction = 0.8\n", "<t>")
    assert sc.blobs[0].static_friction == 0.2 and sc.statics[0].static_friction == 0.8
    both = parse_scene("[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\nfriction = 0.2\nstatic_friction = 0.3\n", "<t>")
    assert both.blobs[0].static_friction == 0.3
    neither = parse_scene("[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\n", "<t>")
    assert (neither.blobs[0].friction, neither.blobs[0].static_friction) == (0.5, 0.6)
    with pytest.raises(SceneError, match=r"static_friction: must be >= friction \(0.5\) \(got 0.4\)"):
        parse_scene("[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\nstatic_friction = 0.4\n", "<t>")


@pytest.mark.parametrize("text, expected", [
    (GOOD_BLOB + "mass = 5e-324\n", "s.toml:4: blob[0].mass: must be >= 1e-06 kg (got 5e-324)"),
    (GOOD_BLOB.replace("[[blob]]", '[[blob]]\nname = "a"') + '[[schedule]]\nkey = "blob.a.mass"\nat = [[0.0, 1.0], [1.0, 1e-9]]\n',
     "s.toml:7: schedule[0].at[1]: mass must be >= 1e-06 kg (got 1e-09)"),
    (GOOD_BLOB.replace("[[blob]]", '[[blob]]\nname = "a"') + '[[schedule]]\nkey = "blob.a.scale"\nat = [[0.0, 1.0], [1.0, 1e-9]]\n',
     "s.toml:7: schedule[0].at[1]: scales blob[0] (radius 0.5 m) to 5e-10 m; its radius must stay from 1e-06 to "
     "1e+06 m (got 1e-09)"),
    (GOOD_BLOB.replace("[[blob]]", '[[blob]]\nname = "a"') + '[[schedule]]\nkey = "blob.a.scale"\nat = [[0.0, 1e300]]\n',
     "s.toml:7: schedule[0].at[0]: scales blob[0] (radius 0.5 m) to 5e+299 m; its radius must stay from 1e-06 to "
     "1e+06 m (got 1e+300)"),
])
def test_masses_and_scaled_sizes_are_bounded(text, expected):
    """A blob's mass (written or scheduled) at least MIN_MASS, and a scale schedule keeps its radius from MIN_LENGTH
    to MAX_COORDINATE: as the keys' docs say."""
    assert problems(text) == [expected]
    parse_scene(GOOD_BLOB + "mass = 1e-6\n", "s.toml")


def test_a_bad_scene_table_adds_no_false_error_about_a_periodic_boxs_copies():
    """A [scene] table with one bad key (seed = -1) still has its periodic box: its blobs with count need no
    region, and its shear schedule is in a box; only the real error is reported."""
    text = ("[scene]\nperiodic = [2.0, 2.0]\nseed = -1\n[[blob]]\nradius = 0.1\ncount = 3\n"
            '[[schedule]]\nkey = "scene.shear"\nat = [[0.0, 0.1]]\n')
    assert problems(text) == ["s.toml:3: scene.seed: must be >= 0 (got -1)"]
