/* Sleeping islands: blobs at rest stop costing anything but the broad phase.
 *
 * After Box2D v3 (its islands and sleep timers, solver.c / island.c), for blobs. Once per step:
 *
 * 1. Each awake blob is still while it goes nowhere, on average: its still time grows by dt while its centre stays
 *    within d = sleep_speed × time_to_sleep of where its window began, and its first vertex has turned about the
 *    centre by less than d / r since (r its radius); the step it goes farther, its still time begins again, from
 *    there. A window begins where the still time begins and again after each whole time_to_sleep of it, the still
 *    time kept: a blob creeping slower than sleep_speed stays still. (Measured from where the still time began, a
 *    blob creeping at v passed d every d / v and began again, and in a pile of 300 one of them nearly always had
 *    less than time_to_sleep: the island slept 10.2 s after the drop, 4 s after all but 10 of its blobs had been
 *    still for a second; with windows at 6.0 s.) So an island sleeps once every blob has gone slower than
 *    sleep_speed on average over its last window. Centre and turn are read from the positions, and only once per
 *    step: a vertex may flicker while its blob goes nowhere. Not the speed at each step: the bottom row of a pile
 *    of 1,000 blobs (24 rows on top) rocks in place at 4-6 mm/s (spin × radius) with an excursion under 2 mm, and
 *    tested step by step one of its blobs always broke its still time, so the whole pile, one island, never
 *    slept. (Nor the spin integrated, ∫ω dt: ω read once per step from the last substep's velocities aliased that
 *    rocking into a steady turn.)
 * 2. Islands are the connected groups of the broad phase's blob pairs (centres closer than r_a + r_b + margin:
 *    touching, or about to) of the step's last substep, found with a union-find over the pairs in pair order. A
 *    pair of two sleeping blobs still links them: the broad phase runs over every blob.
 * 3. An island in which every awake blob has been still for `time_to_sleep` goes to sleep as a whole; an island
 *    with any other awake blob in it is awake as a whole: a moving blob that comes near a sleeping island wakes
 *    every blob of it (their still time starts again from 0, so a woken island stays awake at least
 *    `time_to_sleep`).
 *
 * A sleeping blob is not simulated: every stage skips it, its positions stay exactly as they were, its velocity is
 * 0 (set when it falls asleep) and its contacts are cleared. Awake blobs that touch it during the step (before the
 * island wakes at its end) treat it as immovable: its inverse mass in their contacts is 0, or the steady trade of
 * area and contact pushes would press into it every iteration. A collider that moves wakes the blobs near it
 * (walls.c), and a blob touching a moving surface is never at rest.
 */
#include <math.h>
#include <stdbool.h>

#include "collide_limits.h"
#include "ring.h"
#include "scratch.h"
#include "sleep.h"

static const double PI = 3.141592653589793; /* math.pi */

/* Ring o..e's centre (the mean of its vertices) into (cx, cy), and the angle of its first vertex about it (rad) */
static inline double pose(const double *pos, int64_t n, int64_t o, int64_t e, double *cx, double *cy) {
    double means[4];
    bc_ring_means(pos, pos, n, o, e, means);
    *cx = means[0];
    *cy = means[1];
    return atan2(pos[n + o] - *cy, pos[o] - *cx);
}

/* Blob b's still time begins now, its centre at (cx, cy) and its first vertex at `angle` about it. */
static inline void begin_still(bcState *s, int64_t b, double cx, double cy, double angle) {
    s->still[b] = 0.0;
    s->still_center[2 * b] = cx;
    s->still_center[2 * b + 1] = cy;
    s->still_angle[b] = angle;
}

/* Whether a vertex of ring o..e touches a moving surface (a conveyor, a moving or loaded wall): such a blob is
 * never at rest, held in place against it or not, so its island never sleeps while it rides. */
static bool on_moving_surface(const bcState *s, int64_t n, int64_t o, int64_t e) {
    const double *material = s->contact_material;
    for (int64_t i = o; i < e; i++) {
        if (s->contact_depth[i] > 0.0
            && (material[3 * n + i] != 0.0 || material[4 * n + i] != 0.0 || material[5 * n + i] != 0.0)) {
            return true;
        }
    }
    return false;
}

/* Union-find root of b, halving the path on the way. */
static int64_t root(int64_t *parent, int64_t b) {
    while (parent[b] != b) {
        parent[b] = parent[parent[b]];
        b = parent[b];
    }
    return b;
}

/* One step's sleep bookkeeping (above), over the pairs of the step's last substep (scratch.h: pairs, pair_count).
 * awake (B,), still (B,) s, still_center (B, 2) m and still_angle (B,) rad are updated in place; blobs falling
 * asleep get v = 0, x_prev = x and no contacts. Returns how many blobs are awake. Serial, once a step. */
int64_t bc_update_sleep(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const bcScratch *w = ctx->w;
    const int64_t B = m->blob_count, n = m->vertex_count, *offsets = m->offsets;
    const double *pos = s->position, time_to_sleep = ctx->c->time_to_sleep, dt = ctx->c->dt;
    uint8_t *awake = s->awake;
    double *still = s->still;
    double reach = ctx->c->sleep_speed * time_to_sleep; /* d: how far a still blob may go in its still time */
    for (int64_t b = 0; b < B; b++) {
        if (!awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double cx, cy;
        double angle = pose(pos, n, o, e, &cx, &cy);
        double turn = angle - s->still_angle[b];
        /* in [-π, π]: round() half to even, as numba's (rint); |turn| <= 2π, or NaN, which stays NaN */
        turn -= 2.0 * PI * rint(turn / (2.0 * PI));
        double mx = cx - s->still_center[2 * b], my = cy - s->still_center[2 * b + 1];
        double moved2 = mx * mx + my * my;
        if (moved2 < reach * reach && fabs(turn) * bc_ring_radius(pos, n, o, e, cx, cy) < reach
            && !on_moving_surface(s, n, o, e)) {
            /* numba's math.floor is an int64: the same order for any still / time_to_sleep below 2^63 */
            double windows = floor(still[b] / time_to_sleep);
            still[b] += dt;
            if (floor(still[b] / time_to_sleep) > windows) { /* a whole window still: the next is measured */
                s->still_center[2 * b] = cx;                  /* from here, its still time kept */
                s->still_center[2 * b + 1] = cy;
                s->still_angle[b] = angle;
            }
        } else { /* it went somewhere: its still time begins again, from here */
            begin_still(s, b, cx, cy, angle);
        }
    }
    /* union-find over the pairs; the root is the smallest blob index of the island */
    int64_t *parent = w->sleep_parent;
    for (int64_t b = 0; b < B; b++) parent[b] = b;
    const int64_t pair_count = bc_imin(w->pair_count, w->pair_capacity);
    for (int64_t k = 0; k < pair_count; k++) {
        int64_t ra = root(parent, w->pairs[2 * k]), rb = root(parent, w->pairs[2 * k + 1]);
        if (ra != rb) parent[bc_imax(ra, rb)] = bc_imin(ra, rb);
    }
    uint8_t *restless = w->sleep_restless; /* by root: the island has an awake blob not yet still long enough */
    for (int64_t b = 0; b < B; b++) restless[b] = 0;
    for (int64_t b = 0; b < B; b++) {
        if (awake[b] && still[b] < time_to_sleep) restless[root(parent, b)] = 1;
    }
    for (int64_t b = 0; b < B; b++) {
        bool keep_awake = restless[root(parent, b)] != 0;
        if (keep_awake && !awake[b]) { /* woken: its still time begins again, where it slept */
            double cx, cy;
            double angle = pose(pos, n, offsets[b], offsets[b + 1], &cx, &cy);
            begin_still(s, b, cx, cy, angle);
        } else if (awake[b] && !keep_awake) { /* falls asleep: frozen exactly where it is */
            for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
                s->velocity[i] = s->velocity[n + i] = 0.0;
                s->previous[i] = pos[i];
                s->previous[n + i] = pos[n + i];
                s->contact_depth[i] = 0.0;
                for (int64_t c = 0; c < BC_CONTACTS_PER_VERTEX; c++) s->c_edge[c * n + i] = -1;
            }
        }
        awake[b] = keep_awake;
    }
    return bc_awake_count(ctx);
}

/* How many blobs are awake */
int64_t bc_awake_count(const bcContext *ctx) {
    int64_t count = 0;
    for (int64_t b = 0; b < ctx->m->blob_count; b++) count += ctx->s->awake[b] != 0;
    return count;
}

/* Every blob's still time begins now, where it is (a state just built). Reads only ctx->m and ctx->s. */
void bc_begin_still(const bcContext *ctx) {
    const int64_t n = ctx->m->vertex_count, *offsets = ctx->m->offsets;
    for (int64_t b = 0; b < ctx->m->blob_count; b++) {
        double cx, cy;
        double angle = pose(ctx->s->position, n, offsets[b], offsets[b + 1], &cx, &cy);
        begin_still(ctx->s, b, cx, cy, angle);
    }
}
