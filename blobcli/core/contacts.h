/* contacts.h: what the blob-contact stages share (contact_solver.c, contact_velocities.c): the arrays they read
 * and small geometry (not read by cffi) */
#ifndef BC_CONTACTS_H
#define BC_CONTACTS_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "blobcore.h"
#include "collide_limits.h"
#include "friction.h"
#include "packing_records.h"
#include "periodic.h"
#include "ring.h"
#include "scratch.h"

#define CPV BC_CONTACTS_PER_VERTEX

/* The arrays the contact stages read, with the vertex count N: (2, N) arrays are x = a[i], y = a[N + i];
 * c_edge and the like (CONTACTS_PER_VERTEX, N): slot c of vertex p is [c N + p] */
typedef struct Contacts {
    int64_t n;
    double *pos;
    const double *prev, *inv_mass;
    const int64_t *offsets, *blob_of;
    const uint8_t *awake;
    const double *orient, *material; /* material: (B, 3) μ_s, μ_k, e */
    int64_t *c_edge;
    uint8_t *c_hit;
    double *c_normal; /* (2, CONTACTS_PER_VERTEX, N) */
    double *depth;    /* blob_contact_depth */
    const double *center, *radius;
    double up_x, up_y;
    int64_t *stick_edge;
    double *stick_t;
    bcBox box;
    bool records;         /* the step keeps the packing records (a periodic box's: bcContext.records) ... */
    double *virial;       /* ... the blobs' virial, (B, 4), NULL in an open world ... */
    const bcScratch *w;   /* ... and the pairs and their impulses (packing_records.h) */
    double *friction_sum; /* (2, CONTACTS_PER_VERTEX, N): K, each contact's tangential correction this substep */
    double h;
} Contacts;

static inline Contacts contacts_of(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const bcSettings *c = ctx->c;
    return (Contacts){.n = m->vertex_count, .pos = s->position, .prev = s->previous, .inv_mass = m->inv_mass,
                      .offsets = m->offsets, .blob_of = m->blob_of, .awake = s->awake, .orient = m->orient,
                      .material = m->material, .c_edge = s->c_edge, .c_hit = s->c_hit, .c_normal = s->c_normal,
                      .depth = s->blob_contact_depth, .center = s->center, .radius = s->radius, .up_x = c->up_x,
                      .up_y = c->up_y, .stick_edge = s->stick_edge, .stick_t = s->stick_t,
                      .box = bc_box(c->box_x, c->box_y, c->box_tilt), .records = ctx->records != 0,
                      .virial = s->virial, .w = ctx->w, .friction_sum = ctx->w->friction_sum, .h = h};
}

static inline double clamp01(double t) { return bc_min(bc_max(t, 0.0), 1.0); }

/* Where p projects onto the line of edge e0→e1, as t (0 at x_0, 1 at x_1; 0 for a zero-length edge) */
static inline double along(const double *pos, int64_t n, int64_t e0, int64_t e1, double px, double py) {
    double ex = pos[e1] - pos[e0], ey = pos[n + e1] - pos[n + e0];
    double len2 = ex * ex + ey * ey;
    return len2 > 0.0 ? ((px - pos[e0]) * ex + (py - pos[n + e0]) * ey) / len2 : 0.0;
}

/* (μ_s D, μ_k D) of a contact between blobs a and b */
static inline void friction_limits(const double *material, int64_t a, int64_t b, double D, double *static_limit,
                                   double *kinetic_limit) {
    *static_limit = bc_mix_friction(material[3 * a], material[3 * b]) * D;
    *kinetic_limit = bc_mix_friction(material[3 * a + 1], material[3 * b + 1]) * D;
}


#endif
