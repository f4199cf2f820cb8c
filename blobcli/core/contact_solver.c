/* The blob contacts' solver: each kept contact (bcState.c_edge, found by the narrow phase) pushes its vertex
 * out of the other blob where it is inside, with friction, every iteration; after the substep, the contacts
 * that pushed lose their approach and their slip at velocity level (contact_velocities.c).
 *
 * The point–edge constraint, with q = (1 - t) x_0 + t x_1 the closest point on edge (x_0, x_1) and n its
 * outward normal:
 *     C = (p - q) · n >= 0,   ∇_p C = n,   ∇_0 C = -(1 - t) n,   ∇_1 C = -t n,
 *     λ = -C / (w_p + (1 - t)² w_0 + t² w_1),
 *     Δp = w_p λ n,   Δx_0 = -(1 - t) w_0 λ n,   Δx_1 = -t w_1 λ n.
 * Σ m Δx = λ n (1 - (1 - t) - t) = 0: contacts never change total momentum, but for the mass scaling of
 * stacks: a lighter blob below a heavier one acts in their contacts as w_light (w_heavy / w_light)^2f, with
 * f = Δz / (r_a + r_b) in [0, 1] along -g (Gauss-Seidel moves a heavy blob resting on a much lighter one by
 * only w_heavy / (w_heavy + w_light) of their overlap per iteration, and it ploughs through). Side by side,
 * equal masses, or zero gravity: f or the ratio is 1, and momentum is exact.
 *
 * Every iteration a kept contact follows p along the other blob's ring to the locally nearest point (see
 * contact_push) and acts only while p is inside there: a one-sided constraint. Near a convex corner of the
 * other blob, where p is behind both edges' lines, the push turns from the nearer edge's normal toward the
 * corner's bisector as p nears it (near_convex_corner). The velocity stage acts along each contact's last
 * push normal (c_normal), not its edge's.
 *
 * Resolution order: blob by blob (Gauss-Seidel across blobs, every second iteration in the reverse order),
 * and within a blob all its vertices' contacts together (Jacobi): every push found from the same positions,
 * then each scaled by 1 / k, k the most pushes any of its three vertices is in (an edge's end counted by its
 * weight, 1 - t or t, so that a mirror image of the pushes counts the same; k at least 1), and added. A
 * mirror image of a blob's contacts so gets the mirror image of its pushes (two equal frictionless blobs
 * meeting head-on stay on their axis), while a blob's load reaches the next blob within one pass. Scenes of
 * 64 blobs or more are cut into vertical strips (the broad phase's, in the scratch), and contacts that share
 * no blob run in parallel; smaller scenes keep one strip, so their blobs go in index order. Either way the
 * order is set by the scene, not by the number of threads.
 *
 * Friction (with each push, Müller et al. 2020): Coulomb on the contact's tangential correction over the
 * substep, with the same generalized masses as the push. The slip Δx_t of the vertex against the other blob is
 * measured from a stick point, a material point of the other blob (an edge and t along it: stick_edge,
 * stick_t) that the contact keeps while it holds: set where the vertex touches after its first push, and again
 * after every kinetic slide. Each iteration the contact would undo all of Δx_t; K, the tangential correction it
 * has made so far this substep (friction_sum), plus Δx_t is what holding it costs over the substep, and
 * Coulomb bounds that against D, the vertex's push-out this substep: held (static) while |K + Δx_t| <= μ_s D;
 * else it slides, and the correction is set back so that the substep's total is (K + Δx_t) μ_k D / |K + Δx_t|,
 * along the same direction. The bound is on the substep's sum, not on each iteration's share of it: the
 * perimeter and area stages move a loaded blob's contact vertices to and fro within a substep (tension and
 * pressure at a flattened contact), and a contact that counted each of those moves against μ_s D slid where
 * the substep's net force on it was small, and piles crept. Coefficients of the two blobs combine as
 * √(μ_a μ_b) (friction.h).
 *
 * Periodic box: a vertex p of blob a meets blob b's vertices as p + s, s the shift to a's image nearest b
 * (bc_image; s = 0 without arithmetic in an open world), and each contact's impulses go into the blobs'
 * virial (packing.py's stress).
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "contact_solver.h"
#include "contacts.h"
#include "parallel.h"


static inline int64_t floor_div(int64_t a, int64_t b) { return a / b - (a % b != 0 && (a < 0) != (b < 0)); }
static inline int64_t floor_mod(int64_t a, int64_t b) { return a - b * floor_div(a, b); }
static inline int64_t iabs(int64_t a) { return a < 0 ? -a : a; }

/* Whether edge e0→e1's outward normal (the sign of its ring's winding, orient) opposes v */
static inline bool faces(const double *pos, int64_t n, double orient, int64_t e0, int64_t e1, double vnx,
                         double vny) {
    return orient * ((pos[n + e1] - pos[n + e0]) * vnx - (pos[e1] - pos[e0]) * vny) < 0.0;
}

/* Move p by w_p d and the edge ends by -w d: the relative motion changes by W d, momentum by 0 */
static inline void apply(double *pos, int64_t n, int64_t p, int64_t e0, int64_t e1, double wp, double w0, double w1,
                         double dx, double dy) {
    pos[p] += wp * dx;
    pos[n + p] += wp * dy;
    pos[e0] -= w0 * dx;
    pos[n + e0] -= w0 * dy;
    pos[e1] -= w1 * dx;
    pos[n + e1] -= w1 * dy;
}

/* A vertex p inside the other blob, behind edge E = e0→e1 (C < 0, normal n_E): near a convex corner k of E,
 * where p is also behind the neighbouring edge F's line, the push turns toward F's normal, so that it does
 * not jump where p crosses the corner's bisector (the edge nearer to p pushing along its own normal throws a
 * vertex on the bisector to one side: which side, the ring's order decided).
 *
 * With d_E = -C and d_F = -(p - k) · n_F the depths behind the two lines, d = min and D = max,
 * u = (D - d) / d: the push goes along n = (n_near + max(1 - u, 0) n_far) / |...|, the bisector on it
 * (u = 0), the nearer edge's normal from u = 1 on (D >= 2 d; in a polygon's flat middle, D - d is the
 * edge's length times the turn of the corner, far above the depth of a contact). Symmetric in the two
 * edges, so a mirror image of the pair gets the mirror image of the push. p goes along n by s, to where it
 * first leaves the corner's wedge: s = min over the lines L of d_L / (n · n_L); the edge of that line takes
 * the reaction, at the exit point. Updates (e0, e1, t, n_x, n_y, C) to the contact's, C = -s; leaves them
 * where the corner is reflex or straight, p is in front of F's line, or u >= 1. */
void bc_near_convex_corner(const double *pos, int64_t n, double orient, int64_t o, int64_t e, int64_t *e0,
                           int64_t *e1, double *t, double *nx, double *ny, double *C, double px, double py) {
    double ex = pos[*e1] - pos[*e0], ey = pos[n + *e1] - pos[n + *e0];
    int64_t k, kf;
    double fx, fy, turn;
    if (*t < 0.5) { /* corner k = e0, F = kf→k */
        k = *e0;
        kf = bc_prev_in_ring(*e0, o, e);
        fx = pos[k] - pos[kf];
        fy = pos[n + k] - pos[n + kf];
        turn = fx * ey - fy * ex; /* F then E */
    } else {        /* corner k = e1, F = k→kf */
        k = *e1;
        kf = bc_next_in_ring(*e1, o, e);
        fx = pos[kf] - pos[k];
        fy = pos[n + kf] - pos[n + k];
        turn = ex * fy - ey * fx; /* E then F */
    }
    double f = sqrt(fx * fx + fy * fy);
    if (orient * turn <= 0.0 || f == 0.0) return; /* reflex or straight corner: the nearest side is continuous */
    double mx = orient * fy / f, my = -orient * fx / f;
    double dE = -*C, dF = -((px - pos[k]) * mx + (py - pos[n + k]) * my);
    if (dF <= 0.0) return; /* in front of F's line */
    double near = bc_min(dE, dF), far = bc_max(dE, dF);
    double w = 1.0 - (far - near) / near;
    if (w <= 0.0) return;
    double bx, by;
    if (dE <= dF) {
        bx = *nx + w * mx;
        by = *ny + w * my;
    } else {
        bx = mx + w * *nx;
        by = my + w * *ny;
    }
    double b = sqrt(bx * bx + by * by);
    bx = bx / b;
    by = by / b;
    double cE = bx * *nx + by * *ny, cF = bx * mx + by * my;
    double sE = cE > 0.0 ? dE / cE : INFINITY;
    double sF = cF > 0.0 ? dF / cF : INFINITY;
    if (sE == INFINITY && sF == INFINITY) return; /* (a corner too sharp for the turned push to leave by) */
    int64_t q0, q1;
    double depth;
    if (sE <= sF) {
        q0 = *e0;
        q1 = *e1;
        depth = sE;
    } else if (*t < 0.5) {
        q0 = kf;
        q1 = k;
        depth = sF;
    } else {
        q0 = k;
        q1 = kf;
        depth = sF;
    }
    double x = px + depth * bx, y = py + depth * by;
    *t = clamp01(along(pos, n, q0, q1, x, y));
    *e0 = q0;
    *e1 = q1;
    *nx = bx;
    *ny = by;
    *C = -depth;
}

/* Vertex p's contact s: follow it to the nearest point of the other blob's ring, and if p is inside there,
 * the push that puts it out, with friction, not yet applied (see apply_push): push (a row) = Δ_x, Δ_y, w_p,
 * w_e, t, whether the stick point is set anew after it, the depth -C, and c_edge[s, p] the edge it pushes.
 * Returns whether it pushes. (px, py): p where the other blob meets it (in a periodic box, the image of p's
 * blob nearest the other). Writes only p's slots. */
static bool contact_push(const Contacts *cs, int64_t p, int64_t s, double *push) {
    const int64_t n = cs->n;
    const double *pos = cs->pos;
    int64_t e0 = cs->c_edge[s * n + p];
    int64_t blob = cs->blob_of[e0], a = cs->blob_of[p];
    int64_t o = cs->offsets[blob], e = cs->offsets[blob + 1];
    double orient = cs->orient[blob];
    double sx, sy;
    bc_image(cs->center, a, blob, cs->box, &sx, &sy);
    double px = pos[p] + sx, py = pos[n + p] + sy;
    /* Walk along the ring to the locally nearest point q = (1 - t) x_0 + t x_1: while p projects before the
     * kept edge's start (t < 0) and onto the previous edge short of their shared corner, step back; likewise
     * forward. Each step strictly shortens |p - q|, so it cannot cycle; it stops on an edge (0 < t < 1) or at
     * a corner between two edges (t = 0 or 1). It steps only onto edges facing p's own outward normal v (the
     * narrow phase's rule): a vertex deep inside must not walk round to the far side and be pushed out
     * through it. */
    int64_t e1 = bc_next_in_ring(e0, o, e);
    double t = along(pos, n, e0, e1, px, py);
    double vnx = 0.0, vny = 0.0; /* p's normal, found only if the walk steps (most contacts stay on their edge) */
    if (t < 0.0 || t > 1.0) bc_vertex_normal(pos, n, cs->orient[a], p, cs->offsets[a], cs->offsets[a + 1], &vnx, &vny);
    for (int64_t step = 0; step < e - o; step++) {
        if (t < 0.0) {
            int64_t before = bc_prev_in_ring(e0, o, e);
            double t_before = along(pos, n, before, e0, px, py);
            if (t_before < 1.0 && faces(pos, n, orient, before, e0, vnx, vny)) {
                e1 = e0;
                e0 = before;
                t = t_before;
                continue;
            }
        } else if (t > 1.0) {
            int64_t after = bc_next_in_ring(e1, o, e);
            double t_after = along(pos, n, e1, after, px, py);
            if (t_after > 0.0 && faces(pos, n, orient, e1, after, vnx, vny)) {
                e0 = e1;
                e1 = after;
                t = t_after;
                continue;
            }
        }
        break;
    }
    t = clamp01(t);
    cs->c_edge[s * n + p] = e0;
    double ex = pos[e1] - pos[e0], ey = pos[n + e1] - pos[n + e0];
    double length = sqrt(ex * ex + ey * ey);
    if (length == 0.0) return false;
    double nx = orient * ey / length, ny = -orient * ex / length; /* outward normal of the edge */
    double qx = pos[e0] + t * ex, qy = pos[n + e0] + t * ey;
    double C = (px - qx) * nx + (py - qy) * ny;
    if (t == 0.0 || t == 1.0) {
        /* q is the corner k between this edge and its neighbour. p is inside when it lies behind the corner's
         * pseudo-normal, the sum of the two edges' outward normals (in the corner's region that is the
         * polygon's side, convex corner or reflex). Push toward the corner, along q - p (along the normal of
         * whichever edge came first, every push was turned the same way round the ring, and stacked blobs slid
         * off each other). */
        int64_t corner = t == 0.0 ? e0 : e1;
        int64_t other = t == 0.0 ? bc_prev_in_ring(e0, o, e) : bc_next_in_ring(e1, o, e);
        double fx = pos[other] - pos[corner], fy = pos[n + other] - pos[n + corner]; /* the next edge, from k */
        double f = sqrt(fx * fx + fy * fy);
        double mx, my;
        if (f > 0.0) {
            /* its outward normal: the edge k→other turned like e0→e1 when t = 1, reversed when t = 0 */
            double side = t == 1.0 ? 1.0 : -1.0;
            mx = side * orient * fy / f;
            my = -side * orient * fx / f;
        } else {
            mx = nx;
            my = ny;
        }
        double dx = qx - px, dy = qy - py;
        if (dx * (nx + mx) + dy * (ny + my) <= 0.0) return false; /* p - q along the pseudo-normal: outside */
        double dist = sqrt(dx * dx + dy * dy);
        if (dist == 0.0) return false;
        nx = dx / dist;
        ny = dy / dist;
        C = -dist;
    } else if (C >= 0.0) {
        return false;
    } else {
        bc_near_convex_corner(pos, n, orient, o, e, &e0, &e1, &t, &nx, &ny, &C, px, py);
        cs->c_edge[s * n + p] = e0;
    }
    cs->c_hit[s * n + p] = 1;
    cs->c_normal[s * n + p] = nx;
    cs->c_normal[(CPV + s) * n + p] = ny;
    double wp = cs->inv_mass[p], we = cs->inv_mass[e0]; /* vertex masses are uniform within a blob */
    /* Heavy on light: a lighter blob below a heavier one acts heavier, by how directly it is below:
     * f = Δz / (r_a + r_b), along -g. */
    if (!cs->awake[blob]) { /* a sleeping blob does not move */
        we = 0.0;
    } else if (we != wp) { /* (equal masses: no scaling, so f is not needed) */
        double dz = (cs->center[2 * a] - cs->center[2 * blob]) * cs->up_x +
                    (cs->center[2 * a + 1] - cs->center[2 * blob + 1]) * cs->up_y;
        double f = dz / (cs->radius[a] + cs->radius[blob]);
        if (f > 0.0 && we > wp) /* the vertex's blob is above and heavier */
            we *= pow(wp / we, bc_min(2.0 * f, 2.0));
        else if (f < 0.0 && wp > we) /* the edge's blob is above and heavier */
            wp *= pow(we / wp, bc_min(-2.0 * f, 2.0));
    }
    double w0 = (1.0 - t) * we, w1 = t * we;
    double W = wp + (1.0 - t) * w0 + t * w1;
    /* Friction on the relative slip r of p: from its stick point on the other blob, or for a contact that has
     * none yet, against q since the substep began. The normal push changes r by -C n only, so r's tangential
     * part t_r can be read before it, and push and friction go in one move: Δ = (-C n - f) / W, f the
     * tangential correction (t_r where the contact holds). */
    int64_t a0 = cs->stick_edge[s * n + p];
    double rx, ry;
    if (a0 >= 0) { /* held at a stick point: the slip is p's way from it */
        int64_t a1 = bc_next_in_ring(a0, o, e);
        double ta = cs->stick_t[s * n + p];
        rx = px - (1.0 - ta) * pos[a0] - ta * pos[a1];
        ry = py - (1.0 - ta) * pos[n + a0] - ta * pos[n + a1];
    } else {
        const double *prev = cs->prev;
        rx = (pos[p] - prev[p]) - (1.0 - t) * (pos[e0] - prev[e0]) - t * (pos[e1] - prev[e1]);
        ry = (pos[n + p] - prev[n + p]) - (1.0 - t) * (pos[n + e0] - prev[n + e0]) - t * (pos[n + e1] - prev[n + e1]);
    }
    double rn = rx * nx + ry * ny;
    double tx = rx - rn * nx, ty = ry - rn * ny;
    double fx = 0.0, fy = 0.0;
    bool slides = false;
    /* where there is friction (frictionless, both limits are 0, and nothing is corrected, whatever the slip) */
    const double *material = cs->material;
    if (material[3 * a] * material[3 * blob] > 0.0 || material[3 * a + 1] * material[3 * blob + 1] > 0.0) {
        /* Coulomb on the substep's whole correction K + t_r: held within μ_s D, D the push-out summed over the
         * substep (this push's -C too); else the substep's total set to μ_k D along it */
        double static_limit, kinetic_limit;
        friction_limits(material, a, blob, cs->depth[p] - C, &static_limit, &kinetic_limit);
        const double *K = cs->friction_sum;
        double kx = K[s * n + p] + tx, ky = K[(CPV + s) * n + p] + ty;
        double total = sqrt(kx * kx + ky * ky);
        if (total <= static_limit) {
            fx = tx;
            fy = ty;
        } else {
            double kept = kinetic_limit / total;
            fx = kx * kept - K[s * n + p];
            fy = ky * kept - K[(CPV + s) * n + p];
            slides = true;
        }
    }
    push[0] = (-C * nx - fx) / W;
    push[1] = (-C * ny - fy) / W;
    push[2] = wp;
    push[3] = we;
    push[4] = t;
    push[5] = a0 < 0 || slides ? 1.0 : 0.0; /* whether the stick point is set anew after it */
    push[6] = -C;
    push[7] = fx;
    push[8] = fy;
    return true;
}

/* The contact of push row r of the blob whose vertices start at o: p, c, the other blob b, the edge e0 → e1 */
static inline void pushed(const Contacts *cs, int64_t r, int64_t o, int64_t *p, int64_t *c, int64_t *b, int64_t *e0,
                          int64_t *e1) {
    *p = o + r / CPV;
    *c = r % CPV;
    *e0 = cs->c_edge[*c * cs->n + *p];
    *b = cs->blob_of[*e0];
    *e1 = bc_next_in_ring(*e0, cs->offsets[*b], cs->offsets[*b + 1]);
}

/* A push (its row, see contact_push) of contact slot c, scaled: p moves by w_p Δ, the edge's ends by
 * -(1 - t) w_e Δ and -t w_e Δ; the contact's push-out D and tangential correction K grow by the scaled -C and f. In a
 * periodic box its impulses go into the virial, m Δx / h on p's blob at p and on the other at the edge point, and
 * into the pair's record (packing_records.h). */
static void apply_push(const Contacts *cs, int64_t p, int64_t c, int64_t e0, int64_t e1, int64_t a, int64_t b,
                       double scale, const double *push) {
    const int64_t n = cs->n;
    double *pos = cs->pos;
    double dx = scale * push[0], dy = scale * push[1], wp = push[2], we = push[3], t = push[4];
    if (cs->records) {
        const double *center = cs->center;
        double qx = (1.0 - t) * pos[e0] + t * pos[e1], qy = (1.0 - t) * pos[n + e0] + t * pos[n + e1];
        bc_add_virial(cs->virial, a, pos[p] - center[2 * a], pos[n + p] - center[2 * a + 1],
                   wp * dx / (cs->inv_mass[p] * cs->h), wp * dy / (cs->inv_mass[p] * cs->h));
        bc_add_virial(cs->virial, b, qx - center[2 * b], qy - center[2 * b + 1], -we * dx / (cs->inv_mass[e0] * cs->h),
                   -we * dy / (cs->inv_mass[e0] * cs->h));
        bc_add_pair_impulse(cs->w, a, b, wp * dx / (cs->inv_mass[p] * cs->h), wp * dy / (cs->inv_mass[p] * cs->h));
    }
    apply(pos, n, p, e0, e1, wp, (1.0 - t) * we, t * we, dx, dy);
    cs->depth[p] += scale * push[6];
    cs->friction_sum[c * n + p] += scale * push[7];
    cs->friction_sum[(CPV + c) * n + p] += scale * push[8];
}

/* The contacts of a vertex in strip s with an edge in strip `other`, then (if other != s) those of a vertex in
 * `other` with an edge in s (only crossing blobs have such contacts); backward: each strip's blobs in reverse
 * order. far: instead, the contacts across strips two or more apart, blobs in index order. A blob's contacts
 * go together, Jacobi: push and listed are the task's own rows of the scratch (slots of them). */
static void resolve_between(const Contacts *cs, const bcScratch *w, bool far, int64_t s, int64_t other,
                            bool backward, double *push, int64_t *listed) {
    const int64_t n = cs->n, blob_count = w->blob_count;
    const int64_t *rows = w->resolve_rows, *row_count = w->resolve_row_count, *strip_of = w->strip_of;
    double *share = w->resolve_share;
    for (int side = 0; side < (other == s || far ? 1 : 2); side++) {
        int64_t here = side == 0 ? s : other, there = side == 0 ? other : s;
        int64_t first = far ? 0 : w->strip_start[here], last = far ? blob_count : w->strip_start[here + 1];
        for (int64_t i = first; i < last; i++) {
            int64_t j = backward ? first + last - 1 - i : i;
            int64_t a = far ? j : w->strip_blobs[j];
            if (w->crossing[a] < (far ? 2 : other != s ? 1 : 0)) continue; /* (a has no contacts here) */
            int64_t o = cs->offsets[a];
            /* a's contacts here, their slots r in vertex order (listed[:here_rows]), from its rows ... */
            int64_t here_rows = 0;
            for (int64_t m = CPV * o; m < CPV * o + row_count[a]; m++) {
                int64_t theirs = rows[CPV * n + m];
                if (far ? iabs(theirs - strip_of[a]) >= 2 : theirs == there) listed[here_rows++] = rows[m];
            }
            /* ... every push of those, found from the same positions (push row r; listed[:pushes] the rows that
             * push, written over the rows already read), and how many of them each vertex is in (an edge's end
             * by its weight in the push, 1 - t or t: a mirror image of the pushes counts the same) ... */
            int64_t pushes = 0;
            for (int64_t i_row = 0; i_row < here_rows; i_row++) {
                int64_t r = listed[i_row];
                int64_t p = o + r / CPV, c = r % CPV;
                double *row = push + BC_PUSH_ROW * r;
                if (contact_push(cs, p, c, row)) {
                    listed[pushes++] = r;
                    int64_t b, e0, e1;
                    pushed(cs, r, o, &p, &c, &b, &e0, &e1);
                    share[p] += 1.0;
                    share[e0] += 1.0 - row[4];
                    share[e1] += row[4];
                }
            }
            /* ... then each, scaled by 1 / k (k at least 1), added in vertex order */
            for (int64_t i_row = 0; i_row < pushes; i_row++) {
                int64_t r = listed[i_row], p, c, b, e0, e1;
                pushed(cs, r, o, &p, &c, &b, &e0, &e1);
                double most = bc_max(bc_max(bc_max(share[p], share[e0]), share[e1]), 1.0);
                apply_push(cs, p, c, e0, e1, a, b, 1.0 / most, push + BC_PUSH_ROW * r);
            }
            for (int64_t i_row = 0; i_row < pushes; i_row++) {
                int64_t r = listed[i_row], p, c, b, e0, e1;
                pushed(cs, r, o, &p, &c, &b, &e0, &e1);
                share[p] = share[e0] = share[e1] = 0.0;
                if (push[BC_PUSH_ROW * r + 5] != 0.0) { /* held from now on where it touches now (after a slide: there) */
                    double sx, sy;
                    bc_image(cs->center, a, b, cs->box, &sx, &sy);
                    cs->stick_edge[c * n + p] = e0;
                    cs->stick_t[c * n + p] = clamp01(along(cs->pos, n, e0, e1, cs->pos[p] + sx, cs->pos[n + p] + sy));
                }
            }
        }
    }
}

/* The contacts blob by blob (each blob's together), in parallel where they share no blob (collide._resolve).
 *
 * A contact moves only its own two blobs, so contacts within different strips are independent, and so are
 * contacts across the strip boundaries s|s+1 and s+2|s+3. Order: (1) contacts across strips two or more
 * apart (a strip narrower than a pair's reach; rare), in vertex order; (2) contacts across neighbouring
 * strips s, s+1, even s in parallel, then odd s; (3) contacts within a strip, even strips in parallel, then
 * odd ones, each in blob order. The contacts within strips, nearly all of them, go last: with the boundary
 * contacts last instead, the deepest overlap in the settled pile tripled. Contacts across strips are looked
 * for only where the pairs say there are some (crossing, far). */
void bc_resolve_blob_contacts(const bcContext *ctx, int reverse, double h) {
    const Contacts cs = contacts_of(ctx, h);
    const bcScratch *w = ctx->w;
    const int64_t n = cs.n, blob_count = ctx->m->blob_count, strips = w->strip_count, slots = w->resolve_slots;
    /* Each blob's contacts, read once here for the five phases: rows[0, CONTACTS_PER_VERTEX o + i],
     * i < row_count[a], the slot r = CONTACTS_PER_VERTEX (p - o) + c of a's i-th contact, in vertex order, and
     * rows[1, ...] the strip of the blob it touches (a contact follows the other blob's ring, never to another
     * blob: both hold for the whole stage). */
    int64_t *rows = w->resolve_rows, *row_count = w->resolve_row_count;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < blob_count; a++), {
        int64_t o = cs.offsets[a], e = cs.offsets[a + 1];
        int64_t i = CPV * o;
        for (int64_t p = o; p < e; p++) {
            for (int64_t c = 0; c < CPV; c++) {
                int64_t edge = cs.c_edge[c * n + p];
                if (edge >= 0) {
                    rows[i] = CPV * (p - o) + c;
                    rows[CPV * n + i] = w->strip_of[cs.blob_of[edge]];
                    i++;
                }
            }
        }
        row_count[a] = i - CPV * o;
    });
    /* phase 0 is (1), phases 1-4 are (2) then (3), each even s then odd s: s|s+1 (shift 1), then s|s (shift 0) */
    for (int64_t phase = 0; phase < 5; phase++) {
        int64_t shift = 1 - floor_div(phase - 1, 2), parity = floor_mod(phase - 1, 2);
        int64_t tasks = phase == 0 ? (w->far ? 1 : 0) : (strips - parity + 1 - shift) / 2;
        /* (phase 0 has one task: that order is sequential) */
        BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t q = 0; q < tasks; q++), {
            int64_t s = parity + 2 * q;
            resolve_between(&cs, w, phase == 0, s, s + shift, reverse != 0, w->resolve_push + q * slots * BC_PUSH_ROW,
                            w->resolve_listed + q * slots);
        });
    }
}
