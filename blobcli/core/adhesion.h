/* adhesion.h: sticky blobs and colliders, the adhesion stage's entry points (read by cffi) */
#ifndef BC_ADHESION_H
#define BC_ADHESION_H

#include "blobcore.h"

/* The range of adhesion, in mean rest edges of the blob: a vertex holds to a surface whose gap at the substep's
 * start is at most this × its blob's rest perimeter / its vertex count (adhesion.c) */
double bc_adhesion_range_edges(void);

/* Whether any blob or collider is sticky (an adhesion above 0): the step runs bc_adhere only then */
int bc_any_adhesion(const bcContext *ctx);

/* Once a substep, in its last iteration after the area: every awake vertex within range of a collider or of another
 * blob (its kept contacts, s->c_edge) loses its separation from it since the substep began, and a touching one is
 * pressed onto it, up to its adhesion × its share of the ring's length as force (adhesion.c); h the substep (s).
 * Writes the positions, the colliders' records (touch: s->static_of, static_push; a loaded wall's wall_of,
 * wall_push) and, in a periodic box, the virial. */
void bc_adhere(const bcContext *ctx, double h);

#endif
