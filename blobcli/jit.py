"""The numba decorators every kernel uses.

cache=True keeps compiled kernels on disk between runs; error_model="numpy" lets
divisions skip the zero check so loops vectorize; fastmath stays off because it
reorders sums, and runs must be bit-identical. Small helpers called per vertex or per
edge are inlined into their callers at the numba IR level (`inline_kernel`): left as
calls, the perimeter sweep ran 7× slower.
"""

import numba

kernel = numba.njit(cache=True, error_model="numpy", nogil=True)
inline_kernel = numba.njit(cache=True, error_model="numpy", nogil=True, inline="always")
# Every stage whose outer loop has independent iterations (blobs, or vertices, each writing
# only its own) loops with numba.prange under `parallel_kernel`: results do not depend on the
# number of threads, and one thread still gains. (dev: the perimeter sweep at 1,000 blobs took
# 16.7 ns per edge as a plain kernel, 7.1 ns as a parallel kernel on one thread and 3.7 ns on
# two; numba compiles a prange body as a separate function, and it compiled that one better.)
# A parallel launch costs ~1.5 µs, which one-blob scenes can afford.
parallel_kernel = numba.njit(cache=True, error_model="numpy", nogil=True, parallel=True)
