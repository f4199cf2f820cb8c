/* Self-contact: a ring's non-adjacent parts do not pass through each other.
 *
 * Blob–blob contacts keep two rings apart; nothing else keeps one ring from crossing itself. A strip
 * folded in two (its outer surface meets itself), pinched over a post (its inner surfaces meet), or a
 * fine ring kinked on a bump pushes a vertex through one of its own edges, and once crossed the signed
 * area no longer measures the blob. So a vertex p is kept off every edge (x_0, x_1) of its own ring that
 * is not one of p's two.
 *
 * With q = (1 - t) x_0 + t x_1 the point of the edge facing p (0 <= t <= 1) and n the edge's outward
 * normal, s = (p - q) · n is p's signed distance from the edge: > 0 outside (two parts of the surface
 * folding onto each other), < 0 inside (the blob pinched between them). p keeps to the side σ = sign(s)
 * it was on (below), at least a gap g from the edge:
 *     C = σ (p - q) · n - g >= 0,   ∇_p C = σ n,   ∇_0 C = -(1 - t) σ n,   ∇_1 C = -t σ n,
 *     λ = -C / (w_p + (1 - t)² w_0 + t² w_1),   Δp = w_p λ σ n,   Δx_0 = -(1 - t) w_0 λ σ n,   Δx_1 = -t w_1 λ σ n:
 * the point–edge constraint of blob–blob contacts, one-sided; Σ m Δx = 0, so momentum is exact.
 * g = min(GAP L̄, |s_0|), L̄ the ring's mean rest edge and s_0 the distance when the substep began: a push
 * never leaves p farther out than it was, so it stops an approach and never throws the two parts apart
 * (no energy is created). Friction: Coulomb on the slip of p against q over the substep, with the blob's
 * μ_s and μ_k and D the depth this contact pushed out this substep: the slip is undone if |slip| <= μ_s D,
 * else cut by μ_k times each iteration's push.
 *
 * The side is read where p faces the edge (0 <= t <= 1): at the substep's start, or, for p beyond the
 * edge's end then, where its straight path from there to its predicted place comes to face the edge, or
 * else where it first faces the edge in the iterations. (Beyond the end, the edge's line says nothing: at
 * a convex corner it runs out of the ring, and p may go round the corner outside.) While p is beyond the
 * edge's ends, it is kept GAP L̄ off the vertex there: the wedge beyond a convex corner faces neither of
 * its edges, and a vertex falling onto the corner's tip went through it. A pair acts only while p is
 * shallower than REACH L̄ plus how far the prediction moved it against the edge: deeper, p is a far part
 * of the ring whose foot happens to fall on the edge, not a crossing.
 *
 * Pairs are found once per substep, after predict, so that a blob nowhere near folding pays almost
 * nothing. The ring is cut into chunks of CHUNK edges. Two chunks that are not neighbours are tested
 * vertex by edge only when their boxes, over the substep's start and its predicted end, come within the
 * reach R = REACH L̄. A chunk with its neighbour (and a chunk alone) is skipped when all their edges point
 * within 75° of one axis û, at both ends of the substep: then two points of the arc they make a length ℓ
 * of ring apart are at least ℓ cos 75° apart ((x_b - x_a) · û = ∫ τ · û dℓ), and a vertex is at least a
 * whole edge of ring from any edge not its own, so farther than R when L_min cos 75° > R, L_min their
 * shortest edge. (Each chunk's edges lie in a cone about its chord; two cones of half-angles α_c, α_d
 * whose axes are θ apart lie in one of half-angle (α_c + α_d + θ) / 2.) A round 32-gon's neighbouring
 * chunks turn through 90° (8 edges of 11.25°): a blob that keeps its shape has no pair to test. A pair is
 * kept when it is within R at either end of the substep or its path passes through the edge, up to
 * PER_VERTEX per vertex. A ring whose chunks were all apart keeps that shape as a skin (in_skin): while it
 * only moves rigidly and deforms a little from it, it is not measured again.
 *
 * What the iterations still leave crossed, bc_keep_rings_simple mends after them (impact_zones.c).
 *
 * Arrays (blobcore.h): positions (2, N), x of vertex i at [i], y at [N + i]; pairs (2, PER_VERTEX N): each
 * pair's vertex and edge (its first vertex); values (4, PER_VERTEX N): its side σ (±1, or UNDECIDED), its
 * gap g (m), the depth D it pushed out this substep (m) and the deepest it may act at (m); ring b's pairs
 * fill count[b] slots from PER_VERTEX × its first vertex on.
 */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "parallel.h"
#include "ring.h"
#include "scratch.h"
#include "self_chunks.h"
#include "self_contact.h"

#define PER_VERTEX BC_SELF_PER_VERTEX

static const double GAP = 0.05;   /* × the mean rest edge: how close a vertex may come to an edge of its own ring */
/* a pair acts only where the vertices free to move can move it: w > this × their largest w */
static const double MIN_LEVER = 0.25;
/* the side of a pair whose vertex has not yet faced its edge this substep */
static const double UNDECIDED = 0.0;

/* Vertex p against edge (j, j1) at positions x: s, its signed distance along the edge's outward normal;
 * t, where its foot falls along the edge, unclamped; d, its distance from the segment. d < 0: a
 * degenerate edge. */
static inline void facing(const double *x, int64_t N, double orient, int64_t p, int64_t j, int64_t j1,
                          double *s, double *t, double *d) {
    double ex = x[j1] - x[j], ey = x[N + j1] - x[N + j];
    double len2 = ex * ex + ey * ey;
    if (len2 == 0.0) {
        *s = 0.0;
        *t = 0.0;
        *d = -1.0;
        return;
    }
    double rx = x[p] - x[j], ry = x[N + p] - x[N + j];
    *t = (rx * ex + ry * ey) / len2;
    *s = orient * (rx * ey - ry * ex) / sqrt(len2);
    double tc = bc_min(bc_max(*t, 0.0), 1.0);
    *d = hypot(rx - tc * ex, ry - tc * ey);
}

/* Whether p passes through edge (j, j1) between the substep's start (s0) and predicted end (s1): s changes
 * sign at τ = s0 / (s0 - s1), and there, with every point moved linearly, p faces the edge. */
static inline bool crosses(const double *prev, const double *pos, int64_t N, int64_t p, int64_t j, int64_t j1,
                           double s0, double s1) {
    if (s0 * s1 >= 0.0) return false;
    double tau = s0 / (s0 - s1);
    double x0 = prev[j] + tau * (pos[j] - prev[j]), y0 = prev[N + j] + tau * (pos[N + j] - prev[N + j]);
    double ex = prev[j1] + tau * (pos[j1] - prev[j1]) - x0;
    double ey = prev[N + j1] + tau * (pos[N + j1] - prev[N + j1]) - y0;
    double rx = prev[p] + tau * (pos[p] - prev[p]) - x0;
    double ry = prev[N + p] + tau * (pos[N + p] - prev[N + p]) - y0;
    double along = rx * ex + ry * ey;
    return 0.0 <= along && along <= ex * ex + ey * ey;
}

/* Test every vertex of one run of the ring against every edge of another that is not its own; keep the
 * pairs that are within reach or crossed (see above). Ring b's pairs fill slots slot0 .. slot0 + count[b],
 * at most PER_VERTEX (e - o) of them. */
static void keep_pairs(const double *prev, const double *pos, int64_t N, double orient, int64_t o, int64_t e,
                       int64_t vertices_from, int64_t vertices_to, int64_t edges_from, int64_t edges_to, double reach,
                       double gap, int64_t *pairs, double *values, int64_t slot0, int64_t *count, int64_t b) {
    const int64_t V = PER_VERTEX * N;  /* the length of a row of pairs and values */
    for (int64_t p = vertices_from; p < vertices_to; p++) {
        for (int64_t j = edges_from; j < edges_to; j++) {
            int64_t j1 = bc_next_in_ring(j, o, e);
            if (j == p || j1 == p) continue;
            double s0, t0, d0, s1, t1, d1;
            facing(prev, N, orient, p, j, j1, &s0, &t0, &d0);
            facing(pos, N, orient, p, j, j1, &s1, &t1, &d1);
            if (d0 < 0.0 || d1 < 0.0) continue;
            if (!(d0 < reach || d1 < reach || crosses(prev, pos, N, p, j, j1, s0, s1))) continue;
            int64_t k = count[b];
            if (k == PER_VERTEX * (e - o)) return;
            count[b] = k + 1;
            double side = UNDECIDED, s = s0;
            if (0.0 <= t0 && t0 <= 1.0) {
                side = s0 >= 0.0 ? 1.0 : -1.0;
            } else if ((t0 < 0.0) != (t1 < 0.0) || (t0 > 1.0) != (t1 > 1.0)) {
                /* p comes to face the edge: its side then */
                double tau = (t0 < 0.0 ? -t0 : t0 - 1.0) / fabs(t1 - t0);
                s = s0 + tau * (s1 - s0);
                side = s >= 0.0 ? 1.0 : -1.0;
            }
            pairs[slot0 + k] = p;
            pairs[V + slot0 + k] = j;
            values[slot0 + k] = side;
            values[V + slot0 + k] = bc_min(gap, side != UNDECIDED ? fabs(s) : d0);
            values[2 * V + slot0 + k] = 0.0;
            values[3 * V + slot0 + k] = reach + fabs(s1 - s0);
        }
    }
}

/* Whether ring o..e is still inside the skin set when it was last measured apart: then no vertex can come
 * within reach of an edge not its own this substep, and it need not be measured again. With y_i the ring
 * then about its centre (rows REF_X, REF_Y) and G a lower bound on how far apart its parts were (SKIN),
 * each end of the substep is fitted a rigid motion x_i ≈ c + Q y_i (2D Procrustes, as move_zones_rigidly)
 * and d is the farthest any vertex is from its fit. Every point between the two ends is
 * x_i(τ) = c_τ + ((1 - τ) Q_0 + τ Q_1) y_i + (at most d), and (1 - τ) Q_0 + τ Q_1 is a rotation scaled by
 * s >= cos(Δθ / 2), Δθ the angle between Q_0 and Q_1: every vertex-to-edge distance is at least s G - 2 d
 * all through the substep, and the ring needs no pair while that exceeds the reach (with 1% to spare for
 * rounding). */
static bool in_skin(const double *prev, const double *pos, int64_t N, int64_t o, int64_t e, const double *chunks,
                    double reach) {
    double apart = chunks[SKIN * N + o];
    if (apart == 0.0) return false;
    double means[4];
    bc_ring_means(prev, pos, N, o, e, means);
    double c0x = means[0], c0y = means[1], c1x = means[2], c1y = means[3];
    const double *ref_x = chunks + REF_X * N, *ref_y = chunks + REF_Y * N;
    double cross0 = 0.0, dot0 = 0.0, cross1 = 0.0, dot1 = 0.0;
    for (int64_t i = o; i < e; i++) {
        double yx = ref_x[i], yy = ref_y[i];
        cross0 += yx * (prev[N + i] - c0y) - yy * (prev[i] - c0x);
        dot0 += yx * (prev[i] - c0x) + yy * (prev[N + i] - c0y);
        cross1 += yx * (pos[N + i] - c1y) - yy * (pos[i] - c1x);
        dot1 += yx * (pos[i] - c1x) + yy * (pos[N + i] - c1y);
    }
    double norm0 = hypot(cross0, dot0), norm1 = hypot(cross1, dot1);
    if (norm0 == 0.0 || norm1 == 0.0) return false;
    double cos0 = dot0 / norm0, sin0 = cross0 / norm0, cos1 = dot1 / norm1, sin1 = cross1 / norm1;
    double scale = sqrt(bc_max(0.5 * (1.0 + cos0 * cos1 + sin0 * sin1), 0.0));  /* cos(Δθ / 2) */
    double far2 = 0.0;
    for (int64_t i = o; i < e; i++) {
        double yx = ref_x[i], yy = ref_y[i];
        double ax = prev[i] - c0x - cos0 * yx + sin0 * yy, ay = prev[N + i] - c0y - sin0 * yx - cos0 * yy;
        double bx = pos[i] - c1x - cos1 * yx + sin1 * yy, by = pos[N + i] - c1y - sin1 * yx - cos1 * yy;
        far2 = bc_max(bc_max(far2, ax * ax + ay * ay), bx * bx + by * by);
    }
    return 0.99 * scale * apart - 2.0 * sqrt(far2) > reach;
}

/* Ring o..e measured at pos with its parts at least `apart` from each other (0: some may meet): the skin
 * in_skin checks it against from now on. */
static void set_skin(const double *pos, int64_t N, int64_t o, int64_t e, double *chunks, double apart) {
    chunks[SKIN * N + o] = apart;
    if (apart == 0.0) return;
    double means[4];
    bc_ring_means(pos, pos, N, o, e, means);
    double cx = means[0], cy = means[1];
    for (int64_t i = o; i < e; i++) {
        chunks[REF_X * N + i] = pos[i] - cx;
        chunks[REF_Y * N + i] = pos[N + i] - cy;
    }
}

/* Each awake ring's self-contact pairs for this substep (see above); prev: positions at its start, pos:
 * predicted. near[b]: NEAR where two chunks of ring b may meet (else APART: bc_keep_rings_simple may skip
 * it). A ring still in the skin of its last measurement is not measured. */
void bc_find_self_contacts(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    const double *prev = s->previous, *pos = s->position;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        s->self_count[b] = 0;
        s->self_near[b] = APART;
        if (!s->awake[b]) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double mean_edge = m->rest_perimeter[b] / (double)(e - o);
        double reach = REACH * mean_edge, gap = GAP * mean_edge;
        if (in_skin(prev, pos, N, o, e, s->self_chunks, reach)) continue;
        chunk_shapes(prev, pos, N, o, e, s->self_chunks);
        int64_t slot0 = PER_VERTEX * o;
        double apart = INFINITY;
        for (int64_t c = o; c < e; c += CHUNK) {
            for (int64_t d = c; d < e; d += CHUNK) {
                double apart_by = chunks_apart_by(N, o, e, s->self_chunks, c, d, reach);
                if (apart_by > 0.0) {
                    apart = bc_min(apart, apart_by);
                    continue;
                }
                s->self_near[b] = NEAR;
                int64_t c_to = bc_imin(c + CHUNK, e), d_to = bc_imin(d + CHUNK, e);
                keep_pairs(prev, pos, N, m->orient[b], o, e, c, c_to, d, d_to, reach, gap, s->self_pairs,
                           s->self_values, slot0, s->self_count, b);
                if (d != c)
                    keep_pairs(prev, pos, N, m->orient[b], o, e, d, d_to, c, c_to, reach, gap, s->self_pairs,
                               s->self_values, slot0, s->self_count, b);
            }
        }
        set_skin(pos, N, o, e, s->self_chunks, s->self_near[b] == APART ? apart : 0.0);
    });
}

/* How many pairs bc_find_self_contacts found in all (none: the resolve stage has nothing to do). */
int64_t bc_self_pairs_found(const bcContext *ctx) {
    int64_t found = 0;
    for (int64_t b = 0; b < ctx->m->blob_count; b++) found += ctx->s->self_count[b];
    return found;
}

/* What one resolve pass reads: positions x (2, N), where the substep began, each vertex's inverse mass w,
 * its static push depth this substep (held) and that push's direction (normal, (2, N)). */
typedef struct Resolve {
    double *pos;
    const double *prev, *inv_mass;
    double *held;
    const double *normal;
    int64_t N;
    bool hold;
} Resolve;

/* A held vertex v that a push would have moved by share × w_v (dx, dy) does not move: the collider holding
 * it takes the push instead, and its depth D_v (held, the normal force its friction and bounce read) grows
 * by the part along its normal n_v that presses v into it. */
static inline void to_collider(const Resolve *r, int64_t v, double share, double dx, double dy) {
    if (r->held[v] == 0.0) return;
    double into = -share * r->inv_mass[v] * (dx * r->normal[v] + dy * r->normal[r->N + v]);
    if (into > 0.0) r->held[v] += into;
}

/* Vertex i's inverse mass in a self-contact: with `hold`, 0 when a collider has pushed it this substep. */
static inline double free_w(const Resolve *r, int64_t i) {
    return r->hold && r->held[i] != 0.0 ? 0.0 : r->inv_mass[i];
}

/* p beyond an end of the edge is kept at least `gap` from that end's vertex v: C = |p - x_v| - g >= 0,
 * ∇_p C = -∇_v C = (p - x_v) / |p - x_v| (at a convex corner, the wedge beyond both edges' ends is faced by
 * neither, and a vertex falling onto the corner's tip went through it). */
static void keep_off_vertex(const Resolve *r, int64_t p, int64_t v, double gap) {
    double *pos = r->pos;
    const int64_t N = r->N;
    double dx = pos[p] - pos[v], dy = pos[N + p] - pos[N + v];
    double distance = hypot(dx, dy);
    double C = distance - gap;
    double wp = free_w(r, p), wv = free_w(r, v);
    if (C >= 0.0 || distance == 0.0 || wp + wv == 0.0) return;
    double lam = -C / ((wp + wv) * distance);
    pos[p] += wp * lam * dx;
    pos[N + p] += wp * lam * dy;
    pos[v] -= wv * lam * dx;
    pos[N + v] -= wv * lam * dy;
}

/* One pair's push and friction (see above), its values in column k of values (4 rows of length V). With
 * `hold`, only a pair a collider has pushed into. */
static void resolve_pair(const Resolve *r, double orient, double mu_s, double mu_k, int64_t p, int64_t j, int64_t j1,
                         double *values, int64_t V, int64_t k) {
    double *pos = r->pos;
    const double *prev = r->prev;
    const int64_t N = r->N;
    /* the pair's σ, g, D and the deepest it may act at */
    double *side_k = values + k, *gap_k = values + V + k, *depth_k = values + 2 * V + k;
    const double *deepest_k = values + 3 * V + k;
    if (r->hold && r->held[p] == 0.0 && r->held[j] == 0.0 && r->held[j1] == 0.0) return;
    double ex = pos[j1] - pos[j], ey = pos[N + j1] - pos[N + j];
    double len2 = ex * ex + ey * ey;
    if (len2 == 0.0) return;
    double rx = pos[p] - pos[j], ry = pos[N + p] - pos[N + j];
    double t = (rx * ex + ry * ey) / len2;
    if (t < 0.0 || t > 1.0) {
        keep_off_vertex(r, p, t < 0.0 ? j : j1, *gap_k);
        return;
    }
    double length = sqrt(len2);
    double nx = orient * ey / length, ny = -orient * ex / length;
    double s = rx * nx + ry * ny;
    if (*side_k == UNDECIDED) {  /* p faces the edge for the first time this substep: its side from now on */
        *side_k = s >= 0.0 ? 1.0 : -1.0;
        *gap_k = bc_min(*gap_k, fabs(s));
    }
    double side = *side_k;
    double C = side * s - *gap_k;
    /* deeper than p could have come this substep: not a crossing, a far part of the ring */
    if (C < -*deepest_k) return;
    double wp = free_w(r, p), w0 = free_w(r, j), w1 = free_w(r, j1);
    double w = wp + (1.0 - t) * (1.0 - t) * w0 + t * t * w1;
    /* only a held vertex could move q: the free one would be flung by 1/lever */
    if (w <= MIN_LEVER * bc_max(bc_max(wp, w0), w1)) return;
    double pushed = 0.0;
    if (C < 0.0) {
        double lam = -C / w;
        double dx = lam * side * nx, dy = lam * side * ny;
        pos[p] += wp * dx;
        pos[N + p] += wp * dy;
        pos[j] -= (1.0 - t) * w0 * dx;
        pos[N + j] -= (1.0 - t) * w0 * dy;
        pos[j1] -= t * w1 * dx;
        pos[N + j1] -= t * w1 * dy;
        pushed = -C;
        *depth_k += pushed;
        if (r->hold) {  /* a held vertex's share goes to the collider that holds it (see to_collider) */
            to_collider(r, p, 1.0, dx, dy);
            to_collider(r, j, -(1.0 - t), dx, dy);
            to_collider(r, j1, -t, dx, dy);
        }
    }
    double D = *depth_k;
    if (D == 0.0) return;
    /* Coulomb: the slip of p against q along the edge since the substep began */
    double tx = ex / length, ty = ey / length;
    double slip = ((pos[p] - prev[p]) - (1.0 - t) * (pos[j] - prev[j]) - t * (pos[j1] - prev[j1])) * tx
        + ((pos[N + p] - prev[N + p]) - (1.0 - t) * (pos[N + j] - prev[N + j]) - t * (pos[N + j1] - prev[N + j1])) * ty;
    double cut = fabs(slip) <= mu_s * D ? slip : copysign(bc_min(fabs(slip), mu_k * pushed), slip);
    if (cut == 0.0) return;
    double lam = cut / w;
    pos[p] -= wp * lam * tx;
    pos[N + p] -= wp * lam * ty;
    pos[j] += (1.0 - t) * w0 * lam * tx;
    pos[N + j] += (1.0 - t) * w0 * lam * ty;
    pos[j1] += t * w1 * lam * tx;
    pos[N + j1] += t * w1 * lam * ty;
}

/* One Gauss-Seidel pass over each awake ring's self-contact pairs, in reverse order when `reverse` (every
 * second iteration, as blob contacts: one order alone favours the pairs it visits first). held
 * (s->contact_depth): each vertex's static push depth this substep, normal (s->contact_normal): its
 * direction; with `hold`, only the pairs a collider pushed into, with the vertices it pushed held (see
 * free_w, to_collider). */
void bc_resolve_self_contacts(const bcContext *ctx, int hold, int reverse) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count, V = PER_VERTEX * N;
    const Resolve r = {s->position, s->previous, m->inv_mass, s->contact_depth, s->contact_normal, N, hold != 0};
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        /* (count[b] is at most PER_VERTEX (e - o): bc_find_self_contacts's slots for the ring) */
        int64_t pairs_here = bc_imin(s->self_count[b], PER_VERTEX * (e - o));
        if (pairs_here <= 0 || !s->awake[b]) continue;
        int64_t slot0 = PER_VERTEX * o;
        for (int64_t n = 0; n < pairs_here; n++) {
            int64_t k = slot0 + (reverse ? pairs_here - 1 - n : n);
            int64_t p = s->self_pairs[k], j = s->self_pairs[V + k];
            if (p < o || p >= e || j < o || j >= e) continue;  /* (never, for pairs this stage found) */
            resolve_pair(&r, m->orient[b], m->material[3 * b], m->material[3 * b + 1], p, j, bc_next_in_ring(j, o, e),
                         s->self_values, V, k);
        }
    });
}
