"""How many threads a run's step uses, call by call.

The compiled core (blobcli/core) splits the parallel build's loops over an OpenMP pool (libgomp).
Each of those parallel regions, about 35 a substep, ends at a barrier where the threads wait for each
other: libgomp's waiting threads spin a while, then sleep. On an idle 2-core machine two threads make
the 120-blob pile's step 1.4× faster (2.69 → 1.87 ms). But when another process wants a core, one of
the run's threads is descheduled for a time slice at some barrier and the other spins it out, at each
of the step's regions: two 120-blob piles started together on two threads each take 10 to 115 s
against 1.1 s alone, and beside a one-core busy loop a 2-thread step takes 2.2× (the 120-blob pile)
to 4.4× (60 blobs) a 1-thread one. One thread has no barrier to wait at. (Waiting threads that sleep
at once, OMP_WAIT_POLICY=passive, spare a shared machine, but then every region wakes them: 3 to 6×
slower alone.)

The pool has OMP_NUM_THREADS threads where the user set it (a count fixed: used as is), else one per
core this process may run on. An auto run (no --threads, no OMP_NUM_THREADS of the user's) watches
its threads and its speed:
- after each call on several threads it compares the process's CPU time with the wall time: threads
  that get their cores use one core each (waiting threads spin), 0.98 to 1.00 of a core per thread
  on the idle machine; beside a busy-loop process, 0.61 to 0.65. Below CPU_SHARE of a core per
  thread, over calls of SHARE_SECONDS or more in all, the run falls back to one thread at once (one
  call of one step is too short to judge);
- now and then it runs one short call on the other thread count (all of the pool's threads, or
  one), and whichever gave the faster step runs until the next probe. While probes keep losing they
  come less often (the interval doubles, up to PROBE_MAX_SECONDS); a step that suddenly slows brings
  the next probe forward;
- where it can see the machine's load (Linux: /proc/loadavg's count of running tasks) it probes
  only what can win: one thread while other processes run on the cores its threads need, more
  threads once those cores are free again. So it starts on one thread beside a busy process, and
  alone it never pays for a probe.
The thread count never changes a bit of the result (core/parallel.h: a loop split over threads
writes only its own slots), only the speed.
"""

from __future__ import annotations

import math
import os
import time

FIRST_PROBE_SECONDS = 0.1  # wall time before the first probe ...
PROBE_SECONDS = 0.5  # ... then between probes ...
PROBE_MAX_SECONDS = 8.0  # ... doubled while they lose, up to this
PROBE_SHARE = 0.125  # a probe runs this share of the steps of a normal call: a call of fewer than 1 / this
# steps is not probed (one step timed alone is noise: a jam's 7-ms step took 6.5-14 ms on two threads)
SWITCH = 0.9  # the other count takes over when its step takes less than this × the current one's
SLOWDOWN = 2.5  # a call this many times slower per step than the current count's average probes at once
AVERAGE = 0.3  # weight of the newest call in the current count's average seconds per step
CPU_SHARE = 0.85  # cores per thread below which a call's threads were not getting their cores ...
SHARE_SECONDS = 0.05  # ... judged over consecutive calls this long in all


def _core():
    """The compiled core's library (imported here, not with this module: `blobsim --help` stays light)."""
    from ..core import load
    return load()[1]


def user_threads() -> int | None:
    """The count the user fixed for the core's OpenMP pool (OMP_NUM_THREADS: a positive integer, or a
    list whose first entry is this level's count), or None where it is unset or not a count (libgomp
    ignores such a value and keeps its default)."""
    text = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()
    try:
        n = int(text)
    except ValueError:
        return None
    return n if n > 0 else None


def available() -> int:
    """The threads the core's pool may use: OMP_NUM_THREADS if set, else the cores this process may
    run on (libgomp's own default); one where the core was built without OpenMP."""
    if not _core().bc_has_openmp():
        return 1
    n = user_threads()
    if n is not None:
        return n
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # (no affinity mask here: macOS)
        return os.cpu_count() or 1


def free_cores(ours: int = 1) -> int | None:
    """Cores that no other runnable task wants at this moment (Linux: the running count of
    /proc/loadavg, less the `ours` threads this run has: the caller, and the pool's others, which
    spin a while after each parallel region), or None where that cannot be read."""
    try:
        with open("/proc/loadavg") as f:
            running = int(f.read().split()[3].split("/")[0])
        cores = len(os.sched_getaffinity(0))
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    return cores - max(running - ours, 0)


SHARED_POOL = "BLOBSIM_SHARED_POOL"  # environment: "1" where OMP_NUM_THREADS was set by blobsim, not the user


def fixed_by_environment() -> bool:
    """Whether the user fixed the core's thread count (OMP_NUM_THREADS): then it is used as is. A
    local Dask worker's OMP_NUM_THREADS is the machine's cores, set by tools/executor.py with
    SHARED_POOL: its runs adapt (one thread while the other workers keep the cores busy, all of them
    once those are idle, as for a jam's last seed)."""
    return user_threads() is not None and os.environ.get(SHARED_POOL) != "1"


class ThreadChoice:
    """The thread count for each compiled call of a run. `threads`: a fixed count (--threads N), or
    None for auto: all of the core's threads (or OMP_NUM_THREADS, fixed), falling back to one while
    more are slower. A serial build (small scenes) runs on one thread whatever the count. The count
    is the calling thread's (omp_set_num_threads): plan() and the compiled call run on one thread."""

    def __init__(self, threads: int | None, parallel: bool):
        most = threads or available()
        self.adaptive = threads is None and parallel and most > 1 and not fixed_by_environment()
        self.most = most if parallel else 1
        self.current = 1 if self.adaptive and self._crowded(ours=1) else self.most  # (no pool thread runs yet)
        self.average = math.inf  # seconds per step at the current count
        self.interval = PROBE_SECONDS
        self.next_probe = time.perf_counter() + FIRST_PROBE_SECONDS
        self.switches = 0
        self._share = [0.0, 0.0]  # wall and CPU seconds of the calls on several threads not yet judged
        self._lib = _core()
        self._before = self._lib.bc_threads()

    def __enter__(self):
        self._lib.bc_set_threads(self.most)
        return self

    def __exit__(self, *exc):
        self._lib.bc_set_threads(self._before)  # the calling thread's count, as it was (tests run many runs)

    def _crowded(self, ours: int) -> bool | None:
        """Whether other processes are running on the cores that more threads would need, this run
        having `ours` threads that may be running (None: cannot tell here)."""
        free = free_cores(ours)
        return None if free is None else free < self.most

    def plan(self, steps: int) -> tuple[int, int]:
        """(threads, steps) for the next call, which would run `steps` steps: a probe is shorter."""
        threads = self.current
        now = time.perf_counter()
        if self.adaptive and now >= self.next_probe and steps * PROBE_SHARE >= 1.0:  # (a shorter call waits)
            crowded = self._crowded(self.current)
            if crowded is None or crowded == (self.current > 1):  # worth a probe of the other count
                threads, steps = (1 if self.current > 1 else self.most), max(1, int(steps * PROBE_SHARE))
            elif self.current == 1:  # no core for more threads: ask again later
                self.interval = min(2.0 * self.interval, PROBE_MAX_SECONDS)
                self.next_probe = now + self.interval
            else:  # on all threads and the cores are free: nothing to learn from one thread
                self.next_probe = now + PROBE_SECONDS
        self._lib.bc_set_threads(threads)
        return threads, steps

    def observe(self, threads: int, steps: int, seconds: float, cpu_seconds: float | None = None) -> None:
        """A call on `threads` threads ran `steps` steps in `seconds` of wall time, using `cpu_seconds`
        of the process's CPU time (all its threads)."""
        if not self.adaptive or steps <= 0:
            return
        per_step = seconds / steps
        now = time.perf_counter()
        # (not judged on a probe: a short call's share is mostly the other threads waking up)
        starved = False
        if threads > 1 and threads == self.current and cpu_seconds is not None:
            self._share[0] += seconds
            self._share[1] += cpu_seconds
            if self._share[0] >= SHARE_SECONDS:
                starved = self._share[1] < CPU_SHARE * threads * self._share[0]
                self._share = [0.0, 0.0]
        if threads != self.current:  # a probe
            if per_step < SWITCH * self.average:
                self.current, self.average, self.interval = threads, per_step, PROBE_SECONDS
                self._share = [0.0, 0.0]
                self.switches += 1
            else:
                self.interval = min(2.0 * self.interval, PROBE_MAX_SECONDS)
            self.next_probe = now + self.interval
        elif starved:  # something else has our cores: one thread now, and a probe later
            self.current, self.average = 1, math.inf
            self.switches += 1
            self.next_probe = now + self.interval
        elif math.isinf(self.average):
            self.average = per_step
        else:
            if per_step > SLOWDOWN * self.average:  # slowed sharply: is the other count better now?
                self.next_probe = now
                self.interval = PROBE_SECONDS
            self.average += AVERAGE * (per_step - self.average)
