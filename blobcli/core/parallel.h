/* Threads: one binary for serial and parallel. A loop over blobs or pairs that writes only its own
 * slots is split statically over the threads when the scene runs its parallel build
 * (bcSettings.parallel, from model.PARALLEL_BLOBS blobs on), so any thread count gives the same bits;
 * without OpenMP the pragma is ignored and the loop runs serially, with the same bits. */
#ifndef BC_PARALLEL_H
#define BC_PARALLEL_H

#define BC_PRAGMA(x) _Pragma(#x)
/* Before a `for` over independent items: BC_PARALLEL_FOR(ctx->c->parallel) */
#define BC_PARALLEL_FOR(on) BC_PRAGMA(omp parallel for schedule(static) if (on))

#endif
