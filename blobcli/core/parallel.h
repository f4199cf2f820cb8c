/* Threads: one binary for serial and parallel. A loop over blobs, pairs or vertices whose iterations write
 * only their own slots is split statically over the threads when the scene runs parallel
 * (bcSettings.parallel, from model.PARALLEL_BLOBS blobs on), so any thread count gives the same bits.
 * Serial, the same loop runs without entering the OpenMP runtime at all: a parallel region with a false
 * `if` clause still starts a team of one, which cost a one-blob step more than its own work. Without
 * OpenMP the pragma is ignored, and the loop is serial either way, with the same bits. */
#ifndef BC_PARALLEL_H
#define BC_PARALLEL_H

#define BC_PRAGMA(x) _Pragma(#x)

/* for HEADER BODY, over threads when `on`: BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < B; b++), { ... });
 * (the body is the macro's variadic tail, so commas in it need no parentheses; it is written twice) */
#define BC_PARALLEL_LOOP(on, header, ...)                      \
    do {                                                       \
        if (on) {                                              \
            BC_PRAGMA(omp parallel for schedule(static))       \
            for header __VA_ARGS__                             \
        } else {                                               \
            for header __VA_ARGS__                             \
        }                                                      \
    } while (0)

#endif
