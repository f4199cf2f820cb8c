/* Restitution: blobs bounce, whole, off statics (bc_restitution) and off each other (bc_blob_restitution), by
 * one rule (bounce) on a contact's record of its impact.
 *
 * A vertex cannot bounce on its own: the perimeter and area stages average its reversed velocity away against the
 * rest of the blob, which is still falling. So restitution acts on the whole blob (on a pair of blobs), along the
 * contact's normal n̄, by a uniform velocity change that does not disturb its shape.
 */
#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "collide_limits.h"
#include "driving.h"
#include "friction.h"
#include "parallel.h"
#include "packing_records.h"
#include "periodic.h"
#include "restitution.h"
#include "ring.h"
#include "scratch.h"

static const double REST_SPEED_FACTOR = 2.0; /* no bounce below this × |g| h of approach speed (kills contact
                                                 jitter) ... */
static const double MIN_REST_SPEED = 0.01;   /* m/s ... nor below this (without gravity, jitter from pushing
                                                 overlaps apart) */
#define NO_BOUNCE (-INFINITY)                 /* the leave energy of a contact that has not bounced yet (bounce) */

/* The approach speed (m/s) below which a contact never bounces this step: max(REST_SPEED_FACTOR |g| h,
 * MIN_REST_SPEED), g = |g|, h the substep */
double bc_rest_speed(double g, double h) { return bc_max(REST_SPEED_FACTOR * g * h, MIN_REST_SPEED); }

/* Work W (per unit mass: of the blob, or of the pair's μ) a drive did on a contact's motion this substep, into its
 * record: as if it had fallen by W more since its impact (P), and, once it has bounced, as energy it has now beyond
 * its potential P_now (E <- max(E, P_now) + W). The max: a blob that bounced at e = 0 and then rose on its own
 * recoil (the rule holds its speed, not its place) has E < P_now, and would stay held until the drive's work made
 * up that deficit (a jump off a floor lost 4 of its 18 steps of push, and 45% of its height). So from there
 * ½ u² <= W - (P_now' - P_now): what the drive did, less the climb. */
static inline void add_work(double *record, double work, double potential_now) {
    record[3] += work;
    if (record[1] != NO_BOUNCE) record[1] = bc_max(record[1], potential_now) + work;
}

/* One substep of a contact's restitution rule along its normal, for record = (V, E, K, P) of the contact; returns
 * the change Δu of the normal speed u to apply.
 *
 * V is the contact's fastest approach so far, read before the substep's constraints (`approach`): after them a hard
 * blob has already stopped, and what is left depends on the substeps and iterations, not on e. K and P are the
 * kinetic and potential energy (per unit of the normal's mass) then (`energy`, `potential`; P_now after the solve).
 * Once the solve leaves the bodies no longer approaching (u >= 0), they bounce: u is set to e V', up for a hard blob
 * that stopped dead, down for a soft one whose own recoil would leave faster. V'² = V² + 2 (P - P_now) is the impact
 * speed that the fall while squashing adds (coarse substeps squash a hard blob, which would otherwise rebound from
 * lower), so the rebound is about e² of the fall whatever the step. Never more kinetic energy than came in: the
 * solve has turned some into vibration (`other`: the kinetic energy besides ½ u²), so ½ u² <= K + P - P_now -
 * other. E keeps the energy ½ u² + P_now it left with (-∞ before the bounce), and while the contact lasts u is never
 * raised again (that would cancel gravity) nor let above √(2 (E - P_now)): the blob's recoil, pushing it up or on,
 * would add energy. So no bounce goes higher than the drop. The record outlives the contact: a vibrating blob that
 * has bounced touches again on its way up, and those touches, inelastic for the vertex, would turn vibration into
 * lift. A new impact starts when the bodies approach faster than rest_speed after a bounce (or faster than V before
 * it); slower approaches never bounce (resting). A driving force or torque (driving.h) that does work W on the
 * contact's motion is energy that comes in too, as a fall is (add_work), so a driven blob may push off a contact it
 * landed on (a jump) and leave it faster than it came. */
static double bounce(double *record, double approach, double energy, double potential, double potential_now,
                     double u, double other, double e, double rest_speed) {
    if (approach > (record[1] != NO_BOUNCE ? rest_speed : record[0])) {
        record[0] = approach;
        record[1] = NO_BOUNCE;
        record[2] = energy;
        record[3] = potential;
    }
    double V = record[0];
    if (u < 0.0 || V <= rest_speed) return 0.0;
    if (record[1] == NO_BOUNCE) {
        double fell = bc_max(record[3] - potential_now, 0.0);
        double leave = bc_min(e * sqrt(V * V + 2.0 * fell), sqrt(2.0 * bc_max(record[2] + fell - other, 0.0)));
        record[1] = 0.5 * leave * leave + potential_now;
        return leave - u;
    }
    return bc_min(sqrt(2.0 * bc_max(record[1] - potential_now, 0.0)) - u, 0.0);
}

/* Bounce off statics (the rule of bounce), of each blob's centre of mass; off a moving collider, in its frame:
 * velocities relative to w̄, its surface's depth-weighted velocity at the contacts.
 *
 * The blob bounces along the depth-weighted normal n̄ of its static contacts, by one uniform Δv = Δu n̄. For a
 * deformable blob, e (the largest restitution among its contacts) is the ratio of its centre's leave and impact
 * speeds: it rebounds to about e² of the drop, less what it keeps as vibration. Energies here are per unit mass:
 * ½ mean |v|². */
void bc_restitution(const bcContext *ctx, double rest_speed) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double *pos = s->position, *normal = s->contact_normal, *contact_depth = s->contact_depth;
    const double *material = s->contact_material, *predicted = s->predicted;
    const double gx = ctx->c->gx, gy = ctx->c->gy;
    const bool moving = ctx->c->moving != 0;
    double *vel = s->velocity;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!s->awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double nx = 0.0, ny = 0.0, ux = 0.0, uy = 0.0, kinetic = 0.0, cx = 0.0, cy = 0.0;
        double e_max = 0.0;                       /* the largest restitution among its contacts */
        double wx = 0.0, wy = 0.0, depth = 0.0;   /* Σ D w, Σ D: the contacts' surface velocity */
        for (int64_t i = o; i < e; i++) {
            cx += pos[i];
            cy += pos[n + i];
            ux += vel[i];
            uy += vel[n + i];
            kinetic += vel[i] * vel[i] + vel[n + i] * vel[n + i];
            double D = contact_depth[i];
            if (D > 0.0) {
                nx += D * normal[i];
                ny += D * normal[n + i];
                e_max = bc_max(e_max, material[2 * n + i]);
                if (moving) {
                    wx += D * material[4 * n + i];
                    wy += D * material[5 * n + i];
                    depth += D;
                }
            }
        }
        double length = sqrt(nx * nx + ny * ny);
        if (length == 0.0) continue; /* airborne (its impact record is kept: see bounce) */
        nx = nx / length;
        ny = ny / length;
        double count = (double)(e - o);
        double u = (ux * nx + uy * ny) / count; /* the centre's speed along n̄, after the solve */
        double approach = -(predicted[4 * b] * nx + predicted[4 * b + 1] * ny);
        double came = predicted[4 * b + 2]; /* kinetic energy per unit mass before the solve ... */
        kinetic = 0.5 * kinetic / count;    /* ... and after */
        if (moving) { /* in the frame of the surface: v - w̄, ½ |v - w̄|² = ½ |v|² - w̄ · v + ½ |w̄|² */
            wx = wx / depth;
            wy = wy / depth;
            double wn = wx * nx + wy * ny, w2 = 0.5 * (wx * wx + wy * wy);
            u -= wn;
            approach += wn;
            came += w2 - (wx * predicted[4 * b] + wy * predicted[4 * b + 1]);
            kinetic += w2 - (wx * ux + wy * uy) / count;
        }
        double drive[6]; /* the drive's work on the blob this substep, per unit mass (none: the same bits as before) */
        double potential_now = -(gx * cx + gy * cy) / count;
        if (bc_driving_work(m, pos, s->previous, b, drive))
            add_work(s->impact + 4 * b, drive[0] / drive[5], potential_now);
        double du = bounce(s->impact + 4 * b, approach, came, predicted[4 * b + 3], potential_now, u,
                           kinetic - 0.5 * u * u, e_max, rest_speed);
        if (du != 0.0) {
            for (int64_t i = o; i < e; i++) {
                vel[i] += du * nx;
                vel[n + i] += du * ny;
            }
        }
    });
}

/* Whether a contact between the two blobs of each pair pushed this substep, both awake (a sleeping blob does not
 * move: sleep.c), into touching (pair_count). Each blob reads its own vertices' contacts once and marks its own
 * partner slots in pushed (2 pair_count; partner_start, partner, partner_pair: CSR, see scratch.h), in parallel. */
static void find_touching(const bcContext *ctx, uint8_t *pushed, uint8_t *touching) {
    const bcModel *m = ctx->m;
    const bcScratch *w = ctx->w;
    const int64_t n = m->vertex_count, *offsets = m->offsets, *blob_of = m->blob_of;
    const int64_t *c_edge = ctx->s->c_edge, *start = w->partner_start, *partner = w->partner;
    const uint8_t *c_hit = ctx->s->c_hit, *awake = ctx->s->awake;
    const int64_t pair_count = bc_imin(w->pair_count, w->pair_capacity);
    memset(pushed, 0, (size_t)(2 * pair_count));
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < m->blob_count; a++), {
        for (int64_t p = offsets[a]; p < offsets[a + 1]; p++) {
            for (int64_t c = 0; c < BC_CONTACTS_PER_VERTEX; c++) {
                /* a contact that pushed in an earlier iteration keeps its c_hit when the narrow phase finds its
                 * blob's contacts again and this slot finds no edge (c_edge -1): then it holds no contact */
                int64_t edge = c_edge[c * n + p];
                if (c_hit[c * n + p] != 0 && edge >= 0) {
                    int64_t other = blob_of[edge];
                    for (int64_t j = start[a]; j < start[a + 1]; j++) { /* a blob has a few partners */
                        if (partner[j] == other) {
                            pushed[j] = 1;
                            break;
                        }
                    }
                }
            }
        }
    });
    memset(touching, 0, (size_t)pair_count);
    for (int64_t j = 0; j < 2 * pair_count; j++) touching[w->partner_pair[j]] |= pushed[j];
    for (int64_t k = 0; k < pair_count; k++) {
        uint8_t both = awake[w->pairs[2 * k]] ? awake[w->pairs[2 * k + 1]] : 0; /* awake[a] and awake[b] */
        touching[k] = (touching[k] & both) != 0;
    }
}

/* Blob b's centre-of-mass displacement this substep, Σ m_i (x_i − x_prev,i) / M, into shift (2,) */
static void centre_shift(const bcModel *m, const double *pos, const double *prev, int64_t b, double shift[2]) {
    const int64_t n = m->vertex_count;
    double M = 0.0, dx = 0.0, dy = 0.0;
    for (int64_t i = m->offsets[b]; i < m->offsets[b + 1]; i++) {
        double m_i = 1.0 / m->inv_mass[i];
        M += m_i;
        dx += m_i * (pos[i] - prev[i]);
        dy += m_i * (pos[n + i] - prev[n + i]);
    }
    shift[0] = dx / M;
    shift[1] = dy / M;
}

/* The work the drives of blobs a and b (driving.h) did on their relative motion this substep, per unit of their
 * reduced mass μ: what each did, W_a + W_b, less what their forces did on the pair's centre of mass, which moved by
 * Δx_cm = (m_a Δc_a + m_b Δc_b) / (m_a + m_b); 0 when neither is driven. */
static double pair_drive_work(const bcContext *ctx, int64_t a, int64_t b, double ma, double mb, double mu) {
    const double *pos = ctx->s->position, *prev = ctx->s->previous;
    double da[6] = {0.0}, db[6] = {0.0}; /* W, Δc, F (driving.h: bc_driving_work) */
    bool driven_a = bc_driving_work(ctx->m, pos, prev, a, da), driven_b = bc_driving_work(ctx->m, pos, prev, b, db);
    if (!driven_a && !driven_b) return 0.0;
    if (!driven_a) centre_shift(ctx->m, pos, prev, a, da + 1);
    if (!driven_b) centre_shift(ctx->m, pos, prev, b, db + 1);
    double cx = (ma * da[1] + mb * db[1]) / (ma + mb), cy = (ma * da[2] + mb * db[2]) / (ma + mb);
    return (da[0] + db[0] - (da[3] + db[3]) * cx - (da[4] + db[4]) * cy) / mu;
}

/* Bounce between blobs: the rule of bounce for each touching pair of the broad phase's (scratch.h: pairs,
 * pair_impact), along n̄, the unit vector between their centres, on their relative normal speed u = (v_b - v_a) · n̄,
 * with e = max(e_a, e_b) (as statics combine). Energies are in the pair's centre-of-mass frame, per unit of its
 * reduced mass μ = m_a m_b / (m_a + m_b); gravity does not change relative motion (P = 0). Δu goes to the two blobs
 * as uniform velocity changes -Δu m_b/(m_a + m_b) n̄ and +Δu m_a/(m_a + m_b) n̄: momentum is unchanged. Pairs run one
 * after another, in pair order, on each blob's centre motion (c, v̄, k = ½ mean |v|²), found once in parallel and
 * carried through a uniform change δ exactly: v̄ += δ, k += v̄ · δ + ½ |δ|²; the vertices get the sum at the end.
 * In a periodic box each bounce adds its impulses to the virial (packing). */
void bc_blob_restitution(const bcContext *ctx, double rest_speed) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t B = m->blob_count, n = m->vertex_count, *offsets = m->offsets, *pairs = w->pairs;
    const int64_t pair_count = bc_imin(w->pair_count, w->pair_capacity);
    const double *inv_mass = m->inv_mass, *material = m->material, *predicted = s->predicted;
    const bcBox box = bc_box(ctx->c->box_x, ctx->c->box_y, ctx->c->box_tilt);
    double *vel = s->velocity;
    uint8_t *touching = w->bounce_touching, *involved = w->bounce_involved;
    find_touching(ctx, w->bounce_pushed, touching);
    double *center = w->bounce_center; /* (B, 2) c of the blobs in a touching pair ... */
    double *motion = w->bounce_motion; /* (B, 3) ... and their v̄x, v̄y, k */
    double *shift = w->bounce_shift;   /* (B, 2) δ: the velocity change of each blob */
    memset(center, 0, (size_t)(2 * B) * sizeof *center);
    memset(motion, 0, (size_t)(3 * B) * sizeof *motion);
    memset(shift, 0, (size_t)(2 * B) * sizeof *shift);
    memset(involved, 0, (size_t)B);
    for (int64_t k = 0; k < pair_count; k++) {
        if (touching[k]) involved[pairs[2 * k]] = involved[pairs[2 * k + 1]] = 1;
    }
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < B; b++), {
        if (involved[b]) {
            double means[4], kinetic;
            bc_centre_motion(s->position, vel, n, offsets[b], offsets[b + 1], means, &kinetic);
            center[2 * b] = means[0];
            center[2 * b + 1] = means[1];
            motion[3 * b] = means[2];
            motion[3 * b + 1] = means[3];
            motion[3 * b + 2] = kinetic;
        }
    });
    for (int64_t k = 0; k < pair_count; k++) {
        if (!touching[k]) continue;
        int64_t a = pairs[2 * k], b = pairs[2 * k + 1];
        double ma = (double)(offsets[a + 1] - offsets[a]) / inv_mass[offsets[a]];
        double mb = (double)(offsets[b + 1] - offsets[b]) / inv_mass[offsets[b]];
        double mu = ma * mb / (ma + mb);
        double sx, sy;
        bc_image(center, a, b, box, &sx, &sy);
        double nx = center[2 * b] - (center[2 * a] + sx), ny = center[2 * b + 1] - (center[2 * a + 1] + sy);
        double length = sqrt(nx * nx + ny * ny);
        if (length == 0.0) continue;
        nx = nx / length;
        ny = ny / length;
        double vax = motion[3 * a], vay = motion[3 * a + 1], ka = motion[3 * a + 2];
        double vbx = motion[3 * b], vby = motion[3 * b + 1], kb = motion[3 * b + 2];
        const double *pa = predicted + 4 * a, *pb = predicted + 4 * b;
        /* kinetic energy in the pair's centre-of-mass frame: Σ m k - ½ (m_a + m_b) |v_cm|², per μ */
        double before_x = ma * pa[0] + mb * pb[0], before_y = ma * pa[1] + mb * pb[1];
        double before = (ma * pa[2] + mb * pb[2] - 0.5 * (before_x * before_x + before_y * before_y) / (ma + mb)) / mu;
        double after_x = ma * vax + mb * vbx, after_y = ma * vay + mb * vby;
        double after = (ma * ka + mb * kb - 0.5 * (after_x * after_x + after_y * after_y) / (ma + mb)) / mu;
        double approach = (pa[0] - pb[0]) * nx + (pa[1] - pb[1]) * ny;
        double u = (vbx - vax) * nx + (vby - vay) * ny;
        double work = pair_drive_work(ctx, a, b, ma, mb, mu);
        if (work != 0.0) add_work(w->pair_impact + 4 * k, work, 0.0);
        double du = bounce(w->pair_impact + 4 * k, approach, before, 0.0, 0.0, u, after - 0.5 * u * u,
                           bc_mix_restitution(material[3 * a + 2], material[3 * b + 2]), rest_speed);
        if (du == 0.0) continue;
        const int64_t blob[2] = {a, b};
        /* the virial (packing): ∓μ Δu n̄ on a and b, at the midpoint between them, and -μ Δu n̄ into the pair's
         * record, in the step that keeps the packing records (bcContext.records; an open world keeps none) */
        if (ctx->records) {
            const double side[2] = {0.5, -0.5};
            for (int r = 0; r < 2; r++) {
                bc_add_virial(s->virial, blob[r], side[r] * length * nx, side[r] * length * ny,
                              -side[r] * 2.0 * mu * du * nx, -side[r] * 2.0 * mu * du * ny);
            }
            w->pair_impulse[2 * k] -= mu * du * nx;
            w->pair_impulse[2 * k + 1] -= mu * du * ny;
        }
        const double share[2] = {-mb / (ma + mb), ma / (ma + mb)};
        for (int r = 0; r < 2; r++) {
            int64_t c = blob[r];
            double dx = du * share[r] * nx, dy = du * share[r] * ny;
            motion[3 * c + 2] += motion[3 * c] * dx + motion[3 * c + 1] * dy + 0.5 * (dx * dx + dy * dy);
            motion[3 * c] += dx;
            motion[3 * c + 1] += dy;
            shift[2 * c] += dx;
            shift[2 * c + 1] += dy;
        }
    }
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < B; b++), {
        if (shift[2 * b] != 0.0 || shift[2 * b + 1] != 0.0) {
            for (int64_t p = offsets[b]; p < offsets[b + 1]; p++) {
                vel[p] += shift[2 * b];
                vel[n + p] += shift[2 * b + 1];
            }
        }
    });
}
