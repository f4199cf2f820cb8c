"""Ctrl-C and SIGTERM, turned into one exception or one flag.

`install()` (called first thing by the command line) makes SIGINT and SIGTERM raise
`Interrupted`, so any command stops with exit 130 and one line, never a traceback. Inside
`deferred()` (the run loop, and every step that writes or renames the output) a signal is
only recorded: the loop polls `pending()` between steps and stops at a step boundary, and
no write or rename is ever cut in half.
"""

from __future__ import annotations

import signal
import sys
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
_raised = False  # an Interrupted was raised since the last clear(): see caused_by_signal


def _handler(signum, frame):
    global _pending, _raised
    _pending = signum  # recorded even when raised: see _quiet_interrupts
    if not _deferring:
        _raised = True
        raise Interrupted(signum)


def _quiet_interrupts(unraisable) -> None:
    """sys.unraisablehook: an Interrupted raised while a __del__ runs (any object's finaliser) is
    swallowed by Python, which prints its traceback, and the command would run on to its end. Silent here;
    it stays pending, so the run stops at its first step boundary and exits 130. Anything else goes to the
    hook that was there."""
    if not isinstance(unraisable.exc_value, Interrupted):
        _previous_hook(unraisable)


_previous_hook = sys.unraisablehook


def _quiet_printed_interrupts(kind, value, tb) -> None:
    """sys.excepthook: C code that prints an error and raises another (PyErr_Print in an extension
    module's import cut by a SIGTERM prints the Interrupted and raises an ImportError) prints nothing for an
    Interrupted; the command then
    stops with exit 130 (caused_by_signal). Anything else goes to the hook that was there."""
    if not issubclass(kind, (Interrupted, KeyboardInterrupt)):
        _previous_excepthook(kind, value, tb)


_previous_excepthook = sys.excepthook


def install() -> None:
    global _previous_hook, _previous_excepthook
    for s in SIGNALS:
        signal.signal(s, _handler)
    if sys.unraisablehook is not _quiet_interrupts:
        _previous_hook, sys.unraisablehook = sys.unraisablehook, _quiet_interrupts
    if sys.excepthook is not _quiet_printed_interrupts:
        _previous_excepthook, sys.excepthook = sys.excepthook, _quiet_printed_interrupts


def caused_by_signal(error: BaseException) -> bool:
    """Whether `error` wraps an Interrupted or KeyboardInterrupt (Python 3.11 turns one raised while a
    class is created, in a __set_name__, into a RuntimeError caused by it), or came after one was raised
    since the last clear() (C code that replaces an error by its own keeps no chain: see
    _quiet_printed_interrupts)."""
    if _raised:
        return True
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, (Interrupted, KeyboardInterrupt)):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


def request_stop(signum: int = signal.SIGINT) -> None:
    """Ask a run in this process to stop as for a signal (a sweep's worker, told by the sweep that
    was interrupted: signals do not reach its task thread)."""
    global _pending
    _pending = signum


def pending() -> int | None:
    """The signal that arrived in a deferred section, if any (it stays pending until cleared)."""
    return _pending


def clear() -> None:
    """Forget a pending signal: at the start of a command, and once a run has stopped for it."""
    global _pending, _raised
    _pending = None
    _raised = False


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
