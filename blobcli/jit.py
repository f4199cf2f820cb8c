"""The numba decorators every kernel uses.

cache=True keeps compiled kernels on disk between runs; error_model="numpy" lets
divisions skip the zero check so loops vectorize; fastmath stays off because it
reorders sums, and runs must be bit-identical. Small helpers called per vertex or per
edge are inlined into their callers at the numba IR level (`inline_kernel`): left as
calls, the perimeter sweep ran 7× slower.
"""

import types

import numba

FLAGS = dict(cache=True, error_model="numpy", nogil=True)
kernel = numba.njit(**FLAGS)
inline_kernel = numba.njit(inline="always", **FLAGS)

_STAGES: dict[int, tuple] = {}  # id(serial build) -> (serial build, its Python function)
_TWINS: dict[int, object] = {}  # id(serial build) -> parallel build


def stage_kernel(fn):
    """A stage kernel: returns its serial build (numba.prange runs as range); `parallel(k)` gives
    the same code built with parallel=True, which stages use from 32 blobs (model.parallel).
    Both give the same bits: a prange loop's iterations write only their own slots.

    A stage kernel may call other stage kernels (the step's driver calls them all): in the
    parallel build, each one it names is its parallel build too. So the step is compiled twice,
    serial and parallel, from one text.

    Why both (dev, `blobsim bench`): a parallel launch costs ~2 µs, which made a one-blob step
    3× slower, while at 1,000 blobs the parallel builds are far faster, on one thread too (the
    perimeter sweep: 16.7 ns per edge serial, 7.1 parallel on one thread, 3.7 on two).
    """
    serial = kernel(fn)
    _STAGES[id(serial)] = (serial, fn)
    return serial


def parallel(serial):
    """The parallel build of a stage kernel, compiled from a renamed copy of its code (numba's disk
    cache keys a kernel by its name and bytecode, not its flags, so two builds of one function
    would overwrite each other's cache: numba issue #6845) whose globals name the parallel builds
    of the stage kernels it calls. Built on first use, when every module it names is loaded."""
    twin = _TWINS.get(id(serial))
    if twin is None:
        _, fn = _STAGES[id(serial)]
        scope = dict(fn.__globals__)
        code = fn.__code__.replace(co_name=fn.__name__ + "_parallel", co_qualname=fn.__qualname__ + "_parallel")
        function = types.FunctionType(code, scope, code.co_name, fn.__defaults__, fn.__closure__)
        # parallel=True where the code has prange loops of its own; a stage that only calls others
        # (the driver, say) is parallel through them
        own_loops = "prange" in fn.__code__.co_names
        twin = _TWINS[id(serial)] = numba.njit(parallel=own_loops, **FLAGS)(function)
        for name, value in scope.items():  # after registering the twin: a module's kernels name each other
            if id(value) in _STAGES:
                scope[name] = parallel(value)
    return twin


def build(serial, is_parallel: bool):
    """The serial or the parallel build of a stage kernel."""
    return parallel(serial) if is_parallel else serial
