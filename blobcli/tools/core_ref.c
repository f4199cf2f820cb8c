/* The core substep as a plain C loop: the reference `blobsim bench` compares the numba step with.
 *
 * The same work and the same arithmetic, in the same order, as blobsim's stages for blobs on a
 * floor plane y = 0 (damping off, no blob contacts): predict, then `iters` times (perimeter
 * red-black XPBD, exact area projection `kot`, floor with static friction), then the velocity
 * update with kinetic friction. Built with -ffp-contract=off (no fused multiply-adds, as numba
 * without fastmath), so its positions equal the numba step's bit for bit; bench checks that.
 * Layout as blobsim's arrays: pos, prev, vel are (2, N), structure of arrays (x row, then y row).
 */
#include <math.h>

static void solve_distance(double *x, double *y, const double *w, long i, long j, double rest, double *lam, long k,
                           double alpha) {
    double dx = x[j] - x[i], dy = y[j] - y[i];
    double length = sqrt(dx * dx + dy * dy);
    if (length == 0.0) return;
    double C = length - rest;
    double dlam = (-C - alpha * lam[k]) / (w[i] + w[j] + alpha);
    lam[k] += dlam;
    double nx = dx / length, ny = dy / length;
    x[i] -= w[i] * dlam * nx;
    y[i] -= w[i] * dlam * ny;
    x[j] += w[j] * dlam * nx;
    y[j] += w[j] * dlam * ny;
}

static void area_kot(double *x, double *y, const double *w, long o, long e, double target) {
    long n = e - o;
    double xl = x[e - 1], yl = y[e - 1];
    double x1 = x[o + 1], y1 = y[o + 1];
    double px = 0.5 * w[o] * (y1 - yl), py = 0.5 * w[o] * (xl - x1);
    double a = 0.0, b = 0.0, c = 0.0;
    long j = o + 1, jj = o + 2; /* i + 1 and i + 2 around the ring (n >= 3), wrapped without a division */
    for (long k = 0; k < n; k++) {
        long i = o + k;
        double xi = x[i], yi = y[i], xj = x[j], yj = y[j];
        double qx = 0.5 * w[j] * (y[jj] - yi), qy = 0.5 * w[j] * (xi - x[jj]);
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
    double xlast = x[e - 1], ylast = y[e - 1], x0 = x[o], y0 = y[o];
    for (long k = 0; k < n; k++) {
        long i = o + k;
        double xn, yn;
        if (k + 1 < n) {
            xn = x[i + 1];
            yn = y[i + 1];
        } else {
            xn = x0;
            yn = y0;
        }
        double sx = x[i], sy = y[i];
        x[i] = sx + h * 0.5 * w[i] * (yn - ylast);
        y[i] = sy + h * 0.5 * w[i] * (xlast - xn);
        xlast = sx;
        ylast = sy;
    }
}

void core_steps(long steps, long substeps, long iters, double dt, double gx, double gy, long blobs,
                const long *off, double *pos, double *prev, double *vel, const double *w, const double *rest,
                const double *compliance, double *lam, const double *target, double *depth, double mu_s,
                double mu_k) {
    long n = off[blobs];
    double *x = pos, *y = pos + n, *x0 = prev, *y0 = prev + n, *vx = vel, *vy = vel + n;
    double h = dt / (double)substeps;
    for (long s = 0; s < steps * substeps; s++) {
        for (long i = 0; i < n; i++) { /* predict */
            x0[i] = x[i];
            y0[i] = y[i];
            vx[i] += gx * h;
            vy[i] += gy * h;
            x[i] += vx[i] * h;
            y[i] += vy[i] * h;
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
                        solve_distance(x, y, w, i, i + 1 < e ? i + 1 : o, rest[i], lam, i, alpha);
                    }
                if (m % 2 == 1) solve_distance(x, y, w, e - 1, o, rest[e - 1], lam, e - 1, alpha);
            }
            for (long b = 0; b < blobs; b++) area_kot(x, y, w, off[b], off[b + 1], target[b]);
            for (long i = 0; i < n; i++) { /* the floor y = 0, normal (0, 1), with static friction */
                double d = y[i];
                if (d < 0.0) {
                    depth[i] += -d;
                    double px = x[i] - d * 0.0, py = y[i] - d * 1.0;
                    double dx = px - x0[i], dy = py - y0[i];
                    double dn = dx * 0.0 + dy * 1.0;
                    double tx = dx - dn * 0.0, ty = dy - dn * 1.0;
                    if (tx * tx + ty * ty <= (mu_s * depth[i]) * (mu_s * depth[i])) {
                        px -= tx;
                        py -= ty;
                    }
                    x[i] = px;
                    y[i] = py;
                }
            }
        }
        double inv_h = 1.0 / h;
        for (long i = 0; i < n; i++) { /* velocities, kinetic friction */
            vx[i] = (x[i] - x0[i]) * inv_h;
            vy[i] = (y[i] - y0[i]) * inv_h;
            double D = depth[i];
            if (D == 0.0) continue;
            double vn = vx[i] * 0.0 + vy[i] * 1.0;
            double vtx = vx[i] - vn * 0.0, vty = vy[i] - vn * 1.0;
            double vt = sqrt(vtx * vtx + vty * vty);
            if (vt > 0.0) {
                double f = fmax(vt - mu_k * D * inv_h, 0.0) / vt;
                vtx *= f;
                vty *= f;
            }
            vn = fmax(vn, 0.0);
            vx[i] = vtx + vn * 0.0;
            vy[i] = vty + vn * 1.0;
        }
    }
}
