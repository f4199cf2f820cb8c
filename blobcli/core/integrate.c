/* Time integration stages: damping, prediction and the velocity update.
 *
 * Position-based dynamics (Müller et al. 2007; XPBD small steps, Macklin et al. 2019): each substep of length h
 * predicts x* = x + h v + h² g (symplectic Euler), lets the constraint stages move x*, and then reads the velocity
 * back from x - x_prev. The rigid part of the motion (translation and rotation about the centre) is predicted and
 * read back exactly (bc_predict, bc_update_velocities); restitution is the blobs' (restitution.c).
 */
#include <math.h>
#include <stdbool.h>

#include "driving.h"
#include "integrate.h"
#include "parallel.h"
#include "ring.h"
#include "scratch.h"

static const double PI = 3.141592653589793; /* math.pi */

/* A step takes more substeps than the scene's `substeps` where fewer would let a blob move more than STRIDE × the
 * shortest mean rest edge L in one, at the fastest awake blob's rigid speed at the step's start plus g dt (a contact
 * found at the substep's start would be passed through: a ring folds, a pile interpenetrates), or let gravity sag a
 * blob by more than SAG × L in one, g h² (the contacts' push back after the area stage squeezes every blob of a pile
 * by about that much each substep), n g h² for the blob at the bottom of a stack of n (rows_stacked): h = dt / k with
 *     k = max(substeps, ⌈(v + g dt) dt / (STRIDE L)⌉, ⌈dt √(n g / (SAG L))⌉),  at most `most_substeps`.
 * Chosen on `blobsim stress`'s pile at dt = 1/30 s and one substep (area drift after settling, energy rise):
 * STRIDE 0.5, SAG 0.05: 7%, 0.6%; STRIDE 1: 13%, 8%; STRIDE 0.75: 10%, 6%. */
static const double STRIDE = 0.5;
static const double SAG = 0.05;
/* of a blob's radius (rest perimeter / 2π): a static push this deep in one substep is an impact that stops the
 * whole blob (bc_stop_impacts) */
static const double IMPACT_DEPTH = 0.1;
/* numba's merge sort sorts this many items or fewer by insertion (numba/misc/mergesort.py) */
#define SMALL_MERGESORT 20

/* The rigid motion that best fits ring o..e's velocities: (c, v_c) into means = (c_x, c_y, v_cx, v_cy), and ω
 * returned, with c = Σ x / n, v_c = Σ v / n and ω = Σ r × v / Σ |r|², r = x - c. Vertex masses are equal within a
 * blob, so c is the centre of mass, and v_c + ω ẑ × r is the least-squares (kinetic-energy) fit: ∂/∂v_c
 * Σ |v - v_c - ω ẑ × r|² = 0 gives the mean (Σ r = 0), ∂/∂ω gives ω I = L. The residual v - v_c - ω ẑ × r, the
 * deformation, carries neither momentum nor angular momentum. */
static inline double rigid_motion(const double *pos, const double *vel, int64_t n, int64_t o, int64_t e,
                                  double means[4]) {
    bc_ring_means(pos, vel, n, o, e, means);
    double cx = means[0], cy = means[1], vx = means[2], vy = means[3];
    double L = 0.0, I = 0.0;
    for (int64_t i = o; i < e; i++) {
        double rx = pos[i] - cx, ry = pos[n + i] - cy;
        L += rx * (vel[n + i] - vy) - ry * (vel[i] - vx);
        I += rx * rx + ry * ry;
    }
    return I > 0.0 ? L / I : 0.0;
}

/* Decay each blob's deformation velocity by factor = exp(-damping h): v <- v_rig + (v - v_rig) f, with
 * v_rig = v_c + ω ẑ × r the best-fit rigid motion (rigid_motion). Neither momentum nor angular momentum changes,
 * and a blob that moves, spins or rolls rigidly is not slowed. */
void bc_damp_deformation(const bcContext *ctx, double factor) {
    const bcModel *m = ctx->m;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const uint8_t *awake = ctx->s->awake;
    const double *pos = ctx->s->position;
    double *vel = ctx->s->velocity;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double means[4];
        double w = rigid_motion(pos, vel, n, o, e, means);
        double cx = means[0], cy = means[1], vx = means[2], vy = means[3];
        for (int64_t i = o; i < e; i++) {
            double rigid_x = vx - w * (pos[n + i] - cy);
            double rigid_y = vy + w * (pos[i] - cx);
            vel[i] = rigid_x + (vel[i] - rigid_x) * factor;
            vel[n + i] = rigid_y + (vel[n + i] - rigid_y) * factor;
        }
    });
}

/* A viscous drag on all motion (`[scene] drag` γ): v <- v f, f = exp(-γ h), the exact decay of dv/dt = -γ v over
 * the substep. Unlike bc_damp_deformation it slows moving, spinning and rolling too: a damped dynamics that brings
 * a packing to rest (the O'Hern group's deformable polygons relax the same way, or by FIRE). Momentum decays with
 * it: the drag is a force from outside, the medium. */
void bc_drag_motion(const bcContext *ctx, double factor) {
    const bcModel *m = ctx->m;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const uint8_t *awake = ctx->s->awake;
    double *vel = ctx->s->velocity;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!awake[b]) continue;
        for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
            vel[i] *= factor;
            vel[n + i] *= factor;
        }
    });
}

/* numba's order of floats in its sorts and searches (numba/np/numpy_support.py lt_floats): a < b, NaNs last */
static inline bool lt_floats(double a, double b) { return a < b || (isnan(b) && !isnan(a)); }

/* np.argsort(vals, kind="mergesort") as numba sorts, on the indices arr[0 .. count) in place (numba/misc/
 * mergesort.py, numpy's mergesort.c.src): halves sorted recursively and merged, the left half first on ties
 * (stable), with insertion sort at SMALL_MERGESORT items or fewer; ws holds count / 2 indices. */
static void argmergesort(int64_t *arr, int64_t count, const double *vals, int64_t *ws) {
    if (count > SMALL_MERGESORT) {
        int64_t mid = count / 2;
        argmergesort(arr, mid, vals, ws);
        argmergesort(arr + mid, count - mid, vals, ws);
        for (int64_t i = 0; i < mid; i++) ws[i] = arr[i];
        const int64_t *left = ws, *right = arr + mid;
        int64_t right_count = count - mid, i = 0, j = 0, k = 0;
        while (i < mid && j < right_count) {
            if (!lt_floats(vals[right[j]], vals[left[i]])) arr[k++] = left[i++];
            else arr[k++] = right[j++];
        }
        while (i < mid) arr[k++] = left[i++];
        while (j < right_count) arr[k++] = right[j++];
    } else {
        for (int64_t i = 1; i < count; i++) {
            for (int64_t j = i; j > 0 && lt_floats(vals[arr[j]], vals[arr[j - 1]]); j--) {
                int64_t swap = arr[j - 1];
                arr[j - 1] = arr[j];
                arr[j] = swap;
            }
        }
    }
}

/* np.searchsorted(a, key) (side "left") as numba finds it: the first place in the sorted a[0 .. count) whose value
 * is not before key (binary search, numba/np/arraymath.py) */
static int64_t search_left(const double *a, int64_t count, double key) {
    int64_t low = 0, high = count;
    while (low < high) {
        int64_t mid = low + ((high - low) >> 1);
        if (lt_floats(a[mid], key)) low = mid + 1;
        else high = mid;
    }
    return low;
}

/* a.max() as numba takes it (count >= 1): the first NaN, else the largest, in order */
static double array_max(const double *a, int64_t count) {
    double most = a[0];
    if (isnan(most)) return most;
    for (int64_t i = 1; i < count; i++) {
        if (isnan(a[i])) return a[i];
        if (a[i] > most) most = a[i];
    }
    return most;
}

/* n: the most blobs in a chain each resting on the one below it, read from positions alone (a resumed run takes
 * the same substeps): b rests on a when their centres are within 1.1 (R_a + R_b) and b's is higher by more than
 * 0.2 (R_a + R_b), R the rest radius. Blobs side by side, or one alone, give 1. Blobs go up in height order, each
 * one more than the deepest blob it rests on; its candidates are those within 1.1 (R_a + R_b) across (along the
 * level), found by bisection in the blobs sorted that way. Serial, once a step. */
int64_t bc_rows_stacked(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcScratch *w = ctx->w;
    const int64_t count = m->blob_count, n = m->vertex_count, *offsets = m->offsets;
    const double *pos = ctx->s->position, up_x = ctx->c->up_x, up_y = ctx->c->up_y;
    if (count < 2) return 1;
    double *height = w->stack_height, *across = w->stack_across, *radius = w->stack_radius;
    for (int64_t b = 0; b < count; b++) {
        double sx = 0.0, sy = 0.0;
        for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
            sx += pos[i];
            sy += pos[n + i];
        }
        double k = (double)(offsets[b + 1] - offsets[b]);
        height[b] = (sx * up_x + sy * up_y) / k;
        across[b] = (sx * up_y - sy * up_x) / k;
        radius[b] = m->rest_perimeter[b] / (2.0 * PI);
    }
    int64_t *side = w->stack_side, *by_height = w->stack_by_height, *depth = w->stack_depth;
    double *sorted_across = w->stack_sorted_across;
    for (int64_t b = 0; b < count; b++) side[b] = by_height[b] = b;
    argmergesort(side, count, across, w->stack_work);
    for (int64_t j = 0; j < count; j++) sorted_across[j] = across[side[j]];
    double reach = 2.2 * array_max(radius, count);
    for (int64_t b = 0; b < count; b++) depth[b] = 1;
    int64_t most = 1;
    argmergesort(by_height, count, height, w->stack_work);
    for (int64_t r = 0; r < count; r++) {
        int64_t b = by_height[r];
        for (int64_t j = search_left(sorted_across, count, across[b] - reach); j < count; j++) {
            int64_t a = side[j];
            if (sorted_across[j] > across[b] + reach) break;
            double both = radius[a] + radius[b];
            if (height[b] - height[a] > 0.2 * both
                && hypot(height[b] - height[a], across[b] - across[a]) < 1.1 * both) {
                depth[b] = bc_imax(depth[b], depth[a] + 1);
            }
        }
        most = bc_imax(most, depth[b]);
    }
    return most;
}

/* How many substeps this step takes: k above (STRIDE, SAG), at least `substeps` and at most `most_substeps`. L is
 * read from the rest perimeters as they are now (a scale schedule changes them); v is each awake blob's rigid speed
 * |v_c| + |ω| R, R its rest radius (rigid_motion): a vertex's own jitter in a squeezed blob is not motion that
 * passes a contact. g = |g|. Serial, once a step: two passes over the awake blobs' vertices, and with gravity one
 * over every blob's (rows_stacked, in the scratch ctx->w). */
int64_t bc_substeps_for(const bcContext *ctx, double g) {
    const bcModel *m = ctx->m;
    const bcSettings *c = ctx->c;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double dt = c->dt, *rest_perimeter = m->rest_perimeter;
    double edge = INFINITY, fastest = 0.0;
    for (int64_t b = 0; b < m->blob_count; b++) {
        edge = bc_min(edge, rest_perimeter[b] / (double)(offsets[b + 1] - offsets[b]));
        if (ctx->s->awake[b]) {
            double means[4], drive[6];
            double omega = rigid_motion(ctx->s->position, ctx->s->velocity, n, offsets[b], offsets[b + 1], means);
            double radius = rest_perimeter[b] / (2.0 * PI);
            double speed = hypot(means[2], means[3]) + fabs(omega) * radius;
            /* a driven blob also gains up to (|F| / M + |τ| R / I) dt over the step, as g dt below */
            if (bc_driving_of(m, ctx->s->position, b, drive))
                speed += (hypot(drive[0], drive[1]) + fabs(drive[2]) * radius) * dt;
            fastest = bc_max(fastest, speed);
        }
    }
    if (edge == INFINITY) return c->substeps; /* no blobs */
    /* the sag of the blob at the bottom of the deepest stack: it carries the n - 1 above it, n g h² (the 1,000-blob
     * pile, ~25 rows, takes 6 substeps by this and comes to rest, fastest centre / vertex 0.46 / 15 mm/s in seconds
     * 21-25, against 1.77 / 58.5 at 4) */
    int64_t rows = g > 0.0 ? bc_rows_stacked(ctx) : 1;
    double need = bc_max((fastest + g * dt) * dt / (STRIDE * edge), dt * sqrt((double)rows * g / (SAG * edge)));
    /* (also a non-finite speed: the runaway check ends the run after this step) */
    if (!(need < (double)c->most_substeps)) return c->most_substeps;
    /* numba's math.ceil is an int64: need is finite and below most_substeps here */
    return bc_imax(c->substeps, (int64_t)ceil(need));
}

/* x_prev <- x; v += (g + f_i / m_i) h, f_i a driven blob's share of its force and torque (driving.h); x moves by
 * the rigid motion exactly and by the deformation to first order; clear this substep's multipliers and contacts.
 * predicted[b] = (v_c, ½ mean |v|², -g · c), the blob's velocity, kinetic and potential energy per unit mass
 * before the constraints (restitution).
 *
 * x += h v would move a spinning vertex along its tangent, off its circle around c by |r| (√(1 + ω²h²) - 1); the
 * perimeter stage then pulls it back and the chord it travelled is short of ωh: spin decayed (35 % of 4 rad/s in
 * 10 s at h = 1/240 s). So, with (c, v_c, ω) the best-fit rigid motion (rigid_motion) and R(φ) the rotation by φ,
 *     x <- c + h v_c + R(ωh) r + h (v - v_c - ω ẑ × r),
 * which is x + h v to first order, and moves a rigid blob exactly: no edge changes length. */
void bc_predict(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double gx = ctx->c->gx, gy = ctx->c->gy;
    double *pos = s->position, *prev = s->previous, *vel = s->velocity, *lam = s->lam, *depth = s->contact_depth;
    double *predicted = s->predicted;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double drive[6]; /* F / M, τ / I, the centre of mass and M (driving.h) */
        bool driven = bc_driving_of(m, pos, b, drive);
        for (int64_t i = o; i < e; i++) {
            prev[i] = pos[i];
            prev[n + i] = pos[n + i];
            if (driven) { /* v += (g + f_i / m_i) h, f_i / m_i = F / M + (τ / I) ẑ × r_i */
                vel[i] += (gx + drive[0] - drive[2] * (pos[n + i] - drive[4])) * h;
                vel[n + i] += (gy + drive[1] + drive[2] * (pos[i] - drive[3])) * h;
            } else {
                vel[i] += gx * h;
                vel[n + i] += gy * h;
            }
            lam[i] = 0.0; /* XPBD multipliers accumulate over one substep's iterations only */
            depth[i] = 0.0;
        }
        double means[4];
        double w = rigid_motion(pos, vel, n, o, e, means);
        double cx = means[0], cy = means[1], vx = means[2], vy = means[3];
        double kinetic = 0.0;
        for (int64_t i = o; i < e; i++) kinetic += vel[i] * vel[i] + vel[n + i] * vel[n + i];
        predicted[4 * b] = vx;
        predicted[4 * b + 1] = vy;
        predicted[4 * b + 2] = 0.5 * kinetic / (double)(e - o);
        predicted[4 * b + 3] = -(gx * cx + gy * cy);
        double cos_wh = cos(w * h), sin_wh = sin(w * h);
        for (int64_t i = o; i < e; i++) {
            double rx = pos[i] - cx, ry = pos[n + i] - cy;
            double dx = vel[i] - vx + w * ry; /* the deformation velocity v - v_c - ω ẑ × r */
            double dy = vel[n + i] - vy - w * rx;
            pos[i] = cx + h * vx + cos_wh * rx - sin_wh * ry + h * dx;
            pos[n + i] = cy + h * vy + sin_wh * rx + cos_wh * ry + h * dy;
        }
    });
}

/* Blob b's deepest static push D this substep, if deeper than IMPACT_DEPTH × its radius (else 0), and the
 * depth-weighted normal n̄ of its pushes (as restitution's), into (nx, ny). */
static inline double impact_of(const bcContext *ctx, int64_t b, double *nx, double *ny) {
    const int64_t n = ctx->m->vertex_count, *offsets = ctx->m->offsets;
    const double *normal = ctx->s->contact_normal, *depth = ctx->s->contact_depth;
    double deepest = 0.0, sx = 0.0, sy = 0.0;
    for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
        double D = depth[i];
        if (D > 0.0) {
            deepest = bc_max(deepest, D);
            sx += D * normal[i];
            sy += D * normal[n + i];
        }
    }
    double length = sqrt(sx * sx + sy * sy);
    if (deepest <= IMPACT_DEPTH * ctx->m->rest_perimeter[b] / (2.0 * PI) || length == 0.0) {
        *nx = *ny = 0.0;
        return 0.0;
    }
    *nx = sx / length;
    *ny = sy / length;
    return deepest;
}

/* A fast impact stops the whole blob, not only the vertices that reached the collider.
 *
 * At 100 m/s and h = 1/240 s a blob moves 0.42 m in a substep: the collider stage stops its front vertices at the
 * surface while the rest go on, through them, and the ring folds across itself (no constraint can unfold a crossed
 * ring: its signed area no longer measures it). So where a blob's deepest static push D this substep exceeds
 * IMPACT_DEPTH × its radius, its vertices the colliders did not push move back along that push's normal n by D
 * too, and after the velocity update no vertex of it keeps approaching along n (bc_stop_impact_velocities): the
 * blob stops where its front met the surface, as a rigid body would, and bounces as restitution says (from its
 * approach speed before the constraints). Only motion toward the surface is taken: energy is lost, never made.
 * Slower impacts (a 0.5 m blob dropped 1 m at the defaults pushes 18 mm a substep, against 50 mm) are not
 * touched. */
void bc_stop_impacts(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double *depth = ctx->s->contact_depth;
    double *pos = ctx->s->position;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!ctx->s->awake[b]) continue;
        double nx, ny;
        double deepest = impact_of(ctx, b, &nx, &ny);
        if (deepest == 0.0) continue;
        for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
            if (depth[i] == 0.0) {
                pos[i] += deepest * nx;
                pos[n + i] += deepest * ny;
            }
        }
    });
}

/* After a fast impact (bc_stop_impacts), no vertex of the blob approaches the surface along n. */
void bc_stop_impact_velocities(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    double *vel = ctx->s->velocity;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!ctx->s->awake[b]) continue;
        double nx, ny;
        double deepest = impact_of(ctx, b, &nx, &ny);
        if (deepest == 0.0) continue;
        for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
            double vn = vel[i] * nx + vel[n + i] * ny;
            if (vn < 0.0) {
                vel[i] -= vn * nx;
                vel[n + i] -= vn * ny;
            }
        }
    });
}

/* v from the substep's motion, rotation read as an angle; then kinetic Coulomb friction at static contacts.
 *
 * v = (x - x_prev) / h reads a rotation by θ as the chord (R(θ) - 1) r / h: shorter than ω |r| by sin(θ/2) / (θ/2),
 * and turned: spin would decay every substep. So the motion is split into the centre's translation c - c_prev, the
 * rotation R(θ) that best fits the ring's turn (2D Procrustes: θ minimizes Σ |r - R(θ) r_prev|²,
 * tan θ = Σ r_prev × r / Σ r_prev · r), and the rest, and
 *     v = (c - c_prev) / h + (θ / h) ẑ × r + (r - R(θ) r_prev) / h.
 * The two rigid fields differ from the chord only in ways that carry no momentum (Σ r = 0): Σ m v is
 * (x - x_prev) / h's; a rigid motion is read back exactly. */
void bc_update_velocities(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double *pos = s->position, *prev = s->previous, *normal = s->contact_normal, *depth = s->contact_depth;
    const double *material = s->contact_material;
    const bool moving = ctx->c->moving != 0;
    double *vel = s->velocity;
    double inv_h = 1.0 / h;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double means[4];
        bc_ring_means(pos, prev, n, o, e, means);
        double cx = means[0], cy = means[1], px = means[2], py = means[3];
        double cross = 0.0, dot = 0.0;
        for (int64_t i = o; i < e; i++) {
            double rx = pos[i] - cx, ry = pos[n + i] - cy, qx = prev[i] - px, qy = prev[n + i] - py;
            cross += qx * ry - qy * rx;
            dot += qx * rx + qy * ry;
        }
        double theta = atan2(cross, dot);
        double cos_t = cos(theta), sin_t = sin(theta), w = theta * inv_h;
        for (int64_t i = o; i < e; i++) {
            double rx = pos[i] - cx, ry = pos[n + i] - cy, qx = prev[i] - px, qy = prev[n + i] - py;
            vel[i] = (cx - px) * inv_h - w * ry + (rx - (cos_t * qx - sin_t * qy)) * inv_h;
            vel[n + i] = (cy - py) * inv_h + w * rx + (ry - (sin_t * qx + cos_t * qy)) * inv_h;
        }
    });
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t i = 0; i < n; i++), {
        double D = depth[i];
        if (D == 0.0) continue;
        /* At a static contact (static friction already held the vertex in the collider stage), relative to the
         * collider's surface: a moving one's velocity w there (walls.c) ... */
        double vx = vel[i], vy = vel[n + i];
        if (moving) {
            vx -= material[4 * n + i];
            vy -= material[5 * n + i];
        }
        double nx = normal[i], ny = normal[n + i];
        double vn = vx * nx + vy * ny;
        double vtx = vx - vn * nx, vty = vy - vn * ny;
        /* ... and a conveyor's, u along t = (n_y, -n_x) (statics.c) */
        double u = material[3 * n + i];
        if (u != 0.0) {
            vtx -= u * ny;
            vty += u * nx;
        }
        /* Kinetic friction: |Δv_t| <= μ_k |Δv_n|, with |Δv_n| = D / h. */
        double vt = sqrt(vtx * vtx + vty * vty);
        if (vt > 0.0) {
            double scale = bc_max(vt - material[n + i] * D * inv_h, 0.0) / vt;
            vtx *= scale;
            vty *= scale;
        }
        if (u != 0.0) {
            vtx += u * ny;
            vty -= u * nx;
        }
        /* A vertex in contact does not keep approaching the surface (inelastic vertex; the bounce is the blob's,
         * see restitution.c). */
        vn = bc_max(vn, 0.0);
        vel[i] = vtx + vn * nx;
        vel[n + i] = vty + vn * ny;
        if (moving) {
            vel[i] += material[4 * n + i];
            vel[n + i] += material[5 * n + i];
        }
    });
}
