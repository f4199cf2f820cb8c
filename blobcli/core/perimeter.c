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
#include "vector_loops.h"

#define TOTAL_STEP 0.4 /* the total-length step moves no vertex more than this × a mean rest edge */
#define SWEEPS 2 /* Jacobi passes per iteration: a Jacobi pass converges about half as fast as a Gauss-Seidel one */

/* Δλ n of one XPBD step of C = |e| - rest for the edge e = x_j - x_i = (dx, dy) (see above), with its multiplier
 * *lam (updated) and inv_weight = 1 / (w_i + w_j + α̃). Out: (gx, gy). An edge of length 0 has no direction: it
 * moves nothing and keeps its λ; as arithmetic, not a branch, so that a loop of edges has none and runs on vector
 * registers (length + 0 and Δλ × 1 are length and Δλ to the bit). */
static inline void edge_step(double dx, double dy, double rest, double *lam, double alpha, double inv_weight,
                             double *gx, double *gy) {
    double length = sqrt(dx * dx + dy * dy);
    double dlam = (-(length - rest) - alpha * *lam) * inv_weight;
    double degenerate = (double)(length == 0.0);
    double scale = dlam / (length + degenerate);
    *lam += dlam * (1.0 - degenerate);
    *gx = scale * dx;
    *gy = scale * dy;
}

/* edge_step for every edge i of the ring, e_i = x_{i+1} - x_i (the closing edge's from x_{n-1} to x_0), all from
 * the same positions; x, y: the ring's n coordinates, lam its edges' multipliers. Out: (gx[i], gy[i]). */
BC_VECTOR_LOOPS static void edge_steps(const double *restrict x, const double *restrict y, int64_t n,
                                       const double *restrict rest, double *restrict lam, double alpha,
                                       double inv_weight, double *restrict gx, double *restrict gy) {
    for (int64_t i = 0; i < n - 1; i++)
        edge_step(x[i + 1] - x[i], y[i + 1] - y[i], rest[i], lam + i, alpha, inv_weight, gx + i, gy + i);
    edge_step(x[0] - x[n - 1], y[0] - y[n - 1], rest[n - 1], lam + n - 1, alpha, inv_weight, gx + n - 1,
              gy + n - 1);
}

/* x_k += scale (g_{k-1} - g_k) for each vertex k of the ring, g_{-1} = g_{n-1}: vertex k ends edge k - 1 and starts
 * edge k */
BC_VECTOR_LOOPS static void move_by_edges(double *restrict x, double *restrict y, int64_t n, double scale,
                                          const double *restrict gx, const double *restrict gy) {
    x[0] += scale * (gx[n - 1] - gx[0]);
    y[0] += scale * (gy[n - 1] - gy[0]);
    for (int64_t k = 1; k < n; k++) {
        x[k] += scale * (gx[k - 1] - gx[k]);
        y[k] += scale * (gy[k - 1] - gy[k]);
    }
}

/* |e| and e / |e| (0 for e = 0), as arithmetic without a branch (l + 0 is l to the bit) */
static inline void unit_edge(double dx, double dy, double *length, double *unit_x, double *unit_y) {
    double l = sqrt(dx * dx + dy * dy);
    double inv = 1.0 / (l + (double)(l == 0.0));
    *length = l;
    *unit_x = dx * inv;
    *unit_y = dy * inv;
}

/* Each edge's length |e_i| and unit vector t_i = e_i / |e_i|, e_i = x_{i+1} - x_i, the closing edge's from x_{n-1}
 * to x_0; x, y: the ring's n coordinates. Every edge on its own: a vector loop. */
BC_VECTOR_LOOPS static void unit_edges(const double *restrict x, const double *restrict y, int64_t n,
                                       double *restrict length, double *restrict unit_x, double *restrict unit_y) {
    for (int64_t i = 0; i < n - 1; i++)
        unit_edge(x[i + 1] - x[i], y[i + 1] - y[i], length + i, unit_x + i, unit_y + i);
    unit_edge(x[0] - x[n - 1], y[0] - y[n - 1], length + n - 1, unit_x + n - 1, unit_y + n - 1);
}

/* One XPBD step of the ring's total length, C = Σ |e_k| - Σ L_k, with α̃ = n α / h² (the compliance of its n
 * edges in series) and multiplier lam[b]; x, y: the ring's n coordinates, w its vertices' inverse mass;
 * length, unit_x, unit_y: scratch for the |e_i| and t_i.
 *
 * A pass over the edges moves a correction one edge along the ring, so a ring of n vertices needs O(n)
 * iterations to resist a stretch spread over all of it: under its own weight a 128-vertex blob sagged to a flat
 * patch of a third of its perimeter (stretched 17 %) at 2 iterations. This one scalar constraint resists that
 * mode in one step, whatever n. ∇_i C = t_{i-1} - t_i (t_k the unit vector along edge k, from x_k to x_{k+1}):
 *     Δλ = (-C - α̃ λ) / (Σ w_i |∇_i C|² + α̃),   Δx_i = w_i Δλ ∇_i C.
 * Σ m_i Δx_i = Δλ Σ (t_{i-1} - t_i) = 0: momentum is unchanged; C is a sum over the ring, so it has no order
 * and keeps mirror symmetry. */
static inline void solve_total_length(double *x, double *y, int64_t n, double w, double rest, double alpha,
                                      double *lam, int64_t b, double *length, double *unit_x, double *unit_y) {
    unit_edges(x, y, n, length, unit_x, unit_y);
    double C = -rest;
    double weight = 0.0, steepest = 0.0; /* Σ w_i |∇_i C|², and the largest |∇_i C|² ... */
    for (int64_t i = 0; i < n; i++) {
        int64_t before = i > 0 ? i - 1 : n - 1;
        double gx = unit_x[before] - unit_x[i], gy = unit_y[before] - unit_y[i];
        C += length[i];
        double g2 = gx * gx + gy * gy;
        weight += w * g2;
        steepest = bc_max(steepest, g2);
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
    /* Δx_i = w Δλ (t_{i-1} - t_i) needs the t_i at the positions C was measured at: the t_i kept from the sum above
     * (recomputing them, a square root and a division per edge, cost 11% of this stage). */
    move_by_edges(x, y, n, w * dlam, unit_x, unit_y);
}

/* Ring b's edges' rest lengths (Jacobi sweeps), then its total length; scratch: (3, N) rows, ring b's in its own
 * columns. */
static void solve_ring(const bcModel *m, bcState *s, double *scratch, int64_t b, double h) {
    /* Jacobi: every edge's correction is computed from the same positions, and each vertex moves by the sum of
     * its two edges' (x_i -= w_i Δλ_i n_i, x_{i+1} += w_{i+1} Δλ_i n_i). The result does not depend on the order
     * of the edges, so a mirror-symmetric blob stays mirror-symmetric. Any sweep order leaks into the result: a
     * plain sweep i = 0..n-1 passes each correction on to the next edge and pumps material round the ring like
     * a tank tread; red-black (even edges, then odd) is not mirror-symmetric either (a mirror maps even edges to
     * odd), and with friction that small asymmetry made a blob dropped straight onto a floor roll 0.1 m aside.
     * A sweep computes every edge's correction (edge_steps), then moves the vertices (move_by_edges). Then the
     * ring's total length, as one constraint (see solve_total_length). */
    const int64_t N = m->vertex_count;
    int64_t o = m->offsets[b], n = m->offsets[b + 1] - o;
    double *x = s->position + o, *y = s->position + N + o, *ring_lam = s->lam + o;
    const double *rest = m->rest_length + o;
    double w = m->inv_mass[o]; /* vertex masses are equal within a blob */
    double alpha = m->compliance[b] / (h * h);
    double inv_weight = 1.0 / (w + w + alpha);
    double *gx = scratch + o, *gy = scratch + N + o; /* each edge's Δλ n */
    for (int sweep = 0; sweep < SWEEPS; sweep++) {
        edge_steps(x, y, n, rest, ring_lam, alpha, inv_weight, gx, gy);
        move_by_edges(x, y, n, w, gx, gy); /* x_i -= w Δλ_i n_i, x_{i+1} += w Δλ_i n_i */
    }
    solve_total_length(x, y, n, w, m->rest_perimeter[b], m->compliance[b] * (double)n / (h * h), s->perimeter_lam,
                       b, scratch + 2 * N + o, scratch + o, scratch + N + o);
}

/* The edges' rest lengths, then each ring's total length (solve_ring). */
void bc_solve_perimeter(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    double *scratch = ctx->w->perimeter_scratch;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (s->awake[b]) solve_ring(m, s, scratch, b, h);
    });
}
