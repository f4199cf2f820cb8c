/* The XPBD distance constraint the perimeter's edges and the spring blobs' springs share (perimeter.py's
 * solve_distance), over the structure-of-arrays positions (x = p[i], y = p[n + i], n the vertex count).
 *
 * For edge (i, j): C = |x_j - x_i| - L, ∇_j C = n = (x_j - x_i)/|x_j - x_i|, ∇_i C = -n.
 * XPBD (Macklin et al. 2016) with α̃ = α / h²:
 *     Δλ = (-C - α̃ λ) / (w_i + w_j + α̃),   x_i -= w_i Δλ n,   x_j += w_j Δλ n.
 * The two corrections are equal and opposite in momentum (m_i w_i = m_j w_j = 1), so the constraint never
 * moves a blob's centre of mass. α = 0 makes the edge inextensible. */
#ifndef BC_CONSTRAINTS_H
#define BC_CONSTRAINTS_H

#include <math.h>
#include <stdint.h>

/* One XPBD step of C = |x_j - x_i| - rest, with multiplier lam[k] and α̃ = alpha (see above) */
static inline void bc_solve_distance(double *p, int64_t n, const double *inv_mass, int64_t i, int64_t j,
                                     double rest, double *lam, int64_t k, double alpha) {
    double dx = p[j] - p[i], dy = p[n + j] - p[n + i];
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) return;
    double C = length - rest;
    double dlam = (-C - alpha * lam[k]) / (inv_mass[i] + inv_mass[j] + alpha);
    lam[k] += dlam;
    double nx = dx / length, ny = dy / length;
    p[i] -= inv_mass[i] * dlam * nx;
    p[n + i] -= inv_mass[i] * dlam * ny;
    p[j] += inv_mass[j] * dlam * nx;
    p[n + j] += inv_mass[j] * dlam * ny;
}

#endif
