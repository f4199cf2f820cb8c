/* broad_phase.h: the broad phase's and the blob contacts' bookkeeping entry points (read by cffi) */
#ifndef BC_BROAD_PHASE_H
#define BC_BROAD_PHASE_H

#include "blobcore.h"

/* Broad phase: every blob's centre, radius and edge table (s->center, radius, edges), then the pairs of blobs
 * close enough to touch this substep, sleeping or not, into the scratch (pairs, pair_count, partner_start,
 * partner, partner_pair, strip_count, strip_of, strip_start, strip_blobs, crossing, far); clears
 * s->blob_contact_depth and s->c_hit. Returns how many pairs there are: past w->pair_capacity none are listed
 * (pair_count 0) and the step must stop. */
int64_t bc_find_blob_pairs(const bcContext *ctx);

/* Each blob's centre, radius and edge table (s->center, radius, edges): every blob's with `everyone`, else
 * the awake blobs' (the narrow phase's: a sleeping blob's have not changed since the broad phase) */
void bc_blob_bounds(const bcContext *ctx, int everyone);

/* The impact records of this substep's pairs into w->pair_impact: each pair's kept one (s->pair_key,
 * s->pair_impact, s->pair_count), or a fresh record */
void bc_carry_impacts(const bcContext *ctx);

/* Keep the records of w->pair_impact's pairs that have had an impact, sorted by key, in s->pair_key,
 * s->pair_impact and s->pair_count */
void bc_keep_impacts(const bcContext *ctx);

/* At the end of a substep: a contact that did not push in it lets go of its stick point (s->stick_edge) */
void bc_release_sticks(const bcContext *ctx);

/* In a periodic box: the pairs whose contacts pushed in the step's last substep (of length h), asleep or not,
 * into s->touching, in pair order, their contact forces into s->touching_force, and how many into
 * s->touching_count */
void bc_keep_touching(const bcContext *ctx, double h);

#endif
