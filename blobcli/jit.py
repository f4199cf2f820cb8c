"""The numba decorators every kernel uses.

cache=True keeps compiled kernels on disk between runs; error_model="numpy" lets
divisions skip the zero check so loops vectorize; fastmath stays off because it
reorders sums, and runs must be bit-identical. Small helpers called per vertex or per
edge are inlined into their callers at the numba IR level (`inline_kernel`): left as
calls, the perimeter sweep ran 7× slower.
"""

import types

import numba

kernel = numba.njit(cache=True, error_model="numpy", nogil=True)
inline_kernel = numba.njit(cache=True, error_model="numpy", nogil=True, inline="always")
# Loops over independent blobs or vertices (each iteration writes only its own) use
# numba.prange, and results do not depend on the number of threads.
parallel_kernel = numba.njit(cache=True, error_model="numpy", nogil=True, parallel=True)

def stage_kernel(fn):
    """A stage kernel whose outer loop is a numba.prange, built twice: [False] serial (prange
    runs as range), [True] parallel; stages pick by model.parallel (from 32 blobs). Both give
    the same bits.

    Why both (dev, `blobsim bench`): a parallel launch costs ~2 µs, which made a one-blob step
    3× slower (0.105 against 0.034 ms), while at 1,000 blobs the parallel builds are far
    faster, on one thread too (the perimeter sweep: 16.7 ns per edge serial, 7.1 parallel on
    one thread, 3.7 on two). The parallel build compiles a renamed copy of fn: numba's disk
    cache keys a kernel by its name and bytecode, not its flags, so two builds of one function
    would overwrite each other's cache (numba issue #6845).
    """
    code = fn.__code__.replace(co_name=fn.__name__ + "_parallel", co_qualname=fn.__qualname__ + "_parallel")
    twin = types.FunctionType(code, fn.__globals__, code.co_name, fn.__defaults__, fn.__closure__)
    return kernel(fn), parallel_kernel(twin)
