/* Perimeter stage: every edge keeps its rest length, with XPBD compliance.
 *
 * For edge (i, j): C = |x_j - x_i| - L, ∇_j C = n = (x_j - x_i)/|x_j - x_i|, ∇_i C = -n.
 * XPBD (Macklin et al. 2016) with α̃ = α / h²:
 *     Δλ = (-C - α̃ λ) / (w_i + w_j + α̃),   x_i -= w_i Δλ n,   x_j += w_j Δλ n.
 * The two corrections are equal and opposite in momentum (m_i w_i = m_j w_j = 1), so this stage never moves a
 * blob's centre of mass. α = 0 makes the edge inextensible.
 */
#include <math.h>

#include "parallel.h"
#include "perimeter.h"
#include "ring.h"
#include "scratch.h"

#define TOTAL_STEP 0.4 /* the total-length step moves no vertex more than this × a mean rest edge */
#define SWEEPS 2 /* Jacobi passes per iteration: a Jacobi pass converges about half as fast as a Gauss-Seidel one */

/* Δλ n of one XPBD step of C = |x_j - x_i| - rest (see above), with multiplier lam[i] and
 * inv_weight = 1 / (w_i + w_j + α̃); x, y: the ring's coordinates. Out: (gx, gy) */
static inline void edge_step(const double *x, const double *y, int64_t i, int64_t j, double rest, double *lam,
                             double alpha, double inv_weight, double *gx, double *gy) {
    double dx = x[j] - x[i], dy = y[j] - y[i];
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) {
        *gx = 0.0;
        *gy = 0.0;
        return;
    }
    double dlam = (-(length - rest) - alpha * lam[i]) * inv_weight;
    lam[i] += dlam;
    double scale = dlam / length;
    *gx = scale * dx;
    *gy = scale * dy;
}

/* (d / |d|, |d|); (0, 0, 0) for d = 0 */
static inline double unit(double dx, double dy, double *ux, double *uy) {
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) {
        *ux = 0.0;
        *uy = 0.0;
        return 0.0;
    }
    double inv = 1.0 / length;
    *ux = dx * inv;
    *uy = dy * inv;
    return length;
}

/* One XPBD step of the ring's total length, C = Σ |e_k| - Σ L_k, with α̃ = n α / h² (the compliance of its n
 * edges in series) and multiplier lam[b]; x, y: the ring's n coordinates, w its vertices' inverse mass;
 * unit_x, unit_y: scratch for the t_i.
 *
 * A pass over the edges moves a correction one edge along the ring, so a ring of n vertices needs O(n)
 * iterations to resist a stretch spread over all of it: under its own weight a 128-vertex blob sagged to a flat
 * patch of a third of its perimeter (stretched 17 %) at 2 iterations. This one scalar constraint resists that
 * mode in one step, whatever n. ∇_i C = t_{i-1} - t_i (t_k the unit vector along edge k, from x_k to x_{k+1}):
 *     Δλ = (-C - α̃ λ) / (Σ w_i |∇_i C|² + α̃),   Δx_i = w_i Δλ ∇_i C.
 * Σ m_i Δx_i = Δλ Σ (t_{i-1} - t_i) = 0: momentum is unchanged; C is a sum over the ring, so it has no order
 * and keeps mirror symmetry. */
static inline void solve_total_length(double *x, double *y, int64_t n, double w, double rest, double alpha,
                                      double *lam, int64_t b, double *unit_x, double *unit_y) {
    double C = -rest;
    double weight = 0.0, steepest = 0.0; /* Σ w_i |∇_i C|², and the largest |∇_i C|² ... */
    double tx0, ty0;
    unit(x[0] - x[n - 1], y[0] - y[n - 1], &tx0, &ty0);
    double tx = tx0, ty = ty0; /* t_{i-1} */
    for (int64_t i = 0; i < n; i++) {
        int64_t j = i + 1 < n ? i + 1 : 0;
        double ux, uy;
        double length = unit(x[j] - x[i], y[j] - y[i], &ux, &uy);
        unit_x[i] = ux;
        unit_y[i] = uy;
        C += length;
        double g2 = (tx - ux) * (tx - ux) + (ty - uy) * (ty - uy);
        weight += w * g2;
        steepest = bc_max(steepest, g2);
        tx = ux;
        ty = uy;
    }
    /* ... whose root, times w, is the largest w |∇_i C|: √ and the product by w never decrease, so the largest
     * of the products is the product of the largest, to the bit (one root, not n) */
    steepest = w * sqrt(steepest);
    if (weight + alpha == 0.0) return;
    double dlam = (-C - alpha * lam[b]) / (weight + alpha);
    /* C is far from linear where the ring turns sharply (∇C concentrates there): a full step overshot and blew
     * up an over-pressured blob (pressure 2) landing on a floor. So no vertex moves more than TOTAL_STEP of a
     * mean rest edge per step (a trust region). Its size trades two things: too small and a long ring sags (a
     * hard 128-vertex blob rolled at 0.893 of a ring's acceleration with 0.2, 0.909 with 0.4) and a squashed
     * blob re-rounds slowly; too large and the over-pressured blob rings (kinetic energy still 4 mJ after 4 s
     * with 0.5, 1 J peaks with 1.0; at rest and asleep by 1.5 s with 0.4). */
    double most = TOTAL_STEP * rest / (double)n;
    if (fabs(dlam) * steepest > most) dlam = copysign(most / steepest, dlam);
    lam[b] += dlam;
    /* Δx_i needs t_{i-1} and t_i at the positions C was measured at: the t_i kept from the sum above
     * (recomputing them, a square root and a division per edge, cost 11% of this stage). */
    tx = tx0;
    ty = ty0;
    for (int64_t i = 0; i < n; i++) {
        double ux = unit_x[i], uy = unit_y[i];
        x[i] += w * dlam * (tx - ux);
        y[i] += w * dlam * (ty - uy);
        tx = ux;
        ty = uy;
    }
}

/* The edges' rest lengths (Jacobi sweeps), then each ring's total length. */
void bc_solve_perimeter(const bcContext *ctx, double h) {
    /* Jacobi: every edge's correction is computed from the same positions, and each vertex moves by the sum of
     * its two edges' (x_i -= w_i Δλ_i n_i, x_{i+1} += w_{i+1} Δλ_i n_i). The result does not depend on the order
     * of the edges, so a mirror-symmetric blob stays mirror-symmetric. Any sweep order leaks into the result: a
     * plain sweep i = 0..n-1 passes each correction on to the next edge and pumps material round the ring like
     * a tank tread; red-black (even edges, then odd) is not mirror-symmetric either (a mirror maps even edges to
     * odd), and with friction that small asymmetry made a blob dropped straight onto a floor roll 0.1 m aside.
     * One pass round the ring: edge i's correction is computed before vertex i moves, and the closing edge's
     * first, before vertex o does. Then the ring's total length, as one constraint (see solve_total_length). */
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    double *unit_rows = ctx->w->perimeter_unit; /* (2, N): its unit edge vectors t_i, each blob in its own columns */
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        int64_t n = e - o;
        double *x = s->position + o, *y = s->position + N + o, *ring_lam = s->lam + o;
        const double *rest = m->rest_length + o;
        double w = m->inv_mass[o]; /* vertex masses are equal within a blob */
        double alpha = m->compliance[b] / (h * h);
        double inv_weight = 1.0 / (w + w + alpha);
        for (int sweep = 0; sweep < SWEEPS; sweep++) {
            double last_x, last_y;
            edge_step(x, y, n - 1, 0, rest[n - 1], ring_lam, alpha, inv_weight, &last_x, &last_y);
            double before_x = last_x, before_y = last_y; /* the correction of the edge ending at vertex k */
            for (int64_t k = 0; k < n; k++) {
                double gx, gy;
                if (k < n - 1) {
                    edge_step(x, y, k, k + 1, rest[k], ring_lam, alpha, inv_weight, &gx, &gy);
                } else {
                    gx = last_x;
                    gy = last_y;
                }
                x[k] += w * (before_x - gx);
                y[k] += w * (before_y - gy);
                before_x = gx;
                before_y = gy;
            }
        }
        solve_total_length(x, y, n, w, m->rest_perimeter[b], m->compliance[b] * (double)n / (h * h),
                           s->perimeter_lam, b, unit_rows + o, unit_rows + N + o);
    });
}
