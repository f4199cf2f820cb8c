"""The line a command prints while numba compiles the step for a new configuration.

A cold compile takes tens of seconds; a program silent that long is taken for a hung one. So the
moment it starts, one line on stderr says what is compiled and that it happens once per machine; on
a terminal the line then counts the seconds (a thread redraws it: numba's compiler spends most of
its time in LLVM, which releases the GIL), and says how long it took when done.
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager

TICK_SECONDS = 1.0


def announcer(live: bool, stream=None):
    """A context manager factory for pipeline.compile_step: `announcer(live)(description)`. With
    live (a terminal), the elapsed time is redrawn in place every TICK_SECONDS."""
    @contextmanager
    def announce(description: str):
        out = stream or sys.stderr
        head = f"blobsim: compiling the step for this scene ({description}): once per machine, then cached"
        start = time.perf_counter()
        out.write(head + ("" if live else "\n"))
        out.flush()
        done = threading.Event()

        def tick():
            while not done.wait(TICK_SECONDS):
                out.write(f"\r{head} ... {time.perf_counter() - start:.0f} s")
                out.flush()

        ticker = threading.Thread(target=tick, daemon=True) if live else None
        if ticker is not None:
            ticker.start()
        try:
            yield
        finally:
            done.set()
            if ticker is not None:
                ticker.join()
                out.write(f"\r{head}: {time.perf_counter() - start:.0f} s\n")
                out.flush()
    return announce
