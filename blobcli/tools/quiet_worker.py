"""A Dask worker preload for a local sweep's workers (executor.run_tasks): they ignore SIGINT. A Ctrl-C
at a terminal reaches the whole process group; the sweep itself then asks each worker's run to stop
at its next step boundary (io.interrupts.request_stop) and closes the cluster in order, so no worker
dies mid-task printing a KeyboardInterrupt traceback or leaking its semaphores."""

import signal

signal.signal(signal.SIGINT, signal.SIG_IGN)
