/* Adhesion: sticky blobs (bcModel.adhesion, N/m) and sticky colliders (bcModel.static_adhesion), Gish's tar.
 *
 * The law. A vertex i of blob b is within range of a surface (a collider, or the ring of another blob it keeps a
 * contact with: s->c_edge) where its gap z_0 at the substep's start x_0 is at most r = RANGE_EDGES × L̄_b, L̄_b the
 * blob's mean rest edge. There the surface holds it with a force of at most
 *     F_i = a ℓ_i,   ℓ_i = ½ (|x_i - x_{i-1}| + |x_{i+1} - x_i|) at the substep's start,
 * a = bc_mix_adhesion(a_blob, a_surface) (friction.h: the stickier side's), ℓ_i the vertex's share of the ring's
 * length: a blob holds a × the length of it that touches, shared along it as its vertices share the ring. Between
 * two blobs each side's vertices hold with ½ F_i, so that the interface holds a × its length once, not twice.
 *
 * A force f over a substep h moves a vertex of inverse mass w by w f h² (x += v h + w f h², read back as
 * Δv = w f h), so in position-based terms the surface may move the vertex toward it, along the unit normal n out
 * of the surface at x_0, by Δx = -w λ n with 0 <= λ <= F_i h² (N s²; λ / h² is the force). It takes
 *     λ_hold  = min(F_i h², max(s, 0) / w),            s = (x - x_0) · n,
 *     λ_press = min(F_i h² - λ_hold, r / w)  where the vertex touches (z_0 <= TOUCH), else 0,
 * λ = λ_hold + λ_press: s is the separation the substep has made so far (its gravity, its drive, the constraints),
 * which the hold undoes as far as F_i reaches; what is left presses a touching vertex into the surface, whose
 * contact stage (statics.c, the blob contacts' solver) pushes it back and counts the press as normal load: static
 * friction against a wall, μ_s D, then holds a sticky blob up (the press is at most r deep: r = 0.1 × 2π R / n is
 * below the depth an impact is read at, 0.1 R, integrate.c: IMPACT_DEPTH, for rings of 7 vertices and more; a
 * sticky ring of 3 to 6 can have its press read as an impact). A load the hold cannot undo separates the vertex
 * by what is left of it, faster every substep (the pull is capped, so a larger load separates), until it is out of
 * range and free; its neighbours then take its share of the load (a peel).
 *
 * Energy: the hold never makes energy. With u = s / h the normal speed the substep would read, the hold leaves
 *     u' = u - w λ_hold / h,   0 <= w λ_hold <= s:   u' in [0, u] when u > 0, and u' = u when u <= 0,
 * so ½ m u'² <= ½ m u²: it removes separation, never adds approach (a one-sided brake, as static friction is along
 * the surface). It never pulls a gap shut: a vertex ends no nearer than where its substep began (z >= z_0). In terms
 * of the potential U = a ℓ z (0 <= z <= r) of an adhesive layer, the hold is the force -∂U/∂z = -a ℓ acting only
 * against separation, so the work it does is never positive: the energy a blob has after it leaves a sticky
 * surface is at most what it would have without the glue. The press ends where it began: it moves a vertex that
 * touches (z_0 <= TOUCH) into the surface, and the contact stage puts it back on the surface, so the vertex moves
 * toward the surface by at most TOUCH (10⁻⁹ m) a substep through it. A drop onto a sticky floor never rebounds
 * higher than onto a clean one.
 *
 * Between blobs the same, for the relative motion of vertex p of blob A and the edge point q = (1 - t) x_0 + t x_1
 * of blob B it keeps a contact with (t from the substep's start, n the edge's outward normal then):
 *     s = ((p - q) - (p_0 - q_0)) · n,   W = w_p + (1 - t)² w_0 + t² w_1,
 *     Δp = -w_p λ n,   Δx_0 = (1 - t) w_0 λ n,   Δx_1 = t w_1 λ n,   λ_hold = min(½ F_p h², max(s, 0) / W),
 * so Σ m Δx = λ n (-1 + (1 - t) + t) = 0: the pulls are equal and opposite, momentum is kept (a sleeping B does not
 * move: w_0 = w_1 = 0, as in the contacts); and the relative normal speed u = s / h drops to u - W λ_hold / h in
 * [0, u]: with the impulse J = λ_hold / h, the pair's kinetic energy changes by -J u + ½ W J² = -J (u - ½ W J) <= 0.
 *
 * When: once a substep, in its last iteration, after the area and before the blob contacts and the statics (step.c),
 * so that what a press puts inside is pushed back in the same iteration and the statics keep the last word. Order:
 * blob pairs first, vertex by vertex (serial: a pull moves the other blob's vertices too; the same order for any
 * thread count), then the colliders, each vertex on its own (parallel). A vertex's colliders share one budget,
 * F_i h² in all; each of its (at most two) blob contacts has its own, ½ F_i h².
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "adhesion.h"
#include "collide_limits.h"
#include "friction.h"
#include "parallel.h"
#include "packing_records.h"
#include "periodic.h"
#include "ring.h"
#include "scratch.h"
#include "touch.h"

#define CPV BC_CONTACTS_PER_VERTEX
enum { PLANE, SEGMENT, CIRCLE, POLYGON }; /* the solver kinds, colliders.SOLVERS */

/* of the blob's mean rest edge: how far from a surface, at the substep's start, a vertex still holds to it (1 cm
 * for a default blob, r = 0.5 m and 32 vertices: within the kept blob contacts' margin, narrow_phase.c, so a vertex
 * in range of another blob has a contact with it) */
static const double RANGE_EDGES = 0.1;
/* m: a vertex this near a surface (or inside it) at the substep's start touches it, and may be pressed onto it
 * (the statics put a vertex back on a plane or polygon to round-off, not exactly) */
static const double TOUCH = 1e-9;
/* m: the statics keep a vertex this far off a segment (statics.c: SKIN), which is where its surface is for us */
static const double SEGMENT_SKIN = 1e-6;

double bc_adhesion_range_edges(void) { return RANGE_EDGES; }

int bc_any_adhesion(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    for (int64_t b = 0; b < m->blob_count; b++)
        if (m->adhesion[b] > 0.0) return 1;
    for (int64_t k = 0; k < m->walls.count; k++)
        if (m->static_adhesion[k] > 0.0) return 1;
    return 0;
}

/* ℓ_i: half of vertex i's two edges at the positions x (ring o..e) */
static inline double share_of_length(const double *x, int64_t n, int64_t i, int64_t o, int64_t e) {
    int64_t a = bc_prev_in_ring(i, o, e), b = bc_next_in_ring(i, o, e);
    double ax = x[i] - x[a], ay = x[n + i] - x[n + a], bx = x[b] - x[i], by = x[n + b] - x[n + i];
    return 0.5 * (sqrt(ax * ax + ay * ay) + sqrt(bx * bx + by * by));
}

/* λ = λ_hold + λ_press (see above) of a contact: the cap F h² (what is left of it), the separation s, the inverse
 * mass W the pull acts on, whether the vertex touches, and the range r */
static inline double pull(double cap, double s, double W, bool touching, double r) {
    if (cap <= 0.0 || W <= 0.0) return 0.0;
    double hold = bc_min(cap, bc_max(s, 0.0) / W);
    return touching ? hold + bc_min(cap - hold, r / W) : hold;
}

/* --- colliders: where a point is, from each kind's surface ---------------------------------------------------
 * Each query gives the gap z at (x, y) (m, > 0 outside the solid, < 0 inside) and the unit normal n out of the
 * solid at the surface point nearest to it, or false where there is no normal (a point on a circle's centre, on a
 * segment's line). Kernel rows as statics.c reads them (colliders.py). `interior`: whether a press along -n stays
 * on the surface's own side (a segment's end is not: pressed round it, a vertex would pass to the other side). */

static inline bool plane_gap(const double *row, double x, double y, double *z, double *nx, double *ny) {
    *nx = row[2];
    *ny = row[3];
    *z = (x - row[0]) * row[2] + (y - row[1]) * row[3];
    return true;
}

static inline bool segment_gap(const double *row, double x, double y, double *z, double *nx, double *ny,
                               bool *interior) {
    double ax = row[0], ay = row[1], ex = row[2] - ax, ey = row[3] - ay;
    double u = ((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey);
    *interior = u > 0.0 && u < 1.0;
    u = bc_min(bc_max(u, 0.0), 1.0);
    double dx = x - (ax + u * ex), dy = y - (ay + u * ey);
    double d = sqrt(dx * dx + dy * dy);
    if (d == 0.0) return false;
    *nx = dx / d;
    *ny = dy / d;
    *z = d - SEGMENT_SKIN;
    return true;
}

static inline bool circle_gap(const double *row, double x, double y, double *z, double *nx, double *ny) {
    double rx = x - row[0], ry = y - row[1];
    double d = sqrt(rx * rx + ry * ry);
    if (d == 0.0) return false;
    double side = row[3] != 0.0 ? -1.0 : 1.0; /* a container is solid outside: its normal points in */
    *nx = side * rx / d;
    *ny = side * ry / d;
    *z = side * (d - row[2]);
    return true;
}

/* A polygon, edges geom[start:stop] counter-clockwise: the nearest boundary point; n the face's outward normal
 * there, or at a corner the direction from it to the point (their bisector for a point on the corner itself) */
static inline bool polygon_gap(const double *geom, int64_t start, int64_t stop, double x, double y, double *z,
                               double *nx, double *ny) {
    double best = INFINITY, bu = 0.0;
    int64_t face = -1;
    bool inside = false;
    for (int64_t k = start; k < stop; k++) {
        const double *r = geom + 4 * k;
        if (bc_crosses_ray(r[0], r[1], r[2], r[3], x, y)) inside = !inside;
        double ex = r[2] - r[0], ey = r[3] - r[1];
        double u = bc_min(bc_max(((x - r[0]) * ex + (y - r[1]) * ey) / (ex * ex + ey * ey), 0.0), 1.0);
        double dx = x - (r[0] + u * ex), dy = y - (r[1] + u * ey);
        double d2 = dx * dx + dy * dy;
        if (d2 < best) {
            best = d2;
            face = k;
            bu = u;
        }
    }
    if (face < 0) return false;
    const double *r = geom + 4 * face;
    double d = sqrt(best);
    *z = inside ? -d : d;
    if (bu > 0.0 && bu < 1.0) { /* on a face: its outward normal (e_y, -e_x) / |e| */
        double ex = r[2] - r[0], ey = r[3] - r[1], length = sqrt(ex * ex + ey * ey);
        *nx = ey / length;
        *ny = -ex / length;
        return true;
    }
    double cx = bu == 0.0 ? r[0] : r[2], cy = bu == 0.0 ? r[1] : r[3]; /* a corner */
    if (d > 0.0) {
        double side = inside ? -1.0 : 1.0;
        *nx = side * (x - cx) / d;
        *ny = side * (y - cy) / d;
        return true;
    }
    int64_t other = bu == 0.0 ? (face > start ? face - 1 : stop - 1) : (face + 1 < stop ? face + 1 : start);
    double sx = 0.0, sy = 0.0;
    for (int j = 0; j < 2; j++) {
        const double *q = geom + 4 * (j == 0 ? face : other);
        double ex = q[2] - q[0], ey = q[3] - q[1], length = sqrt(ex * ex + ey * ey);
        sx += ey / length;
        sy += -ex / length;
    }
    double length = sqrt(sx * sx + sy * sy);
    if (length == 0.0) return false;
    *nx = sx / length;
    *ny = sy / length;
    return true;
}

/* The colliders' pulls on every awake vertex of a blob that, or whose collider, is sticky */
static void stick_to_colliders(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count;
    const bool moving = ctx->c->moving != 0, loaded = ctx->c->loaded != 0;
    bool sticky_wall = false;
    for (int64_t k = 0; k < m->walls.count; k++) sticky_wall |= m->static_adhesion[k] > 0.0;
    double *pos = s->position;
    const double *prev = s->previous;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t i = 0; i < n; i++), {
        int64_t b = m->blob_of[i];
        if (!s->awake[b] || (m->adhesion[b] <= 0.0 && !sticky_wall)) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double r = RANGE_EDGES * m->rest_perimeter[b] / (double)(e - o);
        double w = m->inv_mass[i];
        double x = pos[i], y = pos[n + i];
        double used = 0.0, ell = -1.0; /* λ taken so far; ℓ_i, found at the first collider in range */
        for (int kind = 0; kind < BC_SOLVER_KINDS; kind++) {
            const bcStaticSet *set = &m->statics[kind];
            const bcPlaced *placed = &s->placed[kind];
            for (int64_t c = 0; c < set->shapes; c++) {
                int64_t k = set->index[c];
                double a = bc_mix_adhesion(m->adhesion[b], m->static_adhesion[k]);
                if (a <= 0.0) continue;
                /* x_0: the substep's start, carried with a collider that moves (statics.c: carried) */
                double x0 = prev[i], y0 = prev[n + i];
                const double *delta = placed->delta + 5 * c;
                if (moving) {
                    double cx = delta[0] * x0 - delta[1] * y0 + delta[2];
                    y0 = delta[1] * x0 + delta[0] * y0 + delta[3];
                    x0 = cx;
                }
                const double *box = placed->aabb + 4 * c;
                if (kind != PLANE && (x0 < box[0] - r || x0 > box[2] + r || y0 < box[1] - r || y0 > box[3] + r))
                    continue;
                double z0, nx, ny;
                bool found, interior = true;
                const double *row = placed->geom + 4 * (kind == POLYGON ? set->shape_offsets[c] : c);
                switch (kind) {
                case PLANE: found = plane_gap(row, x0, y0, &z0, &nx, &ny); break;
                case SEGMENT: found = segment_gap(row, x0, y0, &z0, &nx, &ny, &interior); break;
                case CIRCLE: found = circle_gap(row, x0, y0, &z0, &nx, &ny); break;
                default:
                    found = polygon_gap(placed->geom, set->shape_offsets[c], set->shape_offsets[c + 1], x0, y0, &z0,
                                        &nx, &ny);
                }
                if (!found || z0 > r) continue;
                if (ell < 0.0) ell = share_of_length(prev, n, i, o, e);
                double sep = (x - x0) * nx + (y - y0) * ny;
                double lam = pull(a * ell * h * h - used, sep, w, z0 <= TOUCH && interior, r);
                if (lam <= 0.0) continue;
                used += lam;
                double dx = -w * lam * nx, dy = -w * lam * ny;
                x += dx;
                y += dy;
                /* the collider's record: it is pulled toward the blob (walls.c: bc_account_contacts), and a loaded
                 * wall takes its share of the pull as of a push (walls.c: bc_yield_loaded_walls) */
                bc_account(i, k, dx, dy, s->static_of, s->static_push, n);
                if (loaded && delta[4] != 0.0) {
                    s->wall_of[i] = k;
                    s->wall_push[i] += dx;
                    s->wall_push[n + i] += dy;
                }
            }
        }
        pos[i] = x;
        pos[n + i] = y;
    });
}

/* Where p_0 (image-shifted) is nearest to edge f0→f1 at the positions x: t in [0, 1] and the squared distance */
static inline double nearest_on_edge(const double *x, int64_t n, int64_t f0, int64_t f1, double px, double py,
                                     double *t) {
    double ex = x[f1] - x[f0], ey = x[n + f1] - x[n + f0];
    double len2 = ex * ex + ey * ey;
    double u = len2 > 0.0 ? ((px - x[f0]) * ex + (py - x[n + f0]) * ey) / len2 : 0.0;
    u = bc_min(bc_max(u, 0.0), 1.0);
    double dx = px - (x[f0] + u * ex), dy = py - (x[n + f0] + u * ey);
    *t = u;
    return dx * dx + dy * dy;
}

/* The pulls between blobs, at each vertex's kept contacts: vertex by vertex, in order */
static void stick_to_blobs(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count;
    const bcBox box = bc_box(ctx->c->box_x, ctx->c->box_y, ctx->c->box_tilt);
    double *pos = s->position;
    const double *prev = s->previous, *w = m->inv_mass;
    for (int64_t p = 0; p < n; p++) {
        int64_t A = m->blob_of[p];
        if (!s->awake[A]) continue;
        int64_t oa = m->offsets[A], ea = m->offsets[A + 1];
        double r = RANGE_EDGES * m->rest_perimeter[A] / (double)(ea - oa);
        for (int64_t c = 0; c < CPV; c++) {
            int64_t kept = s->c_edge[c * n + p];
            if (kept < 0) continue;
            int64_t B = m->blob_of[kept];
            double a = bc_mix_adhesion(m->adhesion[A], m->adhesion[B]);
            if (a <= 0.0) continue;
            int64_t ob = m->offsets[B], eb = m->offsets[B + 1];
            double sx, sy;
            bc_image(s->center, A, B, box, &sx, &sy);
            double px0 = prev[p] + sx, py0 = prev[n + p] + sy;
            /* the edge nearest p_0 at the substep's start, of the kept one and its two neighbours */
            int64_t next = bc_next_in_ring(kept, ob, eb);
            int64_t corners[4] = {bc_prev_in_ring(kept, ob, eb), kept, next, bc_next_in_ring(next, ob, eb)};
            int64_t f0 = kept, f1 = next;
            double t = 0.0, d2 = INFINITY;
            for (int j = 0; j < 3; j++) { /* the edges before, kept, after: the first nearest */
                double t_j, d2_j = nearest_on_edge(prev, n, corners[j], corners[j + 1], px0, py0, &t_j);
                if (d2_j < d2) {
                    f0 = corners[j];
                    f1 = corners[j + 1];
                    t = t_j;
                    d2 = d2_j;
                }
            }
            if (d2 > r * r) continue;
            double ex = prev[f1] - prev[f0], ey = prev[n + f1] - prev[n + f0];
            double length = sqrt(ex * ex + ey * ey);
            if (length == 0.0) continue;
            double nx = m->orient[B] * ey / length, ny = -m->orient[B] * ex / length; /* out of B */
            double z0 = (px0 - (prev[f0] + t * ex)) * nx + (py0 - (prev[n + f0] + t * ey)) * ny;
            double qx = (1.0 - t) * pos[f0] + t * pos[f1], qy = (1.0 - t) * pos[n + f0] + t * pos[n + f1];
            double sep = (pos[p] + sx - qx) * nx + (pos[n + p] + sy - qy) * ny - z0;
            double w0 = s->awake[B] ? w[f0] : 0.0, w1 = s->awake[B] ? w[f1] : 0.0; /* a sleeping blob stays */
            double W = w[p] + (1.0 - t) * (1.0 - t) * w0 + t * t * w1;
            double lam = pull(0.5 * a * share_of_length(prev, n, p, oa, ea) * h * h, sep, W, z0 <= TOUCH, r);
            if (lam <= 0.0) continue;
            double dx = lam * nx, dy = lam * ny;
            pos[p] -= w[p] * dx;
            pos[n + p] -= w[p] * dy;
            pos[f0] += (1.0 - t) * w0 * dx;
            pos[n + f0] += (1.0 - t) * w0 * dy;
            pos[f1] += t * w1 * dx;
            pos[n + f1] += t * w1 * dy;
            if (ctx->records) { /* impulses λ / h: -n on A at p, +n on B at q (the stress, packing.py) */
                const double *center = s->center;
                bc_add_virial(s->virial, A, pos[p] - center[2 * A], pos[n + p] - center[2 * A + 1], -dx / h, -dy / h);
                bc_add_virial(s->virial, B, qx - center[2 * B], qy - center[2 * B + 1], dx / h, dy / h);
                bc_add_pair_impulse(ctx->w, A, B, -dx / h, -dy / h);
            }
        }
    }
}

void bc_adhere(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bool statics = false;
    for (int k = 0; k < BC_SOLVER_KINDS; k++) statics |= m->statics[k].shapes > 0;
    if (m->blob_count > 1 && ctx->w->pair_count > 0) stick_to_blobs(ctx, h);
    if (statics) stick_to_colliders(ctx, h);
}
