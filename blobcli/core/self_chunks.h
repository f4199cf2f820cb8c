/* self_chunks.h: what the self-contact stages share (self_contact.c finds and resolves the pairs,
 * impact_zones.c mends what they leave crossed): the reach, the chunks a ring is cut into and the table of
 * their shapes (not read by cffi) */
#ifndef BC_SELF_CHUNKS_H
#define BC_SELF_CHUNKS_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "ring.h"
#include "self_contact.h"

#define CHUNK BC_SELF_CHUNK

static const double REACH = 0.15; /* × the mean rest edge: pairs closer at the substep's start or end are kept */
/* β = 75°: an arc whose edges all point within β of one axis cannot touch itself. cos β, cos 2β and sin 2β
 * as Python's math gives them for math.radians(75.0) (the bits the reference reads) */
static const double CONE_COS = 0x1.0907dc193069p-2;
static const double CONE_COS_2 = -0x1.bb67ae8584cabp-1;
static const double CONE_SIN_2 = 0x1.fffffffffffffp-2;
enum { APART = 0, NEAR = 1 };  /* a ring's chunks this substep: all apart; some may meet */

/* Rows of the chunk table (bcState.self_chunks, (CHUNK_ROWS, N), chunk c of ring o..e in column o + c CHUNK):
 * its box over both configurations, and for each configuration the cone its edges point in (axis a,
 * half-angle α as cos α and sin α) and its shortest edge, squared. The ring's skin (in_skin): in each
 * vertex's column, where it was about the ring's centre when the ring was last measured apart, and in the
 * ring's first column, how far apart its parts were then (G; 0: no skin). */
enum {
    BOX_X0 = 0, BOX_Y0 = 1, BOX_X1 = 2, BOX_Y1 = 3, AXIS_X = 4, AXIS_Y = 6, COS = 8, SIN = 10, SHORTEST2 = 12,
    REF_X = 14, REF_Y = 15, SKIN = 16, CHUNK_ROWS = BC_SELF_CHUNK_ROWS
};

/* Each chunk's box over the substep's start (prev) and end (pos) and, at each, its cone (about its chord
 * u) and shortest edge. */
static inline void chunk_shapes(const double *prev, const double *pos, int64_t N, int64_t o, int64_t e, double *chunks) {
    for (int64_t first = o; first < e; first += CHUNK) {
        int64_t last = bc_imin(first + CHUNK, e);
        int64_t end = last < e ? last : o;  /* the last edge's end */
        double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (int config = 0; config < 2; config++) {
            const double *x = config == 0 ? prev : pos;
            double ux = x[end] - x[first], uy = x[N + end] - x[N + first];
            double u2 = ux * ux + uy * uy;
            /* cos² α: the least (e · u)² / (|e|² |u|²); < 0: an edge turned back */
            double cos2 = 1.0, shortest2 = INFINITY;
            double ax = x[first], ay = x[N + first];
            for (int64_t i = first + 1; i < last + 1; i++) {
                int64_t j = i < e ? i : o;
                double bx = x[j], by = x[N + j];
                double ex = bx - ax, ey = by - ay;
                double along = ex * ux + ey * uy, e2 = ex * ex + ey * ey;
                shortest2 = bc_min(shortest2, e2);
                cos2 = bc_min(cos2, along * fabs(along) / (e2 * u2));
                x0 = bc_min(x0, bx);
                y0 = bc_min(y0, by);
                x1 = bc_max(x1, bx);
                y1 = bc_max(y1, by);
                ax = bx;
                ay = by;
            }
            x0 = bc_min(x0, x[first]);
            y0 = bc_min(y0, x[N + first]);
            x1 = bc_max(x1, x[first]);
            y1 = bc_max(y1, x[N + first]);
            double u = sqrt(u2);
            double cos_alpha = cos2 > 0.0 && u > 0.0 ? sqrt(cos2) : -1.0;
            chunks[(AXIS_X + config) * N + first] = u > 0.0 ? ux / u : 1.0;
            chunks[(AXIS_Y + config) * N + first] = u > 0.0 ? uy / u : 0.0;
            chunks[(COS + config) * N + first] = cos_alpha;
            chunks[(SIN + config) * N + first] = sqrt(bc_max(1.0 - cos_alpha * cos_alpha, 0.0));
            chunks[(SHORTEST2 + config) * N + first] = shortest2;
        }
        chunks[BOX_X0 * N + first] = x0;
        chunks[BOX_Y0 * N + first] = y0;
        chunks[BOX_X1 * N + first] = x1;
        chunks[BOX_Y1 * N + first] = y1;
    }
}

/* The chunk after chunk c (its first vertex) in ring o..e. */
static inline int64_t next_chunk(int64_t c, int64_t o, int64_t e) { return c + CHUNK < e ? c + CHUNK : o; }

/* How far apart, at least, a vertex of chunk c (its first vertex) and an edge of chunk d not its own, or
 * the reverse, are at both ends of the substep (see above); 0 where they may come within reach: neighbours,
 * and a chunk alone, unless their edges point within 75° of one axis and are longer than reach / cos 75°
 * (then L_min cos 75°); others unless their boxes are farther apart than reach (then that gap). */
static inline double chunks_apart_by(int64_t N, int64_t o, int64_t e, const double *chunks, int64_t c,
                                     int64_t d, double reach) {
    bool after = next_chunk(c, o, e) == d, before = next_chunk(d, o, e) == c;
    if (c == d || after || before) {
        if (after && before) return 0.0;  /* two chunks: their arc is the whole ring */
        double apart = INFINITY;
        for (int config = 0; config < 2; config++) {
            const double *shortest2 = chunks + (SHORTEST2 + config) * N;
            apart = bc_min(apart, sqrt(bc_min(shortest2[c], shortest2[d])) * CONE_COS);
            if (apart <= reach) return 0.0;
            double cos_c = chunks[(COS + config) * N + c], sin_c = chunks[(SIN + config) * N + c];
            double cos_d = chunks[(COS + config) * N + d], sin_d = chunks[(SIN + config) * N + d];
            if (bc_min(cos_c, cos_d) < CONE_COS) return 0.0;  /* a chunk's own edges spread wider than the cone */
            if (c == d) continue;
            /* (α_c + α_d + θ) / 2 <= β: with α_c, α_d <= β, S = α_c + α_d is in [0, 2β] and θ <= 2β - S,
             * both in [0, π], exactly when cos θ >= cos(2β - S) = cos 2β cos S + sin 2β sin S */
            double cos_s = cos_c * cos_d - sin_c * sin_d, sin_s = sin_c * cos_d + cos_c * sin_d;
            const double *axis_x = chunks + (AXIS_X + config) * N, *axis_y = chunks + (AXIS_Y + config) * N;
            double cos_t = axis_x[c] * axis_x[d] + axis_y[c] * axis_y[d];
            if (cos_t < CONE_COS_2 * cos_s + CONE_SIN_2 * sin_s) return 0.0;
        }
        return apart;
    }
    double gap = bc_max(bc_max(bc_max(chunks[BOX_X0 * N + c] - chunks[BOX_X1 * N + d],
                                      chunks[BOX_X0 * N + d] - chunks[BOX_X1 * N + c]),
                               chunks[BOX_Y0 * N + c] - chunks[BOX_Y1 * N + d]),
                        chunks[BOX_Y0 * N + d] - chunks[BOX_Y1 * N + c]);
    return gap > reach ? gap : 0.0;
}

#endif
