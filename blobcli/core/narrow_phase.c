/* The narrow phase between blobs (collide.py's keep_blob_contacts), after Box2D v3, which builds its contacts once
 * per step with a speculative margin and solves them in every substep.
 *
 * Contacts are found once per step: each vertex p of blob A keeps up to CONTACTS_PER_VERTEX contacts, one per
 * neighbouring blob B, nearest first: B's nearest edge, if p is inside B or outside it by less than the pair's
 * margin m_A + m_B. Inside, edges whose outward normal opposes p's own are preferred (as JellyCar's and Gish's
 * engines do), so that a vertex is not pulled through to B's far side. Each blob's budget m (renew) covers the
 * motion the step can bring; before every iteration, a blob with a vertex farther than m from where its contacts
 * were found has them found again, with its partners (whose contacts with it are stale too); the rest keep theirs.
 *
 * Deep overlap (a blob driven far into another, or spawned overlapping): when either centre is inside the other
 * polygon, vertex–edge pushes have no sensible "nearest" side. Then a line perpendicular to c_B - c_A splits the
 * two, placed at c_A + (c_B - c_A) r_A / (r_A + r_B); each blob's vertices beyond it are put back on it, and both
 * blobs are shifted by one common Δx that cancels the momentum this added.
 *
 * In a periodic box every partner is met as its image nearest the blob (periodic.h: bc_image); in an open world
 * the shift is 0 and no arithmetic is done.
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "broad_phase.h"
#include "collide_limits.h"
#include "narrow_phase.h"
#include "parallel.h"
#include "periodic.h"
#include "ring.h"
#include "scratch.h"
#include "vector_loops.h"

#define CONTACTS BC_CONTACTS_PER_VERTEX
static const double BROAD_MARGIN = 0.25; /* × the larger radius: the broad phase's margin (collide.py) */
static const double CONTACT_SLOP = 0.02; /* × the blob's radius: room in the kept contacts' margin for the
                                          * solver's own corrections */
static const int64_t NO_EDGE = INT64_MAX; /* above the bits of any squared distance */

/* For each awake blob b: its centre and radius now, and moved[b], how far its vertices are, at most, from where
 * its contacts were found (its anchor). */
static void moved_since_found(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const uint8_t *awake = s->awake;
    const double *pos = s->position, *anchor = s->anchor;
    double *center = s->center, *radius = s->radius, *moved = s->moved;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!awake[b]) continue;
        int64_t o = offsets[b], e = offsets[b + 1];
        double d2 = 0.0, cx = 0.0, cy = 0.0;
        for (int64_t i = o; i < e; i++) {
            double dx = pos[i] - anchor[i], dy = pos[n + i] - anchor[n + i];
            d2 = bc_max(d2, dx * dx + dy * dy);
            cx += pos[i];
            cy += pos[n + i];
        }
        moved[b] = sqrt(d2);
        center[2 * b] = cx / (double)(e - o);
        center[2 * b + 1] = cy / (double)(e - o);
        radius[b] = bc_ring_radius(pos, n, o, e, center[2 * b], center[2 * b + 1]);
    });
}

/* deep[k]: either centre of pair k lies inside the other blob, both awake (one awake blob deep in a sleeping one
 * wakes its island at the end of the step, and is split from it then). */
static void deep_pairs(const bcContext *ctx, uint8_t *deep, bcBox box) {
    const bcModel *m = ctx->m;
    const bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets, *pairs = ctx->w->pairs;
    const uint8_t *awake = s->awake;
    const double *pos = s->position, *center = s->center, *radius = s->radius;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t k = 0; k < ctx->w->pair_count; k++), {
        int64_t a = pairs[2 * k], b = pairs[2 * k + 1];
        if (!(awake[a] && awake[b])) {
            deep[k] = 0;
            continue;
        }
        /* A centre farther from the other's centre than its radius cannot be inside it. */
        double sx, sy;
        bc_image(center, a, b, box, &sx, &sy);
        double dx = center[2 * a] + sx - center[2 * b], dy = center[2 * a + 1] + sy - center[2 * b + 1];
        double d2 = dx * dx + dy * dy;
        deep[k] = (d2 <= radius[b] * radius[b]
                   && bc_ring_contains(pos, n, offsets[b], offsets[b + 1], center[2 * a] + sx, center[2 * a + 1] + sy))
                  || (d2 <= radius[a] * radius[a]
                      && bc_ring_contains(pos, n, offsets[a], offsets[a + 1], center[2 * b] - sx,
                                          center[2 * b + 1] - sy));
    });
}

/* Deep-overlap fallback for pair (a, b): split them along a line between the centres (a's nearest image of b's,
 * in a periodic box). The line is perpendicular to u = (c_b - c_a) / |c_b - c_a| through
 * s = c_a + (c_b - c_a) r_a / (r_a + r_b); a vertex at d = ±(x - s) · u > 0 beyond it (on the other blob's side)
 * is put back on it, and the momentum Σ m Δx this adds is cancelled by one common shift of both blobs. */
static void separate_deep(const bcContext *ctx, int64_t a, int64_t b, bcBox box) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const double *inv_mass = m->inv_mass, *center = s->center, *radius = s->radius;
    double *pos = s->position;
    double ox, oy;
    bc_image(center, b, a, box, &ox, &oy); /* b's vertices, seen from a: x + o */
    double bx = center[2 * b] + ox, by = center[2 * b + 1] + oy;
    double ux = bx - center[2 * a], uy = by - center[2 * a + 1];
    double dist = sqrt(ux * ux + uy * uy);
    if (dist > 0.0) {
        ux = ux / dist;
        uy = uy / dist;
    } else {
        ux = 1.0;
        uy = 0.0;
    }
    double share = radius[a] / (radius[a] + radius[b]);
    double sx = center[2 * a] + (bx - center[2 * a]) * share, sy = center[2 * a + 1] + (by - center[2 * a + 1]) * share;
    double px = 0.0, py = 0.0, m_sum = 0.0;
    const int64_t blobs[2] = {a, b};
    const double sides[2] = {1.0, -1.0}, fxs[2] = {0.0, ox}, fys[2] = {0.0, oy};
    for (int q = 0; q < 2; q++) {
        double side = sides[q], fx = fxs[q], fy = fys[q];
        for (int64_t i = offsets[blobs[q]]; i < offsets[blobs[q] + 1]; i++) {
            double mass = 1.0 / inv_mass[i];
            m_sum += mass;
            double d = ((pos[i] + fx - sx) * ux + (pos[n + i] + fy - sy) * uy) * side; /* > 0: beyond the line */
            if (d > 0.0) {
                pos[i] -= d * side * ux;
                pos[n + i] -= d * side * uy;
                px -= mass * d * side * ux;
                py -= mass * d * side * uy;
            }
        }
    }
    /* One common shift of both blobs removes the momentum the pushes added. */
    for (int q = 0; q < 2; q++) {
        for (int64_t i = offsets[blobs[q]]; i < offsets[blobs[q] + 1]; i++) {
            pos[i] -= px / m_sum;
            pos[n + i] -= py / m_sum;
        }
    }
}

/* Outgrown blobs start afresh: anchor here, moved 0, and the budget
 *     m = min(CONTACT_SLOP r + |v|_max T + |g| T², BROAD_MARGIN r / 2),
 * T the time left in the step: the motion the step can bring, with room for the solver's corrections; the cap
 * keeps every margin within the broad phase's, so a pair that was not listed when contacts were found cannot
 * touch unseen. */
static void renew(const bcContext *ctx, const uint8_t *outgrown, double reach_time, double g) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t n = m->vertex_count, *offsets = m->offsets;
    const uint8_t *awake = s->awake;
    const double *pos = s->position, *vel = s->velocity, *radius = s->radius;
    double *anchor = s->anchor, *budget = s->budget, *moved = s->moved;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!(awake[b] && outgrown[b])) continue;
        double v2 = 0.0;
        for (int64_t i = offsets[b]; i < offsets[b + 1]; i++) {
            anchor[i] = pos[i];
            anchor[n + i] = pos[n + i];
            v2 = bc_max(v2, vel[i] * vel[i] + vel[n + i] * vel[n + i]);
        }
        moved[b] = 0.0;
        budget[b] = bc_min(CONTACT_SLOP * radius[b] + sqrt(v2) * reach_time + g * (reach_time * reach_time),
                           0.5 * BROAD_MARGIN * radius[b]);
    });
}

/* nearest_edge's running readings: how many edges the ray from p crosses, and the least bits of a squared distance
 * (over all edges, and over the opposing ones) with the edge that has them */
typedef struct {
    int64_t crossings, least, least_opposing, m_least, m_opposing;
} Nearest;

/* The first of count values equal to v (one is) */
static inline int64_t first_equal(const int64_t *values, int64_t count, int64_t v) {
    int64_t k = 0;
    while (values[k] != v && k < count - 1) k++;
    return k;
}

/* Edges first .. first + count - 1 (count <= EDGE_CHUNK) of B (rows ax, ay, ex, ey, inv_len2) taken into `near` for
 * p = (x, y), in order: an edge becomes the nearest when its bits are below the least so far (so the first of
 * equal ones stays). The ray from p toward +x crosses edge m when its ends lie on both sides of y and
 * (r × e) e_y < 0, r = p - a_m (crossing number, without dividing); its nearest point is a_m + t e,
 * t = clamp(r · e / |e|², 0, 1), at d² = |t e - r|²; it opposes p's normal v when its outward normal (B's winding
 * `orient`) does. The readings of the chunk are branch-free, on vector registers; then its least bits, and the
 * first edge that has them. */
#define EDGE_CHUNK 32
BC_VECTOR_LOOPS static void take_edges(Nearest *near, const double *ax, const double *ay, const double *ex,
                                       const double *ey, const double *inv_len2, int64_t first, int64_t count, double x,
                                       double y, double orient, double vnx, double vny) {
    int64_t bits[EDGE_CHUNK], opposing[EDGE_CHUNK]; /* opposing: the bits of an opposing edge, NO_EDGE for others */
    int64_t crossings = 0;
    for (int64_t k = 0; k < count; k++) {
        int64_t m = first + k;
        double rx = x - ax[m], ry = y - ay[m];
        crossings += (ay[m] > y) != (ay[m] + ey[m] > y) && (rx * ey[m] - ry * ex[m]) * ey[m] < 0.0 ? 1 : 0;
        double t = bc_min(bc_max((rx * ex[m] + ry * ey[m]) * inv_len2[m], 0.0), 1.0);
        double dx = t * ex[m] - rx, dy = t * ey[m] - ry;
        double d2 = dx * dx + dy * dy;
        memcpy(bits + k, &d2, sizeof d2);
        opposing[k] = orient * (ey[m] * vnx - ex[m] * vny) < 0.0 ? bits[k] : NO_EDGE;
    }
    int64_t least = NO_EDGE, least_opposing = NO_EDGE;
    for (int64_t k = 0; k < count; k++) {
        least = bits[k] < least ? bits[k] : least;
        least_opposing = opposing[k] < least_opposing ? opposing[k] : least_opposing;
    }
    near->crossings += crossings;
    if (least < near->least) {
        near->least = least;
        near->m_least = first + first_equal(bits, count, least);
    }
    if (least_opposing < near->least_opposing) {
        near->least_opposing = least_opposing;
        near->m_opposing = first + first_equal(opposing, count, least_opposing);
    }
}

/* The edge of blob B nearest p = (x, y) (edge table rows ax, ay, ex, ey, inv_len2 from B's first vertex on, n of
 * them), as its index in B's ring, or -1 when there is none; *inside: whether p is inside B; *d2: the squared
 * distance to it. Inside B, the nearest among the edges whose outward normal (B's winding `orient`) opposes p's
 * own normal v, if any does. Ties: the first edge with the least distance in ring order from the closing edge,
 * n - 1, 0, 1, ..., n - 2.
 *
 * d² >= 0, and the bit patterns of non-negative doubles order as integers do: the least distance is an integer
 * minimum over the bits, so equal distances are equal minima, and the first edge in that order to reach the
 * minimum is the one kept (the same edge as a search for the minimum's bits from n - 1 on). */
static inline int64_t nearest_edge(const double *ax, const double *ay, const double *ex, const double *ey,
                                   const double *inv_len2, int64_t n, double x, double y, double orient, double vnx,
                                   double vny, bool *inside, double *d2_nearest) {
    Nearest near = {0, NO_EDGE, NO_EDGE, -1, -1};
    if (n > 0) take_edges(&near, ax, ay, ex, ey, inv_len2, n - 1, 1, x, y, orient, vnx, vny);
    for (int64_t first = 0; first < n - 1; first += EDGE_CHUNK)
        take_edges(&near, ax, ay, ex, ey, inv_len2, first, bc_imin(n - 1 - first, EDGE_CHUNK), x, y, orient, vnx,
                   vny);
    if (near.least == NO_EDGE) return -1;
    *inside = near.crossings % 2 == 1;
    bool opposing = *inside && near.least_opposing != NO_EDGE;
    memcpy(d2_nearest, opposing ? &near.least_opposing : &near.least, sizeof *d2_nearest);
    return opposing ? near.m_opposing : near.m_least;
}

/* For every vertex of a stale blob A: its contacts (the edge), at most CONTACTS_PER_VERTEX, each with another
 * blob, nearest first (inside before outside): every blob B whose boundary the vertex is inside of, or outside of
 * by less than the pair's margin reach[A] + reach[B], how far each may go from here before it outgrows its budget.
 *
 * A contact with a blob that the vertex had a contact with before keeps that one's stick point (stick_edge,
 * stick_t); the others start without. Parallel over blobs; each blob writes only its own vertices' slots (and
 * the scratch's key and old stick points, per vertex too), so the result does not depend on the number of
 * threads. */
static void detect(const bcContext *ctx, const uint8_t *stale, const uint8_t *deep, const double *reach, bcBox box) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t n = m->vertex_count, *offsets = m->offsets, *blob_of = m->blob_of;
    const int64_t *start = w->partner_start, *partner = w->partner, *pair_of = w->partner_pair;
    const double *orient = m->orient, *pos = s->position, *center = s->center, *radius = s->radius;
    const double *edges = s->edges;
    int64_t *c_edge = s->c_edge, *stick_edge = s->stick_edge, *old_edge = w->detect_old_edge;
    double *stick_t = s->stick_t, *key = w->detect_key, *old_t = w->detect_old_t;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t A = 0; A < m->blob_count; A++), {
        if (!stale[A]) continue;
        int64_t oa = offsets[A], ea = offsets[A + 1];
        /* the stick points of the contacts found before, to carry over to the same blobs' contacts */
        for (int64_t i = oa; i < ea; i++) {
            for (int64_t c = 0; c < CONTACTS; c++) {
                old_edge[c * n + i] = stick_edge[c * n + i];
                old_t[c * n + i] = stick_t[c * n + i];
                c_edge[c * n + i] = stick_edge[c * n + i] = -1;
            }
        }
        for (int64_t k = start[A]; k < start[A + 1]; k++) {
            if (deep[pair_of[k]]) continue;
            int64_t B = partner[k];
            double sx, sy;
            bc_image(center, A, B, box, &sx, &sy); /* A's vertices as B's nearest image of A has them */
            int64_t ob = offsets[B], eb = offsets[B + 1];
            double margin = reach[A] + reach[B];
            double cx = center[2 * B], cy = center[2 * B + 1], reach2 = (radius[B] + margin) * (radius[B] + margin);
            const double *ax = edges + ob, *ay = edges + n + ob, *ex = edges + 2 * n + ob, *ey = edges + 3 * n + ob,
                         *inv_len2 = edges + 4 * n + ob;
            for (int64_t i = oa; i < ea; i++) {
                double x = pos[i] + sx, y = pos[n + i] + sy;
                if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > reach2) continue; /* beyond B's circle and margin */
                double vnx, vny;
                bc_vertex_normal(pos, n, orient[A], i, oa, ea, &vnx, &vny);
                bool inside = false;
                double d2 = 0.0;
                int64_t edge = nearest_edge(ax, ay, ex, ey, inv_len2, eb - ob, x, y, orient[B], vnx, vny, &inside,
                                            &d2);
                if (edge < 0) continue;
                double distance = sqrt(d2);
                if (!inside && distance >= margin) continue;
                /* keep the nearest CONTACTS_PER_VERTEX, by signed distance (< 0 inside; ties: the first found) */
                double signed_distance = inside ? -distance : distance;
                edge += ob;
                for (int64_t c = 0; c < CONTACTS; c++) {
                    int64_t slot = c * n + i;
                    if (c_edge[slot] < 0 || signed_distance < key[slot]) {
                        double kept = key[slot];
                        key[slot] = signed_distance;
                        signed_distance = kept;
                        int64_t kept_edge = c_edge[slot];
                        c_edge[slot] = edge;
                        edge = kept_edge;
                        if (edge < 0) break;
                    }
                }
            }
        }
        for (int64_t i = oa; i < ea; i++) {
            for (int64_t c = 0; c < CONTACTS; c++) {
                if (c_edge[c * n + i] < 0) continue;
                for (int64_t r = 0; r < CONTACTS; r++) {
                    int64_t old = old_edge[r * n + i];
                    if (old >= 0 && blob_of[old] == blob_of[c_edge[c * n + i]]) {
                        stick_edge[c * n + i] = old;
                        stick_t[c * n + i] = old_t[r * n + i];
                    }
                }
            }
        }
    });
}

/* Narrow phase, every iteration: split deeply overlapping pairs; then find the contacts (c_edge) of every awake
 * blob (first: at the start of the step), or only of those whose vertices went farther than their budget from
 * where theirs were found, or were split, and of their partners; the rest keep theirs. reach_time: the time left
 * in the step. */
void bc_keep_blob_contacts(const bcContext *ctx, int first, double reach_time, double g) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t B = m->blob_count, P = w->pair_count, *pairs = w->pairs;
    if (P < 0 || P > w->pair_capacity) return; /* (the broad phase lists no pairs past its capacity) */
    const uint8_t *awake = s->awake;
    const double *budget = s->budget, *moved = s->moved;
    uint8_t *outgrown = w->outgrown, *stale = w->stale, *deep = w->deep;
    double *reach = w->reach;
    bcBox box = bc_box(ctx->c->box_x, ctx->c->box_y, ctx->c->box_tilt);
    moved_since_found(ctx);
    for (int64_t b = 0; b < B; b++) outgrown[b] = awake[b] && (first || moved[b] > budget[b]);
    deep_pairs(ctx, deep, box);
    for (int64_t k = 0; k < P; k++) { /* rare: separate them first, in pair order */
        if (deep[k]) {
            separate_deep(ctx, pairs[2 * k], pairs[2 * k + 1], box);
            outgrown[pairs[2 * k]] = outgrown[pairs[2 * k + 1]] = 1;
        }
    }
    bool any = false;
    for (int64_t b = 0; b < B; b++) any |= outgrown[b] != 0;
    if (!any) return;
    /* a partner's contacts with an outgrown blob are stale too */
    memcpy(stale, outgrown, (size_t)B * sizeof *stale);
    for (int64_t k = 0; k < P; k++) {
        int64_t a = pairs[2 * k], b = pairs[2 * k + 1];
        stale[a] |= outgrown[b] && awake[a];
        stale[b] |= outgrown[a] && awake[b];
    }
    bc_blob_bounds(ctx, 0);
    renew(ctx, outgrown, reach_time, g);
    /* How far each blob may still go from here: its budget, plus what it has moved already (its anchor stays where
     * it was, so its partners' contacts found before stay valid). A sleeping blob does not move. */
    for (int64_t b = 0; b < B; b++) reach[b] = awake[b] ? budget[b] + moved[b] : 0.0;
    detect(ctx, stale, deep, reach, box);
}
