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
 * push the rings' edges as the kernels push vertices (bc_collide_loaded_corners), and a fast impact's stop of a
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
#include "walls.h"

enum { PLANE, SEGMENT, CIRCLE, POLYGON }; /* the solver kinds, colliders.SOLVERS */
static const int64_t POSE = BC_WALL_POSE_COLUMNS;

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

/* Crossing-number test against the rows start .. stop of one polygon (statics.c's inside_shape) */
static bool inside_rows(const double *geom, int64_t start, int64_t stop, double x, double y) {
    bool inside = false;
    for (int64_t r = start; r < stop; r++) {
        const double *row = geom + 4 * r;
        if (bc_crosses_ray(row[0], row[1], row[2], row[3], x, y)) inside = !inside;
    }
    return inside;
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

/* Wake the sleeping blobs whose bounding box meets collider k's (its island wakes at the step's end: sleep) */
static void wake_near(const bcContext *ctx, int64_t k) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k], n = m->vertex_count;
    if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= m->statics[kind].shapes) return;
    const double *aabb = s->placed[kind].aabb + 4 * shape, *pos = s->position;
    for (int64_t b = 0; b < m->blob_count; b++) {
        if (s->awake[b]) continue;
        double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (int64_t i = m->offsets[b]; i < m->offsets[b + 1]; i++) {
            x0 = bc_min(x0, pos[i]);
            y0 = bc_min(y0, pos[n + i]);
            x1 = bc_max(x1, pos[i]);
            y1 = bc_max(y1, pos[n + i]);
        }
        if (x1 >= aabb[0] && x0 <= aabb[2] && y1 >= aabb[1] && y0 <= aabb[3]) {
            s->awake[b] = 1;
            s->still[b] = 0.0;
        }
    }
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
        place(ctx, k, dx0, dy0, th0, next[0], next[1], next[2], motion == BC_LOADED);
        wake_near(ctx, k);
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

/* J_b = Σ m v - Σ m (x - x_prev) / h over ring o..e (vertex mass m): what the substep's velocity stages gave
 * the blob (the velocities read from the positions carry Σ m (x - x_prev) / h) */
static inline void velocity_impulse(const bcState *s, int64_t n, double m, int64_t o, int64_t e, double h,
                                    double *jx, double *jy) {
    const double *pos = s->position, *prev = s->previous, *vel = s->velocity;
    double x = 0.0, y = 0.0;
    for (int64_t i = o; i < e; i++) {
        x += m * (vel[i] - (pos[i] - prev[i]) / h);
        y += m * (vel[n + i] - (pos[n + i] - prev[n + i]) / h);
    }
    *jx = x;
    *jy = y;
}

/* The velocity stages (the velocity update's clamp and kinetic friction, stop_impact_velocities, restitution)
 * change blob b's momentum by J_b (velocity_impulse); each of its contact vertices i takes the part D_i / D_b of
 * it (its push depth over the blob's), for the collider that pushed it (half each for a vertex two colliders
 * pushed this step). Without this the record holds the position pushes only, and a blob dropped on a floor at
 * e = 0 would put several times its weight on the floor's record while it lies still (its bounce, taken back by
 * restitution, recorded and the taking back not). Each blob writes only its own vertices' records. */
void bc_record_contact_impulses(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double depth = 0.0;
        for (int64_t i = o; i < e; i++) depth += s->contact_depth[i];
        if (depth == 0.0) continue;
        double mass = 1.0 / m->inv_mass[o];
        double jx, jy;
        velocity_impulse(s, n, mass, o, e, h, &jx, &jy);
        for (int64_t i = o; i < e; i++) {
            double D = s->contact_depth[i];
            if (D == 0.0) continue;
            bool both = s->static_of[n + i] >= 0;
            for (int64_t slot = 0; slot < (both ? 2 : 1); slot++) {
                int64_t k = s->static_of[slot * n + i];
                if (k < 0 || m->walls.motion[k] == BC_LOADED) continue;
                double part = D / depth * (both ? 0.5 : 1.0) * h / mass; /* recorded as a push: -m Σ Δx / h */
                s->static_push[2 * slot * n + i] += part * jx;
                s->static_push[(2 * slot + 1) * n + i] += part * jy;
            }
        }
    });
}

/* The velocity-level impulses of the substep's static contacts (the velocity update's clamp and kinetic
 * friction, stop_impact_velocities, restitution) act on a loaded wall too, shared as its pushes are.
 *
 * Those stages change blob b's momentum by J_b (velocity_impulse), as if every collider were fixed. The part
 * s_b = D_b,k / D_b of it (its static contacts' depth on wall k over all of them) is wall k's, along n̄_b (the
 * depth-weighted normal of its contacts on k), c_b = n̄_b · e. Left one-sided, a light wall that jiggles under its
 * load has its approaches stopped by the blobs and never feels it. Shared like the pushes, the wall's velocity
 * changes by ΔV and each blob follows it by ΔV s_b c_b n̄_b, so that momentum along e is kept:
 *     M ΔV + Σ s_b J_b · e + ΔV Σ m_b s_b c_b² = 0  =>  ΔV = -Σ s_b J_b · e / (M + Σ m_b s_b c_b²).
 * The blobs' impulse on the wall, -(s_b J_b + m_b ΔV s_b c_b n̄_b), is recorded at b's deepest vertex on it.
 * Serial: the sums over blobs are in blob order. */
void bc_react_loaded_walls(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    int64_t n = m->vertex_count, B = m->blob_count;
    double *share = w->wall_share, *normal = w->wall_normal, *impulse = w->wall_impulse; /* s_b, n̄_b, J_b */
    int64_t *deepest = w->wall_deepest;
    /* J_b before any wall's share: a blob between two loaded walls is pushed back by the first, and the second must
     * not take part of that (internal) push for an impulse of the velocity stages */
    for (int64_t b = 0; b < B; b++) {
        share[b] = 0.0;
        normal[2 * b] = normal[2 * b + 1] = 0.0;
        deepest[b] = -1;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        if (s->awake[b] && e > o)
            velocity_impulse(s, n, 1.0 / m->inv_mass[o], o, e, h, &impulse[2 * b], &impulse[2 * b + 1]);
        else
            impulse[2 * b] = impulse[2 * b + 1] = 0.0;
    }
    for (int64_t k = 0; k < walls->count; k++) {
        if (walls->motion[k] != BC_LOADED) continue;
        double ex = walls->drive[3 * k + 1], ey = walls->drive[3 * k + 2];
        double along = 0.0, heavy = 0.0; /* Σ s_b J_b · e, Σ m_b s_b c_b² */
        for (int64_t b = 0; b < B; b++) {
            share[b] = 0.0;
            if (!s->awake[b]) continue;
            int64_t o = m->offsets[b], e = m->offsets[b + 1];
            double total = 0.0, on_k = 0.0, nx = 0.0, ny = 0.0, most = 0.0;
            for (int64_t i = o; i < e; i++) {
                double D = s->contact_depth[i];
                total += D;
                if (D > 0.0 && (s->static_of[i] == k || s->static_of[n + i] == k)) {
                    on_k += D;
                    nx += D * s->contact_normal[i];
                    ny += D * s->contact_normal[n + i];
                    if (D > most) {
                        most = D;
                        deepest[b] = i;
                    }
                }
            }
            double length = sqrt(nx * nx + ny * ny);
            if (on_k == 0.0 || length == 0.0) continue;
            double mass = 1.0 / m->inv_mass[o];
            share[b] = on_k / total;
            normal[2 * b] = nx / length;
            normal[2 * b + 1] = ny / length;
            double c = normal[2 * b] * ex + normal[2 * b + 1] * ey;
            along += share[b] * (impulse[2 * b] * ex + impulse[2 * b + 1] * ey);
            heavy += mass * (double)(e - o) * share[b] * c * c;
        }
        if (along == 0.0) continue;
        double dV = -along / (walls->mass[k] + heavy);
        s->static_pose[POSE * k + 4] += dV;
        for (int64_t b = 0; b < B; b++) {
            if (share[b] == 0.0) continue;
            int64_t o = m->offsets[b], e = m->offsets[b + 1];
            double c = normal[2 * b] * ex + normal[2 * b + 1] * ey;
            double fx = dV * share[b] * c * normal[2 * b], fy = dV * share[b] * c * normal[2 * b + 1];
            for (int64_t i = o; i < e; i++) {
                s->velocity[i] += fx;
                s->velocity[n + i] += fy;
            }
            int64_t i = deepest[b];
            if (i < 0) continue; /* (share[b] > 0 came from a contact on k: its deepest vertex is known) */
            double mb = (double)(e - o) / m->inv_mass[o], mi = 1.0 / m->inv_mass[i];
            /* recorded as a push: bc_account_contacts reads -m Σ Δx / h */
            bc_account(i, k, (share[b] * impulse[2 * b] + mb * fx) * h / mi,
                       (share[b] * impulse[2 * b + 1] + mb * fy) * h / mi, s->static_of, s->static_push, n);
        }
    }
}

void bc_finish_loaded_walls(const bcContext *ctx, double h) {
    const bcWalls *walls = &ctx->m->walls;
    for (int64_t k = 0; k < walls->count; k++) {
        if (walls->motion[k] == BC_LOADED) {
            double *pose = ctx->s->static_pose + POSE * k;
            pose[4] = (pose[3] - pose[5]) / h; /* V = (s - s_start) / h */
        }
    }
}

/* The impulses of the blobs on each collider over the step, -m Σ Δx / h (N s: the pushes of all its substeps,
 * each of length h), and their moments about its pivot where it is at the step's end (N m s), as
 * impulse[k] = (Jx, Jy, L); clear the vertices' records. Once a step, serial, in vertex order. */
void bc_account_contacts(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    double *impulse = s->static_impulse;
    for (int64_t k = 0; k < 3 * walls->count; k++) impulse[k] = 0.0;
    for (int64_t i = 0; i < n; i++) {
        for (int64_t slot = 0; slot < 2; slot++) {
            int64_t k = s->static_of[slot * n + i];
            if (k < 0) continue;
            double mass = 1.0 / m->inv_mass[i];
            double *push = s->static_push + 2 * slot * n + i; /* x at push[0], y at push[n] */
            double jx = -mass * push[0] / h, jy = -mass * push[n] / h;
            const double *pose = s->static_pose + POSE * k;
            double rx = s->position[i] - (walls->pivot[2 * k] + pose[0]);
            double ry = s->position[n + i] - (walls->pivot[2 * k + 1] + pose[1]);
            impulse[3 * k] += jx;
            impulse[3 * k + 1] += jy;
            impulse[3 * k + 2] += rx * jy - ry * jx;
            s->static_of[slot * n + i] = -1;
            push[0] = push[n] = 0.0;
        }
    }
}

/* ---- A loaded wall's corners ----
 *
 * The collider kernels push a blob's vertices out of a collider, never its edges: a corner narrower than the
 * spacing of a ring's vertices (a wedge's tip, a box's corner) passes between two of them, and a loaded wall
 * pressing on a blob there goes on into it and through it (a 1 kg wedge pushed by 100 N went through a resting
 * blob; a squeeze between two loaded boxes pressed the pile out past their ends, their corners inside it). So each
 * corner q of a loaded polygon (and each end of a loaded segment) that lies inside a ring pushes the ring's edge
 * nearest it, i → j, off it: the point p = x_i + t (x_j - x_i) nearest q moves by d = |q - p| along u = (q - p) / d,
 * the corner held as the kernels hold the collider (the wall's share comes after, bc_yield_loaded_walls). For
 * C = u · (q - p) >= 0 with the corner fixed, PBD's step gives each end a push along u of
 *     Δx_i = w_i (1 - t) λ,  Δx_j = w_j t λ,  λ = d / ((1 - t)² w_i + t² w_j),
 * (w the inverse masses, equal within a ring), which moves p by d. The pushes are recorded as the kernels' are
 * (contact, force, the wall's share), their normal u. Serial, in collider, blob and corner order. */

/* Collider k's corner c, where it is now: a polygon's row c's first point, a segment's end c (0: a, 1: b) */
static void corner_of(const bcContext *ctx, int64_t kind, int64_t shape, int64_t c, double *qx, double *qy) {
    const double *geom = ctx->s->placed[kind].geom;
    int64_t first = ctx->m->statics[kind].shape_offsets[shape];
    const double *row = kind == POLYGON ? geom + 4 * (first + c) : geom + 4 * first + 2 * c;
    *qx = row[0];
    *qy = row[1];
}

/* The corners collider k has: a polygon's rows, a segment's two ends, none for a plane or circle */
static int64_t corner_count(const bcContext *ctx, int64_t kind, int64_t shape) {
    const int64_t *offsets = ctx->m->statics[kind].shape_offsets;
    if (kind == POLYGON) return offsets[shape + 1] - offsets[shape];
    return kind == SEGMENT ? 2 : 0;
}

/* Vertex i's push (dx, dy) by collider k at a corner: moved, its contact recorded for the velocity stages (normal
 * along the push, depth its length, the materials combined as the kernels combine them, the surface's velocity w),
 * and the push recorded for the collider's force and the wall's share */
static void corner_push(const bcContext *ctx, int64_t i, int64_t k, double dx, double dy, double wx, double wy) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count, kind = m->walls.kind[k], shape = m->walls.shape[k];
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) return;
    const double *blob = m->material + 3 * m->blob_of[i], *wall = m->statics[kind].material + 4 * shape;
    s->position[i] += dx;
    s->position[n + i] += dy;
    s->contact_normal[i] = dx / length;
    s->contact_normal[n + i] = dy / length;
    s->contact_depth[i] += length;
    s->contact_material[i] = bc_mix_friction(blob[0], wall[0]);
    s->contact_material[n + i] = bc_mix_friction(blob[1], wall[1]);
    s->contact_material[2 * n + i] = bc_mix_restitution(blob[2], wall[2]);
    s->contact_material[3 * n + i] = wall[3];
    s->contact_material[4 * n + i] = wx;
    s->contact_material[5 * n + i] = wy;
    bc_account(i, k, dx, dy, s->static_of, s->static_push, n);
    s->wall_of[i] = k;
    s->wall_push[i] += dx;
    s->wall_push[n + i] += dy;
}

void bc_collide_loaded_corners(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    const double *pos = s->position, *inv_mass = m->inv_mass;
    for (int64_t k = 0; k < walls->count; k++) {
        if (walls->motion[k] != BC_LOADED) continue;
        int64_t kind = walls->kind[k], shape = walls->shape[k];
        if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= m->statics[kind].shapes) continue;
        int64_t corners = corner_count(ctx, kind, shape);
        if (corners == 0) continue;
        const double *aabb = s->placed[kind].aabb + 4 * shape, *delta = s->placed[kind].delta + 5 * shape;
        /* the corners' velocity over the substep, w = (q - Δ⁻¹(q)) / h: a loaded wall's Δ is a translation */
        double wx = delta[2] / h, wy = delta[3] / h;
        for (int64_t b = 0; b < m->blob_count; b++) {
            if (!s->awake[b]) continue;
            int64_t o = m->offsets[b], e = m->offsets[b + 1];
            if (e - o < 3) continue;
            double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
            for (int64_t i = o; i < e; i++) {
                x0 = bc_min(x0, pos[i]);
                y0 = bc_min(y0, pos[n + i]);
                x1 = bc_max(x1, pos[i]);
                y1 = bc_max(y1, pos[n + i]);
            }
            if (x1 < aabb[0] || x0 > aabb[2] || y1 < aabb[1] || y0 > aabb[3]) continue;
            for (int64_t c = 0; c < corners; c++) {
                double qx, qy;
                corner_of(ctx, kind, shape, c, &qx, &qy);
                if (qx < x0 || qx > x1 || qy < y0 || qy > y1 || !bc_ring_contains(pos, n, o, e, qx, qy)) continue;
                /* the edge nearest the corner, i → j, and the point p of it nearest */
                double best = INFINITY, t = 0.0;
                int64_t i = -1;
                for (int64_t a = o; a < e; a++) {
                    int64_t z = bc_next_in_ring(a, o, e);
                    double ex = pos[z] - pos[a], ey = pos[n + z] - pos[n + a], e2 = ex * ex + ey * ey;
                    double u = e2 > 0.0 ? bc_min(bc_max(((qx - pos[a]) * ex + (qy - pos[n + a]) * ey) / e2, 0.0), 1.0)
                                        : 0.0;
                    double dx = pos[a] + u * ex - qx, dy = pos[n + a] + u * ey - qy;
                    if (dx * dx + dy * dy < best) {
                        best = dx * dx + dy * dy;
                        t = u;
                        i = a;
                    }
                }
                double d = sqrt(best);
                if (i < 0 || d == 0.0) continue;
                int64_t j = bc_next_in_ring(i, o, e);
                double px = pos[i] + t * (pos[j] - pos[i]), py = pos[n + i] + t * (pos[n + j] - pos[n + i]);
                double ux = (qx - px) / d, uy = (qy - py) / d;
                double wi = inv_mass[i], wj = inv_mass[j];
                double lambda = d / ((1.0 - t) * (1.0 - t) * wi + t * t * wj);
                corner_push(ctx, i, k, wi * (1.0 - t) * lambda * ux, wi * (1.0 - t) * lambda * uy, wx, wy);
                corner_push(ctx, j, k, wj * t * lambda * ux, wj * t * lambda * uy, wx, wy);
            }
        }
    }
}

/* ---- A fast impact on a loaded wall ----
 *
 * A fast impact stops the whole blob (integrate.c: bc_stop_impacts): its vertices no collider pushed move along the
 * push's normal as far as its deepest vertex was pushed. Where that vertex was pushed by a loaded wall, the stop is
 * the wall's push too, and shared with it as its pushes are: without that, a blob the wall struck took the stop's
 * momentum from nowhere, and two balanced loads on a pile (gravity off) set the walls and the pile drifting at
 * 0.85 m/s together. bc_keep_impact_positions notes the positions before the stop, bc_share_impact_stops records what
 * it moved as the wall's pushes (for bc_yield_loaded_walls and the wall's force). */
void bc_keep_impact_positions(const bcContext *ctx) {
    int64_t n = ctx->m->vertex_count;
    const double *pos = ctx->s->position;
    double *kept = ctx->w->wall_kept;
    for (int64_t i = 0; i < 2 * n; i++) kept[i] = pos[i];
}

void bc_share_impact_stops(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    const double *pos = s->position, *kept = ctx->w->wall_kept, *depth = s->contact_depth;
    for (int64_t b = 0; b < m->blob_count; b++) {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1], deepest = -1;
        double most = 0.0;
        for (int64_t i = o; i < e; i++) {
            if (depth[i] > most) {
                most = depth[i];
                deepest = i;
            }
        }
        if (deepest < 0) continue;
        int64_t k = s->wall_of[deepest]; /* the loaded wall that pushed it this iteration, if one did */
        if (k < 0) continue;
        for (int64_t i = o; i < e; i++) {
            double dx = pos[i] - kept[i], dy = pos[n + i] - kept[n + i];
            if (dx == 0.0 && dy == 0.0) continue;
            bc_account(i, k, dx, dy, s->static_of, s->static_push, n);
            s->wall_of[i] = k;
            s->wall_push[i] += dx;
            s->wall_push[n + i] += dy;
        }
    }
}

/* ---- How many substeps a loaded wall's load needs ----
 *
 * A loaded wall at rest on blobs is pushed back each substep by what its load moves it, h² F / M; the blobs take
 * that push by being dented at its contacts, and the dent the wall's share leaves (bc_yield_loaded_walls) comes to
 *     δ = h² F / m_c,
 * m_c the mass of the vertices it presses, whatever its own mass (its share is M / (M + m_c) of a push, and a push
 * of δ (M + m_c) / m_c moves it back h² F / M). The area stage takes the dent back in the next iteration and the
 * wall dents it again, so each substep ends with the blobs short of their area by about δ over the contact: a 1 kg
 * box pressed by 1,000 N on a 12-vertex blob (of 1 kg) on a floor, at 4 substeps of 1/60 s, left it 24% short and
 * 0.17 m high. As the sag of a stack under its weight (integrate.c: bc_substeps_for's SAG), the step takes the
 * substeps that keep δ within DENT × the shortest mean rest edge L:
 *     k >= dt √(F / (m_c DENT L)),
 * m_c the mass of the awake vertices it presses first: those within TOUCH × L of the nearest, where that one is
 * within the wall's reach over the step, V dt + F dt² / 2M, and TOUCH × L (else no bound), at most `most_substeps`.
 * Read from the state (the positions and the walls' poses), so a resumed run takes the same. */
static const double DENT = 0.05;
static const double TOUCH = 0.1;

/* The distance from (x, y) to collider k where a loaded wall is now (its rows as written, moved by (dx, dy) along
 * its line: it never turns); 0 inside a solid */
static double distance_to(const bcContext *ctx, int64_t k, double x, double y) {
    const bcModel *m = ctx->m;
    int64_t kind = m->walls.kind[k], shape = m->walls.shape[k];
    const double *pose = ctx->s->static_pose + POSE * k;
    const double *geom = m->statics[kind].geom;
    const int64_t *offsets = m->statics[kind].shape_offsets;
    x -= pose[0];
    y -= pose[1];
    if (kind == PLANE) {
        const double *row = geom + 4 * shape;
        return bc_max((x - row[0]) * row[2] + (y - row[1]) * row[3], 0.0);
    }
    if (kind == CIRCLE) {
        const double *row = geom + 4 * shape;
        double r = hypot(x - row[0], y - row[1]) - row[2];
        return row[3] != 0.0 ? bc_max(-r, 0.0) : bc_max(r, 0.0);
    }
    if (kind == POLYGON && inside_rows(geom, offsets[shape], offsets[shape + 1], x, y)) return 0.0;
    double best = INFINITY;
    for (int64_t r = offsets[shape]; r < offsets[shape + 1]; r++) {
        const double *row = geom + 4 * r;
        double ex = row[2] - row[0], ey = row[3] - row[1], e2 = ex * ex + ey * ey;
        double t = e2 > 0.0 ? bc_min(bc_max(((x - row[0]) * ex + (y - row[1]) * ey) / e2, 0.0), 1.0) : 0.0;
        best = bc_min(best, hypot(row[0] + t * ex - x, row[1] + t * ey - y));
    }
    return best;
}

int64_t bc_loaded_substeps(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    const bcWalls *walls = &m->walls;
    const bcSettings *c = ctx->c;
    bcState *s = ctx->s;
    int64_t n = m->vertex_count;
    double edge = INFINITY, need = 0.0;
    for (int64_t b = 0; b < m->blob_count; b++)
        edge = bc_min(edge, m->rest_perimeter[b] / (double)(m->offsets[b + 1] - m->offsets[b]));
    if (edge == INFINITY) return c->substeps;
    for (int64_t k = 0; k < walls->count; k++) {
        double F = walls->drive[3 * k];
        if (walls->motion[k] != BC_LOADED || !(F > 0.0)) continue;
        int64_t kind = walls->kind[k], shape = walls->shape[k];
        if (kind < 0 || kind >= BC_SOLVER_KINDS || shape < 0 || shape >= m->statics[kind].shapes) continue;
        /* the nearest vertex, and the vertices within TOUCH L of as near: those it presses first */
        double nearest = INFINITY, pressed = 0.0; /* m_c */
        for (int64_t i = 0; i < n; i++)
            if (s->awake[m->blob_of[i]])
                nearest = bc_min(nearest, distance_to(ctx, k, s->position[i], s->position[n + i]));
        double *pose = s->static_pose + POSE * k;
        double reach = bc_max(pose[4] * c->dt + 0.5 * F / walls->mass[k] * c->dt * c->dt, 0.0);
        if (!(nearest <= reach + TOUCH * edge)) continue; /* it reaches no blob this step */
        for (int64_t i = 0; i < n; i++) {
            if (s->awake[m->blob_of[i]] &&
                distance_to(ctx, k, s->position[i], s->position[n + i]) <= nearest + TOUCH * edge)
                pressed += 1.0 / m->inv_mass[i];
        }
        if (pressed > 0.0) need = bc_max(need, c->dt * sqrt(F / (pressed * DENT * edge)));
    }
    if (!(need < (double)c->most_substeps)) return c->most_substeps; /* (a NaN too) */
    return bc_imax(c->substeps, (int64_t)ceil(need));
}

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
        double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (int64_t i = o; i < e; i++) {
            x0 = bc_min(x0, pos[i]);
            y0 = bc_min(y0, pos[n + i]);
            x1 = bc_max(x1, pos[i]);
            y1 = bc_max(y1, pos[n + i]);
        }
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
            if (x < aabb[0] || x > aabb[2] || y < aabb[1] || y > aabb[3] || !inside_rows(geom, start, stop, x, y))
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
