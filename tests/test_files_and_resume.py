"""Trajectory files and resume: what a run writes is complete or says it is not; one run writes a file at a time;
a crash, a full disk or a signal at any moment keeps what was written; a resumed run continues it bit for bit;
and the readers refuse a file that is not a trajectory."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import ONE, cli, scene_file, start_run

import blobcli.io.h5md.writer as h5md_writer
import blobcli.io.interrupts as interrupts
import blobcli.io.outputs as outputs
import blobcli.io.run as run_module
from blobcli import load_scene, read_trajectory, simulate

ROOT = Path(__file__).resolve().parent.parent
LONG = ONE.replace("steps = 40", "steps = 1000000").replace('name = "solo"', 'name = "solo"\ngrid = [5, 5]\nspacing = [1.2, 1.2]')


def frames_of(path):
    with h5py.File(path, "r") as f:
        return len(f["particles/blobs/position/step"]), bool(f.attrs["complete"]), "restart" in f


def small_blocks(monkeypatch):
    monkeypatch.setattr(h5md_writer, "BLOCK_BYTES", 1)  # one frame per block: many flushes, many copy steps


def pending_after(monkeypatch, calls: int, signum=signal.SIGINT):
    """interrupts.pending() reports `signum` from its (calls + 1)-th call on."""
    count = {"n": 0}

    def pending():
        count["n"] += 1
        return signum if count["n"] > calls else None
    monkeypatch.setattr(interrupts, "pending", pending)
    return count


# One writer per file ---------------------------------------------------------------------
def test_a_second_run_on_the_same_output_is_refused_naming_the_first(tmp_path):
    out = tmp_path / "c.h5"
    first = start_run([scene_file(tmp_path, LONG)], out)  # a first block of frames is on disk
    try:
        code, _, err = cli("run", scene_file(tmp_path), "-o", out, "-q")
        assert code == 2 and f"another blobsim run (pid {first.pid}) is writing this file" in err
    finally:
        first.send_signal(signal.SIGINT)
        stdout, stderr = first.communicate(timeout=60)
    assert first.returncode == 130, stderr
    n, complete, restart = frames_of(out)
    assert n > 1 and not complete and restart  # the first run's file is whole


def test_the_lock_is_released_when_a_run_is_killed(tmp_path):
    out = tmp_path / "k.h5"
    proc = start_run([scene_file(tmp_path, LONG)], out, min_bytes=1 << 16)
    proc.kill()
    proc.wait(timeout=30)
    (tmp_path / "k.h5.partial").rename(tmp_path / "killed.h5")  # as the refusal message says
    code, _, err = cli("run", scene_file(tmp_path), "-o", out, "-q")
    assert code == 0, err


# Interrupts while a resume copies the file -----------------------------------------------
def test_interrupt_while_an_in_place_resume_copies_leaves_the_original(tmp_path, monkeypatch):
    small_blocks(monkeypatch)
    scene = load_scene(scene_file(tmp_path))
    path = tmp_path / "r.h5"
    pending_after(monkeypatch, 20)  # stopped after 20 steps
    assert simulate(scene, path).status == "interrupted"
    before = path.read_bytes()
    pending_after(monkeypatch, 5)  # stopped while copying its 21 frames, one block each
    result = simulate(scene, path, resume=path)
    assert result.status == "interrupted" and not result.written and "unchanged" in result.message
    assert path.read_bytes() == before
    assert not (tmp_path / "r.h5.partial").exists()


def test_interrupt_after_the_copy_leaves_a_longer_resumable_file(tmp_path, monkeypatch):
    small_blocks(monkeypatch)
    scene = load_scene(scene_file(tmp_path))
    path = tmp_path / "r.h5"
    pending_after(monkeypatch, 20)
    simulate(scene, path)
    pending_after(monkeypatch, 21 + 5)  # 21 copy checks, then 5 steps
    result = simulate(scene, path, resume=path)
    assert result.status == "interrupted" and result.written
    n, complete, restart = frames_of(path)
    assert n == 26 and not complete and restart


def test_a_resumed_file_stopped_before_its_next_frame_keeps_its_restart(tmp_path, monkeypatch):
    scene = load_scene(scene_file(tmp_path))
    path = tmp_path / "r.h5"
    pending_after(monkeypatch, 20)
    simulate(scene, path)
    pending_after(monkeypatch, 10**6)  # the copy, then stopped before the first step
    monkeypatch.setattr(interrupts, "pending", iter([None] * 2 + [2] * 100).__next__)
    simulate(scene, path, resume=path)
    assert frames_of(path)[2]


# A run that stops early: the older file, a crash, no memory ------------------------------
def test_interrupt_before_the_first_step_leaves_an_older_file_alone(tmp_path, monkeypatch):
    path = tmp_path / "old.h5"
    assert cli("run", scene_file(tmp_path), "-o", path, "-q")[0] == 0
    before = path.read_bytes()
    pending_after(monkeypatch, 0)
    result = simulate(load_scene(scene_file(tmp_path)), path)
    assert result.status == "interrupted" and not result.written and result.exit_code == 130
    assert path.read_bytes() == before and not (tmp_path / "old.h5.partial").exists()


def test_a_crash_inside_the_loop_is_never_marked_complete(tmp_path, monkeypatch):
    real_advance, calls = run_module.advance, {"n": 0}

    def crashing_advance(*args, **kwargs):  # one step per call here: the scene records every step
        calls["n"] += 1
        if calls["n"] > 3:
            raise ZeroDivisionError("a bug")
        return real_advance(*args, **kwargs)
    monkeypatch.setattr(run_module, "advance", crashing_advance)
    code, _, err = cli("run", scene_file(tmp_path), "-o", tmp_path / "o.h5", "-q")
    assert code == 1 and "internal error: ZeroDivisionError: a bug" in err and "Traceback" not in err
    t = h5py.File(tmp_path / "o.h5")
    assert not t.attrs["complete"] and "ZeroDivisionError" in t.attrs["stopped"]
    assert len(t["particles/blobs/position/step"]) == 4


def test_out_of_memory_inside_the_loop_is_a_failed_run(tmp_path, monkeypatch):
    def no_memory(*args, **kwargs):
        raise MemoryError
    monkeypatch.setattr(run_module, "advance", no_memory)
    code, out, err = cli("run", scene_file(tmp_path), "-o", tmp_path / "o.h5", "-q")
    assert code == 1 and "blobsim: failed" in out, err
    assert not h5py.File(tmp_path / "o.h5").attrs["complete"]


# A full disk -----------------------------------------------------------------------------
def test_a_full_disk_keeps_the_frames_written_and_says_so(tmp_path, monkeypatch):
    small_blocks(monkeypatch)
    real, calls = os.statvfs, {"n": 0}

    class Full:
        f_bavail, f_frsize = 10, 4096

    def statvfs(path):
        calls["n"] += 1
        return real(path) if calls["n"] <= 10 else Full()
    monkeypatch.setattr(h5md_writer.os, "statvfs", statvfs)
    code, out, err = cli("run", scene_file(tmp_path), "-o", tmp_path / "o.h5", "-q")
    assert code == 1 and "no space left on the disk" in err and "kept the 10 frames" in err
    n, complete, restart = frames_of(tmp_path / "o.h5")
    assert n == 10 and not complete and restart
    assert not (tmp_path / "o.h5.partial").exists()
    monkeypatch.setattr(h5md_writer.os, "statvfs", real)  # room again: it resumes
    assert cli("run", scene_file(tmp_path), "--resume", tmp_path / "o.h5", "-q")[0] == 0


@pytest.mark.slow
def test_a_real_full_file_system(tmp_path):
    """On a 12 MiB tmpfs: room for two blocks of the pile (needs root and mount; skipped where neither is to be had)."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=12m", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (not root, or no mount permission)")
    try:
        r = subprocess.run([sys.executable, "-m", "blobcli", "run", str(ROOT / "scenes" / "pile.toml"), "-o",
                            str(mnt / "full.h5"), "--steps", "300", "-q"], capture_output=True, text=True, timeout=300)
        assert r.returncode == 1 and "no space left" in r.stderr and "Traceback" not in r.stderr, r.stderr
        assert not frames_of(mnt / "full.h5")[1]
        assert sorted(p.name for p in mnt.iterdir()) == ["full.h5"]
    finally:
        subprocess.run(["umount", str(mnt)])


# A signal during the final rename --------------------------------------------------------
def test_a_signal_during_the_final_rename_is_held_until_the_file_is_in_place(tmp_path, monkeypatch):
    real = outputs.publish

    def publish_with_signal(partial, path):
        os.kill(os.getpid(), signal.SIGTERM)  # arrives inside the deferred section
        real(partial, path)
    monkeypatch.setattr(h5md_writer, "publish", publish_with_signal)
    code, out, _ = cli("run", scene_file(tmp_path), "-o", tmp_path / "o.h5", "-q")
    assert code == 0 and frames_of(tmp_path / "o.h5") == (41, True, True)
    assert not (tmp_path / "o.h5.partial").exists()


# Resume needs more steps than were done --------------------------------------------------
def test_resume_of_a_complete_run_asks_for_more_steps_and_keeps_restart(tmp_path):
    scene = scene_file(tmp_path, ONE.replace("steps = 40", "steps = 10") + "[output]\nevery = 3\n")
    path = tmp_path / "ev.h5"
    assert cli("run", scene, "-o", path, "-q")[0] == 0
    code, _, err = cli("run", scene, "--resume", path, "-q")
    assert code == 2 and "the run is complete at step 10; give more --steps (got 10)" in err
    assert cli("run", scene, "--resume", path, "--steps", "20", "-q")[0] == 0
    assert frames_of(path) == (7, True, True)


def test_resume_with_fewer_steps_than_done_is_refused(tmp_path, monkeypatch):
    pending_after(monkeypatch, 30)
    path = tmp_path / "p.h5"
    simulate(load_scene(scene_file(tmp_path)), path)
    monkeypatch.undo()
    code, _, err = cli("run", scene_file(tmp_path), "--resume", path, "--steps", "20", "-q")
    assert code == 2 and "already reached step 30; give more --steps (got 20)" in err


# A run that cannot go on says why --------------------------------------------------------
@pytest.mark.slow
def test_thousands_of_coincident_blobs_stop_with_a_reason_not_exhausted_memory(tmp_path):
    text = ('[scene]\nsteps = 5\n[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.01\nvertices = 3\n'
            'grid = [100, 50]\nspacing = [1e-6, 1e-6]\n')
    code, out, err = cli("run", scene_file(tmp_path, text), "-o", tmp_path / "o.h5", "-q")
    assert code == 1 and "blob pairs overlap" in err and "spawned on top of each other" in err
    assert not frames_of(tmp_path / "o.h5")[1]


# Signals before the loop, and inside a finaliser -----------------------------------------
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_early_signal_exits_130_without_a_traceback(tmp_path, signum):
    proc = subprocess.Popen([sys.executable, "-m", "blobcli", "run", str(scene_file(tmp_path, LONG)), "-o",
                             str(tmp_path / "o.h5"), "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(0.5)  # inside main (its handlers are installed first), before the loop
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in err, err


def test_a_signal_whose_raise_python_swallows_is_kept_quietly():
    """A signal that lands while a __del__ runs (llvmlite's, as numba compiles) raises its Interrupted where Python
    swallows it and prints a traceback: it prints nothing and stays pending, so the run stops at its next step."""
    code = ("import os, signal\n"
            "from blobcli.io import interrupts\n"
            "interrupts.install()\n"
            "class Dying:\n"
            "    def __del__(self):\n"
            "        os.kill(os.getpid(), signal.SIGINT)\n"
            "Dying()\n"
            "print(interrupts.pending())\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == str(int(signal.SIGINT)) and "Traceback" not in r.stderr, r


# What the file records about the shapes, and what the readers accept ---------------------
def test_a_run_that_ends_inside_out_says_so_and_records_it(tmp_path, monkeypatch):
    real_advance = run_module.advance

    def flipping_advance(state, model, params, *args, **kwargs):
        done = real_advance(state, model, params, *args, **kwargs)
        # after the last step only, a mirror image: every ring turned inside out (mirrored after each call,
        # a ring would be mirrored back by the next, which self-contact keeps from turning itself over between)
        if state.steps_done[0] == params.steps:
            state.pos[:, 0] *= -1.0
        return done
    monkeypatch.setattr(run_module, "advance", flipping_advance)
    code, out, _ = cli("run", scene_file(tmp_path), "-o", tmp_path / "o.h5", "-q")
    assert code == 0 and "warning: 1 blob inside out (solo) at the end" in out
    assert h5py.File(tmp_path / "o.h5").attrs["warnings"] == "1 blob inside out (solo) at the end"


def test_self_intersecting_rings_are_found():
    from blobcli import build, parse_scene
    from blobcli.sim.measure import shape_warning
    model, state = build(parse_scene("[[blob]]\npoints = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]\n"))
    assert shape_warning(state, model) == ""
    state.pos[:] = state.pos[::-1].copy()  # the same square, wound the other way
    assert shape_warning(state, model) == "1 blob inside out (blob0) at the end"
    state.pos[:] = [[0.0, 0.0], [4.0, 0.0], [1.0, 2.0], [3.0, 2.0]]  # edges 1 and 3 cross; area still +2
    assert shape_warning(state, model) == "1 blob self-intersecting (blob0) at the end"


def test_readers_refuse_files_that_are_not_trajectories(tmp_path):
    traj = tmp_path / "t.h5"
    assert cli("run", scene_file(tmp_path), "-o", traj, "-q")[0] == 0
    read_trajectory(traj)
    with h5py.File(traj, "r+") as f:
        f["parameters/blob_offsets"][...] = np.array([0, 5])
    for args in (("compare", traj, traj), ("replay", traj, "-o", tmp_path / "r.rrd"), ("render", traj),
                 ("run", scene_file(tmp_path), "--resume", traj, "--steps", "99")):
        code, _, err = cli(*args)
        assert code == 2 and "do not split the 32 vertices" in err, (args, err)
