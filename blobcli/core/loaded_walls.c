/* Loaded walls and the colliders' records: the impulses the blobs give the walls, a loaded wall's share of the
 * contacts' velocity stages, its corners pushing the rings' edges, and the substeps its load needs. What a loaded
 * wall is, and how it moves and yields to the blobs, is derived at the top of walls.c.
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
            double ring[4]; /* its bounds x0, y0, x1, y1 */
            bc_ring_bounds(pos, n, o, e, ring);
            double x0 = ring[0], y0 = ring[1], x1 = ring[2], y1 = ring[3];
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
    if (kind == POLYGON && bc_rows_contain(geom, offsets[shape], offsets[shape + 1], x, y)) return 0.0;
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
