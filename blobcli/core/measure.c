/* Per-blob measurements taken at recorded frames (called from Python, over any positions), and the runaway check
 * the step makes after every step. Positions and velocities (2, n): x of vertex i at [i], y at [n + i]. */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "measure.h"
#include "ring.h"
#include "walls.h"

int64_t bc_first_runaway_in(const double *position, int64_t n, double limit) {
    bool bad = false;
    for (int64_t i = 0; i < n; i++) { /* a loop with no exit, so that it vectorizes: it runs every step */
        bad |= !(fabs(position[i]) <= limit) || !(fabs(position[n + i]) <= limit); /* also catches NaN */
    }
    if (bad) {
        for (int64_t i = 0; i < n; i++) {
            if (!(fabs(position[i]) <= limit) || !(fabs(position[n + i]) <= limit)) return i;
        }
    }
    return -1;
}

int64_t bc_first_runaway(const bcContext *ctx, double limit) {
    return bc_first_runaway_in(ctx->s->position, ctx->m->vertex_count, limit);
}

int64_t bc_first_runaway_wall(const double *pose, int64_t walls, double limit) {
    for (int64_t k = 0; k < walls; k++) {
        const double *row = pose + BC_WALL_POSE_COLUMNS * k;
        bool bad = !(fabs(row[0]) <= limit) || !(fabs(row[1]) <= limit) || !(fabs(row[3]) <= limit);
        for (int64_t c = 0; c < BC_WALL_POSE_COLUMNS; c++) bad |= !isfinite(row[c]);
        if (bad) return k;
    }
    return -1;
}

/* area = ½ Σ (x_i y_{i+1} − x_{i+1} y_i) in ring order, kinetic = ½ Σ m_i |v_i|² */
void bc_blob_measures(const double *position, const double *velocity, int64_t n, const double *inv_mass,
                      const int64_t *offsets, int64_t blob_count, double *area, double *kinetic) {
    for (int64_t b = 0; b < blob_count; b++) {
        int64_t o = offsets[b], e = offsets[b + 1];
        double ke = 0.0;
        for (int64_t i = o; i < e; i++) {
            ke += (velocity[i] * velocity[i] + velocity[n + i] * velocity[n + i]) / inv_mass[i];
        }
        area[b] = 0.5 * bc_twice_ring_area(position, n, o, e);
        kinetic[b] = 0.5 * ke;
    }
}

/* Edges i → i1 and j → j1 properly cross when each one's ends lie strictly on either side of the other's line */
void bc_shape_faults(const double *position, int64_t n, const int64_t *offsets, int64_t blob_count,
                     const double *orient, int64_t *faults) {
    for (int64_t b = 0; b < blob_count; b++) {
        int64_t o = offsets[b], e = offsets[b + 1];
        faults[b] = 0;
        if (bc_twice_ring_area(position, n, o, e) * orient[b] <= 0.0) {
            faults[b] = 1;
            continue;
        }
        if (e - o > BC_SELF_CROSSING_MAX_VERTICES) continue;
        for (int64_t i = o; i < e && !faults[b]; i++) {
            int64_t i1 = bc_next_in_ring(i, o, e);
            for (int64_t j = i + 2; j < e; j++) {
                int64_t j1 = bc_next_in_ring(j, o, e);
                if (j1 == i) continue;
                if (bc_turn(position, n, i, i1, j) * bc_turn(position, n, i, i1, j1) < 0 &&
                    bc_turn(position, n, j, j1, i) * bc_turn(position, n, j, j1, i1) < 0) {
                    faults[b] = 2;
                    break;
                }
            }
        }
    }
}
