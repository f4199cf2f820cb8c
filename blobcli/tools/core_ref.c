/* The core substep as a plain C loop: the reference `blobsim bench` compares the numba step with.
 *
 * The same work and the same arithmetic, in the same order, as blobsim's stages for blobs on a
 * floor plane y = 0 (damping off, no blob contacts): predict, then `iters` times (perimeter
 * red-black XPBD, exact area projection `kot`, floor with static friction), then the velocity
 * update with kinetic friction. Built with -ffp-contract=off (no fused multiply-adds, as numba
 * without fastmath), so its positions equal the numba step's bit for bit; bench checks that.
 * Layout as blobsim's arrays: pos, prev, vel are (N, 2) row-major.
 */
#include <math.h>

static void solve_distance(double *pos, const double *w, long i, long j, double rest, double *lam, long k,
                           double alpha) {
    double dx = pos[2 * j] - pos[2 * i], dy = pos[2 * j + 1] - pos[2 * i + 1];
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) return;
    double C = length - rest;
    double dlam = (-C - alpha * lam[k]) / (w[i] + w[j] + alpha);
    lam[k] += dlam;
    double nx = dx / length, ny = dy / length;
    pos[2 * i] -= w[i] * dlam * nx;
    pos[2 * i + 1] -= w[i] * dlam * ny;
    pos[2 * j] += w[j] * dlam * nx;
    pos[2 * j + 1] += w[j] * dlam * ny;
}

static void area_kot(double *pos, const double *w, long o, long e, double target) {
    long n = e - o;
    double xl = pos[2 * (e - 1)], yl = pos[2 * (e - 1) + 1];
    double x1 = pos[2 * (o + 1)], y1 = pos[2 * (o + 1) + 1];
    double px = 0.5 * w[o] * (y1 - yl), py = 0.5 * w[o] * (xl - x1);
    double a = 0.0, b = 0.0, c = 0.0;
    long j = o + 1, jj = o + 2; /* i + 1 and i + 2 around the ring (n >= 3), wrapped without a division */
    for (long k = 0; k < n; k++) {
        long i = o + k;
        double xi = pos[2 * i], yi = pos[2 * i + 1], xj = pos[2 * j], yj = pos[2 * j + 1];
        double qx = 0.5 * w[j] * (pos[2 * jj + 1] - yi), qy = 0.5 * w[j] * (xi - pos[2 * jj]);
        a += px * qy - py * qx;
        b += (xi * qy - yi * qx) + (px * yj - py * xj);
        c += xi * yj - yi * xj;
        px = qx;
        py = qy;
        j = j + 1 < e ? j + 1 : o;
        jj = jj + 1 < e ? jj + 1 : o;
    }
    c -= 2.0 * target;
    double disc = b * b - 4.0 * a * c, h;
    if (disc < 0.0) {
        h = -b / (2.0 * a);
    } else {
        double q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));
        h = q != 0.0 ? c / q : 0.0;
    }
    double xlast = pos[2 * (e - 1)], ylast = pos[2 * (e - 1) + 1], x0 = pos[2 * o], y0 = pos[2 * o + 1];
    for (long k = 0; k < n; k++) {
        long i = o + k;
        double xn, yn;
        if (k + 1 < n) {
            xn = pos[2 * (i + 1)];
            yn = pos[2 * (i + 1) + 1];
        } else {
            xn = x0;
            yn = y0;
        }
        double sx = pos[2 * i], sy = pos[2 * i + 1];
        pos[2 * i] = sx + h * 0.5 * w[i] * (yn - ylast);
        pos[2 * i + 1] = sy + h * 0.5 * w[i] * (xlast - xn);
        xlast = sx;
        ylast = sy;
    }
}

void core_steps(long steps, long substeps, long iters, double dt, double gx, double gy, long blobs,
                const long *off, double *pos, double *prev, double *vel, const double *w, const double *rest,
                const double *compliance, double *lam, const double *target, double *depth, double mu_s,
                double mu_k) {
    long n = off[blobs];
    double h = dt / (double)substeps;
    for (long s = 0; s < steps * substeps; s++) {
        for (long i = 0; i < n; i++) { /* predict */
            prev[2 * i] = pos[2 * i];
            prev[2 * i + 1] = pos[2 * i + 1];
            vel[2 * i] += gx * h;
            vel[2 * i + 1] += gy * h;
            pos[2 * i] += vel[2 * i] * h;
            pos[2 * i + 1] += vel[2 * i + 1] * h;
            lam[i] = 0.0;
            depth[i] = 0.0;
        }
        for (long it = 0; it < iters; it++) {
            for (long b = 0; b < blobs; b++) { /* perimeter, red-black */
                long o = off[b], e = off[b + 1], m = e - o;
                double alpha = compliance[b] / (h * h);
                long paired = m - (m % 2);
                for (long start = 0; start < 2; start++)
                    for (long k = start; k < paired; k += 2) {
                        long i = o + k;
                        solve_distance(pos, w, i, i + 1 < e ? i + 1 : o, rest[i], lam, i, alpha);
                    }
                if (m % 2 == 1) solve_distance(pos, w, e - 1, o, rest[e - 1], lam, e - 1, alpha);
            }
            for (long b = 0; b < blobs; b++) area_kot(pos, w, off[b], off[b + 1], target[b]);
            for (long i = 0; i < n; i++) { /* the floor y = 0, normal (0, 1), with static friction */
                double d = pos[2 * i + 1];
                if (d < 0.0) {
                    depth[i] += -d;
                    double x = pos[2 * i] - d * 0.0, y = pos[2 * i + 1] - d * 1.0;
                    double dx = x - prev[2 * i], dy = y - prev[2 * i + 1];
                    double dn = dx * 0.0 + dy * 1.0;
                    double tx = dx - dn * 0.0, ty = dy - dn * 1.0;
                    if (tx * tx + ty * ty <= (mu_s * depth[i]) * (mu_s * depth[i])) {
                        x -= tx;
                        y -= ty;
                    }
                    pos[2 * i] = x;
                    pos[2 * i + 1] = y;
                }
            }
        }
        double inv_h = 1.0 / h;
        for (long i = 0; i < n; i++) { /* velocities, kinetic friction */
            vel[2 * i] = (pos[2 * i] - prev[2 * i]) * inv_h;
            vel[2 * i + 1] = (pos[2 * i + 1] - prev[2 * i + 1]) * inv_h;
            double D = depth[i];
            if (D == 0.0) continue;
            double vn = vel[2 * i] * 0.0 + vel[2 * i + 1] * 1.0;
            double vtx = vel[2 * i] - vn * 0.0, vty = vel[2 * i + 1] - vn * 1.0;
            double vt = sqrt(vtx * vtx + vty * vty);
            if (vt > 0.0) {
                double f = fmax(vt - mu_k * D * inv_h, 0.0) / vt;
                vtx *= f;
                vty *= f;
            }
            vn = fmax(vn, 0.0);
            vel[2 * i] = vtx + vn * 0.0;
            vel[2 * i + 1] = vty + vn * 1.0;
        }
    }
}
