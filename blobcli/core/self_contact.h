/* self_contact.h: the self-contact stages' entry points and sizes (read by cffi) */
#ifndef BC_SELF_CONTACT_H
#define BC_SELF_CONTACT_H

#include "blobcore.h"

#define BC_SELF_PER_VERTEX 4  /* pairs kept per vertex of a ring: bcState.self_pairs is (2, PER_VERTEX N) */
#define BC_SELF_CHUNK 4       /* edges per chunk of a ring */
#define BC_SELF_CHUNK_ROWS 17 /* rows of the chunk table bcState.self_chunks, (CHUNK_ROWS, N) */

/* Each awake ring's self-contact pairs for this substep (s->previous: positions at its start, s->position:
 * predicted), into s->self_pairs, self_values, self_count, self_near and self_chunks */
void bc_find_self_contacts(const bcContext *ctx);

/* How many pairs bc_find_self_contacts found in all */
int64_t bc_self_pairs_found(const bcContext *ctx);

/* One Gauss-Seidel pass over each awake ring's self-contact pairs, in reverse order when `reverse`; with
 * `hold`, only the pairs a collider pushed into, with the vertices it pushed held */
void bc_resolve_self_contacts(const bcContext *ctx, int hold, int reverse);

/* The fail-safe after the substep's constraints: crossed parts of a ring move rigidly (impact zones); with
 * `exact_area` (method kot), a ring so moved is projected onto its target area again where that keeps it simple */
void bc_keep_rings_simple(const bcContext *ctx, double h, int exact_area);

#endif
