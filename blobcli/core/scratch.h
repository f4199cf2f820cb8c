/* The scratch of one run of the step (blobcore.h: bcScratch): what each stage needs beyond the
 * state, allocated once per bc_advance call (scratch.c), one section per stage file. */
#ifndef BC_SCRATCH_H
#define BC_SCRATCH_H

#include "blobcore.h"

struct bcScratch {
    int64_t blob_count, vertex_count;
    /* collide.c */
    int64_t unused_collide;
    /* perimeter.c */
    int64_t unused_perimeter;
};

#endif
