/* step.h: the step's driver, bc_advance (read by cffi) */
#ifndef BC_STEP_H
#define BC_STEP_H

#include "blobcore.h"

/* Why bc_advance returned */
#define BC_DONE 0
#define BC_RUNAWAY_VERTEX 1  /* the step left vertex `detail` non-finite or beyond the runaway limit */
#define BC_TOO_MANY_PAIRS 2  /* `detail` blob pairs overlap: more than the scratch holds (the state is mid-step) */
#define BC_NO_MEMORY 3       /* the scratch could not be allocated: nothing was done */
#define BC_RUNAWAY_WALL 4    /* the step left collider `detail`'s pose non-finite or beyond the runaway limit */
#define BC_BROKEN_BLOB 5     /* the step left a blob inside out or crushed beside a moving collider (walls.c) */
#define BC_PASSED_BLOB 6     /* a loaded wall passed into or through a blob in the step (walls.c) */

/* The stage clock's slots, in pipeline.STAGES's order */
#define BC_STAGE_COUNT 16

typedef struct bcStop {
    int64_t steps;   /* steps done */
    int64_t why;     /* BC_DONE, BC_RUNAWAY_VERTEX, BC_TOO_MANY_PAIRS, BC_NO_MEMORY, BC_RUNAWAY_WALL,
                      * BC_BROKEN_BLOB or BC_PASSED_BLOB (`detail` of these two: b S + k, blob b, collider k) */
    int64_t detail;
} bcStop;

bcStop bc_advance(const bcContext *ctx, int64_t steps, double runaway, double *clock);

#endif
