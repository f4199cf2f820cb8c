/* Driving forces and torques on blobs (bcModel.driving: the scene's `force` and `torque`, or a schedule's): the one
 * home of how they are shared over a blob's vertices (bc_predict adds them to gravity) and of the work they do (the
 * restitution rule counts it, so that a driven blob may leave a contact faster than it came: a jump). */
#ifndef BC_DRIVING_H
#define BC_DRIVING_H

#include <stdbool.h>
#include <stdint.h>

#include "blobcore.h"

/* Blob b's driving force F and torque τ as accelerations, with the positions `pos` (the substep's start):
 * vertex i of mass m_i feels f_i = F m_i / M + τ m_i (ẑ × r_i) / I, with M = Σ m_i, r_i = x_i − x_cm and
 * I = Σ m_i |r_i|²; so a_i = f_i / m_i = F / M + (τ / I) ẑ × r_i. The force is shared by mass (Σ f_i = F, every
 * vertex accelerated alike by F / M). The torque's part moves no momentum and has exactly τ of moment about the
 * centre of mass, since Σ m_i r_i = 0 there and, in 2D, r × (ẑ × r) = |r|² ẑ:
 *     Σ f_i = (τ / I) ẑ × Σ m_i r_i = 0,      Σ r_i × f_i = (τ / I) Σ m_i |r_i|² = τ
 * (its moment about any other point p differs by (x_cm − p) × Σ f_i = 0). Over a substep of h the blob's momentum
 * gains F h and its angular momentum about the centre τ h; the constraints after it are internal and change
 * neither. For a rigid ring this is the angular acceleration τ / I; a soft one shares it with its deformation.
 * Out: (F_x / M, F_y / M, τ / I, x_cm, y_cm, M). A blob not driven (F = 0, τ = 0) returns false without a pass
 * over its vertices: gravity alone, to the bit, as before the driving keys. */
static inline bool bc_driving_of(const bcModel *m, const double *pos, int64_t b, double out[6]) {
    const double *drive = m->driving + 3 * b;
    if (drive[0] == 0.0 && drive[1] == 0.0 && drive[2] == 0.0) return false;
    const int64_t n = m->vertex_count, o = m->offsets[b], e = m->offsets[b + 1];
    const double *inv_mass = m->inv_mass;
    double M = 0.0, sx = 0.0, sy = 0.0;
    for (int64_t i = o; i < e; i++) {
        double m_i = 1.0 / inv_mass[i];
        M += m_i;
        sx += m_i * pos[i];
        sy += m_i * pos[n + i];
    }
    double cx = sx / M, cy = sy / M, I = 0.0;
    for (int64_t i = o; i < e; i++) {
        double rx = pos[i] - cx, ry = pos[n + i] - cy;
        I += (rx * rx + ry * ry) / inv_mass[i];
    }
    out[0] = drive[0] / M;
    out[1] = drive[1] / M;
    out[2] = I > 0.0 ? drive[2] / I : 0.0;
    out[3] = cx;
    out[4] = cy;
    out[5] = M;
    return true;
}

/* The work blob b's drive did over this substep, from `prev` (its start, where bc_predict took r_i) to `pos`:
 * W = Σ f_i · (x_i − x_prev,i) (J), and the displacement of its centre of mass Δc = Σ m_i Δx_i / M (m). Out:
 * (W, Δc_x, Δc_y, F_x, F_y, M). False for a blob not driven (no pass over its vertices). */
static inline bool bc_driving_work(const bcModel *m, const double *pos, const double *prev, int64_t b,
                                   double out[6]) {
    double a[6];
    if (!bc_driving_of(m, prev, b, a)) return false;
    const int64_t n = m->vertex_count, o = m->offsets[b], e = m->offsets[b + 1];
    double work = 0.0, dx = 0.0, dy = 0.0;
    for (int64_t i = o; i < e; i++) {
        double m_i = 1.0 / m->inv_mass[i];
        double ux = pos[i] - prev[i], uy = pos[n + i] - prev[n + i];
        /* f_i = m_i (F / M + (τ / I) ẑ × r_i), r_i = x_prev,i − c_prev */
        work += m_i * ((a[0] - a[2] * (prev[n + i] - a[4])) * ux + (a[1] + a[2] * (prev[i] - a[3])) * uy);
        dx += m_i * ux;
        dy += m_i * uy;
    }
    out[0] = work;
    out[1] = dx / a[5];
    out[2] = dy / a[5];
    out[3] = a[0] * a[5];
    out[4] = a[1] * a[5];
    out[5] = a[5];
    return true;
}

#endif
