"""The step is compiled per configuration: a scene compiles only the stages it runs, and says so
while it compiles (issue "The first run and the tests in seconds")."""

import subprocess
import sys

import pytest
from conftest import ACROSS, ALONE, FLOOR, cli, scene

from blobcli import build, build_params
from blobcli.jit import in_disk_cache
from blobcli.sim import pipeline

ONE_BLOB = """
[scene]
duration = 0.1
[[blob]]
center = [0.0, 1.0]
radius = 0.5
""" + FLOOR

pytestmark = pytest.mark.own_builds  # these tests are about each scene's own build


def test_a_one_blob_scene_compiles_no_blob_contact_stage_and_no_other_area_method():
    """In a fresh process: after a one-blob run on a floor, none of the blob–blob stages, other
    area methods, other collider kinds or parallel builds has been compiled."""
    code = f"""
import numba
from blobcli import parse_scene, build, build_params, step
from blobcli.sim import collide, area, statics, pipeline
from blobcli import jit
sc = parse_scene({ONE_BLOB!r}, "t")
model, state = build(sc)
step(state, model, build_params(sc))
unused = [collide.find_blob_pairs, collide.keep_blob_contacts, collide.resolve_blob_contacts,
          collide.blob_contact_velocities, collide.blob_restitution, area.area_xpbd, area.area_gas,
          area.area_springs, statics._collide_segment, statics._collide_circle, statics._collide_polygon]
print([k.py_func.__name__ for k in unused if k.overloads])
print([b.py_func.__name__ for b in jit._BUILDS.values() if b.overloads and "_parallel_" in b.py_func.__name__])
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:2] == ["[]", "[]"], r.stdout


def test_each_configuration_has_its_own_build_and_one_build_serves_a_configuration():
    model, state = build(scene(ONE_BLOB))
    params = build_params(scene(ONE_BLOB))
    kot = pipeline.settings(model, params)
    xpbd = pipeline.settings(model, build_params(scene(ONE_BLOB.replace("[scene]", "[scene]\nmethod = \"xpbd\""))))
    assert pipeline.step_build(model, kot) is pipeline.step_build(model, kot)
    assert pipeline.step_build(model, kot) is not pipeline.step_build(model, xpbd)
    assert "method0" in pipeline.step_build(model, kot).py_func.__name__
    assert pipeline.describe(model, kot) == "kot, plane colliders, sleeping; serial"


def test_numba_cache_is_asked_correctly_for_a_build_it_holds():
    """in_disk_cache reads numba's private cache index: after a run, the step's build is there (True,
    not None: numba's internals still answer as this code expects)."""
    sc = scene(ONE_BLOB)
    model, state = build(sc)
    step_settings = pipeline.settings(model, build_params(sc))
    pipeline.compile_step(state, model, step_settings)
    kernel = pipeline.step_build(model, step_settings)
    assert in_disk_cache(kernel, (0, state, model.arrays, step_settings, pipeline.NO_CLOCK)) is True


def test_a_cold_build_prints_what_it_compiles_unless_quiet(tmp_path, monkeypatch):
    toml = tmp_path / "one.toml"
    toml.write_text(ONE_BLOB)
    monkeypatch.setattr(pipeline, "in_disk_cache", lambda kernel, args: False)  # as with an empty cache
    code, out, err = cli("run", toml, "-o", tmp_path / "a.h5")
    assert code == 0, err
    assert "blobsim: compiling the step for this scene (kot, plane colliders, sleeping; serial): once per machine" \
        in err
    code, out, err = cli("run", toml, "-o", tmp_path / "b.h5", "-q")
    assert code == 0 and "compiling" not in err, err


_RESTING = ONE_BLOB.replace("duration = 0.1", "duration = 4.0").replace("center = [0.0, 1.0]", "center = [0.0, 0.5]")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["drum", "press", "piston", "press sleep off", "resting", "alone", "across"])
def test_the_shared_build_gives_a_scenes_own_bits(name):
    """The shared build (pipeline.shared_build, which the suite runs) gives the bits of a scene's own build:
    shipped scenes with circles, moving and loaded walls; the press with sleeping off (the sleep stage runs,
    nobody sleeps); one blob coming to rest on a floor and falling asleep (blob contacts over no pairs, the
    moving-wall code with none moving, every blob asleep); one blob alone, no collider, sleeping off (every
    collider stage over no colliders); two blobs meeting across a periodic box's edge (the shared build's
    periodic stages, run only where there is a box: the open-world cases above run without them), their
    packing records too. gish's and crusher's goldens, made with their own builds, are compared in the fast
    tier under the shared build too."""
    from pathlib import Path

    from blobcli import load_scene, parse_scene
    from blobcli.sim.model import PARALLEL_BLOBS
    shipped = Path(__file__).resolve().parent.parent / "scenes" / f"{name.split()[0]}.toml"
    text = {"resting": _RESTING, "alone": ALONE, "across": ACROSS}.get(name) or shipped.read_text()
    if name.endswith("sleep off"):
        text = text.replace("[scene]", "[scene]\nsleep = false", 1)
    own_text = name in ("resting", "alone", "across") or name.endswith("off")
    sc = parse_scene(text, name) if own_text else load_scene(shipped)
    assert sc.blob_count < PARALLEL_BLOBS  # serial: the parallel builds give the same bits (test_collide)
    params = build_params(sc)
    model, _ = build(sc)
    own = pipeline.settings(model, params)
    shared = own._replace(config=pipeline.shared_build(own.config))
    assert shared.config != own.config
    runs = []
    for step_settings in (own, shared):
        model, state = build(sc)
        pipeline.advance(state, model, params, 240, step_settings=step_settings)  # resting: asleep from step ~170
        runs.append((state.pos.tobytes(), state.vel.tobytes(), state.static_impulse.tobytes(), state.awake.tobytes(),
                     *(a.tobytes() for a in state.packing)))
    assert runs[0] == runs[1]
    if name == "across":  # they met (across the edge: nothing else is near), and pushed
        assert abs(float(state.vel[:model.offsets[1], 0].mean()) - 2.0) > 0.1
    if name == "resting":
        assert not state.awake.any()  # it did fall asleep: the all-asleep step ran in both builds
