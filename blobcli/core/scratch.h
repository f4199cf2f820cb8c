/* The scratch of one run of the step (blobcore.h: bcScratch), its fields visible to the tests (read by cffi):
 * what each stage needs beyond the state, allocated once per bc_advance call (scratch.c), one section per
 * stage file. */
#ifndef BC_SCRATCH_H
#define BC_SCRATCH_H

#include "blobcore.h"

struct bcScratch {
    int64_t blob_count, vertex_count;
    /* broad_phase.c: the blob pairs close enough to touch this substep, and what is derived from them,
     * read by the contact stages after it (collide.py's find_blob_pairs returns these) */
    int64_t pair_capacity;  /* PAIRS_PER_BLOB B: past this many pairs the step stops */
    int64_t pair_count;     /* P: pairs listed this substep (0 when there were more than the capacity) */
    int64_t *pairs;         /* (capacity, 2): a, b */
    int64_t *partner_start; /* (B + 1): blob b's partners are partner[partner_start[b] .. partner_start[b + 1]) ... */
    int64_t *partner;       /* (2 capacity) ... the other blob ... */
    int64_t *partner_pair;  /* (2 capacity) ... and the pair's index (collide._partners: pair_of) */
    int64_t strip_count;    /* collide._strips: how many vertical strips the resolution cuts the scene into ... */
    int64_t *strip_of;      /* (B) ... each blob's strip ... */
    int64_t *strip_start;   /* (MAX_STRIPS + 1) ... each strip's blobs, strip_blobs[strip_start[k] .. [k + 1]) ... */
    int64_t *strip_blobs;   /* (B) ... in index order ... */
    int64_t *crossing;      /* (B) ... how many strips apart each blob's farthest partner is ... */
    int64_t far;            /* ... and whether any pair spans two strips or more */
    double *pair_impact;    /* (capacity, 4): this substep's pairs' impact records (collide.carry_impacts) */
    /* broad_phase.c, its own */
    /* narrow_phase.c */
    /* contact_solver.c */
    /* self_contact.c */
    /* perimeter.c, area.c */
    /* integrate.c, restitution.c, sleep.c */
    /* statics.c, walls.c */
};

#endif
