"""Where many runs go: a Dask cluster (local by default), or this process.

`blobsim sweep`, `study` and `stress` hand their runs to `run_tasks`, one code path for all
three. With `workers = 0` the tasks run here, one after another; otherwise on Dask
distributed: an embedded `LocalCluster` of single-threaded worker processes (one per core
unless told), or the cluster at `scheduler` (its workers must have blobsim installed).
Dask is imported only here, so `blobsim --help` and `blobsim run` never load it.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Callable, Iterator

RETRIES = 2  # a task whose worker died (killed, out of memory) is run again elsewhere this often
MAX_WORKERS_PER_CORE = 4  # --workers at most this many local worker processes per core
CONNECT_SECONDS = 10  # a scheduler that does not answer within this is an error
CLOSE_SECONDS = 3  # a local cluster's workers get this long to stop in order (a Ctrl-C: within 5 s in all)


def _quiet_workers() -> dict:
    """Dask settings that leave a local cluster's cores to the runs (the jam of
    scenes/jamming/bidisperse.toml, two workers on two cores: 11.0 and 10.5 ms a step against 8.3 and
    8.2 in two plain processes; 8.3 and 8.9 with these):
    - no MALLOC_TRIM_THRESHOLD_ for the workers (Dask sets 64 KiB to hand freed memory back to the
      system). Any value set fixes glibc's mmap threshold at 128 KiB, so each of the step's
      temporaries that size or larger came from new pages: 17,000 page faults a second, a tenth
      of the step's time spent in the kernel. The workers keep glibc's own defaults;
    - no statistical profiler in the workers (it samples every thread's stack 100 times a second,
      each time taking the core from the run; the dashboard's profile page stays empty);
    - the servers' event-loop check every second instead of every 20 ms.
    And no OMP_NUM_THREADS before the spawn: Dask writes its pre-spawn environment (OMP_NUM_THREADS=1
    by default) into this process's own os.environ, where it would read as the user's fixed count
    (io/threads.py) for every later run here. The workers get theirs from worker_threads()."""
    import dask
    import distributed  # noqa: F401 - loads distributed's defaults into dask.config
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k not in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS")}
    return {"distributed.nanny.pre-spawn-environ": environ, "distributed.worker.profile.enabled": False,
            "distributed.admin.tick.interval": "1s"}


# numpy's BLAS in a worker: one thread (the workers already take a core each). Named for each library, as
# OMP_NUM_THREADS is the compiled core's pool (OpenBLAS reads OPENBLAS_NUM_THREADS before OMP_NUM_THREADS).
SINGLE_THREADED_BLAS = {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def worker_threads() -> dict:
    """The environment that sets a local worker's threads for the compiled core's OpenMP pool
    (OMP_NUM_THREADS: libgomp reads it when the core is loaded, in the worker). One single-threaded
    worker process per core, each with a pool of every core's threads that its runs use only while
    the cores are free (io/threads.py): a run starts on one thread beside busy workers and takes the
    idle ones' cores at the end (the last seed of a jam). An OMP_NUM_THREADS of the user's is kept,
    and fixed."""
    from ..io.threads import SHARED_POOL, fixed_by_environment
    if fixed_by_environment():
        return {"OMP_NUM_THREADS": os.environ["OMP_NUM_THREADS"]}
    return {"OMP_NUM_THREADS": str(default_workers()), SHARED_POOL: "1"}


class SchedulerError(Exception):
    """The Dask scheduler named cannot be reached; the message is one line for the user."""


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def run_tasks(fn: Callable, tasks: list[tuple], scheduler: str | None = None, workers: int | None = None,
              progress: bool = False, label: str = "runs",
              stop: Callable | None = None) -> Iterator[tuple[int, object]]:
    """Yield (index, fn(*tasks[index])) as each task finishes, in any order. A task that raises
    is re-raised here. Closing the generator (or Ctrl-C) cancels the tasks not yet started; on Dask,
    `stop` is then run on every worker (a running task should see it and return soon: a run stops at
    its next step boundary, its file whole and resumable) and they get CLOSE_SECONDS to do so."""
    if not tasks:
        return
    if workers == 0 and scheduler is None:
        bar = _bar(len(tasks), label, progress)
        for i, args in enumerate(tasks):
            result = fn(*args)
            bar.update(1)
            yield i, result
        bar.close()
        return
    import dask
    from distributed import Client, LocalCluster, as_completed
    cluster = None
    if scheduler is None:
        # Workers fork from a server that has imported Dask's own packages (numpy among them) once,
        # instead of each starting from scratch (spawn). distributed sets that server's preload list
        # itself (utils.get_mp_context), so blobsim's modules are not on it: each worker imports them.
        # quiet_worker: the workers leave SIGINT to this process, which stops them in order.
        dask.config.set({"distributed.worker.multiprocessing-method": "forkserver", **_quiet_workers()})
        n = workers or default_workers()
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                               host="127.0.0.1", silence_logs=logging.CRITICAL,  # blobsim says what failed
                               env={**worker_threads(), **SINGLE_THREADED_BLAS},
                               preload=["blobcli.tools.quiet_worker"])
    try:
        client = Client(cluster if cluster is not None else scheduler, timeout=f"{CONNECT_SECONDS}s")
    except (OSError, TimeoutError, ValueError) as e:
        if cluster is not None:
            cluster.close()
            raise
        raise SchedulerError(f"--scheduler {scheduler}: no Dask scheduler answered within {CONNECT_SECONDS} s "
                             f"({type(e).__name__})") from None
    bar = _bar(len(tasks), label, progress)
    futures = {}
    try:
        if progress:
            print(f"blobsim: dask dashboard at {client.dashboard_link}", file=sys.stderr)
        futures = {client.submit(fn, *args, key=f"{label}-{i}-{os.getpid()}", pure=False, retries=RETRIES): i
                   for i, args in enumerate(tasks)}
        for future in as_completed(futures):
            i = futures[future]
            result = future.result()
            bar.update(1)
            yield i, result
    finally:
        bar.close()
        unfinished = [f for f in futures if not f.done()]
        for future in unfinished:
            if future.status == "pending":
                future.cancel()
        if unfinished and stop is not None:
            from distributed import wait
            try:
                client.run(stop)
                wait(unfinished, timeout=CLOSE_SECONDS)
            except Exception:  # noqa: BLE001 - stopping is best effort: the cluster is closed next anyway
                pass
        for future in futures:
            future.cancel()
        client.close()
        if cluster is not None:
            cluster.close(timeout=CLOSE_SECONDS)


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _bar(total: int, label: str, progress: bool):
    if not progress:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, unit=label.rstrip("s") or "run", file=sys.stderr, leave=False)
