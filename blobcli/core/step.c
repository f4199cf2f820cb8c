/* The step: a list of named stages, run for as many steps as asked in one call.
 *
 * Each stage is a function over the model, the state and the scratch (blobcore.h, one concept a file).
 * Python is entered only between calls (to record a frame, update the progress bar, see a Ctrl-C), never
 * per substep. A stage a scene has nothing for is not run: run-time flags (one blob: no blob contacts; no
 * colliders; nothing sticky: no adhesion; the area method; sleeping; moving or loaded walls; a periodic box) take
 * the place of builds per configuration, and cost a predicted branch each.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime under -std=c11 */
#include <math.h>
#include <stdbool.h>
#include <time.h>

#include "adhesion.h"
#include "area.h"
#include "broad_phase.h"
#include "contact_solver.h"
#include "contact_velocities.h"
#include "integrate.h"
#include "measure.h"
#include "narrow_phase.h"
#include "perimeter.h"
#include "restitution.h"
#include "ring.h"
#include "scratch.h"
#include "self_contact.h"
#include "sleep.h"
#include "statics.h"
#include "step.h"
#include "walls.h"

enum { KOT, XPBD, GAS, SPRINGS }; /* the area methods, in the order of scene/schema.py METHODS */

/* The stage clock's slots (pipeline.STAGES) */
enum {
    LAP_WALLS, LAP_DAMPING, LAP_PREDICT, LAP_BROAD_PHASE, LAP_PERIMETER, LAP_AREA, LAP_BLOB_DETECT, LAP_BLOB_RESOLVE,
    LAP_SELF_CONTACT, LAP_STATICS, LAP_VELOCITIES, LAP_RESTITUTION, LAP_BLOB_VELOCITIES, LAP_BLOB_RESTITUTION,
    LAP_SLEEP, LAP_ADHESION
};

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* With a clock, add the time since t to clock[stage] and return the time now. */
static double lap(double *clock, int stage, double t) {
    if (clock == NULL) return t;
    double time_now = now();
    clock[stage] += time_now - t;
    return time_now;
}

static int64_t zoned_total(const bcContext *ctx) {
    int64_t total = 0;
    for (int64_t b = 0; b < ctx->m->blob_count; b++) total += ctx->s->zoned[b];
    return total;
}

/* One iteration of the constraints: perimeter, self-contacts, area, adhesion (the last iteration, where something is
 * sticky), blob contacts, statics. */
static double iterate(const bcContext *ctx, int64_t it, int64_t self_found, int first_detection, double reach_time,
                      bool sticky, double g, double h, double *clock, double t) {
    const bcModel *m = ctx->m;
    const bcSettings *c = ctx->c;
    bool collides = m->blob_count > 1, reverse = it % 2 == 1;
    bool statics = false;
    for (int k = 0; k < BC_SOLVER_KINDS; k++) statics |= m->statics[k].shapes > 0;
    bc_solve_perimeter(ctx, h); /* XPBD */
    t = lap(clock, LAP_PERIMETER, t);
    /* a ring's vertices kept off its own edges, so that folds and pinches do not cross (before the area,
     * which stays exact where nothing comes after it) */
    if (self_found > 0) {
        bc_resolve_self_contacts(ctx, 0, reverse);
        t = lap(clock, LAP_SELF_CONTACT, t);
    }
    /* the scene's area method; kot: exact, a h² + b h + c = 0 */
    switch (c->method) {
    case KOT: bc_area_kot(ctx); break;
    case XPBD: bc_area_xpbd(ctx, h); break;
    case GAS: bc_area_gas(ctx, h * h / (double)c->iterations); break;
    case SPRINGS: bc_area_springs(ctx, h); break;
    }
    t = lap(clock, LAP_AREA, t);
    /* sticky blobs and colliders hold what touches them against the substep's separation, up to adhesion × length
     * as force: once a substep, after the area (which would otherwise undo part of the hold in the next iteration)
     * and before the contacts and the statics, which push back what a press puts inside them and count it as normal
     * load for friction (adhesion.c) */
    if (sticky && it == c->iterations - 1) {
        bc_adhere(ctx, h);
        t = lap(clock, LAP_ADHESION, t);
    }
    if (collides && ctx->w->pair_count > 0) { /* a vertex inside another blob: pushed out, with friction */
        /* contacts are found once per step, and again for blobs that went past their margin */
        bc_keep_blob_contacts(ctx, first_detection, reach_time, g);
        t = lap(clock, LAP_BLOB_DETECT, t);
        bc_resolve_blob_contacts(ctx, reverse, h);
        t = lap(clock, LAP_BLOB_RESOLVE, t);
    }
    if (statics) {
        bc_collide_statics(ctx, h);
        if (c->loaded) bc_collide_loaded_corners(ctx, h); /* a loaded wall's corners push the rings' edges */
        if (it == 0) { /* a fast impact stops the whole blob, so its ring does not fold ... */
            if (c->loaded) bc_keep_impact_positions(ctx);
            bc_stop_impacts(ctx);
            if (c->loaded) bc_share_impact_stops(ctx); /* ... a loaded wall's impact is its push too */
        }
        if (c->loaded) bc_yield_loaded_walls(ctx); /* each loaded wall takes its share of its pushes */
        t = lap(clock, LAP_STATICS, t);
        /* again after the statics, holding the vertices they pushed (the statics keep the last word) */
        if (self_found > 0) {
            bc_resolve_self_contacts(ctx, 1, reverse);
            t = lap(clock, LAP_SELF_CONTACT, t);
        }
    }
    return t;
}

bcStop bc_advance(const bcContext *ctx_in, int64_t steps, double runaway, double *clock) {
    bcContext context = *ctx_in, *ctx = &context;
    bcScratch *own = NULL;
    if (ctx->w == NULL) {
        own = ctx->w = bc_scratch_new(ctx->m);
        if (own == NULL) return (bcStop){0, BC_NO_MEMORY, 0};
    }
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const bcSettings *c = ctx->c;
    bcStop stop = {steps, BC_DONE, 0};
    bool collides = m->blob_count > 1, statics = false;
    for (int k = 0; k < BC_SOLVER_KINDS; k++) statics |= m->statics[k].shapes > 0;
    bool periodic = collides && c->box_x > 0.0;
    ctx->w->pair_count = 0; /* no pairs before the first broad phase */
    int64_t awake_blobs = bc_awake_count(ctx);
    double t = clock != NULL ? now() : 0.0;
    double g = sqrt(c->gx * c->gx + c->gy * c->gy);
    bool movers = c->moving && bc_any_moves(ctx);
    bool sticky = bc_any_adhesion(ctx) != 0; /* (a schedule changes adhesion only between calls) */
    for (int64_t n = 0; n < steps; n++) {
        if (awake_blobs == 0 && !movers) { /* everything asleep: nothing moves, and only a mover could wake it */
            s->steps_done[0] += 1;
            continue;
        }
        int first_detection = 1; /* blob contacts are found once per step (and again when a blob outgrows them) */
        if (c->loaded) bc_note_wall_sides(ctx); /* which side of each loaded wall each blob is on */
        /* the scene's substeps, or more where a blob would move or sag too far in one */
        int64_t substeps = bc_substeps_for(ctx, g);
        if (c->loaded) substeps = bc_imax(substeps, bc_loaded_substeps(ctx)); /* and as a loaded wall's load dents */
        double h = c->dt / (double)substeps;
        double damping = exp(-c->damping * h);
        double rest_speed = bc_rest_speed(g, h); /* slower impacts never bounce (restitution.c) */
        s->substeps_taken[0] = s->substeps_taken[0] > substeps ? s->substeps_taken[0] : substeps;
        s->substeps_taken[1] += substeps > c->substeps;
        /* the packing records (the step's contact impulses as the stress, the pairs touching at its end and their
         * forces: packing.py) are what the caller reads after the call, so only its last step keeps them */
        context.records = periodic && n == steps - 1;
        if (ctx->records)
            for (int64_t k = 0; k < 4 * m->blob_count; k++) s->virial[k] = 0.0;
        for (int64_t sub = 0; sub < substeps; sub++) {
            if (c->moving) { /* colliders to where they are at the substep's end; those near sleeping blobs wake them */
                bc_place_walls(ctx, (double)(s->steps_done[0] * substeps + sub) * h, h);
                t = lap(clock, LAP_WALLS, t);
            }
            if (c->damping > 0.0) { /* (v - v_rigid) *= exp(-damping h) */
                bc_damp_deformation(ctx, damping);
                t = lap(clock, LAP_DAMPING, t);
            }
            if (c->drag > 0.0) { /* v *= exp(-drag h): all motion, toward rest */
                bc_drag_motion(ctx, exp(-c->drag * h));
                t = lap(clock, LAP_DAMPING, t);
            }
            /* x_prev <- x, v += g h, x += v h (rigid rotation exact); multipliers and contacts start at 0 */
            bc_predict(ctx, h);
            for (int64_t b = 0; b < m->blob_count; b++) {
                s->area_lam[b] = 0.0;
                s->perimeter_lam[b] = 0.0;
            }
            for (int64_t k = 0; k < m->spring_count; k++) s->spring_lam[k] = 0.0;
            t = lap(clock, LAP_PREDICT, t);
            /* pairs of a vertex and an edge of its own ring that may meet this substep */
            bc_find_self_contacts(ctx);
            int64_t self_found = bc_self_pairs_found(ctx);
            t = lap(clock, LAP_SELF_CONTACT, t);
            if (collides) { /* uniform grid of blob centres */
                int64_t count = bc_find_blob_pairs(ctx);
                if (count > ctx->w->pair_capacity) {
                    stop = (bcStop){n, BC_TOO_MANY_PAIRS, count};
                    goto done;
                }
                bc_carry_impacts(ctx);
                t = lap(clock, LAP_BROAD_PHASE, t);
            }
            for (int64_t it = 0; it < c->iterations; it++) {
                t = iterate(ctx, it, self_found, first_detection, (double)(substeps - sub) * h, sticky, g, h, clock,
                            t);
                if (collides && ctx->w->pair_count > 0) first_detection = 0;
            }
            /* where the constraints left two edges of a ring crossed, their ends move rigidly for the substep */
            int64_t zoned_before = zoned_total(ctx);
            bc_keep_rings_simple(ctx, h, c->method == KOT);
            t = lap(clock, LAP_SELF_CONTACT, t);
            if (statics && (self_found > 0 || zoned_total(ctx) > zoned_before)) {
                /* the statics have the last word: a vertex that the self-contacts or a zone moved into a collider
                 * is put back now; left there, the next substep would take the far side of a segment (or of a
                 * moving wall's line) for the side it belongs to, and keep it there */
                bc_collide_statics(ctx, h);
                if (c->loaded) {
                    bc_collide_loaded_corners(ctx, h);
                    bc_yield_loaded_walls(ctx);
                }
                t = lap(clock, LAP_STATICS, t);
            }
            if (c->loaded) {
                bc_finish_loaded_walls(ctx, h);
                t = lap(clock, LAP_STATICS, t);
            }
            /* v = (x - x_prev) / h (rotation read as an angle), kinetic friction at static contacts */
            bc_update_velocities(ctx, h);
            if (statics) bc_stop_impact_velocities(ctx);
            t = lap(clock, LAP_VELOCITIES, t);
            if (statics) { /* leave statics at e × impact speed, never faster */
                bc_restitution(ctx, rest_speed);
                t = lap(clock, LAP_RESTITUTION, t);
                /* the velocity stages' impulses into the colliders' records, and a loaded wall's share of them */
                bc_record_contact_impulses(ctx, h);
                if (c->loaded) bc_react_loaded_walls(ctx, h);
                t = lap(clock, LAP_STATICS, t);
            }
            if (collides && ctx->w->pair_count > 0) { /* blob contacts: no approach, Coulomb friction */
                bc_blob_contact_velocities(ctx, h);
                t = lap(clock, LAP_BLOB_VELOCITIES, t);
            }
            if (collides) { /* blob pairs leave each other at e × impact speed, never faster */
                bc_blob_restitution(ctx, rest_speed);
                bc_keep_impacts(ctx);
                bc_release_sticks(ctx); /* static friction holds only contacts that keep pushing */
                t = lap(clock, LAP_BLOB_RESTITUTION, t);
            }
        }
        if (ctx->records) bc_keep_touching(ctx, h); /* the pairs in contact at the step's end, for the contact numbers */
        if (c->sleep) { /* islands of blobs at rest fall asleep, islands with a mover wake */
            awake_blobs = bc_update_sleep(ctx);
            t = lap(clock, LAP_SLEEP, t);
        }
        if (statics) { /* the step's pushes as impulses on the colliders */
            bc_account_contacts(ctx, h);
            t = lap(clock, LAP_STATICS, t);
        }
        s->steps_done[0] += 1;
        int64_t bad = bc_first_runaway(ctx, runaway);
        if (bad >= 0) {
            stop = (bcStop){n, BC_RUNAWAY_VERTEX, bad};
            goto done;
        }
        if (c->moving) {
            bad = bc_first_runaway_wall(s->static_pose, m->walls.count, runaway);
            if (bad >= 0) {
                stop = (bcStop){n, BC_RUNAWAY_WALL, bad};
                goto done;
            }
            bad = c->loaded ? bc_find_passed_blob(ctx) : -1; /* a blob a loaded wall passed through */
            if (bad >= 0) {
                stop = (bcStop){n, BC_PASSED_BLOB, bad};
                goto done;
            }
            bad = bc_first_broken_blob(ctx); /* a blob a moving collider turned inside out or crushed */
            if (bad >= 0) {
                stop = (bcStop){n, BC_BROKEN_BLOB, bad};
                goto done;
            }
        }
    }
done:
    bc_scratch_free(own);
    return stop;
}
