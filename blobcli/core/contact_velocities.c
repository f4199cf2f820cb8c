/* The blob contacts' velocity stage: after the velocities are read from the substep's motion, every contact that
 * pushed loses, at velocity level, the relative approach along its push's normal and, by Coulomb's rule with the
 * substep's push-out, its tangential velocity (see bc_blob_contact_velocities). */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "contact_velocities.h"
#include "contacts.h"
#include "parallel.h"

static const int VELOCITY_PASSES = 2; /* Jacobi passes of bc_blob_contact_velocities */

/* (t, n_x, n_y, 1 / W, w_e, μ_s D / h, μ_k D / h) of vertex p's contact c with edge e0→e1 into column i of
 * geometry (rows of `stride`), n the normal of its last push; a zero-length edge gets scale 0 (no impulse) */
static void contact_geometry(const Contacts *cs, int64_t p, int64_t e0, int64_t e1, int64_t c, double *geometry,
                             int64_t stride) {
    const int64_t n = cs->n;
    const double *pos = cs->pos;
    int64_t a = cs->blob_of[p], blob = cs->blob_of[e0];
    double ex = pos[e1] - pos[e0], ey = pos[n + e1] - pos[n + e0];
    double len2 = ex * ex + ey * ey;
    if (len2 == 0.0) {
        for (int r = 0; r < 7; r++) geometry[r * stride] = 0.0;
        return;
    }
    double sx, sy;
    bc_image(cs->center, a, blob, cs->box, &sx, &sy);
    double t = clamp01(along(pos, n, e0, e1, pos[p] + sx, pos[n + p] + sy));
    double we = cs->awake[blob] ? cs->inv_mass[e0] : 0.0;
    double W = cs->inv_mass[p] + ((1.0 - t) * (1.0 - t) + t * t) * we;
    double static_limit, kinetic_limit;
    friction_limits(cs->material, a, blob, cs->depth[p] / cs->h, &static_limit, &kinetic_limit);
    geometry[0] = t;
    geometry[stride] = cs->c_normal[c * n + p];
    geometry[2 * stride] = cs->c_normal[(CPV + c) * n + p];
    geometry[3 * stride] = 1.0 / W;
    geometry[4 * stride] = we;
    geometry[5 * stride] = static_limit;
    geometry[6 * stride] = kinetic_limit;
}

/* The impulse J of a contact with edge point t, normal n, the scale 1 / (W k) and the static and kinetic
 * limits (see contact_geometry) */
static void contact_impulse(const double *vel, int64_t n, int64_t p, int64_t e0, int64_t e1, double t, double nx,
                            double ny, double scale, double static_limit, double kinetic_limit, double *jx,
                            double *jy) {
    double ux = vel[p] - (1.0 - t) * vel[e0] - t * vel[e1];
    double uy = vel[n + p] - (1.0 - t) * vel[n + e0] - t * vel[n + e1];
    double un = ux * nx + uy * ny;
    double tx = ux - un * nx, ty = uy - un * ny;
    double speed = sqrt(tx * tx + ty * ty);
    double cut = 0.0;
    if (speed > 0.0) cut = bc_coulomb_cut(speed, static_limit, kinetic_limit);
    double approach = bc_min(un, 0.0);
    *jx = -(approach * nx + cut * tx) * scale;
    *jy = -(approach * ny + cut * ty) * scale;
}

/* Whether slot c of vertex p holds a contact that pushed this substep. A blob whose contacts are found
 * again after a push keeps the slot's hit while the slot may have found no edge (c_edge -1): such a slot
 * holds no contact. */
static inline bool pushed_contact(const Contacts *cs, int64_t c, int64_t p) {
    return cs->c_hit[c * cs->n + p] != 0 && cs->c_edge[c * cs->n + p] >= 0;
}

/* Contact velocities between blobs: at every contact that pushed this substep (c_hit), the relative velocity
 * of vertex p and the edge point q = (1 - t) x_0 + t x_1 it touches, u = v_p - v_q, loses its approach along
 * the normal n of its last push (u · n < 0: one-sided, as the push) and its tangential part u_t by Coulomb's
 * rule at velocity level: all of it if |u_t| h <= μ_s D (static), else μ_k D / h of it, D the vertex's
 * push-out summed over the substep (the rule of the push).
 *
 * Why: the push and the friction act on positions, one contact after another, and a vertex in a pile is in
 * several; what the Gauss-Seidel order leaves is a sawtooth of 0.05-0.15 mm per substep, which
 * v = (x - x_prev) / h reads as 20-40 mm/s in a pile at rest. Removing the relative velocity each contact
 * should not have, at velocity level, removes most of it.
 *
 * The impulse that zeroes the component of u along a unit vector d is J = -(u · d) / W, with
 * W = w_p + ((1 - t)² + t²) w_e the generalized inverse mass (as for the push), applied as Δv_p = w_p J d,
 * Δv_0 = -(1 - t) w_e J d, Δv_1 = -t w_e J d: Σ m Δv = 0, so momentum is unchanged. Jacobi: every contact's J
 * is found from the same velocities, then scaled by 1 / k, k the most contacts any of its three vertices is
 * in (an edge's end counted by its weight, 1 - t or t; k at least 1), so that a vertex is not over-corrected,
 * and the results are added in contact order: the same for any thread count. A sleeping blob does not move
 * (w_e = 0). */
void bc_blob_contact_velocities(const bcContext *ctx, double h) {
    const Contacts cs = contacts_of(ctx, h);
    const bcScratch *w = ctx->w;
    const int64_t n = cs.n, B = ctx->m->blob_count;
    double *vel = ctx->s->velocity;
    const double *pos = cs.pos, *center = cs.center, *inv_mass = cs.inv_mass;
    /* The pushed contacts, as vertex p and edge e0 -> e1 (columns of `which`), blob by blob: counted, then
     * filled from each blob's own offset (in parallel, in the same order for any thread count). */
    int64_t *first = w->velocity_first;
    first[0] = 0;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < B; a++), {
        int64_t count = 0;
        if (cs.awake[a])
            for (int64_t p = cs.offsets[a]; p < cs.offsets[a + 1]; p++)
                for (int64_t c = 0; c < CPV; c++) count += pushed_contact(&cs, c, p);
        first[a + 1] = count;
    });
    for (int64_t a = 0; a < B; a++) first[a + 1] += first[a];
    const int64_t K = first[B];
    int64_t *which = w->velocity_which; /* (4, K) */
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < B; a++), {
        if (!cs.awake[a]) continue;
        int64_t i = first[a];
        for (int64_t p = cs.offsets[a]; p < cs.offsets[a + 1]; p++) {
            for (int64_t c = 0; c < CPV; c++) {
                if (pushed_contact(&cs, c, p)) {
                    int64_t e0 = cs.c_edge[c * n + p], b = cs.blob_of[e0];
                    which[i] = p;
                    which[K + i] = e0;
                    which[2 * K + i] = bc_next_in_ring(e0, cs.offsets[b], cs.offsets[b + 1]);
                    which[3 * K + i] = c;
                    i++;
                }
            }
        }
    });
    /* Positions do not change in this stage, so each contact's geometry is found once: t, n, the scale
     * 1 / (W k), the edge's inverse mass, and the static and kinetic limits μ_s D / h, μ_k D / h (rows of
     * `geometry`; row 3 holds 1 / W until k is known). */
    double *geometry = w->velocity_geometry; /* (7, K) */
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t i = 0; i < K; i++), {
        contact_geometry(&cs, which[i], which[K + i], which[2 * K + i], which[3 * K + i], geometry + i, K);
    });
    /* k: how many of the contacts each vertex is in, an edge's end by its weight in the contact (so that a
     * mirror image of the contacts counts the same), at least 1 */
    double *share = w->velocity_share;
    for (int64_t i = 0; i < n; i++) share[i] = 0.0;
    for (int64_t i = 0; i < K; i++) {
        share[which[i]] += 1.0;
        share[which[K + i]] += 1.0 - geometry[i];
        share[which[2 * K + i]] += geometry[i];
    }
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t i = 0; i < K; i++), {
        geometry[3 * K + i] /= bc_max(bc_max(bc_max(share[which[i]], share[which[K + i]]), share[which[2 * K + i]]),
                                      1.0);
    });
    double *impulse = w->velocity_impulse; /* (2, K) */
    for (int pass = 0; pass < VELOCITY_PASSES; pass++) {
        BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t i = 0; i < K; i++), { /* every impulse from the same velocities */
            contact_impulse(vel, n, which[i], which[K + i], which[2 * K + i], geometry[i], geometry[K + i],
                            geometry[2 * K + i], geometry[3 * K + i], geometry[5 * K + i], geometry[6 * K + i],
                            &impulse[i], &impulse[K + i]);
        });
        for (int64_t i = 0; i < K; i++) { /* then added, in contact order */
            int64_t p = which[i], e0 = which[K + i], e1 = which[2 * K + i];
            double t = geometry[i], we = geometry[4 * K + i], jx = impulse[i], jy = impulse[K + i];
            vel[p] += inv_mass[p] * jx;
            vel[n + p] += inv_mass[p] * jy;
            vel[e0] -= (1.0 - t) * we * jx;
            vel[n + e0] -= (1.0 - t) * we * jy;
            vel[e1] -= t * we * jx;
            vel[n + e1] -= t * we * jy;
            if (cs.records) { /* the virial: J on p's blob at p, -m_e w_e J on the other's at q; the pair's J */
                int64_t a = cs.blob_of[p], b = cs.blob_of[e0];
                bc_add_virial(cs.virial, a, pos[p] - center[2 * a], pos[n + p] - center[2 * a + 1], jx, jy);
                double qx = (1.0 - t) * pos[e0] + t * pos[e1], qy = (1.0 - t) * pos[n + e0] + t * pos[n + e1];
                bc_add_virial(cs.virial, b, qx - center[2 * b], qy - center[2 * b + 1], -we * jx / inv_mass[e0],
                           -we * jy / inv_mass[e0]);
                bc_add_pair_impulse(cs.w, a, b, jx, jy);
            }
        }
    }
}
