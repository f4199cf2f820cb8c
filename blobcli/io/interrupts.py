"""Ctrl-C and SIGTERM, turned into one exception or one flag.

`install()` (called first thing by the command line) makes SIGINT and SIGTERM raise
`Interrupted`, so any command stops with exit 130 and one line, never a traceback. Inside
`deferred()` (the run loop, and every step that writes or renames the output) a signal is
only recorded: the loop polls `pending()` between steps and stops at a step boundary, and
no write or rename is ever cut in half.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(Exception):
    """A SIGINT or SIGTERM arrived outside a deferred section."""

    def __init__(self, signum: int):
        super().__init__(f"interrupted by signal {signum}")
        self.signum = signum


_deferring = 0
_pending: int | None = None


def _handler(signum, frame):
    global _pending
    if _deferring:
        _pending = signum
    else:
        raise Interrupted(signum)


def install() -> None:
    for s in SIGNALS:
        signal.signal(s, _handler)


def pending() -> int | None:
    """The signal that arrived in a deferred section, if any (it stays pending until cleared)."""
    return _pending


def clear() -> None:
    global _pending
    _pending = None


@contextmanager
def deferred():
    """Signals arriving inside are recorded, not raised (see `pending`). Nests. Outside the main
    thread (a Dask worker's task thread) signals never reach Python code, so nothing is installed."""
    global _deferring
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    install()
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        for s, h in previous.items():
            if h is not None:
                signal.signal(s, h)
