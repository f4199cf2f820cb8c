"""Rerun recordings: written by run --rerun and by replay, read back and verified."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import blobsim, start_run

from blobcli import read_trajectory
from blobcli.io.recording import blob_colors, read_positions

ROOT = Path(__file__).resolve().parent.parent
RERUN = Path(sys.executable).parent / "rerun"  # the viewer/CLI that ships with rerun-sdk




@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A run of the crusher scene (statics, 4 blobs) with --rerun, and a replay of it."""
    d = tmp_path_factory.mktemp("rec")
    r = blobsim("run", ROOT / "scenes" / "crusher.toml", "-o", d / "c.h5", "--steps", "90", "--rerun", "-q")
    assert r.returncode == 0, r.stderr
    assert f"recorded 91 frames into {d / 'c.rrd'}" in r.stdout
    r = blobsim("replay", d / "c.h5", "-o", d / "replayed.rrd")
    assert r.returncode == 0, r.stderr
    return d


def test_recording_holds_the_trajectory_at_every_frame(recorded):
    t = read_trajectory(recorded / "c.h5")
    steps, pos = read_positions(recorded / "c.rrd")
    np.testing.assert_array_equal(steps, t.step)
    np.testing.assert_array_equal(pos, t.position.astype(np.float32))


def test_rerun_verifies_the_file_and_it_carries_a_blueprint(recorded):
    import rerun.chunk as rc
    r = subprocess.run([str(RERUN), "rrd", "verify", str(recorded / "c.rrd")], capture_output=True, text=True,
                       timeout=120, env={**os.environ, "RERUN_ANALYTICS": "0"})
    assert r.returncode == 0, r.stderr
    reader = rc.RrdReader(str(recorded / "c.rrd"))
    assert len(reader.blueprints()) == 1 and len(reader.recordings()) == 1


def test_recording_content_statics_series_colors(recorded):
    import rerun.chunk as rc
    chunks = rc.RrdReader(str(recorded / "c.rrd")).stream().to_chunks()
    statics = {c.entity_path for c in chunks if c.entity_path.startswith("/world/statics/")}
    assert statics == {"/world/statics/0", "/world/statics/1", "/world/statics/2"}
    assert all(c.is_static for c in chunks if c.entity_path.startswith("/world/statics/"))
    names = [c for c in chunks if c.entity_path == "/series/area_error" and c.is_static][0]
    assert names.to_record_batch().column("SeriesLines:names").to_pylist()[0] == ["light", "heavy_0_0", "heavy_0_1",
                                                                                  "heavy_0_2"]
    series = [c for c in chunks if c.entity_path == "/series/kinetic_energy" and not c.is_static]
    assert sum(c.num_rows for c in series) == 91
    blobs = [c for c in chunks if c.entity_path == "/world/blobs" and not c.is_static]
    assert blobs and all("sim_time" in c.timeline_names for c in blobs)
    np.testing.assert_array_equal(blob_colors(4), blob_colors(10)[:4])  # stable from run to run
    for entity in ("/world/blobs", "/world/vertices", "/world/statics"):  # drawn y-up (rerun's 2D is y-down)
        flip = [c for c in chunks if c.entity_path == entity and c.is_static]
        batch = flip[0].to_record_batch()
        scale = [name for name in batch.column_names if name.endswith(":scale")]
        assert scale and list(batch.column(scale[0]).to_pylist()[0][0]) == [1.0, -1.0, 1.0], entity
    for path in ("area_error/max", "area_error/mean", "kinetic_energy/total"):
        rows = [c for c in chunks if c.entity_path == f"/series/summary/{path}" and not c.is_static]
        assert sum(c.num_rows for c in rows) == 91, path


def test_each_scene_has_its_own_application_id(recorded):
    import rerun.chunk as rc
    run, replayed = (rc.RrdReader(str(recorded / name)).recordings()[0] for name in ("c.rrd", "replayed.rrd"))
    assert run.application_id == replayed.application_id == "blobsim-crusher"  # the scene's, not a shared one
    assert run.recording_id != replayed.recording_id  # two recordings open side by side stay apart


def test_replay_makes_the_same_recording_as_run(recorded):
    a = read_positions(recorded / "c.rrd")
    b = read_positions(recorded / "replayed.rrd")
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


@pytest.mark.slow
def test_interrupted_run_leaves_a_readable_recording(tmp_path):
    out = tmp_path / "long.h5"
    proc = start_run([ROOT / "scenes" / "pile.toml", "--steps", "100000", "--rerun"], out)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    t = read_trajectory(out)
    steps, pos = read_positions(tmp_path / "long.rrd")
    assert len(steps) == len(t.step) > 1
    np.testing.assert_array_equal(pos[-1], t.position[-1].astype(np.float32))


def test_scene_key_and_view_without_display(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(f'[output]\nrerun = "{tmp_path / "from_key.rrd"}"\n\n[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.5\n')
    assert blobsim("run", scene, "-o", tmp_path / "s.h5", "--steps", "10", "-q").returncode == 0
    assert (tmp_path / "from_key.rrd").exists()
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = blobsim("view", tmp_path / "s.h5", env=env)
    assert r.returncode == 0 and f"the recording is {tmp_path / 's.rrd'}" in r.stderr
    assert (tmp_path / "s.rrd").exists()
    r = blobsim("view", tmp_path / "missing.rrd", env=env)
    assert r.returncode == 2 and "no such file" in r.stderr
    r = blobsim("replay", scene)
    assert r.returncode == 2 and "not a readable HDF5 file" in r.stderr


def test_a_growing_blobs_area_error_is_measured_against_its_scheduled_target(tmp_path):
    """A blob scaled 1 -> 1.3 over 1 s: its area grows 1.69× on purpose. The recording's area error follows the
    schedule's target (it read 0.69 against the scene's when only the scene's target was known)."""
    import rerun.chunk as rc
    (tmp_path / "grow.toml").write_text("[scene]\ngravity = [0.0, 0.0]\nsteps = 90\n[[blob]]\nname = \"b\"\n"
                                        "center = [0.0, 0.0]\nradius = 0.3\n[[schedule]]\nkey = \"blob.b.scale\"\n"
                                        "at = [[0.0, 1.0], [1.0, 1.3]]\n")
    r = blobsim("run", tmp_path / "grow.toml", "-o", tmp_path / "g.h5", "--rerun", "-q")
    assert r.returncode == 0, r.stderr
    worst = []
    for chunk in rc.RrdReader(str(tmp_path / "g.rrd")).stream().to_chunks():
        if chunk.entity_path == "/series/summary/area_error/max" and not chunk.is_static:
            batch = chunk.to_record_batch()
            column = [name for name in batch.column_names if "scalar" in name.lower()][0]
            worst += [v[0] for v in batch.column(column).to_pylist()]
    assert len(worst) == 91 and max(worst) < 0.01
