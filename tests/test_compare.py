"""blobsim compare, golden trajectories, determinism and resume."""

import json
import os
import shutil
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import COMPARE_REPORT, GOLDEN_ATOL, blobsim, start_run
from golden_cases import (
    GOLDEN,
    HASH_SCENE,
    HASH_STEPS,
    final_positions_hash,
    version_key,
)

from blobcli import load_scene, simulate
from blobcli.scene.schema import with_overrides
from blobcli.tools.compare import CannotCompare, compare_files

ROOT = Path(__file__).resolve().parent.parent
GOLDEN_DIR = ROOT / "tests" / "golden"




@pytest.fixture
def pair(tmp_path):
    """Two copies of a golden file, the second to be edited by the test."""
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    shutil.copy(GOLDEN_DIR / "crusher.h5", a)
    shutil.copy(GOLDEN_DIR / "crusher.h5", b)
    return a, b


def edit(path, frame, vertex, axis, value):
    with h5py.File(path, "r+") as f:
        f["particles/blobs/position/value"][frame, vertex, axis] = value


def test_identical_files_are_the_same(pair):
    r = blobsim("compare", *pair)
    assert r.returncode == 0 and r.stdout.strip().endswith("verdict: same")


def test_a_difference_is_located_and_divergence_reported(pair):
    a, b = pair
    with h5py.File(a) as f:
        x = f["particles/blobs/position/value"][7, 40, 1]
    edit(b, 7, 40, 1, x + 2e-5)  # blob 1 owns vertices 32..63: vertex 8 of blob 1
    r = blobsim("compare", a, b)
    assert r.returncode == 1
    assert "first difference: frame 7 (step 70, t = 1.16667 s), blob 1 (heavy_0_0) vertex 8:" in r.stdout
    assert "divergence: > 1e-12 m from step 70, > 1e-09 m from step 70, > 1e-06 m from step 70, never > 0.001 m" in r.stdout
    assert "verdict: different" in r.stdout
    report = json.loads(blobsim("compare", a, b, "--json").stdout)
    assert report["first_difference"]["blob_name"] == "heavy_0_0" and not report["same"]
    assert abs(report["max_deviation"] - 2e-5) < COMPARE_REPORT


def test_tolerances_and_horizons(pair):
    a, b = pair
    with h5py.File(a) as f:
        x = f["particles/blobs/position/value"][9, 3, 0]
    edit(b, 9, 3, 0, x * (1 + 1e-9))
    assert blobsim("compare", a, b).returncode == 1
    assert blobsim("compare", a, b, "--atol", "1e-6").returncode == 0
    assert blobsim("compare", a, b, "--rtol", "1e-8").returncode == 0
    assert blobsim("compare", a, b, "--rtol", "1e-10").returncode == 1
    assert blobsim("compare", a, b, "--frames", "9").returncode == 0  # frames 0..8
    assert blobsim("compare", a, b, "--frames", "10").returncode == 1
    assert blobsim("compare", a, b, "--until", "1.4").returncode == 0  # frame 9 is t = 1.5 s
    assert blobsim("compare", a, b, "--until", "1.5").returncode == 1


def test_nan_against_a_number_is_a_difference_nan_against_nan_is_not(pair):
    a, b = pair
    edit(b, 4, 0, 0, np.nan)
    assert blobsim("compare", a, b, "--atol", "1").returncode == 1
    edit(a, 4, 0, 0, np.nan)
    assert blobsim("compare", a, b).returncode == 0


def test_cannot_compare_exits_2(tmp_path, pair):
    a, b = pair
    text = tmp_path / "t.h5"
    text.write_text("not hdf5")
    cases = [(a, tmp_path / "missing.h5", "no such file"),
             (a, text, "not a readable HDF5 file"),
             (a, GOLDEN_DIR / "gish.h5", "different blob layout")]
    every5 = tmp_path / "every5.h5"
    sc = with_overrides(load_scene(ROOT / "scenes" / "crusher.toml"), steps=20)
    from dataclasses import replace
    simulate(replace(sc, output=replace(sc.output, every=5)), every5)
    cases.append((a, every5, "different step grid"))
    with h5py.File(b, "r+") as f:
        f.attrs["complete"] = False
    cases.append((a, b, "incomplete run"))
    for x, y, message in cases:
        r = blobsim("compare", x, y)
        assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr, (message, r.stderr)
    assert blobsim("compare", a, b, "--allow-incomplete").returncode == 0


def test_different_lengths_are_a_difference_unless_a_horizon_is_given(tmp_path):
    sc = load_scene(ROOT / "scenes" / "crusher.toml")
    long, short = tmp_path / "long.h5", tmp_path / "short.h5"
    simulate(with_overrides(sc, steps=30), long)
    simulate(with_overrides(sc, steps=20), short)
    report = compare_files(long, short)
    assert not report.same and "different length: 31 frames" in report.notes[0]
    assert compare_files(long, short, frames=21).same


@pytest.mark.parametrize("name, steps, every", [pytest.param(*g, marks=pytest.mark.slow) if g[0] == "pile" else g
                                                for g in GOLDEN], ids=[g[0] for g in GOLDEN])  # pile: parallel
def test_fresh_runs_match_the_golden_trajectories(tmp_path, name, steps, every):
    from dataclasses import replace
    sc = with_overrides(load_scene(ROOT / "scenes" / f"{name}.toml"), steps=steps)
    simulate(replace(sc, output=replace(sc.output, every=every)), tmp_path / "fresh.h5")
    report = compare_files(GOLDEN_DIR / f"{name}.h5", tmp_path / "fresh.h5", atol=GOLDEN_ATOL)
    assert report.same, report.text() + "\n(if the physics changed on purpose: python tests/golden/regenerate.py)"


@pytest.mark.slow
def test_golden_hash_of_a_chaotic_pile():
    """Box2D-style: the final positions of a tumbling pile hash to a stored constant."""
    hashes = json.loads((GOLDEN_DIR / "hashes.json").read_text())
    key = version_key()
    if key not in hashes:
        pytest.skip(f"no stored hash for {key!r} (stored: {sorted(hashes)}); "
                    "check determinism on these versions, then: python tests/golden/regenerate.py")
    assert final_positions_hash(HASH_SCENE, HASH_STEPS) == hashes[key]


@pytest.mark.slow
def test_runs_are_bit_identical_whatever_the_thread_settings_and_hash_seed(tmp_path):
    outputs = []
    for k, settings in enumerate([{"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "PYTHONHASHSEED": "0"},
                                  {"OMP_NUM_THREADS": "2", "OPENBLAS_NUM_THREADS": "2", "PYTHONHASHSEED": "12345"}]):
        env = {**os.environ, **settings}
        out = tmp_path / f"run{k}.h5"
        r = blobsim("run", ROOT / "scenes" / "pile.toml", "-o", out, "--steps", "60", "-q", env=env)
        assert r.returncode == 0, r.stderr
        outputs.append(out)
        with h5py.File(out) as f:  # the file records the settings a reproduction needs
            assert f["parameters"].attrs["env_OMP_NUM_THREADS"] == settings["OMP_NUM_THREADS"]
            assert f["parameters"].attrs["threads"] == int(settings["OMP_NUM_THREADS"])
    assert compare_files(*outputs).same


@pytest.mark.slow
def test_resume_after_ctrl_c_is_bit_identical_to_an_uninterrupted_run(tmp_path):
    scene = ROOT / "scenes" / "pile.toml"
    partial = tmp_path / "run.h5"
    proc = start_run([scene, "--steps", "100000"], partial)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    with h5py.File(partial) as f:
        stopped_at = int(f["restart"].attrs["step"])
    assert stopped_at > 0
    total = stopped_at + 25
    r = blobsim("run", scene, "--resume", partial, "--steps", total, "-q")
    assert r.returncode == 0, r.stderr
    fresh = tmp_path / "fresh.h5"
    assert blobsim("run", scene, "-o", fresh, "--steps", total, "-q").returncode == 0
    report = compare_files(fresh, partial)
    assert report.same and report.frames == total + 1, report.text()


def test_resume_refuses_another_scene_or_a_finished_run(tmp_path):
    done = tmp_path / "done.h5"
    assert blobsim("run", ROOT / "scenes" / "crusher.toml", "-o", done, "--steps", "10", "-q").returncode == 0
    r = blobsim("run", ROOT / "scenes" / "gish.toml", "--resume", done)
    assert r.returncode == 2 and "different scene text" in r.stderr
    r = blobsim("run", ROOT / "scenes" / "crusher.toml", "--resume", done, "--steps", "10")
    assert r.returncode == 2 and "the run is complete at step 10; give more --steps" in r.stderr
    r = blobsim("run", ROOT / "scenes" / "crusher.toml", "--resume", done, "--steps", "12", "--method", "kot", "-q")
    assert r.returncode == 0  # a finished run can be extended


def test_compare_api_raises_for_missing_files(tmp_path):
    with pytest.raises(CannotCompare):
        compare_files(tmp_path / "x.h5", tmp_path / "y.h5")


def test_docs_show_the_writers_one_schema():
    from blobcli.io.h5md import LAYOUT
    assert LAYOUT in (ROOT / "docs" / "output-format.md").read_text()
