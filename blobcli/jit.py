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
# Loops over independent blobs (each writes only its own vertices) may run on all cores:
# their results do not depend on the number of threads.
parallel_kernel = numba.njit(cache=True, error_model="numpy", nogil=True, parallel=True)
