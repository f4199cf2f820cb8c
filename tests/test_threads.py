"""How many threads a run uses: the choice, --threads, and the same
bits whatever the count, changed call by call."""

import os
from pathlib import Path

import pytest
from conftest import cli

from blobcli import load_scene, read_trajectory, simulate
from blobcli.core import load
from blobcli.io import threads as threads_module
from blobcli.io.threads import PROBE_MAX_SECONDS, PROBE_SECONDS, ThreadChoice
from blobcli.tools.compare import compare_files

ROOT_SCENES = Path(__file__).resolve().parent.parent / "scenes"
_, lib = load()


def auto_choice(monkeypatch, most=2, free=None):
    """An auto choice on `most` threads; `free`: the free cores it sees (None: it cannot see the load)."""
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setattr(threads_module, "available", lambda: most)
    monkeypatch.setattr(threads_module, "free_cores", lambda ours=1: free)
    return ThreadChoice(None, parallel=True)


def probe(choice, per_step_now, per_step_probe):
    """One normal call at per_step_now s/step, then a probe at per_step_probe; returns the probe's threads."""
    threads, steps = choice.plan(80)
    choice.observe(threads, steps, per_step_now * steps)
    choice.next_probe = 0.0
    threads, steps = choice.plan(80)
    assert threads != choice.current and steps == 10  # a probe: the other count, an eighth of the steps
    choice.observe(threads, steps, per_step_probe * steps)
    return threads


def test_auto_falls_back_to_one_thread_when_it_is_faster_and_comes_back(monkeypatch):
    with auto_choice(monkeypatch) as choice:
        assert choice.adaptive and choice.current == 2
        assert probe(choice, 1e-3, 5e-4) == 1 and choice.current == 1  # the other core is busy: one thread wins
        assert probe(choice, 1e-3, 4e-4) == 2 and choice.current == 2  # it is free again


def test_probes_that_lose_come_less_often_and_a_sudden_slowdown_probes_at_once(monkeypatch):
    with auto_choice(monkeypatch) as choice:
        intervals = []
        for _ in range(8):
            probe(choice, 1e-3, 2e-3)
            intervals.append(choice.interval)
        assert choice.current == 2
        assert intervals[0] == 2 * PROBE_SECONDS and intervals[-1] == PROBE_MAX_SECONDS
        choice.next_probe = float("inf")
        threads, steps = choice.plan(80)
        choice.observe(threads, steps, 10 * choice.average * steps)  # 10× slower: something started beside it
        assert choice.next_probe <= threads_module.time.perf_counter() and choice.interval == PROBE_SECONDS


def test_fixed_counts_and_serial_builds_never_probe(monkeypatch):
    before = lib.bc_threads()
    with ThreadChoice(1, parallel=True) as choice:
        assert not choice.adaptive and choice.plan(80) == (1, 80) and lib.bc_threads() == 1
    assert lib.bc_threads() == before  # the calling thread's count, as it was
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    assert not ThreadChoice(None, parallel=True).adaptive  # the user fixed it
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert ThreadChoice(None, parallel=False).most == 1


@pytest.mark.skipif(not lib.bc_has_openmp(), reason="the core is built without OpenMP: one thread")
def test_the_pool_is_the_users_omp_num_threads_else_the_cores(monkeypatch):
    monkeypatch.delenv(threads_module.SHARED_POOL, raising=False)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert threads_module.available() == len(os.sched_getaffinity(0)) and not threads_module.fixed_by_environment()
    for text, n in (("3", 3), (" 5 ", 5), ("3,1", 3)):  # (a list: its first entry is this level's count)
        monkeypatch.setenv("OMP_NUM_THREADS", text)
        assert threads_module.available() == n and threads_module.fixed_by_environment()
    for text in ("", "0", "-2", "many"):  # libgomp ignores these and keeps the cores
        monkeypatch.setenv("OMP_NUM_THREADS", text)
        assert threads_module.available() == len(os.sched_getaffinity(0)), text
        assert not threads_module.fixed_by_environment(), text


def test_threads_above_what_the_core_may_use_is_bad_input(tmp_path):
    code, out, err = cli("run", ROOT_SCENES / "gish.toml", "-o", tmp_path / "g.h5", "--threads", "999")
    assert code == 2 and "--threads: at most" in err and "OMP_NUM_THREADS" in err and "(got 999)" in err, err
    assert not (tmp_path / "g.h5").exists()


@pytest.mark.slow
def test_changing_the_thread_count_call_by_call_changes_no_bit(tmp_path, monkeypatch):
    """The pile (120 blobs: the parallel build) with the count switched between 1 and 2 at every call,
    against a run on one thread."""
    if threads_module.available() < 2:
        pytest.skip("the core has one thread here")
    sc = load_scene(ROOT_SCENES / "pile.toml")
    from blobcli.scene.schema import with_overrides
    sc = with_overrides(sc, steps=90)
    assert simulate(sc, tmp_path / "one.h5", threads=1).status == "complete"
    flips = iter(range(10**6))
    real_plan = ThreadChoice.plan

    def flipping_plan(self, steps):
        threads, steps = real_plan(self, steps)
        threads = 1 + next(flips) % 2
        lib.bc_set_threads(threads)
        return threads, max(1, steps // 4)
    monkeypatch.setattr(ThreadChoice, "plan", flipping_plan)
    assert simulate(sc, tmp_path / "flip.h5").status == "complete"
    assert next(flips) > 10
    assert compare_files(tmp_path / "one.h5", tmp_path / "flip.h5").same
    assert read_trajectory(tmp_path / "flip.h5").complete


def test_threads_that_do_not_get_their_cores_fall_back_to_one_at_once(monkeypatch):
    with auto_choice(monkeypatch) as choice:
        choice.next_probe = float("inf")
        threads, steps = choice.plan(80)
        choice.observe(threads, steps, 0.05, cpu_seconds=2 * 0.05 * 0.99)  # both on their cores: stays
        assert choice.current == 2
        choice.observe(threads, steps, 0.05, cpu_seconds=0.05 * 1.48)  # beside a busy process: one thread
        assert choice.current == 1 and choice.switches == 1


def test_with_the_load_in_view_it_probes_only_what_can_win(monkeypatch):
    with auto_choice(monkeypatch, free=1) as choice:  # another process runs on the second core
        assert choice.current == 1
        choice.next_probe = 0.0
        assert choice.plan(80) == (1, 80) and choice.interval == 2 * PROBE_SECONDS  # no probe: asks again later
        monkeypatch.setattr(threads_module, "free_cores", lambda ours=1: 2)  # the core is free again
        choice.next_probe = 0.0
        assert choice.plan(80) == (2, 10)  # a probe of both threads
    with auto_choice(monkeypatch, free=2) as choice:  # alone: all threads, and no probe of one
        assert choice.current == 2
        choice.next_probe = 0.0
        assert choice.plan(80) == (2, 80)


def test_a_call_too_short_to_time_is_not_a_probe(monkeypatch):
    with auto_choice(monkeypatch) as choice:
        choice.next_probe = 0.0
        assert choice.plan(1) == (2, 1) and choice.plan(7) == (2, 7)  # one step timed alone is noise
        assert choice.plan(8) == (1, 1)  # the first call long enough: the probe that was due


def test_the_load_counts_out_the_runs_own_threads(monkeypatch):
    """/proc/loadavg's running count includes the caller and, right after a parallel region, the pool's
    spinning threads: on two threads alone the run must not see itself as a crowd."""
    class Loadavg:
        def __init__(self, *args):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            pass

        def read(self):
            return "1.00 1.00 1.00 3/200 123\n"
    monkeypatch.setattr(threads_module, "open", Loadavg, raising=False)
    monkeypatch.setattr(threads_module.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert threads_module.free_cores(1) == 0  # two others running: no core free
    assert threads_module.free_cores(2) == 1  # our second thread and one other
    assert threads_module.free_cores(3) == 2


def test_a_local_workers_pool_adapts_and_a_users_count_stays_fixed(monkeypatch):
    from blobcli.tools.executor import default_workers, worker_threads
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.delenv(threads_module.SHARED_POOL, raising=False)
    env = worker_threads()
    assert env == {"OMP_NUM_THREADS": str(default_workers()), threads_module.SHARED_POOL: "1"}
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    monkeypatch.setattr(threads_module, "available", lambda: 2)
    assert ThreadChoice(None, parallel=True).adaptive  # a worker's run: adapts within the pool
    monkeypatch.delenv(threads_module.SHARED_POOL)
    monkeypatch.setenv("OMP_NUM_THREADS", "1")  # the user's own count
    assert worker_threads() == {"OMP_NUM_THREADS": "1"}
    assert not ThreadChoice(None, parallel=True).adaptive


def test_local_workers_keep_the_allocators_defaults_and_no_profiler(monkeypatch):
    """Dask's MALLOC_TRIM_THRESHOLD_ made every one of the step's temporaries of 128 KiB or more come
    from new pages (17,000 page faults a second in a jam's worker); its profiler took the core 100 times
    a second (tools/executor.py). The workers' core pool has every core (adapting), their BLAS one
    thread; and this process's own environment gets no OMP_NUM_THREADS from Dask (it would fix the
    count of every later run here)."""
    from blobcli.tools.executor import default_workers, run_tasks
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.delenv(threads_module.SHARED_POOL, raising=False)

    def inside():
        import os

        import dask
        return (os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS"),
                os.environ.get(threads_module.SHARED_POOL), os.environ.get("OPENBLAS_NUM_THREADS"),
                os.environ.get("MKL_NUM_THREADS"), dask.config.get("distributed.worker.profile.enabled"))
    [(_, seen)] = list(run_tasks(inside, [()], workers=1))
    assert seen == (None, str(default_workers()), "1", "1", "1", False)
    assert "OMP_NUM_THREADS" not in os.environ and not threads_module.fixed_by_environment()


def test_the_cores_share_is_judged_over_calls_not_one_short_call(monkeypatch):
    with auto_choice(monkeypatch) as choice:
        choice.next_probe = float("inf")
        calls = [(0.005, 0.95)] * 10 + [(0.017, 0.80)] + [(0.005, 0.95)] * 7  # one hiccup among 5-ms steps
        for seconds, share in calls:
            choice.observe(2, 1, seconds, cpu_seconds=2 * seconds * share)
        assert choice.current == 2
        for _ in range(20):  # beside a busy process: 0.74 of a core per thread, call after call
            threads, steps = choice.plan(1)
            choice.observe(threads, steps, 0.005, cpu_seconds=threads * 0.005 * 0.74)
        assert choice.current == 1 and choice.switches == 1
