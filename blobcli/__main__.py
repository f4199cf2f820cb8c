"""The `blobsim` command (and `python -m blobcli`): the signal handlers go in before anything else
is imported, so a Ctrl-C or SIGTERM at any moment after Python itself has started, imports
included, ends the command with exit 130 and one line, never a traceback or a death by signal."""

import sys


def entry() -> None:
    from .io import interrupts  # light: signal, sys, threading
    try:
        interrupts.install()
        from .cli import main
        code = main()
    except (KeyboardInterrupt, interrupts.Interrupted):
        print("blobsim: interrupted", file=sys.stderr)
        code = 130
    except Exception as e:  # a signal wrapped while `cli` imports; main() handles the rest
        if not interrupts.caused_by_signal(e):
            raise
        print("blobsim: interrupted", file=sys.stderr)
        code = 130
    sys.exit(code)


if __name__ == "__main__":
    entry()
