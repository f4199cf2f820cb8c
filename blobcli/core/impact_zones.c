/* Impact zones: the fail-safe after the substep's constraints keeps each ring simple.
 *
 * The self-contact pairs (self_contact.c) keep a vertex off the edges of its own ring; what the iterations
 * still leave crossed, bc_keep_rings_simple mends after them: where two edges of a ring cross or touch,
 * their ends move rigidly from where they were when the substep began (below). The chunks and their
 * table are bc_find_self_contacts's (self_chunks.h).
 */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "area.h"
#include "parallel.h"
#include "ring.h"
#include "scratch.h"
#include "self_chunks.h"
#include "self_contact.h"

#define ZONE_ROUNDS 4  /* rounds of impact zones before the whole ring moves rigidly for the substep */
#define SUMS 9         /* columns of the zones' sums (move_zones_rigidly) */

/* × the reach: how far from its predicted place the iterations may move a vertex of a ring whose chunks were all
 * apart before it is checked for crossings again */
static const double STILL_SIMPLE = 0.25;

/* Whether segments (a, a1) and (b, b1) cross or touch: each one's ends not strictly on one side of the
 * other's line, or all four on one line, with their boxes overlapping (geometry.first_crossing's test,
 * which `blobsim stress` judges rings by). */
static inline bool segments_touch(const double *pos, int64_t N, int64_t a, int64_t a1, int64_t b, int64_t b1) {
    int o1 = bc_turn(pos, N, a, a1, b), o2 = bc_turn(pos, N, a, a1, b1);
    int o3 = bc_turn(pos, N, b, b1, a), o4 = bc_turn(pos, N, b, b1, a1);
    if (!((o1 != o2 && o3 != o4) || (o1 == 0 && o2 == 0))) return false;
    return bc_min(pos[a], pos[a1]) <= bc_max(pos[b], pos[b1])
        && bc_min(pos[b], pos[b1]) <= bc_max(pos[a], pos[a1])
        && bc_min(pos[N + a], pos[N + a1]) <= bc_max(pos[N + b], pos[N + b1])
        && bc_min(pos[N + b], pos[N + b1]) <= bc_max(pos[N + a], pos[N + a1]);
}

/* Union of the zones of local vertices a and b (each zone's root: its smallest member). */
static inline void join(int64_t *zone, int64_t a, int64_t b) {
    while (zone[a] != a) a = zone[a];
    while (zone[b] != b) b = zone[b];
    if (a < b) zone[b] = a;
    else if (b < a) zone[a] = b;
}

/* Join the zones of the ends of every two edges of ring o..e that cross or touch, and say whether any do
 * (with no `zone`, NULL, only say). Chunks as bc_find_self_contacts's, at pos, with no reach. zone: the
 * ring's vertices from 0, (e - o,). */
static bool crossings_into_zones(const double *pos, int64_t N, int64_t o, int64_t e, double *chunks, int64_t *zone) {
    chunk_shapes(pos, pos, N, o, e, chunks);
    bool crossed = false;
    for (int64_t c = o; c < e; c += CHUNK) {
        for (int64_t d = c; d < e; d += CHUNK) {
            if (chunks_apart_by(N, o, e, chunks, c, d, 0.0) > 0.0) continue;
            for (int64_t a = c; a < bc_imin(c + CHUNK, e); a++) {
                int64_t a1 = bc_next_in_ring(a, o, e);
                for (int64_t b = d != c ? d : a + 2; b < bc_imin(d + CHUNK, e); b++) {
                    int64_t b1 = bc_next_in_ring(b, o, e);
                    if (b == a || b1 == a || b == a1 || !segments_touch(pos, N, a, a1, b, b1)) continue;
                    if (zone == NULL) return true;
                    crossed = true;
                    join(zone, a - o, a1 - o);
                    join(zone, a - o, b - o);
                    join(zone, a - o, b1 - o);
                }
            }
        }
    }
    return crossed;
}

/* Each zone of two or more vertices moves rigidly from where it was when the substep began: its centre as
 * its vertices' mean moved, turned by the angle θ that best fits their motion (2D Procrustes,
 * tan θ = Σ q × r / Σ q · r, q and r about the centre before and after, as integrate's update_velocities).
 * The zone's momentum is kept, and its relative motion, the part that crossed the ring, is gone. A zone
 * with a vertex a fixed collider pushed this substep (held > 0) stays where it was when the substep began
 * instead (moved, it would go into that collider, whose push it undid); one that a moving collider pushed
 * (wall_velocity: contact_material's rows 4 and 5, the surface's velocity there) is left as it is: where
 * the substep began is inside the collider now, whose push keeps the last word. sums: (e - o, SUMS), per
 * zone root: Σ x, Σ y, Σ x_prev, Σ y_prev, members, Σ q × r, Σ q · r, Σ held, members a moving collider
 * holds. */
static void move_zones_rigidly(double *pos, const double *prev, const double *held, const double *wall_velocity,
                               int64_t N, int64_t o, int64_t e, int64_t *zone, double *sums) {
    int64_t n = e - o;
    for (int64_t k = 0; k < n; k++)
        for (int column = 0; column < SUMS; column++) sums[k * SUMS + column] = 0.0;
    for (int64_t k = 0; k < n; k++) {
        int64_t root = k;
        while (zone[root] != root) root = zone[root];
        zone[k] = root;  /* (flattened: the root of every member) */
        int64_t i = o + k;
        double *sum = sums + root * SUMS;
        sum[0] += pos[i];
        sum[1] += pos[N + i];
        sum[2] += prev[i];
        sum[3] += prev[N + i];
        sum[4] += 1.0;
        sum[7] += held[i];
        if (held[i] != 0.0 && (wall_velocity[4 * N + i] != 0.0 || wall_velocity[5 * N + i] != 0.0)) sum[8] += 1.0;
    }
    for (int64_t k = 0; k < n; k++) {
        int64_t i = o + k;
        double *sum = sums + zone[k] * SUMS;
        double members = sum[4];
        if (members < 2.0) continue;
        double rx = pos[i] - sum[0] / members, ry = pos[N + i] - sum[1] / members;
        double qx = prev[i] - sum[2] / members, qy = prev[N + i] - sum[3] / members;
        sum[5] += qx * ry - qy * rx;
        sum[6] += qx * rx + qy * ry;
    }
    for (int64_t k = 0; k < n; k++) {
        int64_t i = o + k;
        const double *sum = sums + zone[k] * SUMS;
        double members = sum[4];
        if (members < 2.0) continue;
        if (sum[8] > 0.0) continue;  /* a moving collider holds it: its push has the last word */
        if (sum[7] > 0.0) {
            pos[i] = prev[i];
            pos[N + i] = prev[N + i];
            continue;
        }
        double theta = atan2(sum[5], sum[6]);
        double cos_theta = cos(theta), sin_theta = sin(theta);
        double qx = prev[i] - sum[2] / members, qy = prev[N + i] - sum[3] / members;
        pos[i] = sum[0] / members + cos_theta * qx - sin_theta * qy;
        pos[N + i] = sum[1] / members + sin_theta * qx + cos_theta * qy;
    }
}

/* Whether a collider pushed any vertex of ring o..e this substep. */
static inline bool any_held(const double *held, int64_t o, int64_t e) {
    for (int64_t i = o; i < e; i++)
        if (held[i] != 0.0) return true;
    return false;
}

/* The fail-safe after the substep's constraints (Bridson, Fedkiw & Anderson 2002's impact zones): where two
 * edges of a ring now cross or touch, the ends of both move rigidly from where they were when the substep
 * began, where they did not; zones that meet are joined, and after ZONE_ROUNDS rounds the whole ring moves
 * rigidly (zones a collider pushed: see move_zones_rigidly). A ring that began the substep simple ends it
 * simple (unless a moving collider holds the crossing), with its momentum (unless a collider holds the
 * zone); what is lost is the zones' relative motion (kinetic energy is never made). A ring that began the
 * substep crossed is left to the constraints, which untangle it (below). With `exact_area` (method kot), a
 * ring the zones moved and no collider touches is then projected onto its target area again, unless that
 * crosses it again: the area stays exact wherever it can. zoned[b] counts the substeps in which ring b
 * needed this. A zone moved rigidly may go into a collider (a moving one has gone on since the substep
 * began): the statics act again after it (the driver).
 *
 * A ring whose chunks were all apart (bc_find_self_contacts: near[b] = APART) and whose vertices the
 * iterations moved less than STILL_SIMPLE × the reach from their predicted places x_prev + h v is not
 * checked: its parts were farther apart than the reach, and came closer by less than half of it.
 *
 * held: s->contact_depth, wall_velocity: s->contact_material. The zones (zone, sums, kept) are ring b's
 * slices of the scratch, from its first vertex on. */
void bc_keep_rings_simple(const bcContext *ctx, double h, int exact_area) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t N = m->vertex_count;
    double *pos = s->position;
    const double *prev = s->previous, *vel = s->velocity, *held = s->contact_depth;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        int64_t n = e - o;
        if (s->self_near[b] == APART) {
            double bound = STILL_SIMPLE * REACH * m->rest_perimeter[b] / (double)n;
            bound = bound * bound;
            double moved = 0.0;
            for (int64_t i = o; i < e; i++) {
                double dx = pos[i] - prev[i] - h * vel[i], dy = pos[N + i] - prev[N + i] - h * vel[N + i];
                moved = bc_max(moved, dx * dx + dy * dy);
            }
            if (moved < bound) continue;
        }
        if (!crossings_into_zones(pos, N, o, e, s->self_chunks, NULL)) continue;
        /* it began the substep crossed (so given, or a moving collider held a crossing): there is no simple shape
         * to come back to, and the constraints untangle it (kot gives the lobe of positive area its area back and
         * shrinks the other), which zones moved from a crossed start would undo every substep */
        if (crossings_into_zones(prev, N, o, e, s->self_chunks, NULL)) continue;
        s->zoned[b] += 1;
        int64_t *zone = w->self_zone + o;
        double *sums = w->self_sums + SUMS * o;
        for (int64_t k = 0; k < n; k++) zone[k] = k;
        crossings_into_zones(pos, N, o, e, s->self_chunks, zone);
        bool crossing = true;
        for (int rounds = 0; rounds < ZONE_ROUNDS && crossing; rounds++) {
            move_zones_rigidly(pos, prev, held, s->contact_material, N, o, e, zone, sums);
            crossing = crossings_into_zones(pos, N, o, e, s->self_chunks, zone);
        }
        if (crossing) {  /* still crossing: the whole ring, one zone */
            for (int64_t k = 0; k < n; k++) zone[k] = 0;
            move_zones_rigidly(pos, prev, held, s->contact_material, N, o, e, zone, sums);
        }
        if (!exact_area || any_held(held, o, e)) continue;
        double *kept = w->self_kept + 2 * o;  /* (2, n): the ring before the area's projection */
        for (int64_t k = 0; k < n; k++) {
            kept[k] = pos[o + k];
            kept[n + k] = pos[N + o + k];
        }
        bc_project_area(pos, N, m->inv_mass, o, e, m->target_area[b]);
        if (crossings_into_zones(pos, N, o, e, s->self_chunks, NULL)) {
            for (int64_t k = 0; k < n; k++) {
                pos[o + k] = kept[k];
                pos[N + o + k] = kept[n + k];
            }
        }
    });
}
