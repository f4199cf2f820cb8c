/* Wall checks: the blobs a moving collider could not keep whole, and the blobs a loaded wall passed into or
 * through; the run stops on either (walls.c's header says how the walls move).
 */
#include <stdbool.h>
#include <stdint.h>

#include "friction.h"
#include "parallel.h"
#include "ring.h"
#include "scratch.h"
#include "touch.h"
#include "wall_shapes.h"
#include "walls.h"

/* ---- Blobs a moving collider could not keep whole ----
 *
 * A kinematic collider moves as it is told, however hard the blobs push back: a box dragged along a path down onto
 * a blob on a floor squeezes it to a quarter of its area and then out on the box's far side; a box spinning at
 * 1,000 rad/s beside a blob tears its ring across. A loaded wall whose load its blobs cannot carry at the substeps a
 * step may take (bc_loaded_substeps, at most `most_substeps`) crushes them flat. The step cannot undo that, so the
 * run stops instead of finishing with a blob inside out or on the wall's far side: after each step, an awake blob
 * within its own size of a moving collider's bounding box that is inside out (its signed area's sign turned), or,
 * where its area is held exactly (kot, or xpbd without compliance), whose area is off by more than CRUSHED of it
 * (a loaded wall holding what it presses keeps it within a few per cent: 3.7% under 1,000 N on 1 kg at the impact;
 * 5,000 N left 25%). (A fast impact may leave a ring crossed for a step or two, its area kept: the ring comes undone
 * by itself, and the run goes on.) Returns b × S + k for the first such blob b and a moving collider k beside it,
 * or -1. */
static const double CRUSHED = 0.1;
enum { KOT, XPBD }; /* the area methods held exactly (of scene/schema.py METHODS, in its order) */

int64_t bc_first_broken_blob(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    const bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    const double *pos = s->position;
    for (int64_t b = 0; b < m->blob_count; b++) {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        if (e - o < 3) continue;
        double ring[4]; /* its bounds x0, y0, x1, y1 */
        bc_ring_bounds(pos, n, o, e, ring);
        double x0 = ring[0], y0 = ring[1], x1 = ring[2], y1 = ring[3];
        double margin = bc_max(x1 - x0, y1 - y0);
        int64_t beside = -1;
        for (int64_t k = 0; k < walls->count && beside < 0; k++) {
            int64_t kind = walls->kind[k], shape = walls->shape[k];
            if (walls->motion[k] == BC_FIXED || kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 ||
                shape >= m->statics[kind].shapes)
                continue;
            const double *box = s->placed[kind].aabb + 4 * shape;
            if (x1 + margin >= box[0] && x0 - margin <= box[2] && y1 + margin >= box[1] && y0 - margin <= box[3])
                beside = k;
        }
        if (beside < 0) continue;
        double area = 0.5 * bc_twice_ring_area(pos, n, o, e), target = m->target_area[b];
        bool exact = ctx->c->method == KOT || (ctx->c->method == XPBD && m->area_compliance[b] == 0.0);
        if (!(area * m->orient[b] > 0.0) || (exact && !(fabs(area / target - 1.0) <= CRUSHED)))
            return b * walls->count + beside;
    }
    return -1;
}

/* ---- A loaded wall that passed through a blob ----
 *
 * A load far beyond what the substeps a step may take can carry moves its wall farther in a substep than the blobs
 * it meets can be pushed: 10⁶ N on a 1 kg box predicts 1 m a substep at 16 substeps of 1/60 s. The kernels put
 * each vertex back on the face its path entered by, but where that side is taken (the floor under a blob) the floor
 * pushes it out again across the wall, and within a few substeps, or steps, the blob is whole on the wall's far
 * side. So each loaded wall k keeps, for each blob b whose centre lies beside it (within its extent across its load
 * direction e), the side b was last wholly on: AHEAD of it along e (b's least e · x at least the wall's greatest
 * e · p) or BEHIND it (b's greatest at most the wall's least); a blob whose centre leaves its side is forgotten (it
 * went round an end, or over a wedge's top). A blob found wholly on the other side of the one noted, its centre
 * still beside the wall, was passed through; one beside it on neither side with a corner of the wall deep inside its
 * ring, or an edge of its ring deep inside the wall (2 × 10⁴ N pressed a blob out round the press's sides and over
 * its top, the press on the floor inside it), was passed into: either way bc_advance stops. Noted at each step's
 * start (bc_note_wall_sides) and checked at its end (bc_find_passed_blob), in the scratch (a fresh scratch
 * forgets). Polygons, segments and solid circles; a plane or a container has no far side a blob can reach. */

/* Collider k's extent as the scene wrote it (a loaded wall only moves along e: its pose adds s to the first):
 * along e, lo[0] .. hi[0], and across it, along (-e_y, e_x), lo[1] .. hi[1]; false for a plane or a container */
static bool extent_of(const bcModel *m, int64_t k, double lo[2], double hi[2]) {
    const bcWalls *walls = &m->walls;
    int64_t kind = walls->kind[k], shape = walls->shape[k];
    double ex = walls->drive[3 * k + 1], ey = walls->drive[3 * k + 2];
    const double *geom = m->statics[kind].geom;
    const int64_t *offsets = m->statics[kind].shape_offsets;
    lo[0] = lo[1] = INFINITY;
    hi[0] = hi[1] = -INFINITY;
    if (kind == PLANE) return false;
    if (kind == CIRCLE) {
        const double *row = geom + 4 * offsets[shape];
        if (row[3] != 0.0) return false;
        double along = row[0] * ex + row[1] * ey, across = -row[0] * ey + row[1] * ex;
        lo[0] = along - row[2];
        hi[0] = along + row[2];
        lo[1] = across - row[2];
        hi[1] = across + row[2];
        return true;
    }
    for (int64_t r = offsets[shape]; r < offsets[shape + 1]; r++) {
        for (int end = 0; end < 2; end++) { /* both ends of every row: a segment's too */
            double x = geom[4 * r + 2 * end], y = geom[4 * r + 2 * end + 1];
            double along = x * ex + y * ey, across = -x * ey + y * ex;
            lo[0] = bc_min(lo[0], along);
            hi[0] = bc_max(hi[0], along);
            lo[1] = bc_min(lo[1], across);
            hi[1] = bc_max(hi[1], across);
        }
    }
    return true;
}

/* Where blob b is now, for loaded wall k: wholly AHEAD of it along e or BEHIND it (its centre beside it across
 * e), BESIDE it but neither, or AWAY (its centre not beside it) */
enum { AWAY = 0, AHEAD = 1, BEHIND = 2, BESIDE = 3 };
static int side_of(const bcContext *ctx, int64_t k, int64_t b, const double lo[2], const double hi[2]) {
    const bcModel *m = ctx->m;
    int64_t n = m->vertex_count, o = m->offsets[b], e = m->offsets[b + 1];
    const double *pos = ctx->s->position;
    double ex = m->walls.drive[3 * k + 1], ey = m->walls.drive[3 * k + 2], s = ctx->s->static_pose[POSE * k + 3];
    double a0 = INFINITY, a1 = -INFINITY, centre = 0.0; /* the ring's extent along e, its centre across e */
    for (int64_t i = o; i < e; i++) {
        double along = pos[i] * ex + pos[n + i] * ey;
        a0 = bc_min(a0, along);
        a1 = bc_max(a1, along);
        centre += -pos[i] * ey + pos[n + i] * ex;
    }
    centre /= (double)(e - o);
    if (!(centre > lo[1] && centre < hi[1])) return AWAY;
    return a0 >= hi[0] + s ? AHEAD : a1 <= lo[0] + s ? BEHIND : BESIDE;
}

/* Whether collider k is a loaded wall with a far side (and its extent, extent_of) */
static bool loaded_extent(const bcModel *m, int64_t k, double lo[2], double hi[2]) {
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k];
    return m->walls.motion[k] == BC_LOADED && kind >= 0 && kind < BC_SOLVER_KINDS && shape >= 0 &&
           shape < m->statics[kind].shapes && extent_of(m, k, lo, hi);
}

/* Blob b's noted side of wall k after it is found where `now` says: the side it is wholly on, kept while it is
 * beside the wall on neither, forgotten when it is away */
static uint8_t noted(uint8_t was, int now) {
    return (uint8_t)(now == AHEAD || now == BEHIND ? now : now == BESIDE ? was : AWAY);
}

void bc_note_wall_sides(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    uint8_t *side = ctx->w->wall_side;
    for (int64_t k = 0; k < m->walls.count; k++) {
        double lo[2], hi[2];
        if (!loaded_extent(m, k, lo, hi)) continue;
        for (int64_t b = 0; b < m->blob_count; b++) {
            uint8_t *was = side + k * m->blob_count + b;
            if (ctx->s->awake[b]) *was = noted(*was, side_of(ctx, k, b, lo, hi));
        }
    }
}

/* Whether a corner of loaded wall k lies inside ring b deeper than INSIDE × its rest radius (the corners' stage
 * leaves them 0.05 mm deep at most) */
static const double INSIDE = 0.02;
static bool corner_inside(const bcContext *ctx, int64_t k, int64_t b) {
    const bcModel *m = ctx->m;
    int64_t n = m->vertex_count, o = m->offsets[b], e = m->offsets[b + 1];
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k];
    const double *pos = ctx->s->position;
    double deep = INSIDE * m->rest_perimeter[b] / (2.0 * 3.141592653589793);
    for (int64_t c = 0; c < corner_count(ctx, kind, shape); c++) {
        double qx, qy;
        corner_of(ctx, kind, shape, c, &qx, &qy);
        if (!bc_ring_contains(pos, n, o, e, qx, qy)) continue;
        double nearest = INFINITY;
        for (int64_t i = o; i < e; i++) {
            int64_t j = bc_next_in_ring(i, o, e);
            double ex = pos[j] - pos[i], ey = pos[n + j] - pos[n + i], e2 = ex * ex + ey * ey;
            double u = e2 > 0.0 ? bc_min(bc_max(((qx - pos[i]) * ex + (qy - pos[n + i]) * ey) / e2, 0.0), 1.0) : 0.0;
            nearest = bc_min(nearest, hypot(pos[i] + u * ex - qx, pos[n + i] + u * ey - qy));
        }
        if (nearest > deep) return true;
    }
    return false;
}

/* Whether an edge of ring b runs through loaded polygon k deeper than INSIDE × the ring's rest radius, at its
 * quarter points (the ring's vertices are outside it, the kernels see to that, and its corners on the ring's edges
 * at most, the corners' stage sees to that: an edge deep inside it crosses it) */
static bool edge_inside(const bcContext *ctx, int64_t k, int64_t b) {
    const bcModel *m = ctx->m;
    int64_t n = m->vertex_count, o = m->offsets[b], e = m->offsets[b + 1];
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k];
    if (kind != POLYGON) return false;
    const double *pos = ctx->s->position, *geom = ctx->s->placed[kind].geom;
    const double *aabb = ctx->s->placed[kind].aabb + 4 * shape;
    int64_t start = m->statics[kind].shape_offsets[shape], stop = m->statics[kind].shape_offsets[shape + 1];
    double deep = INSIDE * m->rest_perimeter[b] / (2.0 * 3.141592653589793);
    for (int64_t i = o; i < e; i++) {
        int64_t j = bc_next_in_ring(i, o, e);
        for (int q = 1; q < 4; q++) {
            double x = pos[i] + 0.25 * q * (pos[j] - pos[i]), y = pos[n + i] + 0.25 * q * (pos[n + j] - pos[n + i]);
            if (x < aabb[0] || x > aabb[2] || y < aabb[1] || y > aabb[3] || !bc_rows_contain(geom, start, stop, x, y))
                continue;
            double nearest = INFINITY;
            for (int64_t r = start; r < stop; r++) {
                const double *row = geom + 4 * r;
                double ex = row[2] - row[0], ey = row[3] - row[1], e2 = ex * ex + ey * ey;
                double u = e2 > 0.0 ? bc_min(bc_max(((x - row[0]) * ex + (y - row[1]) * ey) / e2, 0.0), 1.0) : 0.0;
                nearest = bc_min(nearest, hypot(row[0] + u * ex - x, row[1] + u * ey - y));
            }
            if (nearest > deep) return true;
        }
    }
    return false;
}

int64_t bc_find_passed_blob(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    uint8_t *side = ctx->w->wall_side;
    int64_t passed = -1;
    for (int64_t k = 0; k < m->walls.count; k++) {
        double lo[2], hi[2];
        if (!loaded_extent(m, k, lo, hi)) continue;
        for (int64_t b = 0; b < m->blob_count; b++) {
            uint8_t *was = side + k * m->blob_count + b;
            if (!ctx->s->awake[b]) continue;
            int now = side_of(ctx, k, b, lo, hi);
            if (passed < 0 && ((*was != AWAY && (now == AHEAD || now == BEHIND) && now != *was) ||
                               (now == BESIDE && (corner_inside(ctx, k, b) || edge_inside(ctx, k, b)))))
                passed = b * m->walls.count + k;
            *was = noted(*was, now);
        }
    }
    return passed;
}
