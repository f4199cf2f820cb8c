/* Area stages: how a blob keeps its volume, picked by the scene's `method` (bcSettings.method: kot 0, xpbd 1,
 * gas 2, springs 3); each reads its own model arrays, and the step (step.c) calls the one a scene names.
 *
 *     kot      exact projection onto the target area (the default; below)
 *     xpbd     the area as one compliant XPBD constraint per blob, solved iteratively
 *     gas      no target area: an ideal-gas pressure force P = P₀ A_target / A
 *     springs  no pressure at all: internal springs across the blob, the classic spring blob
 *
 * Method "kot" (Grant Kot, "Fast and Stable Blob Physics"): move every vertex along a direction p_i by the
 * same amount h, with h chosen so the area is exactly the target.
 *
 * Shoelace area, 2A = Σ x_i × x_{i+1} (2D cross product, > 0 counter-clockwise). With x_i -> x_i + h p_i it is
 * a quadratic in h:
 *     2A(h) = Σ x_i × x_{i+1} + h Σ (x_i × p_{i+1} + p_i × x_{i+1}) + h² Σ p_i × p_{i+1},
 * so 2A(h) = 2A₀ is  a h² + b h + c = 0  with
 *     a = Σ p_i × p_{i+1},  b = Σ (x_i × p_{i+1} + p_i × x_{i+1}),  c = Σ x_i × x_{i+1} - 2A₀.
 *
 * Direction. p_i = w_i ∇_i A, the inverse-mass weighted area gradient, ∇_i A = ½ (y_{i+1} - y_{i-1},
 * x_{i-1} - x_{i+1}). It is the outward normal scaled by half the neighbouring edge lengths, so:
 *   - Σ m_i Δx_i = h Σ ∇_i A = 0: a closed polygon's gradients sum to zero, so the area stage never moves the
 *     centre of mass (unit normals do not sum to zero, and would let a deformed blob propel itself);
 *   - it is the steepest direction for A, the same one XPBD's area constraint uses;
 *   - its sign follows the winding, so clockwise blobs (A₀ < 0) need no special case.
 *
 * Root. The root of least |h| (the smallest move), in a form that never cancels:
 *     q = -(b + sign(b) √(b² - 4ac)) / 2,   h = c / q.
 * (The roots are q/a and c/q; |q| >= √|ac| makes c/q the smaller.) It is also right when a ≈ 0, where it
 * gives h = -c/b. If b² - 4ac < 0 no h reaches A₀; then h = -b / 2a, the vertex of the parabola, moves the
 * blob to the nearest area it can reach.
 */
#include <math.h>

#include "area.h"
#include "constraints.h"
#include "parallel.h"
#include "ring.h"

/* x_i += scale w_i ∇_i A for ring o..e (positions p, n the vertex count), with ∇_i from the positions before
 * the move */
static inline void gradient_step(double *p, int64_t n, const double *inv_mass, int64_t o, int64_t e,
                                 double scale) {
    int64_t count = e - o; /* the ring's vertices (the Python's n) */
    double *x = p + o, *y = p + n + o;
    const double *w = inv_mass + o;
    double xl = x[count - 1], yl = y[count - 1];
    double x0 = x[0], y0 = y[0];
    for (int64_t k = 0; k < count; k++) {
        double xn, yn;
        if (k + 1 < count) {
            xn = x[k + 1];
            yn = y[k + 1];
        } else {
            xn = x0;
            yn = y0;
        }
        double sx = x[k], sy = y[k];
        x[k] = sx + scale * 0.5 * w[k] * (yn - yl);
        y[k] = sy + scale * 0.5 * w[k] * (xl - xn);
        xl = sx;
        yl = sy;
    }
}

/* Ring o..e moved along x_i += h w_i ∇_i A to the area `target` (see the top of this file); n is the vertex
 * count N of the (2, N) positions */
void bc_project_area(double *position, int64_t n, const double *inv_mass, int64_t o, int64_t e, double target) {
    int64_t count = e - o; /* the ring's vertices (the Python's n) */
    const double *x = position + o, *y = position + n + o, *w = inv_mass + o;
    /* Pass 1: a, b, c, carrying p_i from one edge to the next. */
    double xl = x[count - 1], yl = y[count - 1]; /* x_{i-1} */
    double x1 = x[1], y1 = y[1];
    double px = 0.5 * w[0] * (y1 - yl);
    double py = 0.5 * w[0] * (xl - x1);
    double a = 0.0, b = 0.0, c = 0.0;
    for (int64_t i = 0; i < count; i++) {
        int64_t j = i + 1 < count ? i + 1 : i + 1 - count; /* (i + 1) % n, without dividing */
        int64_t jj = i + 2 < count ? i + 2 : i + 2 - count;
        double xi = x[i], yi = y[i];
        double xj = x[j], yj = y[j];
        double qx = 0.5 * w[j] * (y[jj] - yi); /* p_{i+1} */
        double qy = 0.5 * w[j] * (xi - x[jj]);
        a += px * qy - py * qx;
        b += (xi * qy - yi * qx) + (px * yj - py * xj);
        c += xi * yj - yi * xj;
        px = qx;
        py = qy;
    }
    c -= 2.0 * target;
    double disc = b * b - 4.0 * a * c;
    double h;
    if (disc < 0.0) {
        h = -b / (2.0 * a);
    } else {
        /* √(b² - 4ac) as numba compiles disc ** 0.5: LLVM makes pow(x, 0.5) fabs(sqrt(x)) (x = -∞ is the
         * other branch), the correctly rounded root, where libm's pow may be off by an ulp */
        double root = fabs(sqrt(disc));
        double q = -0.5 * (b + (b >= 0.0 ? root : -root));
        h = q != 0.0 ? c / q : 0.0;
    }
    /* Pass 2: x_i += h p_i = h w_i ∇_i A. */
    gradient_step(position, n, inv_mass, o, e, h);
}

/* Exact area projection (see the top of this file). */
void bc_area_kot(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t blob = 0; blob < m->blob_count; blob++), {
        if (!s->awake[blob]) continue;
        bc_project_area(s->position, N, m->inv_mass, m->offsets[blob], m->offsets[blob + 1], m->target_area[blob]);
    });
}

/* (A, Σ w_i |∇_i A|²) of ring o..e */
static inline void area_and_gradient_norm(const double *p, int64_t n, const double *inv_mass, int64_t o, int64_t e,
                                          double *area, double *norm) {
    double sum = 0.0;
    for (int64_t i = o; i < e; i++) {
        int64_t j = bc_next_in_ring(i, o, e);
        int64_t l = bc_prev_in_ring(i, o, e);
        double gx = 0.5 * (p[n + j] - p[n + l]), gy = 0.5 * (p[l] - p[j]);
        sum += inv_mass[i] * (gx * gx + gy * gy);
    }
    *area = 0.5 * bc_twice_ring_area(p, n, o, e);
    *norm = sum;
}

/* The area as a compliant XPBD constraint, one linearized step per iteration. */
void bc_area_xpbd(const bcContext *ctx, double h) {
    /* XPBD (Macklin et al. 2016) for C = A - A₀ with ∇_i C = ∇_i A:
     *   Δλ = (-C - α̃ λ) / (Σ w_i |∇_i A|² + α̃),  x_i += w_i ∇_i A Δλ,  α̃ = α / h².
     * One linearized step per call: the area converges over the iterations, not exactly. */
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double area, norm;
        area_and_gradient_norm(s->position, N, m->inv_mass, o, e, &area, &norm);
        double alpha = m->area_compliance[b] / (h * h);
        if (norm + alpha == 0.0) continue;
        double dlam = (-(area - m->target_area[b]) - alpha * s->area_lam[b]) / (norm + alpha);
        s->area_lam[b] += dlam;
        gradient_step(s->position, N, m->inv_mass, o, e, dlam);
    });
}

/* Ideal-gas pressure force; the area settles where the skin's tension balances it. */
void bc_area_gas(const bcContext *ctx, double scale) {
    /* Ideal gas (Matyka 2004): P = nRT / A, here P = P₀ A₀ / A. The pressure on an edge is P |e| along its
     * outward normal, half to each end; summed at vertex i that is exactly P ∇_i A. Applied as a force over the
     * substep, x_i += h² w_i f_i (here split over the iterations: `scale` = h² / iterations), which symplectic
     * Euler would also give. The area is the true shoelace area. */
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double area, norm;
        area_and_gradient_norm(s->position, N, m->inv_mass, o, e, &area, &norm);
        (void)norm;
        if (area * m->target_area[b] <= 0.0) continue; /* turned inside out: no meaningful pressure */
        double pressure = m->gas_pressure[b] * m->target_area[b] / area;
        gradient_step(s->position, N, m->inv_mass, o, e, scale * pressure);
    });
}

/* No pressure: internal springs hold the shape (and can let it invert). */
void bc_area_springs(const bcContext *ctx, double h) {
    /* XPBD distance constraints, like the perimeter's, across the blob: each vertex to the opposite one and to
     * its neighbours' neighbours (Gish's and JellyCar's spring bodies). Serial: springs of one blob share
     * vertices, and each sees the moves of those before it. */
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    for (int64_t k = 0; k < m->spring_count; k++) {
        int64_t i = m->spring_pairs[2 * k], j = m->spring_pairs[2 * k + 1];
        int64_t b = m->blob_of[i];
        if (!s->awake[b]) continue;
        bc_solve_distance(s->position, N, m->inv_mass, i, j, m->spring_rest[k], s->spring_lam, k,
                          m->spring_compliance[b] / (h * h));
    }
}
