/* Collider stages: push vertices out of the colliders, fixed or moving. One signature, by kind.
 *
 * Each stage projects a penetrating vertex to the nearest surface, applies static friction there (`stuck`),
 * and records the contact (normal, push-out depth, combined material) for the velocity update, which applies
 * kinetic friction, and for restitution. Static friction is applied here rather than after all stages so
 * that a shape can refuse a hold that would put the vertex inside it (beside a reflex corner of a concave
 * polygon, or on a curved circle).
 *
 * Tunnelling: at 100 m/s and h = 1/240 s a vertex moves 0.42 m per substep, through any thin wall. So the
 * segment, circle and polygon stages are swept: they test the path x_prev -> x of the substep, and a vertex
 * whose path entered the shape is put back on the tangent line where it entered, not on the nearest
 * (possibly far) side.
 *
 * Materials combine as Box2D does (friction.h): μ = √(μ_blob μ_static), e = max(e_blob, e_static). A
 * collider's surface velocity u (a conveyor belt) moves its surface along t = (n_y, -n_x), n the normal out
 * of the solid, without moving the collider: friction, static here and kinetic in the velocity update, acts
 * on the slip relative to the surface, so a scene on a belt is the same scene on a fixed floor seen from a
 * frame moving with the belt (Galilean invariance).
 *
 * Colliders that move (walls.c) are where they are at the substep's end (s->placed: geom, aabb), and each
 * kernel tests a vertex's path relative to the collider: from its start carried with the collider, Δ(x_prev)
 * (delta), to x. Fixed colliders in a scene where nothing moves skip that (ctx->c->moving), so their bits are
 * what they were. Every push is recorded per vertex (touch.h), for the force the blobs exert on each collider,
 * and a loaded wall's for its share of the push (walls.c: bc_yield_loaded_walls).
 *
 * Kernel rows (colliders.py), 4 a row: plane (px, py, nx, ny) with unit n out of the solid side; circle
 * (cx, cy, r, inside: 1 for a container, solid outside the circle, else 0); segment and polygon edge
 * (ax, ay, bx, by), polygons counter-clockwise. A plane, a segment and a circle are one row each, so shape s
 * is row s; polygon s is rows shape_offsets[s] .. shape_offsets[s + 1]. delta (shapes, 5): the substep's
 * motion Δ: p -> R(Δθ) p + τ as (cos Δθ, sin Δθ, τx, τy), and 1 for a loaded wall.
 *
 * Every loop over vertices writes only its own vertex's slots: split over threads with the same bits.
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "friction.h"
#include "parallel.h"
#include "ring.h"
#include "statics.h"
#include "touch.h"

/* m: vertices rest this far from a zero-thickness segment, so their side is known */
static const double SKIN = 1e-6;

/* One solver kind's colliders: the model's (shape_offsets, material (shapes, 4): μ_s, μ_k, e, u; index: each
 * one's place among the scene's [[static]] tables) and where they are now (geom, aabb, delta) */
typedef struct Colliders {
    int64_t shapes;
    const double *geom, *aabb, *delta;
    const int64_t *shape_offsets;
    const double *material;
    const int64_t *index;
} Colliders;

/* What every kernel reads besides its colliders: the run's flags and the state's arrays */
typedef struct Stage {
    int64_t n;           /* vertices */
    bool moving, loaded; /* a collider moves; one is a loaded wall (the run's flags) */
    double h;            /* s */
    double *pos;
    const double *prev;
    const int64_t *blob_of;
    const uint8_t *awake;
    const double *blob_material;  /* (B, 3) */
    double *contact_normal, *contact_depth, *contact_material;
    int64_t *static_of, *wall_of;
    double *static_push, *wall_push;
} Stage;

/* Record vertex i's contact: normal n, push-out depth, the surface's velocity w there, and the combined
 * material of its blob's and the collider's (μ_s, μ_k mixed, e the greater, the collider's conveyor speed u) */
static inline void record(const Stage *g, int64_t i, double nx, double ny, double depth, double wx, double wy,
                          const double *blob_material, const double *shape_material) {
    int64_t n = g->n;
    g->contact_normal[i] = nx;
    g->contact_normal[n + i] = ny;
    g->contact_depth[i] += depth;
    g->contact_material[i] = bc_mix_friction(blob_material[0], shape_material[0]);
    g->contact_material[n + i] = bc_mix_friction(blob_material[1], shape_material[1]);
    g->contact_material[2 * n + i] = bc_mix_restitution(blob_material[2], shape_material[2]);
    g->contact_material[3 * n + i] = shape_material[3];
    g->contact_material[4 * n + i] = wx;
    g->contact_material[5 * n + i] = wy;
}

/* Where static friction holds the vertex: its slip along the surface this substep undone, if
 * |Δx_t| <= μ_s D (Coulomb, at position level: Müller et al. 2020), D being how far the surfaces pushed it
 * out this substep, and Δx = x - x0 its motion relative to the collider (x0: its start, carried with a
 * moving collider). (x, y) unchanged when it slides. On a moving surface (a conveyor: speed u along
 * t = (n_y, -n_x)) the slip is relative to it, Δx_t - u h t: a held vertex moves with the belt. */
static inline void stuck(const Stage *g, int64_t i, double x, double y, double x0, double y0, double *sx,
                         double *sy) {
    int64_t n = g->n;
    double nx = g->contact_normal[i], ny = g->contact_normal[n + i];
    double dx = x - x0, dy = y - y0;
    double dn = dx * nx + dy * ny;
    double tx = dx - dn * nx, ty = dy - dn * ny;
    double u = g->contact_material[3 * n + i];
    if (u != 0.0) { /* (a branch, not u h t = 0 added: fixed surfaces keep their bits) */
        tx -= u * g->h * ny;
        ty += u * g->h * nx;
    }
    double limit = g->contact_material[i] * g->contact_depth[i]; /* μ_s D */
    if (tx * tx + ty * ty <= limit * limit) {
        *sx = x - tx;
        *sy = y - ty;
        return;
    }
    *sx = x;
    *sy = y;
}

/* Δ(x): where a point at x at the substep's start is now, carried with collider s */
static inline void carried(const double *delta, int64_t s, double x, double y, double *cx, double *cy) {
    const double *d = delta + 5 * s;
    *cx = d[0] * x - d[1] * y + d[2];
    *cy = d[1] * x + d[0] * y + d[3];
}

/* w = (x - Δ⁻¹(x)) / h: the velocity of collider s's material point at x over the substep */
static inline void surface_velocity(const double *delta, int64_t s, double x, double y, double h, double *wx,
                                    double *wy) {
    const double *d = delta + 5 * s;
    double ux = x - d[2], uy = y - d[3];
    *wx = (x - (d[0] * ux + d[1] * uy)) / h;
    *wy = (y - (d[0] * uy - d[1] * ux)) / h;
}

/* Record collider k's push (dx, dy) of vertex i: for its force, and a loaded wall's share (loaded != 0) */
static inline void pushed(const Stage *g, int64_t i, int64_t k, double dx, double dy, double loaded) {
    bc_account(i, k, dx, dy, g->static_of, g->static_push, g->n);
    if (loaded != 0.0) {
        g->wall_of[i] = k;
        g->wall_push[i] += dx;
        g->wall_push[g->n + i] += dy;
    }
}

/* delta's loaded mark of shape s where the run has loaded walls, else 0 */
static inline double loaded_mark(const Stage *g, const Colliders *c, int64_t s) {
    return g->loaded ? c->delta[5 * s + 4] : 0.0;
}

/* stuck, but only where that is outside the circle (a chord of a curved surface is not) */
static inline void stuck_outside_circle(const Stage *g, int64_t i, double x, double y, double x0, double y0,
                                        double cx, double cy, double r, double *qx, double *qy) {
    double sx, sy;
    stuck(g, i, x, y, x0, y0, &sx, &sy);
    if ((sx - cx) * (sx - cx) + (sy - cy) * (sy - cy) >= r * r) {
        *qx = sx;
        *qy = sy;
        return;
    }
    *qx = x;
    *qy = y;
}

/* stuck, but only where that is outside polygon rows start .. stop (beside a reflex corner the held point can be
 * inside). The held point is on a face to round-off, exactly on an axis-aligned one, where the crossing test is
 * half-open (ring.h: bc_rows_contain): on a face whose solid side is toward +x or +y it would count as inside and the
 * hold be refused, on one toward -x or -y not. So the test reads the held point moved out along the contact normal
 * n by the round-off ε (bc_surface_roundoff): a point on any face is outside, and mirror images hold alike, while a
 * point a reflex corner puts inside lies inside by up to the hold's slip, far more than ε. */
static inline void stuck_outside_polygon(const Stage *g, int64_t i, double x, double y, double x0, double y0,
                                         const double *rows, int64_t start, int64_t stop, double *qx, double *qy) {
    double sx, sy;
    stuck(g, i, x, y, x0, y0, &sx, &sy);
    double eps = bc_surface_roundoff(sx, sy);
    if (!bc_rows_contain(rows, start, stop, sx + eps * g->contact_normal[i], sy + eps * g->contact_normal[g->n + i])) {
        *qx = sx;
        *qy = sy;
        return;
    }
    *qx = x;
    *qy = y;
}

/* Half-space n · (x - p) >= 0: nothing can pass an infinite plane, so no sweep is needed. */
static void collide_plane(const Stage *g, const Colliders *c, int parallel) {
    int64_t n = g->n;
    BC_PARALLEL_LOOP(parallel, (int64_t i = 0; i < n; i++), {
        if (!g->awake[g->blob_of[i]]) continue;
        const double *blob_material = g->blob_material + 3 * g->blob_of[i];
        double x = g->pos[i], y = g->pos[n + i];
        for (int64_t s = 0; s < c->shapes; s++) {
            const double *row = c->geom + 4 * s;
            double px = row[0], py = row[1], nx = row[2], ny = row[3];
            double d = (x - px) * nx + (y - py) * ny;
            if (d < 0.0) {
                double qx = x - d * nx, qy = y - d * ny; /* onto the plane */
                double x0 = g->prev[i], y0 = g->prev[n + i], wx = 0.0, wy = 0.0;
                if (g->moving) {
                    carried(c->delta, s, x0, y0, &x0, &y0);
                    surface_velocity(c->delta, s, qx, qy, g->h, &wx, &wy);
                }
                record(g, i, nx, ny, -d, wx, wy, blob_material, c->material + 4 * s);
                /* held there by static friction (it stays on a flat plane) */
                stuck(g, i, qx, qy, x0, y0, &qx, &qy);
                pushed(g, i, c->index[s], qx - x, qy - y, loaded_mark(g, c, s));
                x = qx;
                y = qy;
            }
        }
        g->pos[i] = x;
        g->pos[n + i] = y;
    });
}

/* A zero-thickness wall, solid from both sides. The side a vertex belongs to is the side its substep began
 * on (d0 = n · (x_prev - a)); if its path reaches within SKIN of the line inside the segment's extent, it is
 * put back at distance SKIN. */
static void collide_segment(const Stage *g, const Colliders *c, int parallel) {
    int64_t n = g->n;
    BC_PARALLEL_LOOP(parallel, (int64_t i = 0; i < n; i++), {
        if (!g->awake[g->blob_of[i]]) continue;
        const double *blob_material = g->blob_material + 3 * g->blob_of[i];
        double x = g->pos[i], y = g->pos[n + i];
        for (int64_t s = 0; s < c->shapes; s++) {
            double x0 = g->prev[i], y0 = g->prev[n + i];
            if (g->moving) carried(c->delta, s, x0, y0, &x0, &y0);
            const double *box = c->aabb + 4 * s;
            if (bc_max(x, x0) < box[0] - SKIN || bc_min(x, x0) > box[2] + SKIN || bc_max(y, y0) < box[1] - SKIN ||
                bc_min(y, y0) > box[3] + SKIN)
                continue;
            const double *row = c->geom + 4 * s;
            double ax = row[0], ay = row[1], bx = row[2], by = row[3];
            double ex = bx - ax, ey = by - ay;
            double length = sqrt(ex * ex + ey * ey);
            double tx = ex / length, ty = ey / length;
            double nx = -ty, ny = tx;
            double d0 = (x0 - ax) * nx + (y0 - ay) * ny;
            double d1 = (x - ax) * nx + (y - ay) * ny;
            double side;
            if (d0 != 0.0)
                side = d0 > 0.0 ? 1.0 : -1.0;
            else /* began exactly on the line: it came from where it is moving away from */
                side = d1 > 0.0 ? -1.0 : 1.0;
            double s0 = side * d0, s1 = side * d1;
            if (s1 >= SKIN) continue;
            /* Where the path reaches the skin line (or the end point, if it began inside it). */
            double t = s0 > SKIN ? (s0 - SKIN) / (s0 - s1) : 1.0;
            double cx = x0 + t * (x - x0), cy = y0 + t * (y - y0);
            double u = (cx - ax) * tx + (cy - ay) * ty;
            if (u < 0.0 || u > length) continue;
            double depth = SKIN - s1;
            double qx = x + depth * side * nx, qy = y + depth * side * ny;
            double wx = 0.0, wy = 0.0;
            if (g->moving) surface_velocity(c->delta, s, qx, qy, g->h, &wx, &wy);
            record(g, i, side * nx, side * ny, depth, wx, wy, blob_material, c->material + 4 * s);
            stuck(g, i, qx, qy, x0, y0, &qx, &qy);
            pushed(g, i, c->index[s], qx - x, qy - y, loaded_mark(g, c, s));
            x = qx;
            y = qy;
        }
        g->pos[i] = x;
        g->pos[n + i] = y;
    });
}

/* A circle with blobs inside, solid outside (a drum): a vertex beyond the radius goes back to the nearest
 * point of the circle, along the radius (no sweep needed: the solid has no far side to tunnel to), with the
 * inward normal. Gives (x, y, nx, ny, depth), depth 0 inside. */
static inline void inside_circle(double x, double y, double cx, double cy, double r, double out[5]) {
    double rx = x - cx, ry = y - cy;
    double dist = sqrt(rx * rx + ry * ry);
    if (dist <= r) {
        out[0] = x;
        out[1] = y;
        out[2] = out[3] = out[4] = 0.0;
        return;
    }
    out[0] = cx + r * rx / dist;
    out[1] = cy + r * ry / dist;
    out[2] = -rx / dist;
    out[3] = -ry / dist;
    out[4] = dist - r;
}

/* Static friction holds a vertex on a drum's wall: the held point, on the tangent line, is brought back onto
 * the circle along its radius. */
static inline void held_inside_circle(const Stage *g, int64_t i, double x, double y, double x0, double y0,
                                      double cx, double cy, double r, double *hx, double *hy) {
    double sx, sy;
    stuck(g, i, x, y, x0, y0, &sx, &sy);
    double qx = sx - cx, qy = sy - cy;
    double q = sqrt(qx * qx + qy * qy);
    if (q > r) {
        *hx = cx + r * qx / q;
        *hy = cy + r * qy / q;
        return;
    }
    *hx = sx;
    *hy = sy;
}

static void collide_circle(const Stage *g, const Colliders *c, int parallel) {
    int64_t n = g->n;
    BC_PARALLEL_LOOP(parallel, (int64_t i = 0; i < n; i++), {
        if (!g->awake[g->blob_of[i]]) continue;
        const double *blob_material = g->blob_material + 3 * g->blob_of[i];
        double x = g->pos[i], y = g->pos[n + i];
        for (int64_t s = 0; s < c->shapes; s++) {
            double x0 = g->prev[i], y0 = g->prev[n + i];
            if (g->moving) carried(c->delta, s, x0, y0, &x0, &y0);
            const double *box = c->aabb + 4 * s;
            if (bc_max(x, x0) < box[0] || bc_min(x, x0) > box[2] || bc_max(y, y0) < box[1] || bc_min(y, y0) > box[3])
                continue;
            const double *row = c->geom + 4 * s;
            const double *shape_material = c->material + 4 * s;
            double cx = row[0], cy = row[1], r = row[2];
            double bx = x, by = y; /* before this circle */
            double wx = 0.0, wy = 0.0;
            if (row[3] != 0.0) { /* a container */
                double out[5];
                inside_circle(x, y, cx, cy, r, out);
                x = out[0];
                y = out[1];
                double nx = out[2], ny = out[3], depth = out[4];
                if (depth > 0.0) {
                    if (g->moving) surface_velocity(c->delta, s, x, y, g->h, &wx, &wy);
                    record(g, i, nx, ny, depth, wx, wy, blob_material, shape_material);
                    held_inside_circle(g, i, x, y, x0, y0, cx, cy, r, &x, &y);
                    pushed(g, i, c->index[s], x - bx, y - by, loaded_mark(g, c, s));
                }
                continue;
            }
            double fx = x0 - cx, fy = y0 - cy;
            double dx = x - x0, dy = y - y0;
            /* Swept: first t in [0, 1] with |x0 + t d - c| = r, for a path that began outside:
             * A t² + B t + C = 0, A = |d|², B = 2 f · d, C = |f|² - r², f = x0 - c. */
            double A = dx * dx + dy * dy;
            double B = 2.0 * (fx * dx + fy * dy);
            double C = fx * fx + fy * fy - r * r;
            double disc = B * B - 4.0 * A * C;
            if (C > 0.0 && A > 0.0 && disc >= 0.0) {
                double t = (-B - sqrt(disc)) / (2.0 * A);
                if (0.0 <= t && t <= 1.0) {
                    double nx = (fx + t * dx) / r, ny = (fy + t * dy) / r;
                    double d = (x - (x0 + t * dx)) * nx + (y - (y0 + t * dy)) * ny;
                    if (d < 0.0) { /* onto the tangent line at the entry point */
                        x -= d * nx;
                        y -= d * ny;
                        if (g->moving) surface_velocity(c->delta, s, x, y, g->h, &wx, &wy);
                        record(g, i, nx, ny, -d, wx, wy, blob_material, shape_material);
                        stuck_outside_circle(g, i, x, y, x0, y0, cx, cy, r, &x, &y);
                        pushed(g, i, c->index[s], x - bx, y - by, loaded_mark(g, c, s));
                        continue;
                    }
                }
            }
            double rx = x - cx, ry = y - cy;
            double dist = sqrt(rx * rx + ry * ry);
            if (dist < r) {
                double nx, ny;
                if (dist > 0.0) {
                    nx = rx / dist;
                    ny = ry / dist;
                } else {
                    nx = 0.0;
                    ny = 1.0;
                }
                x = cx + r * nx;
                y = cy + r * ny;
                if (g->moving) surface_velocity(c->delta, s, x, y, g->h, &wx, &wy);
                record(g, i, nx, ny, r - dist, wx, wy, blob_material, shape_material);
                stuck_outside_circle(g, i, x, y, x0, y0, cx, cy, r, &x, &y);
                pushed(g, i, c->index[s], x - bx, y - by, loaded_mark(g, c, s));
            }
        }
        g->pos[i] = x;
        g->pos[n + i] = y;
    });
}

/* Polygons are counter-clockwise, so edge (a, b) has outward normal (e_y, -e_x) / |e|. */
static void collide_polygon(const Stage *g, const Colliders *c, int parallel) {
    int64_t n = g->n;
    BC_PARALLEL_LOOP(parallel, (int64_t i = 0; i < n; i++), {
        if (!g->awake[g->blob_of[i]]) continue;
        const double *blob_material = g->blob_material + 3 * g->blob_of[i];
        double x = g->pos[i], y = g->pos[n + i];
        for (int64_t s = 0; s < c->shapes; s++) {
            double x0 = g->prev[i], y0 = g->prev[n + i];
            if (g->moving) carried(c->delta, s, x0, y0, &x0, &y0);
            const double *box = c->aabb + 4 * s;
            if (bc_max(x, x0) < box[0] || bc_min(x, x0) > box[2] || bc_max(y, y0) < box[1] || bc_min(y, y0) > box[3])
                continue;
            const double *geom = c->geom, *shape_material = c->material + 4 * s;
            int64_t start = c->shape_offsets[s], stop = c->shape_offsets[s + 1];
            double bx0 = x, by0 = y; /* before this polygon */
            double wx = 0.0, wy = 0.0;
            bool inside = false;
            double best_t = 2.0;
            int64_t best = -1;
            for (int64_t k = start; k < stop; k++) {
                double ax = geom[4 * k], ay = geom[4 * k + 1], bx = geom[4 * k + 2], by = geom[4 * k + 3];
                if (bc_crosses_ray(ax, ay, bx, by, x, y)) inside = !inside; /* crossing number: x inside? */
                /* Swept: did the path enter through this edge (outside its line, then inside)? */
                double ex = bx - ax, ey = by - ay;
                double d0 = (x0 - ax) * ey - (y0 - ay) * ex; /* × |e|; the sign is what matters */
                double d1 = (x - ax) * ey - (y - ay) * ex;
                if (d0 >= 0.0 && d1 < 0.0) {
                    double t = d0 / (d0 - d1);
                    double u = ((x0 + t * (x - x0) - ax) * ex + (y0 + t * (y - y0) - ay) * ey) / (ex * ex + ey * ey);
                    if (0.0 <= u && u <= 1.0 && t < best_t) {
                        best_t = t;
                        best = k;
                    }
                }
            }
            if (best >= 0) {
                /* Entered through edge `best`: back onto its line (on the side it came from). */
                double ax = geom[4 * best], ay = geom[4 * best + 1], bx = geom[4 * best + 2], by = geom[4 * best + 3];
                double ex = bx - ax, ey = by - ay;
                double length = sqrt(ex * ex + ey * ey);
                double nx = ey / length, ny = -ex / length;
                double d = (x - ax) * nx + (y - ay) * ny;
                x -= d * nx;
                y -= d * ny;
                if (g->moving) surface_velocity(c->delta, s, x, y, g->h, &wx, &wy);
                record(g, i, nx, ny, -d, wx, wy, blob_material, shape_material);
                /* Beside a reflex corner that line runs inside the solid: check again. */
                inside = bc_rows_contain(geom, start, stop, x, y);
            }
            if (inside) {
                /* Began inside (spawned there, pushed in by another stage), or still inside after the swept
                 * projection: out to the nearest boundary point. */
                double best_d2 = INFINITY, qx = x, qy = y;
                int64_t face = -1;
                for (int64_t k = start; k < stop; k++) {
                    double ax = geom[4 * k], ay = geom[4 * k + 1], bx = geom[4 * k + 2], by = geom[4 * k + 3];
                    double ex = bx - ax, ey = by - ay;
                    double u = bc_min(bc_max(((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey), 0.0), 1.0);
                    double cx = ax + u * ex, cy = ay + u * ey;
                    double d2 = (cx - x) * (cx - x) + (cy - y) * (cy - y);
                    if (d2 < best_d2) {
                        best_d2 = d2;
                        qx = cx;
                        qy = cy;
                        face = 0.0 < u && u < 1.0 ? k : -1;
                    }
                }
                double depth = sqrt(best_d2);
                if (depth > 0.0) {
                    /* Out along the nearest face's normal; (q - x) / depth only at a corner: for a vertex left
                     * on a face by the swept projection, depth is round-off and (q - x) points anywhere (a box's
                     * side face would give n = (0, ±1), which the velocity update then clamps along). */
                    double nx, ny;
                    if (face >= 0) {
                        double ex = geom[4 * face + 2] - geom[4 * face], ey = geom[4 * face + 3] - geom[4 * face + 1];
                        double length = sqrt(ex * ex + ey * ey);
                        nx = ey / length;
                        ny = -ex / length;
                    } else {
                        nx = (qx - x) / depth;
                        ny = (qy - y) / depth;
                    }
                    x = qx;
                    y = qy;
                    if (g->moving) surface_velocity(c->delta, s, x, y, g->h, &wx, &wy);
                    record(g, i, nx, ny, depth, wx, wy, blob_material, shape_material);
                }
            }
            if (best >= 0 || inside) {
                /* Static friction, unless holding the vertex would put it inside (reflex corners). */
                stuck_outside_polygon(g, i, x, y, x0, y0, geom, start, stop, &x, &y);
                pushed(g, i, c->index[s], x - bx0, y - by0, loaded_mark(g, c, s));
            }
        }
        g->pos[i] = x;
        g->pos[n + i] = y;
    });
}

void bc_collide_statics(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    Stage g = {.n = m->vertex_count, .moving = ctx->c->moving != 0, .loaded = ctx->c->loaded != 0, .h = h,
               .pos = s->position, .prev = s->previous, .blob_of = m->blob_of, .awake = s->awake,
               .blob_material = m->material, .contact_normal = s->contact_normal, .contact_depth = s->contact_depth,
               .contact_material = s->contact_material, .static_of = s->static_of, .wall_of = s->wall_of,
               .static_push = s->static_push, .wall_push = s->wall_push};
    void (*const kernels[BC_SOLVER_KINDS])(const Stage *, const Colliders *, int) = {
        collide_plane, collide_segment, collide_circle, collide_polygon}; /* colliders.SOLVERS' order */
    for (int k = 0; k < BC_SOLVER_KINDS; k++) {
        const bcStaticSet *rest = &m->statics[k];
        if (rest->shapes <= 0) continue; /* a kind the scene lacks */
        Colliders c = {.shapes = rest->shapes, .geom = s->placed[k].geom, .aabb = s->placed[k].aabb,
                       .delta = s->placed[k].delta, .shape_offsets = rest->shape_offsets,
                       .material = rest->material, .index = rest->index};
        kernels[k](&g, &c, (int)ctx->c->parallel);
    }
}
