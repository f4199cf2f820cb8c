/* Allocating and freeing the scratch of one run of the step (scratch.h). */
#include <stdlib.h>

#include "scratch.h"

bcScratch *bc_scratch_new(const bcModel *m) {
    bcScratch *w = calloc(1, sizeof *w);
    if (w == NULL) return NULL;
    w->blob_count = m->blob_count;
    w->vertex_count = m->vertex_count;
    /* collide.c */
    /* perimeter.c */
    return w;
}

void bc_scratch_free(bcScratch *w) {
    if (w == NULL) return;
    /* collide.c */
    /* perimeter.c */
    free(w);
}
