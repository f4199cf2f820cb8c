/* The core substep as a plain C loop: the reference `blobsim bench` compares the numba step with.
 *
 * The same work and the same arithmetic, in the same order, as blobsim's stages for blobs on a
 * floor plane y = 0 (damping off, no blob contacts): predict (rigid rotation exact), then `iters`
 * times (perimeter: Jacobi XPBD passes and the total length, exact area projection `kot`, floor
 * with static friction), then the velocity update (rotation read as an angle) with kinetic
 * friction, and restitution. Built with -ffp-contract=off (no fused multiply-adds, as numba
 * without fastmath), so its positions equal the numba step's bit for bit; bench checks that.
 * Layout as blobsim's arrays: pos, prev, vel are (2, N), structure of arrays (x row, then y row).
 */
#include <math.h>

#define SWEEPS 2
#define TOTAL_STEP 0.4
#define NO_BOUNCE (-INFINITY)

/* Python's max(a, b) and min(a, b): the first argument unless the second is strictly beyond it */
static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }

static void edge_step(const double *x, const double *y, long i, long j, double rest, double *lam, double alpha,
                      double inv_weight, double *gx, double *gy) {
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

static double unit(double dx, double dy, double *ux, double *uy) {
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

static void perimeter(double *x, double *y, const double *w, long o, long e, const double *rest, double rest_total,
                      double compliance, double *lam, double *total_lam, double h) {
    double alpha = compliance / (h * h);
    double inv_weight = 1.0 / (w[o] + w[o] + alpha);
    for (long sweep = 0; sweep < SWEEPS; sweep++) {
        double last_x, last_y, gx, gy;
        edge_step(x, y, e - 1, o, rest[e - 1], lam, alpha, inv_weight, &last_x, &last_y);
        double before_x = last_x, before_y = last_y;
        for (long i = o; i < e; i++) {
            if (i < e - 1) {
                edge_step(x, y, i, i + 1, rest[i], lam, alpha, inv_weight, &gx, &gy);
            } else {
                gx = last_x;
                gy = last_y;
            }
            x[i] += w[i] * (before_x - gx);
            y[i] += w[i] * (before_y - gy);
            before_x = gx;
            before_y = gy;
        }
    }
    /* the total length */
    double talpha = compliance * (double)(e - o) / (h * h);
    double C = -rest_total, weight = 0.0, steepest = 0.0, tx0, ty0, tx, ty, ux, uy;
    double ts[2 * (e - o)]; /* the unit edge vectors, kept for the move */
    unit(x[o] - x[e - 1], y[o] - y[e - 1], &tx0, &ty0);
    tx = tx0;
    ty = ty0;
    for (long i = o; i < e; i++) {
        long j = i + 1 < e ? i + 1 : o;
        C += unit(x[j] - x[i], y[j] - y[i], &ux, &uy);
        ts[2 * (i - o)] = ux;
        ts[2 * (i - o) + 1] = uy;
        double g2 = (tx - ux) * (tx - ux) + (ty - uy) * (ty - uy);
        weight += w[i] * g2;
        steepest = py_max(steepest, w[i] * sqrt(g2));
        tx = ux;
        ty = uy;
    }
    if (weight + talpha == 0.0) return;
    double dlam = (-C - talpha * *total_lam) / (weight + talpha);
    double most = TOTAL_STEP * rest_total / (double)(e - o);
    if (fabs(dlam) * steepest > most) dlam = copysign(most / steepest, dlam);
    *total_lam += dlam;
    tx = tx0;
    ty = ty0;
    for (long i = o; i < e; i++) {
        ux = ts[2 * (i - o)];
        uy = ts[2 * (i - o) + 1];
        x[i] += w[i] * dlam * (tx - ux);
        y[i] += w[i] * dlam * (ty - uy);
        tx = ux;
        ty = uy;
    }
}

static double bounce(double *rec, double approach, double energy, double potential, double potential_now, double u,
                     double other, double e, double rest_speed) {
    if (approach > (rec[1] != NO_BOUNCE ? rest_speed : rec[0])) {
        rec[0] = approach;
        rec[1] = NO_BOUNCE;
        rec[2] = energy;
        rec[3] = potential;
    }
    double V = rec[0];
    if (u < 0.0 || V <= rest_speed) return 0.0;
    if (rec[1] == NO_BOUNCE) {
        double fell = py_max(rec[3] - potential_now, 0.0);
        double leave = py_min(e * sqrt(V * V + 2.0 * fell), sqrt(2.0 * py_max(rec[2] + fell - other, 0.0)));
        rec[1] = 0.5 * leave * leave + potential_now;
        return leave - u;
    }
    return py_min(sqrt(2.0 * py_max(rec[1] - potential_now, 0.0)) - u, 0.0);
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
                const double *compliance, double *lam, const double *target, double *depth, const double *rest_total,
                double *total_lam, double *predicted, double *impact, double mu_s, double mu_k, double e_max,
                double rest_speed) {
    long n = off[blobs];
    double *x = pos, *y = pos + n, *x0 = prev, *y0 = prev + n, *vx = vel, *vy = vel + n;
    double h = dt / (double)substeps;
    for (long s = 0; s < steps * substeps; s++) {
        for (long b = 0; b < blobs; b++) { /* predict: the rigid motion exactly */
            long o = off[b], e = off[b + 1];
            for (long i = o; i < e; i++) {
                x0[i] = x[i];
                y0[i] = y[i];
                vx[i] += gx * h;
                vy[i] += gy * h;
                lam[i] = 0.0;
                depth[i] = 0.0;
            }
            double cx = 0.0, cy = 0.0, cvx = 0.0, cvy = 0.0, L = 0.0, I = 0.0, kinetic = 0.0;
            for (long i = o; i < e; i++) {
                cx += x[i];
                cy += y[i];
                cvx += vx[i];
                cvy += vy[i];
            }
            double m = (double)(e - o);
            cx /= m;
            cy /= m;
            cvx /= m;
            cvy /= m;
            for (long i = o; i < e; i++) {
                double rx = x[i] - cx, ry = y[i] - cy;
                L += rx * (vy[i] - cvy) - ry * (vx[i] - cvx);
                I += rx * rx + ry * ry;
            }
            double om = I > 0.0 ? L / I : 0.0;
            for (long i = o; i < e; i++) kinetic += vx[i] * vx[i] + vy[i] * vy[i];
            predicted[4 * b] = cvx;
            predicted[4 * b + 1] = cvy;
            predicted[4 * b + 2] = 0.5 * kinetic / m;
            predicted[4 * b + 3] = -(gx * cx + gy * cy);
            double co = cos(om * h), si = sin(om * h);
            for (long i = o; i < e; i++) {
                double rx = x[i] - cx, ry = y[i] - cy;
                double dx = vx[i] - cvx + om * ry, dy = vy[i] - cvy - om * rx;
                x[i] = cx + h * cvx + co * rx - si * ry + h * dx;
                y[i] = cy + h * cvy + si * rx + co * ry + h * dy;
            }
            total_lam[b] = 0.0;
        }
        for (long it = 0; it < iters; it++) {
            for (long b = 0; b < blobs; b++)
                perimeter(x, y, w, off[b], off[b + 1], rest, rest_total[b], compliance[b], lam, total_lam + b, h);
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
        for (long b = 0; b < blobs; b++) { /* velocities: translation, best-fit rotation, the rest */
            long o = off[b], e = off[b + 1];
            double m = (double)(e - o);
            double cx = 0.0, cy = 0.0, px = 0.0, py = 0.0, cross = 0.0, dot = 0.0;
            for (long i = o; i < e; i++) {
                cx += x[i];
                cy += y[i];
                px += x0[i];
                py += y0[i];
            }
            cx /= m;
            cy /= m;
            px /= m;
            py /= m;
            for (long i = o; i < e; i++) {
                double rx = x[i] - cx, ry = y[i] - cy, qx = x0[i] - px, qy = y0[i] - py;
                cross += qx * ry - qy * rx;
                dot += qx * rx + qy * ry;
            }
            double theta = atan2(cross, dot);
            double co = cos(theta), si = sin(theta), om = theta * inv_h;
            for (long i = o; i < e; i++) {
                double rx = x[i] - cx, ry = y[i] - cy, qx = x0[i] - px, qy = y0[i] - py;
                vx[i] = (cx - px) * inv_h - om * ry + (rx - (co * qx - si * qy)) * inv_h;
                vy[i] = (cy - py) * inv_h + om * rx + (ry - (si * qx + co * qy)) * inv_h;
            }
        }
        for (long i = 0; i < n; i++) { /* kinetic friction */
            double D = depth[i];
            if (D == 0.0) continue;
            double vn = vx[i] * 0.0 + vy[i] * 1.0;
            double vtx = vx[i] - vn * 0.0, vty = vy[i] - vn * 1.0;
            double vt = sqrt(vtx * vtx + vty * vty);
            if (vt > 0.0) {
                double f = py_max(vt - mu_k * D * inv_h, 0.0) / vt;
                vtx *= f;
                vty *= f;
            }
            vn = py_max(vn, 0.0);
            vx[i] = vtx + vn * 0.0;
            vy[i] = vty + vn * 1.0;
        }
        for (long b = 0; b < blobs; b++) { /* restitution on the floor */
            long o = off[b], e = off[b + 1];
            double m = (double)(e - o);
            double nx = 0.0, ny = 0.0, ux = 0.0, uy = 0.0, kinetic = 0.0, cx = 0.0, cy = 0.0;
            for (long i = o; i < e; i++) {
                cx += x[i];
                cy += y[i];
                ux += vx[i];
                uy += vy[i];
                kinetic += vx[i] * vx[i] + vy[i] * vy[i];
                double D = depth[i];
                if (D > 0.0) {
                    nx += D * 0.0;
                    ny += D * 1.0;
                }
            }
            double length = sqrt(nx * nx + ny * ny);
            if (length == 0.0) continue;
            nx /= length;
            ny /= length;
            double u = (ux * nx + uy * ny) / m;
            double du = bounce(impact + 4 * b, -(predicted[4 * b] * nx + predicted[4 * b + 1] * ny),
                               predicted[4 * b + 2], predicted[4 * b + 3], -(gx * cx + gy * cy) / m, u,
                               0.5 * kinetic / m - 0.5 * u * u, e_max, rest_speed);
            if (du != 0.0) {
                for (long i = o; i < e; i++) {
                    vx[i] += du * nx;
                    vy[i] += du * ny;
                }
            }
        }
    }
}
