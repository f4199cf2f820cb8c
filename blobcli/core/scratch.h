/* The scratch of one run of the step (blobcore.h: bcScratch), its fields visible to the tests (read by cffi):
 * what each stage needs beyond the state, allocated once per bc_advance call (scratch.c), one section per
 * stage file. */
#ifndef BC_SCRATCH_H
#define BC_SCRATCH_H

#define BC_PUSH_ROW 10 /* a blob contact push (contact_solver.c): Δ_x, Δ_y, w_p, w_e, t, renew, -C, f_x, f_y, spare */

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
    /* broad_phase.c, its own: the grid of cells the pairs are found in (collide._find_pairs, _find_pairs_periodic),
     * the pairs as they are counted, and the bookkeeping's buffers */
    int64_t grid_capacity;  /* 4 B + 64: the most cells the table cell_start holds (an open world never has more) */
    int64_t *cell_of;       /* (B): each blob's cell, iy nx + ix ... */
    int64_t *cell_order;    /* (B) ... the blobs by cell, then by index ... */
    int64_t *cell_start;    /* (grid_capacity + 1) ... cell c's at cell_order[cell_start[c] .. cell_start[c + 1]) ... */
    int64_t *cell_key;      /* (B) ... or, in a periodic box of more cells than that, cell_of[cell_order[k]] */
    int64_t *cell_sorting;  /* (B): the merge sort's other half */
    int64_t *fill;          /* (grid_capacity + 1): each bucket's next slot (cells, strips, partners) */
    int64_t *first;         /* (B + 1): blob a's pairs are pairs[first[a] .. first[a + 1]) */
    int64_t *found;         /* (FOUND_PER_BLOB B, 2): each blob's first pairs, kept as they are counted */
    int64_t *kept_order;    /* (capacity): keep_impacts' kept pairs, by key ... */
    int64_t *kept_key;      /* (capacity) ... and their keys */
    uint8_t *pushed;        /* (2 capacity): keep_touching: whether a contact of each partner slot pushed ... */
    uint8_t *touching;      /* (capacity) ... and of each pair */
    double *pair_impulse;   /* (capacity, 2) N s: each pair's contact impulse this substep on its first blob, in a
                             * periodic box (packing_records.h) */
    /* narrow_phase.c: bc_keep_blob_contacts' flags per blob and pair, and _detect's per vertex (rows of N, vertex i's
     * slot c at c N + i: a blob's vertices are its own, so parallel blobs never share a slot) */
    uint8_t *outgrown;        /* (B): went farther than its budget from where its contacts were found, or was split */
    uint8_t *stale;           /* (B): outgrown, or a partner of an outgrown blob: its contacts are found again */
    double *reach;            /* (B) m: how far each blob may still go, budget + moved (0 asleep) */
    uint8_t *deep;            /* (capacity): either centre of pair k inside the other blob */
    double *detect_key;       /* (CONTACTS_PER_VERTEX, N) m: each kept contact's signed distance, < 0 inside */
    int64_t *detect_old_edge; /* (CONTACTS_PER_VERTEX, N): the stick points before the contacts are found again ... */
    double *detect_old_t;     /* (CONTACTS_PER_VERTEX, N) ... and their t */
    /* contact_solver.c: the blob contacts' pushes and rows (collide._resolve's scratch), one row of the first two
     * for each parallel task of a phase, and the velocity stage's contacts (collide.blob_contact_velocities) */
    int64_t resolve_slots;     /* CONTACTS_PER_VERTEX × the most vertices a ring has */
    double *resolve_push;      /* (MAX_STRIPS, slots, BC_PUSH_ROW): each task's blob's pushes, by slot */
    double *friction_sum;      /* (2, CONTACTS_PER_VERTEX N): each contact's tangential correction this substep */
    int64_t *resolve_listed;   /* (MAX_STRIPS, slots): each task's blob's slots here, then those that push */
    double *resolve_share;     /* (N): how many pushes each vertex is in; all zero between blobs */
    int64_t *resolve_rows;     /* (2, CONTACTS_PER_VERTEX N): blob a's contacts from CONTACTS_PER_VERTEX o on ... */
    int64_t *resolve_row_count; /* (B): ... and how many */
    int64_t *velocity_first;   /* (B + 1): blob a's pushed contacts are columns first[a] .. first[a + 1] ... */
    int64_t *velocity_which;   /* (4, K) ... p, e0, e1, c (K <= CONTACTS_PER_VERTEX N) ... */
    double *velocity_geometry; /* (7, K) ... t, n_x, n_y, 1 / (W k), w_e, μ_s D / h, μ_k D / h ... */
    double *velocity_impulse;  /* (2, K) ... J */
    double *velocity_share;    /* (N): how many contacts each vertex is in */
    /* self_contact.c: bc_keep_rings_simple's impact zones, ring b's from its first vertex o on (rings never
     * share a slice, so parallel rings never share a slot) */
    int64_t *self_zone;     /* (N): each vertex's zone (its root's index in the ring), zone[o ..] */
    double *self_sums;      /* (N, 9): per zone root, the zone's sums, rows o .. of the table */
    double *self_kept;      /* (2 N): a ring before its area is projected again, (2, n) from 2 o on */
    /* perimeter.c */
    double *perimeter_scratch; /* (3, N): perimeter.c's per-edge rows (Δλ n, or t_i and |e_i|), ring b's in its own
                                * columns o .. e (parallel rings never share a slot) */
    /* integrate.c, restitution.c, sleep.c */
    double *stack_height;        /* (B) integrate.c rows_stacked: each blob's centre along up ... */
    double *stack_across;        /* (B) ... and across ... */
    double *stack_radius;        /* (B) ... its rest radius ... */
    double *stack_sorted_across; /* (B) ... across in stack_side's order ... */
    int64_t *stack_side;         /* (B) ... the blobs by across ... */
    int64_t *stack_by_height;    /* (B) ... and by height (stable sorts) ... */
    int64_t *stack_depth;        /* (B) ... how many blobs deep each stands ... */
    int64_t *stack_work;         /* (B) ... and the merge sort's workspace */
    uint8_t *bounce_pushed;      /* (2 capacity) restitution.c: whether a contact pushed, by partner slot ... */
    uint8_t *bounce_touching;    /* (capacity) ... whether each pair touches, both awake ... */
    uint8_t *bounce_involved;    /* (B) ... whether a blob is in a touching pair ... */
    double *bounce_center;       /* (B, 2) ... its centre c ... */
    double *bounce_motion;       /* (B, 3) ... its v̄x, v̄y, k = ½ mean |v|² ... */
    double *bounce_shift;        /* (B, 2) ... and δ, its velocity change */
    int64_t *sleep_parent;       /* (B) sleep.c: the union-find's parents ... */
    uint8_t *sleep_restless;     /* (B) ... whether a root's island has an awake blob not still long enough */
    /* statics.c, walls.c */
    double *wall_share;     /* (B) bc_react_loaded_walls: s_b, the part of blob b's impulse a loaded wall takes ... */
    double *wall_normal;    /* (B, 2) ... n̄_b, its contacts' depth-weighted normal on the wall ... */
    double *wall_impulse;   /* (B, 2) ... J_b, the velocity stages' impulse on blob b ... */
    int64_t *wall_deepest;  /* (B) ... and its deepest vertex on the wall (-1: none) */
    double *wall_kept;      /* (2, N) bc_keep_impact_positions: the positions before bc_stop_impacts */
    uint8_t *wall_side;     /* (S, B) bc_note_wall_sides: which side of loaded wall k blob b is on at the step's start */
};

#endif
