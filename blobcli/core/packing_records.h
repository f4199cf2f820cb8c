/* packing_records.h: what the blob contacts leave, in a periodic box, for a packing's measures (sim/packing.py):
 * each blob's virial Σ (x - c) ⊗ J, and each pair's contact impulse over the substep, from which the pairs' contact
 * forces and each blob's net contact force follow (not read by cffi) */
#ifndef BC_PACKING_RECORDS_H
#define BC_PACKING_RECORDS_H

#include <stdint.h>

#include "scratch.h"

/* virial[b] += r ⊗ J (xx, xy, yx, yy): an impulse J on blob b at r from its centre */
static inline void bc_add_virial(double *virial, int64_t b, double rx, double ry, double jx, double jy) {
    virial[4 * b] += rx * jx;
    virial[4 * b + 1] += rx * jy;
    virial[4 * b + 2] += ry * jx;
    virial[4 * b + 3] += ry * jy;
}

/* An impulse J on blob a from blob b, into their pair's record (w->pair_impulse, the impulse on the pair's first
 * blob): the pair found among a's partners (a blob has a few). A contact moves only its own two blobs, so the tasks
 * that resolve contacts in parallel never share a pair. */
static inline void bc_add_pair_impulse(const bcScratch *w, int64_t a, int64_t b, double jx, double jy) {
    for (int64_t j = w->partner_start[a]; j < w->partner_start[a + 1]; j++) {
        if (w->partner[j] == b) {
            int64_t k = w->partner_pair[j];
            double sign = w->pairs[2 * k] == a ? 1.0 : -1.0;
            w->pair_impulse[2 * k] += sign * jx;
            w->pair_impulse[2 * k + 1] += sign * jy;
            return;
        }
    }
}

#endif
