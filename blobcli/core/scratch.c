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
    w->grid_capacity = 4 * B + 64;
    w->cell_of = calloc((size_t)(B + 1), sizeof(int64_t));
    w->cell_order = calloc((size_t)(B + 1), sizeof(int64_t));
    w->cell_start = calloc((size_t)(w->grid_capacity + 1), sizeof(int64_t));
    w->cell_key = calloc((size_t)(B + 1), sizeof(int64_t));
    w->cell_sorting = calloc((size_t)(B + 1), sizeof(int64_t));
    w->fill = calloc((size_t)(w->grid_capacity + 1), sizeof(int64_t));
    w->first = calloc((size_t)(B + 1), sizeof(int64_t));
    w->found = calloc((size_t)(2 * BC_FOUND_PER_BLOB * B + 1), sizeof(int64_t));
    w->kept_order = calloc((size_t)(P + 1), sizeof(int64_t));
    w->kept_key = calloc((size_t)(P + 1), sizeof(int64_t));
    w->pushed = calloc((size_t)(2 * P + 1), sizeof(uint8_t));
    w->touching = calloc((size_t)(P + 1), sizeof(uint8_t));
    w->pair_impulse = calloc((size_t)(2 * P + 1), sizeof(double));
    if (!(w->cell_of && w->cell_order && w->cell_start && w->cell_key && w->cell_sorting && w->fill && w->first &&
          w->found && w->kept_order && w->kept_key && w->pushed && w->touching && w->pair_impulse)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* narrow_phase.c */
    w->outgrown = calloc((size_t)(B + 1), sizeof(uint8_t));
    w->stale = calloc((size_t)(B + 1), sizeof(uint8_t));
    w->reach = calloc((size_t)(B + 1), sizeof(double));
    w->deep = calloc((size_t)(P + 1), sizeof(uint8_t));
    w->detect_key = calloc((size_t)(BC_CONTACTS_PER_VERTEX * m->vertex_count + 1), sizeof(double));
    w->detect_old_edge = calloc((size_t)(BC_CONTACTS_PER_VERTEX * m->vertex_count + 1), sizeof(int64_t));
    w->detect_old_t = calloc((size_t)(BC_CONTACTS_PER_VERTEX * m->vertex_count + 1), sizeof(double));
    if (!(w->outgrown && w->stale && w->reach && w->deep && w->detect_key && w->detect_old_edge && w->detect_old_t)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* contact_solver.c */
    {
        int64_t most = 0; /* the most vertices a ring has */
        for (int64_t b = 0; b < B; b++) {
            int64_t count = m->offsets[b + 1] - m->offsets[b];
            most = count > most ? count : most;
        }
        int64_t N = m->vertex_count, rows = BC_CONTACTS_PER_VERTEX * m->vertex_count;
        w->resolve_slots = BC_CONTACTS_PER_VERTEX * most;
        w->resolve_push = calloc((size_t)(BC_MAX_STRIPS * w->resolve_slots * BC_PUSH_ROW + 1), sizeof(double));
        w->friction_sum = calloc((size_t)(2 * rows + 1), sizeof(double));
        w->resolve_listed = calloc((size_t)(BC_MAX_STRIPS * w->resolve_slots + 1), sizeof(int64_t));
        w->resolve_share = calloc((size_t)(N + 1), sizeof(double));
        w->resolve_rows = calloc((size_t)(2 * rows + 1), sizeof(int64_t));
        w->resolve_row_count = calloc((size_t)(B + 1), sizeof(int64_t));
        w->velocity_first = calloc((size_t)(B + 1), sizeof(int64_t));
        w->velocity_which = calloc((size_t)(4 * rows + 1), sizeof(int64_t));
        w->velocity_geometry = calloc((size_t)(7 * rows + 1), sizeof(double));
        w->velocity_impulse = calloc((size_t)(2 * rows + 1), sizeof(double));
        w->velocity_share = calloc((size_t)(N + 1), sizeof(double));
    }
    if (!(w->resolve_push && w->friction_sum && w->resolve_listed && w->resolve_share && w->resolve_rows && w->resolve_row_count &&
          w->velocity_first && w->velocity_which && w->velocity_geometry && w->velocity_impulse && w->velocity_share)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* self_contact.c */
    w->self_zone = calloc((size_t)(m->vertex_count + 1), sizeof(int64_t));
    w->self_sums = calloc((size_t)(9 * m->vertex_count + 1), sizeof(double));
    w->self_kept = calloc((size_t)(2 * m->vertex_count + 1), sizeof(double));
    if (!(w->self_zone && w->self_sums && w->self_kept)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* perimeter.c */
    w->perimeter_scratch = calloc((size_t)(3 * m->vertex_count + 1), sizeof(double));
    if (!w->perimeter_scratch) {
        bc_scratch_free(w);
        return NULL;
    }
    /* integrate.c, restitution.c, sleep.c */
    w->stack_height = calloc((size_t)(B + 1), sizeof(double));
    w->stack_across = calloc((size_t)(B + 1), sizeof(double));
    w->stack_radius = calloc((size_t)(B + 1), sizeof(double));
    w->stack_sorted_across = calloc((size_t)(B + 1), sizeof(double));
    w->stack_side = calloc((size_t)(B + 1), sizeof(int64_t));
    w->stack_by_height = calloc((size_t)(B + 1), sizeof(int64_t));
    w->stack_depth = calloc((size_t)(B + 1), sizeof(int64_t));
    w->stack_work = calloc((size_t)(B + 1), sizeof(int64_t));
    w->bounce_pushed = calloc((size_t)(2 * P + 1), sizeof(uint8_t));
    w->bounce_touching = calloc((size_t)(P + 1), sizeof(uint8_t));
    w->bounce_involved = calloc((size_t)(B + 1), sizeof(uint8_t));
    w->bounce_center = calloc((size_t)(2 * B + 1), sizeof(double));
    w->bounce_motion = calloc((size_t)(3 * B + 1), sizeof(double));
    w->bounce_shift = calloc((size_t)(2 * B + 1), sizeof(double));
    w->sleep_parent = calloc((size_t)(B + 1), sizeof(int64_t));
    w->sleep_restless = calloc((size_t)(B + 1), sizeof(uint8_t));
    if (!(w->stack_height && w->stack_across && w->stack_radius && w->stack_sorted_across && w->stack_side &&
          w->stack_by_height && w->stack_depth && w->stack_work && w->bounce_pushed && w->bounce_touching &&
          w->bounce_involved && w->bounce_center && w->bounce_motion && w->bounce_shift && w->sleep_parent &&
          w->sleep_restless)) {
        bc_scratch_free(w);
        return NULL;
    }
    /* statics.c, walls.c */
    w->wall_share = calloc((size_t)(B + 1), sizeof(double));
    w->wall_normal = calloc((size_t)(2 * B + 1), sizeof(double));
    w->wall_impulse = calloc((size_t)(2 * B + 1), sizeof(double));
    w->wall_deepest = calloc((size_t)(B + 1), sizeof(int64_t));
    w->wall_kept = calloc((size_t)(2 * m->vertex_count + 1), sizeof(double));
    w->wall_side = calloc((size_t)(m->walls.count * B + 1), sizeof(uint8_t));
    if (!(w->wall_share && w->wall_normal && w->wall_impulse && w->wall_deepest && w->wall_kept && w->wall_side)) {
        bc_scratch_free(w);
        return NULL;
    }
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
    free(w->cell_of);
    free(w->cell_order);
    free(w->cell_start);
    free(w->cell_key);
    free(w->cell_sorting);
    free(w->fill);
    free(w->first);
    free(w->found);
    free(w->kept_order);
    free(w->kept_key);
    free(w->pushed);
    free(w->touching);
    free(w->pair_impulse);
    /* narrow_phase.c */
    free(w->outgrown);
    free(w->stale);
    free(w->reach);
    free(w->deep);
    free(w->detect_key);
    free(w->detect_old_edge);
    free(w->detect_old_t);
    /* contact_solver.c */
    free(w->resolve_push);
    free(w->friction_sum);
    free(w->resolve_listed);
    free(w->resolve_share);
    free(w->resolve_rows);
    free(w->resolve_row_count);
    free(w->velocity_first);
    free(w->velocity_which);
    free(w->velocity_geometry);
    free(w->velocity_impulse);
    free(w->velocity_share);
    /* self_contact.c */
    free(w->self_zone);
    free(w->self_sums);
    free(w->self_kept);
    /* perimeter.c */
    free(w->perimeter_scratch);
    /* integrate.c, restitution.c, sleep.c */
    free(w->stack_height);
    free(w->stack_across);
    free(w->stack_radius);
    free(w->stack_sorted_across);
    free(w->stack_side);
    free(w->stack_by_height);
    free(w->stack_depth);
    free(w->stack_work);
    free(w->bounce_pushed);
    free(w->bounce_touching);
    free(w->bounce_involved);
    free(w->bounce_center);
    free(w->bounce_motion);
    free(w->bounce_shift);
    free(w->sleep_parent);
    free(w->sleep_restless);
    /* statics.c, walls.c */
    free(w->wall_share);
    free(w->wall_normal);
    free(w->wall_impulse);
    free(w->wall_deepest);
    free(w->wall_kept);
    free(w->wall_side);
    free(w);
}
