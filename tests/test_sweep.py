"""blobsim sweep: sweep files validated like scenes, points bit-identical to `blobsim run`,
failures as rows, resume, interrupts, and a real Dask scheduler with a worker killed mid-sweep."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from conftest import cli

from blobcli.tools.sweep import load_sweep

BASE = """[scene]
steps = 30
[[blob]]
name = "b"
center = [0.0, 0.6]
radius = 0.5
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def sweep_file(tmp_path, axes, extra="", base=BASE, name="sw.toml"):
    (tmp_path / "base.toml").write_text(base)
    text = f'[sweep]\nscene = "base.toml"\n{extra}'
    for key, values in axes:
        text += f"\n[[sweep.axis]]\nkey = \"{key}\"\nvalues = {values}\n"
    (tmp_path / name).write_text(text)
    return tmp_path / name


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("extra, axes, message", [
    ('mode = "spiral"\n', [("scene.substeps", "[1]")], "sw.toml:3: sweep.mode: must be one of grid, zip (got 'spiral')"),
    ("", [("blob[*].frction", "[0.1]")], "sweep.axis[0].key: 'frction' is not a key of [blob]; did you mean 'friction'?"),
    ("", [("blob[3].friction", "[0.1]")], "sweep.axis[0].key: the base scene has 1 [[blob]] tables"),
    ("", [("friction", "[0.1]")], "sweep.axis[0].key: must be scene.<key>, output.<key>"),
    ("", [("scene.substeps", "[]")], "sweep.axis[0].values: must be a non-empty list"),
    ('mode = "zip"\n', [("scene.substeps", "[1, 2]"), ("blob[*].friction", "[0.1]")], "mode zip needs axes of equal length"),
    ("", [("blob[0].friction", "[0.2, -1.0]")], "point 1 (blob[0].friction = -1.0) is not a valid scene: "
                                                "blob[0].friction: must be >= 0 (got -1.0)"),
    ("scne = 1\n", [("scene.substeps", "[1]")], "sw.toml:3: sweep.scne: unknown key; did you mean 'scene'?"),
])
def test_bad_sweep_files_exit_2_with_one_line_each(tmp_path, extra, axes, message):
    code, out, err = cli("sweep", sweep_file(tmp_path, axes, extra), "-o", tmp_path / "out", "--workers", "0")
    assert code == 2 and message in err and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()




def test_points_are_the_base_scene_with_the_values_put_in(tmp_path):
    grid = load_sweep(sweep_file(tmp_path, [("blob[*].friction", "[0.1, 0.2]"), ("scene.substeps", "[1, 2, 3]")]))
    assert grid.points == ((0.1, 1), (0.1, 2), (0.1, 3), (0.2, 1), (0.2, 2), (0.2, 3))
    assert "friction = 0.2" in grid.texts[4] and "substeps = 2" in grid.texts[4]
    zipped = load_sweep(sweep_file(tmp_path, [("blob[0].mass", "[1.0, 2.0]"), ("scene.iterations", "[1, 4]")],
                                   'mode = "zip"\n'))
    assert zipped.points == ((1.0, 1), (2.0, 4)) and zipped.name == "sw"


def test_local_cluster_sweep_rows_failures_and_bit_identity(tmp_path):
    sw = sweep_file(tmp_path, [("blob[*].velocity", "[[0.0, 0.0], [1e12, 0.0]]"), ("scene.substeps", "[1, 2]")])
    code, out, err = cli("sweep", sw, "-o", tmp_path / "out", "--workers", "2", "-q")
    assert code == 1, err  # the 1e12 m/s points run away (nothing stops them sideways)
    table = rows(tmp_path / "out" / "sw" / "summary.csv")
    assert [r["status"] for r in table][:2] == ["ok", "ok"]
    assert all(r["status"].startswith("failed: step 1: blob 0 (b)") for r in table[2:])
    assert table[0]["blob[*].velocity"] == "[0.0, 0.0]" and table[1]["scene.substeps"] == "2"
    assert (tmp_path / "out" / "sw" / "summary.png").stat().st_size > 1000
    point = tmp_path / "out" / "sw" / "point-0001.toml"
    assert cli("run", point, "-o", tmp_path / "alone.h5", "-q")[0] == 0
    code, out, _ = cli("compare", tmp_path / "alone.h5", tmp_path / "out" / "sw" / "point-0001.h5")
    assert code == 0 and "verdict: same" in out


def test_a_second_sweep_reuses_finished_points_and_reruns_what_is_missing(tmp_path):
    sw = sweep_file(tmp_path, [("scene.substeps", "[1, 2, 3]")])
    assert cli("sweep", sw, "-o", tmp_path / "out", "--workers", "0", "-q")[0] == 0
    d = tmp_path / "out" / "sw"
    (d / "point-0001.h5").unlink()
    before = (d / "point-0000.h5").stat().st_mtime_ns
    code, _, err = cli("sweep", sw, "-o", tmp_path / "out", "--workers", "0", "-q")
    assert code == 0 and "3 points (2 already done)" in err
    assert (d / "point-0000.h5").stat().st_mtime_ns == before and (d / "point-0001.h5").exists()
    # a changed base scene is a different point: run again
    sw = sweep_file(tmp_path, [("scene.substeps", "[1, 2, 3]")], base=BASE.replace("0.5", "0.4"))
    code, _, err = cli("sweep", sw, "-o", tmp_path / "out", "--workers", "0", "-q")
    assert code == 0 and "(0 already done)" in err


@pytest.mark.slow
def test_interrupted_sweep_keeps_finished_points_and_resumes(tmp_path):
    long = BASE.replace("steps = 30", "steps = 2000")
    sw = sweep_file(tmp_path, [("scene.substeps", "[1, 2, 3, 16, 16, 16]")], base=long)  # the last ones are long
    d = tmp_path / "out" / "sw"
    proc = subprocess.Popen([sys.executable, "-m", "blobcli", "sweep", str(sw), "-o", str(tmp_path / "out"),
                             "--workers", "1", "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (d / "point-0000.h5").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in err, (proc.returncode, out, err)
    table = rows(d / "summary.csv")
    assert table[0]["status"] == "ok" and any(r["status"] == "interrupted" for r in table), table
    code, _, err = cli("sweep", sw, "-o", tmp_path / "out", "--workers", "0", "-q")
    assert code == 0, err
    assert all(r["status"] == "ok" for r in rows(d / "summary.csv"))


@pytest.mark.slow
def test_real_scheduler_and_workers_with_one_worker_killed(tmp_path):
    """A `dask scheduler` and two `dask worker` processes on 127.0.0.1, started and stopped here;
    one worker is killed while the sweep runs, and Dask runs its point again on the other."""
    long = BASE.replace("steps = 30", "steps = 1500")
    sw = sweep_file(tmp_path, [("scene.substeps", "[1, 2, 3, 4, 5, 6]")], base=long)
    info = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen([*dask, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        workers = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                                     "--host", "127.0.0.1", "--no-dashboard", "--no-nanny"], env=env,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        procs += workers
        sweep = subprocess.Popen([sys.executable, "-m", "blobcli", "sweep", str(sw), "-o", str(tmp_path / "out"),
                                  "--scheduler", address, "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)
        procs.append(sweep)
        d = tmp_path / "out" / "sw"
        while not list(d.glob("point-*.h5.partial")) and time.monotonic() < deadline + 60:
            time.sleep(0.02)
        workers[0].kill()
        out, err = sweep.communicate(timeout=240)
        assert sweep.returncode == 0, err
        assert all(r["status"] == "ok" for r in rows(d / "summary.csv"))
        assert not list(d.glob("*.partial")) and len(list(d.glob("point-*.h5"))) == 6
    finally:
        for p in procs:
            p.kill()
            p.wait(timeout=30)
