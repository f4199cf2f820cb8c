"""The command line as a user meets it: exit codes, messages, files, signals, and bad input refused with one line."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import ONE, blobsim, cli, scene_file, start_run

from blobcli import read_trajectory

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes").glob("*.toml"))




def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


ONE_BLOB = """
[scene]
steps = 120
[[blob]]
name = "solo"
center = [0.0, 1.0]
radius = 0.5
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def test_help_is_instant_and_imports_nothing_heavy():
    out = subprocess.run([sys.executable, "-c", "import sys, blobcli.cli as c\n"
                          "try:\n    c.main(['--help'])\nexcept SystemExit: pass\n"
                          "print(sorted(m for m in ('blobcli.core._blobcore', 'cffi', 'h5py', 'numpy', 'tqdm', 'rerun', 'matplotlib', 'dask', 'distributed') if m in sys.modules))"],
                         capture_output=True, text=True)
    assert out.stdout.strip().endswith("[]")


def test_run_writes_a_complete_h5md_file_and_one_summary_line(tmp_path):
    out = tmp_path / "o.h5"
    r = blobsim("run", write(tmp_path, ONE_BLOB), "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("blobsim: 120 steps, 2 s simulated in ")
    assert "worst area error" in lines[0] and str(out) in lines[0]
    assert r.stderr == ""
    with h5py.File(out) as f:
        assert f.attrs["complete"] and f.attrs["blobsim_format"] == 10
        assert list(f["h5md"].attrs["version"]) == [1, 1]
        assert f["h5md/creator"].attrs["name"] == b"blobsim" and "name" in f["h5md/author"].attrs
        assert f["particles/blobs/box"].attrs["dimension"] == 2
        assert [b.decode() for b in f["particles/blobs/box"].attrs["boundary"]] == ["none", "none"]
        pos = f["particles/blobs/position"]
        assert pos["value"].shape == (121, 32, 2) and pos["value"].dtype == np.float64
        assert pos["step"].dtype == np.int64 and list(pos["step"][:3]) == [0, 1, 2]
        np.testing.assert_array_equal(pos["time"][...], pos["step"][...] * (1 / 60))
        assert f["observables/area/value"].shape == (121, 1)
        assert f["observables/kinetic_energy/value"].shape == (121, 1)
        assert list(f["parameters/blob_offsets"][...]) == [0, 32]
        assert [n.decode() for n in f["parameters/blob_names"][...]] == ["solo"]
        p = f["parameters"].attrs
        assert (p["dt"], p["substeps"], p["max_substeps"], p["iterations"], p["method"]) == (1 / 60, 4, 16, 2, "kot")
        assert "core" in p and "compiler" in p and "numpy" in p
        assert f["parameters/scene"][()].decode() == ONE_BLOB
        assert f["restart"].attrs["step"] == 120
        np.testing.assert_array_equal(f["restart/position"][...], pos["value"][-1])
    assert not Path(str(out) + ".partial").exists()


def test_the_summary_says_how_many_steps_took_more_substeps(tmp_path):
    """A blob at 20 m/s moves 0.33 m a step: half an edge (29 mm) a substep takes 12 (blobcli/core/integrate.c: bc_substeps_for)."""
    text = ONE_BLOB.replace("steps = 120", "steps = 3\ngravity = [0.0, 0.0]").replace(
        "radius = 0.5", "radius = 0.3\nvelocity = [20.0, 0.0]")
    r = blobsim("run", write(tmp_path, text), "-o", tmp_path / "o.h5", "-q")
    assert r.returncode == 0, r.stderr
    assert "; 3 steps took more substeps than the scene's (up to 12)" in r.stdout


def test_every_records_every_kth_step_and_cli_overrides(tmp_path):
    scene = write(tmp_path, ONE_BLOB.replace("[scene]", "[output]\nevery = 10\n[scene]"))
    r = blobsim("run", scene, "-o", tmp_path / "o.h5", "--duration", "1.0", "-q")
    assert r.returncode == 0, r.stderr
    t = read_trajectory(tmp_path / "o.h5")
    assert list(t.step) == list(range(0, 61, 10))


def test_default_output_path_is_outputs_name(tmp_path):
    r = blobsim("run", write(tmp_path, ONE_BLOB, "named.toml"), "--steps", "5", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "outputs" / "named.h5").exists()


@pytest.mark.parametrize("text, message", [
    ("[scene]\ndt = -1.0\n" + ONE_BLOB.split("[scene]\nsteps = 120")[1], "s.toml:2: scene.dt: must be > 0 (got -1.0)"),
    ("", "s.toml:1: blob: a scene needs at least one [[blob]]"),
    ("[scene\n", "s.toml:1:7: TOML syntax error"),
])
def test_bad_scene_exits_2_with_no_traceback_and_no_output(tmp_path, text, message):
    out = tmp_path / "o.h5"
    r = blobsim("run", write(tmp_path, text), "-o", out)
    assert r.returncode == 2
    assert message in r.stderr and "Traceback" not in r.stderr
    assert r.stderr.startswith(str(tmp_path / "s.toml"))
    assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_bad_arguments_exit_2(tmp_path):
    scene = write(tmp_path, ONE_BLOB)
    for args in (["--steps", "0"], ["--duration", "nan"], ["--method", "magic"], ["--steps", "3", "--duration", "1"]):
        r = blobsim("run", scene, *args)
        assert r.returncode == 2 and "Traceback" not in r.stderr, args


def test_check_prints_the_resolved_scene_and_flags_bad_ones(tmp_path):
    r = blobsim("check", *SCENES)
    assert r.returncode == 0, r.stderr
    assert "dt = 0.016666666666666666  # s" in r.stdout and "compliance = 0.0002  # m/N" in r.stdout
    bad = write(tmp_path, "[[blob]]\ncenter = [0.0, 1.0]\nradius = -0.5\n", "bad.toml")
    r = blobsim("check", SCENES[0], bad)
    assert r.returncode == 2
    assert r.stderr.strip() == f"{bad}:3: blob[0].radius: must be > 0 (got -0.5)"


def test_missing_scene_file_exits_2(tmp_path):
    r = blobsim("run", tmp_path / "none.toml")
    assert r.returncode == 2 and r.stderr.strip() == f"{tmp_path / 'none.toml'}: no such file"


# Bad input: refused with one line, no traceback, before any work ------------------------
BLOB = '[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\n'


def test_a_nul_in_a_path_or_name_is_refused(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    for text in (f'[output]\npath = "{victim}\\u0000.h5"\n', '[scene]\nname = "a\\u0000b"\n'):
        code, _, err = cli("check", scene_file(tmp_path, text + ONE.split("[scene]\nsteps = 40\n")[1]))
        assert code == 2 and "control characters" in err
    assert victim.read_text() == "keep me"



@pytest.mark.parametrize("text, message", [
    ("[scene]\niterations = 1000000000000\n" + BLOB, "scene.iterations: must be <= 1,000"),
    ("[scene]\nsubsteps = 100000\n" + BLOB, "scene.substeps: must be <= 1,000"),
    ("[scene]\nsubsteps = 1000\niterations = 1000\n" + BLOB.replace("radius = 0.5", "radius = 0.5\nvertices = 10000"),
     "substeps × iterations × vertices is 10,000,000,000 per step"),
    ("[scene]\nduration = 1e307\n" + BLOB, "scene.duration: duration / dt is"),
    ("[scene]\ndt = 1e-320\n" + BLOB, "scene.dt: must be >= 1e-09 s"),
    ("[scene]\nsteps = 9223372036854775808\n" + BLOB, "scene.steps: must be <= 1,000,000,000"),
    ("[output]\nevery = 9223372036854775808\n" + BLOB, "output.every: must be <= 1,000,000,000"),
    (BLOB.replace("0.5", "1" + "0" * 400), "blob[0].radius: must be finite"),
    (BLOB.replace("[0.0, 1.0]", "[1e300, 1.0]"), "blob[0].center: must be within ±1e+06 m"),
    (BLOB.replace("0.5", "5e-324"), "blob[0].radius: must be >= 1e-06 m"),
    (BLOB + "vertices = 9223372036854775807\n", "blob[0].vertices: must be <= 100,000"),
    (BLOB + "grid = [9223372036854775807, 1]\nspacing = [1.0, 1.0]\n", "blob[0].grid: must be <= 200,000"),
    (BLOB + "grid = [3, 1]\nspacing = [600000.0, 1.0]\n", "blob[0].spacing: the grid reaches"),
    ("blob = []\n", "blob: a scene needs at least one [[blob]]"),
    (BLOB + '[[static]]\nkind = ["plane"]\n', "static[0].kind: must be one of plane"),
    (BLOB + 'name = "a\\u0000b"\n', "blob[0].name: must not contain control characters"),
    ('[scene]\nname = "' + "x" * 300 + '"\n' + BLOB, "scene.name: must be at most 100 characters"),
    ('[scene]\nname = "../escape"\n' + BLOB, "scene.name: must not contain /"),
    (BLOB + '[[static]]\nkind = "segment"\na = [0.0, 0.0]\nb = [5e-324, 0.0]\n', "static[0].b: segment must be at least"),
])
def test_bad_numbers_and_names_are_refused_with_one_line(tmp_path, text, message):
    code, out, err = cli("run", scene_file(tmp_path, text), "-o", tmp_path / "o.h5", "-q")
    assert code == 2 and message in err and "Traceback" not in err, err
    assert not list(tmp_path.glob("o.h5*"))


def test_a_huge_polygon_is_refused_before_the_quadratic_check(tmp_path):
    pts = ", ".join(f"[{np.cos(t):.5f}, {np.sin(t):.5f}]" for t in np.linspace(0, 6.28, 100_001))
    t0 = time.perf_counter()
    code, _, err = cli("check", scene_file(tmp_path, f"[[blob]]\npoints = [{pts}]\n"))
    assert code == 2 and "at most 5,000 points" in err
    assert time.perf_counter() - t0 < 30  # the crossing-edges check is quadratic in the points: refused before it


def test_check_reads_at_most_the_size_limit():
    t0 = time.perf_counter()
    code, _, err = cli("check", "/dev/zero")
    assert code == 2 and "larger than" in err and time.perf_counter() - t0 < 10


def test_overrides_that_overflow_are_refused(tmp_path):
    code, _, err = cli("run", scene_file(tmp_path), "--steps", str(10**20), "-o", tmp_path / "o.h5")
    assert code == 2 and "--steps" in err and "at most 1,000,000,000" in err
    code, _, err = cli("run", scene_file(tmp_path), "--duration", "1e300", "-o", tmp_path / "o.h5")
    assert code == 2 and "--duration" in err


def test_edge_inputs_are_taken_or_refused_with_one_line(tmp_path):
    traj = tmp_path / "t.h5"
    assert cli("run", scene_file(tmp_path), "-o", traj, "-q")[0] == 0
    code, out, _ = cli("render", traj, "-o", tmp_path / "adir")
    assert code == 0 and f"drew {tmp_path / 'adir.png'}" in out and (tmp_path / "adir.png").exists()
    code, out, _ = cli("compare", traj, traj, "--frames", "1000")
    assert code == 0 and "verdict: same" in out
    (tmp_path / "d").mkdir()
    assert cli("view", tmp_path / "d")[0] == 2
    bom = scene_file(tmp_path, "\ufeff" + ONE, "bom.toml")
    assert cli("check", bom)[0] == 0
    with h5py.File(traj, "r+") as f:
        del f["restart/position"]
        f["restart/position"] = np.zeros((3, 2))
    code, _, err = cli("run", scene_file(tmp_path), "--resume", traj, "--steps", "80")
    assert code == 2 and "restart/position has shape (3, 2)" in err


def test_no_runtime_warnings_leak(tmp_path):
    text = ONE.replace("radius = 0.5", "radius = 0.5\nvelocity = [0.0, -900000.0]")
    r = subprocess.run([sys.executable, "-m", "blobcli", "run", str(scene_file(tmp_path, text)), "-o",
                        str(tmp_path / "o.h5"), "-q"], capture_output=True, text=True, timeout=120)
    assert r.returncode in (0, 1) and "Warning" not in r.stderr, r.stderr


def test_check_warns_about_blobs_spawned_inside_colliders_or_each_other(tmp_path):
    text = ONE.replace("center = [0.0, 1.0]", "center = [0.0, 0.2]") + BLOB.replace("1.0", "0.8")
    code, _, err = cli("check", scene_file(tmp_path, text))
    assert code == 0
    assert "blob[0] (solo): 11 of its 32 vertices start inside static[0] (plane)" in err
    assert "blob[0] (solo) and blob[1] (blob1) overlap at the start" in err
    assert cli("check", ROOT / "scenes" / "pile.toml")[2] == ""  # touching exactly is not overlapping


LONG = """
[scene]
steps = 1000000
[[blob]]
center = [0.0, 1.0]
radius = 0.3
grid = [5, 5]
spacing = [0.8, 0.8]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def start_long_run(tmp_path):
    out = tmp_path / "long.h5"
    proc = start_run([write(tmp_path, LONG)], out)
    return proc, out, Path(str(out) + ".partial")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_keeps_every_computed_frame_in_a_readable_file(tmp_path, signum):
    proc, out, partial = start_long_run(tmp_path)
    proc.send_signal(signum)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted" in stdout
    t = read_trajectory(out)
    assert not t.complete and len(t.step) > 1
    assert list(t.step) == list(range(len(t.step)))  # every frame up to the stop, none missing
    steps_done = int(stdout.split(" steps")[0].split()[-1])
    assert t.step[-1] == steps_done
    assert np.all(np.isfinite(t.position))
    assert not partial.exists()


def test_killed_run_never_leaves_an_unreadable_file_at_the_path(tmp_path):
    proc, out, partial = start_long_run(tmp_path)
    proc.kill()
    proc.wait(timeout=30)
    assert not out.exists()  # only the .partial holds the unfinished run


def test_runaway_stops_with_exit_1_naming_step_blob_vertex(tmp_path):
    """A blob thrown at 1.3e7 m/s passes RUNAWAY (1e6 m) in step 5 (x = 1.3e7 n / 60 m): the run stops
    there and keeps frames 0..4."""
    from blobcli import parse_scene, simulate
    scene = parse_scene(ONE_BLOB.replace('name = "solo"', 'name = "solo"\nvelocity = [1.3e7, 0.0]').replace(
        "[[blob]]", "[[blob]]\nname = \"a\"\ncenter = [5.0, 1.0]\nradius = 0.5\n[[blob]]", 1), "s.toml")
    result = simulate(scene, tmp_path / "o.h5")
    assert result.status == "runaway" and result.exit_code == 1
    assert result.message.startswith("step 5: blob 1 (solo) vertex 0 "), result.message
    t = read_trajectory(tmp_path / "o.h5")
    assert not t.complete and list(t.step) == [0, 1, 2, 3, 4]


def test_python_runs_once_per_recorded_frame_not_per_step(tmp_path, monkeypatch):
    """The step runs in compiled calls of many steps: with every = 10, Python is entered about once
    per recorded frame (a few more calls while the call length grows), and no call crosses a
    frame, so every frame is recorded; the frames equal a run that records every step."""
    import blobcli.io.run as run_module
    from blobcli import parse_scene, simulate
    real_advance, calls = run_module.advance, []

    def counting_advance(state, model, params, steps, **kwargs):
        calls.append(steps)
        return real_advance(state, model, params, steps, **kwargs)
    monkeypatch.setattr(run_module, "advance", counting_advance)
    text = ONE_BLOB.replace("steps = 120", "steps = 200")
    simulate(parse_scene(text + "[output]\nevery = 10\n", "s.toml"), tmp_path / "ten.h5")
    assert sum(calls) == 200 and len(calls) <= 200 // 10 + 4, calls
    simulate(parse_scene(text, "s.toml"), tmp_path / "one.h5")
    ten, one = read_trajectory(tmp_path / "ten.h5"), read_trajectory(tmp_path / "one.h5")
    assert list(ten.step) == list(range(0, 201, 10))
    assert ten.position.tobytes() == one.position[::10].tobytes()


def test_two_runs_are_bit_identical(tmp_path):
    scene = ROOT / "scenes" / "pegboard.toml"
    for name in ("a.h5", "b.h5"):
        assert blobsim("run", scene, "-o", tmp_path / name, "--steps", "200", "-q").returncode == 0
    a, b = read_trajectory(tmp_path / "a.h5"), read_trajectory(tmp_path / "b.h5")
    assert a.position.tobytes() == b.position.tobytes()


def _runs_parallel(path) -> bool:
    """Whether a scene runs the parallel build (PARALLEL_BLOBS blobs or more): compiled in the slow tier."""
    from blobcli import load_scene
    from blobcli.sim.model import PARALLEL_BLOBS
    return load_scene(path).blob_count >= PARALLEL_BLOBS


@pytest.mark.parametrize("scene", [pytest.param(s, marks=pytest.mark.slow) if _runs_parallel(s) else s
                                   for s in SCENES], ids=[s.stem for s in SCENES])
def test_every_shipped_scene_runs(tmp_path, scene):
    """Smoke: every scene validates, builds and steps (its physics is tested elsewhere)."""
    from blobcli import load_scene, simulate
    from blobcli.scene.schema import with_overrides
    sc = with_overrides(load_scene(scene), steps=20)
    result = simulate(sc, tmp_path / "o.h5")
    assert result.status == "complete"
    t = read_trajectory(tmp_path / "o.h5")
    assert len(t.step) == 21 and np.all(np.isfinite(t.position))


def test_list_options_take_spaces_or_commas():
    from blobcli.cli import parser
    p = parser()
    assert p.parse_args(["stress", "--methods", "kot,xpbd", "gas"]).methods == ["kot", "xpbd", "gas"]
    assert p.parse_args(["study", "s.toml", "--methods", "kot", "springs"]).methods == ["kot", "springs"]
    r = blobsim("stress", "--methods", "kot,bogus")
    assert r.returncode == 2 and "invalid choice: 'bogus'" in r.stderr and "Traceback" not in r.stderr
