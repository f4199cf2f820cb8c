/* Allocating and freeing the scratch of one run of the step (scratch.h). */
#include <stdlib.h>

#include "scratch.h"
#include "collide_limits.h"

bcScratch *bc_scratch_new(const bcModel *m) {
    bcScratch *w = calloc(1, sizeof *w);
    if (w == NULL) return NULL;
    w->blob_count = m->blob_count;
    w->vertex_count = m->vertex_count;
    int64_t B = m->blob_count, P = BC_PAIRS_PER_BLOB * m->blob_count;
    /* broad_phase.c */
    w->pair_capacity = P;
    w->pairs = calloc((size_t)(2 * P + 1), sizeof(int64_t));
    w->partner_start = calloc((size_t)(B + 1), sizeof(int64_t));
    w->partner = calloc((size_t)(2 * P + 1), sizeof(int64_t));
    w->partner_pair = calloc((size_t)(2 * P + 1), sizeof(int64_t));
    w->strip_of = calloc((size_t)(B + 1), sizeof(int64_t));
    w->strip_start = calloc(BC_MAX_STRIPS + 1, sizeof(int64_t));
    w->strip_blobs = calloc((size_t)(B + 1), sizeof(int64_t));
    w->crossing = calloc((size_t)(B + 1), sizeof(int64_t));
    w->pair_impact = calloc((size_t)(4 * P + 1), sizeof(double));
    if (!(w->pairs && w->partner_start && w->partner && w->partner_pair && w->strip_of && w->strip_start &&
          w->strip_blobs && w->crossing && w->pair_impact)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* broad_phase.c, its own */
    /* narrow_phase.c */
    /* contact_solver.c */
    /* self_contact.c */
    /* perimeter.c, area.c */
    /* integrate.c, restitution.c, sleep.c */
    /* statics.c, walls.c */
    return w;
}

void bc_scratch_free(bcScratch *w) {
    if (w == NULL) return;
    /* broad_phase.c */
    free(w->pairs);
    free(w->partner_start);
    free(w->partner);
    free(w->partner_pair);
    free(w->strip_of);
    free(w->strip_start);
    free(w->strip_blobs);
    free(w->crossing);
    free(w->pair_impact);
    /* broad_phase.c, its own */
    /* narrow_phase.c */
    /* contact_solver.c */
    /* self_contact.c */
    /* perimeter.c, area.c */
    /* integrate.c, restitution.c, sleep.c */
    /* statics.c, walls.c */
    free(w);
}
