/* Walls that move: colliders on a prescribed motion, or pushed by a load (a piston).
 *
 * Collider k's pose at time t is the rigid map T(t): p -> q + d + R(θ) (p - q) of the rows as the scene wrote
 * them (m->statics[kind].geom), q its pivot, d its displacement and θ its turn. It moves in one of three ways
 * (bcWalls.motion): at a constant velocity (d = v t, θ = ω t, as Box2D's kinematic bodies: a velocity, not a
 * force, drives them, and nothing the blobs do changes it); along a path (d, θ linear between keyframes); or
 * LOADED: along its load direction e only, d = s e, with Newton's law for s.
 *
 * Each substep (of length h, from t), bc_place_walls moves every collider that moves to its pose at t + h
 * (model rows -> the state's placed rows and bounding boxes) and writes its motion over the substep as the
 * rigid map Δ = T(t + h) ∘ T(t)⁻¹, p -> R(Δθ) p + τ (rows delta: cos Δθ, sin Δθ, τx, τy, loaded). The collider
 * kernels (statics.c) then test each vertex's path relative to the collider: from Δ(x_prev), where the vertex
 * would be had it been carried with the collider, to x, against the collider where it is now. So the swept
 * tests see the wall's own motion (a wall never passes a vertex, however fast), static friction holds a vertex
 * to the moving surface, and the velocity a contact is measured against is the surface's, w = (x - Δ⁻¹(x)) / h.
 *
 * A loaded wall (mass M, load F along e): s* = s + h V + h² F / M is predicted (gravity does not act on it).
 * The collider kernels push vertices out of it as if it were fixed; after each iteration, bc_yield_loaded_walls
 * shares each of those pushes between the wall and the vertices by their masses. Every vertex i it pushed by
 * D_i along n_i stays on its surface, so if the wall moves σ along e, the vertex moves σ c_i along n_i too
 * (c_i = n_i · e), and momentum along e is kept (the wall's guide takes the rest):
 *     M σ + Σ m_i (D_i + σ c_i) c_i = Σ m_i D_i c_i - Σ m_i D_i c_i  =>  σ = -Σ m_i D_i c_i / (M + Σ m_i c_i²),
 * the inelastic two-body split of PBD (a light wall yields, a heavy one barely), never an overshoot. Its corners
 * push the rings' edges as the kernels push vertices (loaded_walls.c: bc_collide_loaded_corners), and a fast impact's stop of a
 * whole blob is its push too (bc_share_impact_stops). After the substep V = (s - s_start) / h; the contacts'
 * velocity stages then share their impulses with it the same way (bc_react_loaded_walls). At rest the load and the
 * blobs' pushes balance: the impulses the blobs give it over a step are F dt, which is what bc_account_contacts
 * records; the dent that takes in the blobs under it, h² F / m_c, sets the substeps a step takes
 * (bc_loaded_substeps). A blob a moving collider leaves inside out or crushed, or a loaded wall passes into or
 * through, stops the run (bc_first_broken_blob, bc_find_passed_blob).
 *
 * Forces: the kernels record for each vertex the pushes Δx each collider gave it over the step (up to two
 * colliders a vertex; a third shares the second's record: touch.h); bc_account_contacts turns them into the
 * impulses -m Σ Δx / h the blobs exert on each collider, and their torques about its pivot, once a step, in
 * vertex order (the same bits for any thread count).
 *
 * Arrays (blobcore.h): static_pose (S, 6): dx, dy (m), θ (rad), s (m), V (m/s), s at the substep's start (m);
 * static_impulse (S, 3); walls.drive (S, 3); walls.path (K, 4): t (s), dx, dy (m), turn (rad).
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "friction.h"
#include "parallel.h"
#include "ring.h"
#include "scratch.h"
#include "touch.h"
#include "wall_shapes.h"
#include "walls.h"

/* (dx, dy, θ) of a kinematic collider at time t */
static void pose_at(const bcWalls *walls, int64_t k, double t, double pose[3]) {
    if (walls->motion[k] == BC_VELOCITY) {
        pose[0] = walls->drive[3 * k] * t;
        pose[1] = walls->drive[3 * k + 1] * t;
        pose[2] = walls->drive[3 * k + 2] * t;
        return;
    }
    int64_t o = walls->path_offsets[k], e = walls->path_offsets[k + 1];
    const double *path = walls->path;
    if (e <= o) { /* a path without keyframes (the scene's check refuses it): no displacement */
        pose[0] = pose[1] = pose[2] = 0.0;
        return;
    }
    if (t <= path[4 * o]) {
        pose[0] = path[4 * o + 1];
        pose[1] = path[4 * o + 2];
        pose[2] = path[4 * o + 3];
        return;
    }
    for (int64_t j = o + 1; j < e; j++) {
        if (t < path[4 * j]) { /* linear between keyframes j - 1 and j */
            const double *a = path + 4 * (j - 1), *b = path + 4 * j;
            double f = (t - a[0]) / (b[0] - a[0]);
            pose[0] = a[1] + f * (b[1] - a[1]);
            pose[1] = a[2] + f * (b[2] - a[2]);
            pose[2] = a[3] + f * (b[3] - a[3]);
            return;
        }
    }
    pose[0] = path[4 * (e - 1) + 1];
    pose[1] = path[4 * (e - 1) + 2];
    pose[2] = path[4 * (e - 1) + 3];
}

/* T as (cos θ, sin θ, tx, ty): p -> R(θ) p + t, t = q + d - R(θ) q */
static void map(const bcWalls *walls, int64_t k, double dx, double dy, double theta, double T[4]) {
    double c = cos(theta), s = sin(theta);
    double qx = walls->pivot[2 * k], qy = walls->pivot[2 * k + 1];
    T[0] = c;
    T[1] = s;
    T[2] = qx + dx - (c * qx - s * qy);
    T[3] = qy + dy - (s * qx + c * qy);
}

/* T(x, y) */
static inline void apply(const double T[4], double x, double y, double *ax, double *ay) {
    *ax = T[0] * x - T[1] * y + T[2];
    *ay = T[1] * x + T[0] * y + T[3];
}

/* Collider k's rows and bounding box at pose (dx1, dy1, θ1), and its delta row from pose 0 to pose 1 */
static void place(const bcContext *ctx, int64_t k, double dx0, double dy0, double th0, double dx1, double dy1,
                  double th1, bool loaded) {
    const bcWalls *walls = &ctx->m->walls;
    int64_t kind = walls->kind[k], shape = walls->shape[k];
    if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= ctx->m->statics[kind].shapes) return;
    double T1[4], T0[4];
    map(walls, k, dx1, dy1, th1, T1);
    map(walls, k, dx0, dy0, th0, T0);
    double c1 = T1[0], s1 = T1[1], tx1 = T1[2], ty1 = T1[3], c0 = T0[0], s0 = T0[1], tx0 = T0[2], ty0 = T0[3];
    /* Δ = T1 ∘ T0⁻¹: p -> R1 R0ᵀ (p - t0) + t1 */
    double cd = c1 * c0 + s1 * s0, sd = s1 * c0 - c1 * s0;
    const double *geom0 = ctx->m->statics[kind].geom;
    const int64_t *offsets = ctx->m->statics[kind].shape_offsets;
    double *geom = ctx->s->placed[kind].geom, *aabb = ctx->s->placed[kind].aabb;
    double *delta = ctx->s->placed[kind].delta + 5 * shape;
    delta[0] = cd;
    delta[1] = sd;
    delta[2] = tx1 - (cd * tx0 - sd * ty0);
    delta[3] = ty1 - (sd * tx0 + cd * ty0);
    delta[4] = loaded ? 1.0 : 0.0;
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int64_t r = offsets[shape]; r < offsets[shape + 1]; r++) {
        const double *row0 = geom0 + 4 * r;
        double *row = geom + 4 * r;
        double ax, ay;
        apply(T1, row0[0], row0[1], &ax, &ay);
        if (kind == PLANE) { /* point and normal */
            row[0] = ax;
            row[1] = ay;
            row[2] = c1 * row0[2] - s1 * row0[3];
            row[3] = s1 * row0[2] + c1 * row0[3];
        } else if (kind == CIRCLE) { /* centre (radius and inside as written) */
            row[0] = ax;
            row[1] = ay;
            x0 = bc_min(x0, ax - row0[2]);
            y0 = bc_min(y0, ay - row0[2]);
            x1 = bc_max(x1, ax + row0[2]);
            y1 = bc_max(y1, ay + row0[2]);
        } else { /* segment, polygon edge: both ends */
            double bx, by;
            apply(T1, row0[2], row0[3], &bx, &by);
            row[0] = ax;
            row[1] = ay;
            row[2] = bx;
            row[3] = by;
            x0 = bc_min(bc_min(x0, ax), bx);
            y0 = bc_min(bc_min(y0, ay), by);
            x1 = bc_max(bc_max(x1, ax), bx);
            y1 = bc_max(bc_max(y1, ay), by);
        }
    }
    /* planes and drums: the whole plane, as built */
    if (kind != PLANE && !(kind == CIRCLE && geom0[4 * offsets[shape] + 3] != 0.0)) {
        aabb[4 * shape] = x0;
        aabb[4 * shape + 1] = y0;
        aabb[4 * shape + 2] = x1;
        aabb[4 * shape + 3] = y1;
    }
}

/* Wake the sleeping blobs whose bounding box meets the box collider k swept over the substep (its island wakes at
 * the step's end: sleep): the union of `was`, its box at the substep's start, and its box now. So it wakes a blob it
 * reaches and a blob it leaves: asleep against it, a blob would stay as the collider left it (flattened under a
 * press that lifts, in the air over a platform that drops). The boxes meet within the round-off a vertex put on a
 * surface lies off it (bc_surface_roundoff): a blob resting on the collider meets it whichever side of the surface
 * round-off left its vertices. */
static void wake_near(const bcContext *ctx, int64_t k, const double was[4]) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k], n = m->vertex_count;
    if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= m->statics[kind].shapes) return;
    const double *now = s->placed[kind].aabb + 4 * shape, *pos = s->position;
    double x0 = bc_min(was[0], now[0]), y0 = bc_min(was[1], now[1]);
    double x1 = bc_max(was[2], now[2]), y1 = bc_max(was[3], now[3]);
    for (int64_t b = 0; b < m->blob_count; b++) {
        if (s->awake[b]) continue;
        double box[4];
        bc_ring_bounds(pos, n, m->offsets[b], m->offsets[b + 1], box);
        double eps = bc_surface_roundoff(bc_max(fabs(box[0]), fabs(box[2])), bc_max(fabs(box[1]), fabs(box[3])));
        if (box[2] >= x0 - eps && box[0] <= x1 + eps && box[3] >= y0 - eps && box[1] <= y1 + eps) {
            s->awake[b] = 1;
            s->still[b] = 0.0;
        }
    }
}

/* Collider k's bounding box where it is placed now, into box (x0, y0, x1, y1); nothing for a collider the model
 * lacks (place and wake_near skip it too) */
static void box_of(const bcContext *ctx, int64_t k, double box[4]) {
    int64_t kind = ctx->m->walls.kind[k], shape = ctx->m->walls.shape[k];
    box[0] = box[1] = box[2] = box[3] = 0.0;
    if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= ctx->m->statics[kind].shapes) return;
    const double *aabb = ctx->s->placed[kind].aabb + 4 * shape;
    for (int j = 0; j < 4; j++) box[j] = aabb[j];
}

int bc_any_moves(const bcContext *ctx) {
    const bcWalls *walls = &ctx->m->walls;
    for (int64_t k = 0; k < walls->count; k++)
        if (walls->motion[k] != BC_FIXED) return 1;
    return 0;
}

void bc_place_walls(const bcContext *ctx, double t, double h) {
    const bcWalls *walls = &ctx->m->walls;
    for (int64_t k = 0; k < walls->count; k++) {
        int64_t motion = walls->motion[k];
        if (motion == BC_FIXED) continue;
        double *pose = ctx->s->static_pose + POSE * k;
        double dx0 = pose[0], dy0 = pose[1], th0 = pose[2];
        double next[3];
        if (motion == BC_LOADED) {
            /* s* = s + h V + h² F / M, along e */
            double ex = walls->drive[3 * k + 1], ey = walls->drive[3 * k + 2];
            pose[5] = pose[3];
            pose[3] += h * pose[4] + h * h * walls->drive[3 * k] / walls->mass[k];
            next[0] = pose[3] * ex;
            next[1] = pose[3] * ey;
            next[2] = 0.0;
        } else {
            pose_at(walls, k, t + h, next);
        }
        pose[0] = next[0];
        pose[1] = next[1];
        pose[2] = next[2];
        double was[4];
        box_of(ctx, k, was);
        place(ctx, k, dx0, dy0, th0, next[0], next[1], next[2], motion == BC_LOADED);
        /* A collider that holds still this substep (between matching keyframes, after its last) is a fixed one to
         * the blobs asleep against it: they sleep on until it moves. */
        if (next[0] != dx0 || next[1] != dy0 || next[2] != th0) wake_near(ctx, k, was);
    }
}

void bc_place_initial(const bcContext *ctx) {
    const bcWalls *walls = &ctx->m->walls;
    for (int64_t k = 0; k < walls->count; k++) {
        if (walls->motion[k] == BC_FIXED) continue;
        double at[3] = {0.0, 0.0, 0.0};
        if (walls->motion[k] != BC_LOADED) pose_at(walls, k, 0.0, at);
        double *pose = ctx->s->static_pose + POSE * k;
        pose[0] = at[0];
        pose[1] = at[1];
        pose[2] = at[2];
        place(ctx, k, at[0], at[1], at[2], at[0], at[1], at[2], walls->motion[k] == BC_LOADED);
    }
}

void bc_yield_loaded_walls(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    double *pos = s->position, *wall_push = s->wall_push;
    const int64_t *wall_of = s->wall_of;
    for (int64_t k = 0; k < walls->count; k++) {
        if (walls->motion[k] != BC_LOADED) continue;
        double ex = walls->drive[3 * k + 1], ey = walls->drive[3 * k + 2];
        /* a = Σ m D c, b = Σ m c² over the vertices it pushed, D c = Δx · e and c² = (D c)² / D² */
        double a = 0.0, b = 0.0;
        for (int64_t i = 0; i < n; i++) {
            if (wall_of[i] == k) {
                double px = wall_push[i], py = wall_push[n + i];
                double d2 = px * px + py * py;
                if (d2 > 0.0) {
                    double mass = 1.0 / m->inv_mass[i];
                    double pe = px * ex + py * ey; /* D c */
                    a += mass * pe;
                    b += mass * pe * pe / d2;
                }
            }
        }
        if (b == 0.0) continue;
        double sigma = -a / (walls->mass[k] + b);
        for (int64_t i = 0; i < n; i++) {
            if (wall_of[i] == k) {
                double px = wall_push[i], py = wall_push[n + i];
                double d2 = px * px + py * py;
                if (d2 > 0.0) { /* along n by σ c: σ (D c / D) (Δx / D) */
                    double f = sigma * (px * ex + py * ey) / d2;
                    pos[i] += f * px;
                    pos[n + i] += f * py;
                    bc_account(i, k, f * px, f * py, s->static_of, s->static_push, n);
                }
            }
        }
        double *pose = s->static_pose + POSE * k;
        pose[3] += sigma;
        pose[0] = pose[3] * ex;
        pose[1] = pose[3] * ey;
        /* placed anew at s from s0: the delta row keeps the substep's whole motion (from s at t) */
        place(ctx, k, pose[5] * ex, pose[5] * ey, 0.0, pose[0], pose[1], 0.0, true);
    }
    for (int64_t i = 0; i < n; i++) {
        if (s->wall_of[i] >= 0) {
            s->wall_of[i] = -1;
            wall_push[i] = wall_push[n + i] = 0.0;
        }
    }
}
