/* Ring geometry for the stages: the formulas of blobcli/geometry.py over the structure-of-arrays
 * positions (x = p[i], y = p[n + i], n the vertex count). Blob b's ring is vertices o..e-1 with
 * o, e = offsets[b], offsets[b + 1]; vertex i's edge joins it to bc_next_in_ring(i, o, e). */
#ifndef BC_RING_H
#define BC_RING_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

/* Python's max(a, b) and min(a, b), as the reference step computes them: the first argument unless
 * the second is strictly beyond it (so ties and NaNs come out as Python's) */
static inline double bc_max(double a, double b) { return b > a ? b : a; }
static inline double bc_min(double a, double b) { return b < a ? b : a; }
static inline int64_t bc_imax(int64_t a, int64_t b) { return b > a ? b : a; }
static inline int64_t bc_imin(int64_t a, int64_t b) { return b < a ? b : a; }

/* The vertex after i in the ring o..e-1 (the last joins the first), and the one before */
static inline int64_t bc_next_in_ring(int64_t i, int64_t o, int64_t e) { return i + 1 < e ? i + 1 : o; }
static inline int64_t bc_prev_in_ring(int64_t i, int64_t o, int64_t e) { return i > o ? i - 1 : e - 1; }

/* The most vertices any ring has (0 with no ring) */
static inline int64_t bc_most_vertices(const int64_t *offsets, int64_t blob_count) {
    int64_t most = 0;
    for (int64_t b = 0; b < blob_count; b++) most = bc_imax(most, offsets[b + 1] - offsets[b]);
    return most;
}

/* The sign of the turn a → b → c: +1 left (counter-clockwise), -1 right, 0 straight on */
static inline int bc_turn(const double *p, int64_t n, int64_t a, int64_t b, int64_t c) {
    double d = (p[b] - p[a]) * (p[n + c] - p[n + a]) - (p[n + b] - p[n + a]) * (p[c] - p[a]);
    return (d > 0.0) - (d < 0.0);
}

/* Vertex i's outward normal (not unit): its neighbours' difference turned by the ring's winding */
static inline void bc_vertex_normal(const double *p, int64_t n, double orient, int64_t i, int64_t o, int64_t e,
                                    double *nx, double *ny) {
    int64_t before = bc_prev_in_ring(i, o, e), after = bc_next_in_ring(i, o, e);
    *nx = orient * (p[n + after] - p[n + before]);
    *ny = -orient * (p[after] - p[before]);
}

/* The means over ring o..e of two (2, N) arrays (positions, velocities): out = (ā_x, ā_y, b̄_x, b̄_y) */
static inline void bc_ring_means(const double *a, const double *b, int64_t n, int64_t o, int64_t e, double out[4]) {
    double ax = 0.0, ay = 0.0, bx = 0.0, by = 0.0;
    for (int64_t i = o; i < e; i++) {
        ax += a[i];
        ay += a[n + i];
        bx += b[i];
        by += b[n + i];
    }
    double count = (double)(e - o);
    out[0] = ax / count;
    out[1] = ay / count;
    out[2] = bx / count;
    out[3] = by / count;
}

/* Centre (cx, cy), centre velocity (vx, vy) and kinetic energy per unit mass (½ mean |v|²) of ring o..e
 * (vertex masses are equal within a blob) */
static inline void bc_centre_motion(const double *p, const double *v, int64_t n, int64_t o, int64_t e,
                                    double means[4], double *kinetic) {
    bc_ring_means(p, v, n, o, e, means);
    double k = 0.0;
    for (int64_t i = o; i < e; i++) k += v[i] * v[i] + v[n + i] * v[n + i];
    *kinetic = 0.5 * k / (double)(e - o);
}

/* The distance from (cx, cy) to the farthest vertex of ring o..e */
static inline double bc_ring_radius(const double *p, int64_t n, int64_t o, int64_t e, double cx, double cy) {
    double r2 = 0.0;
    for (int64_t i = o; i < e; i++) {
        double dx = p[i] - cx, dy = p[n + i] - cy;
        r2 = bc_max(r2, dx * dx + dy * dy);
    }
    return sqrt(r2);
}

/* 2A = Σ (x_i y_{i+1} − x_{i+1} y_i) of the ring, summed in ring order */
static inline double bc_twice_ring_area(const double *p, int64_t n, int64_t o, int64_t e) {
    double twice_area = 0.0;
    for (int64_t i = o; i < e; i++) {
        int64_t j = bc_next_in_ring(i, o, e);
        twice_area += p[i] * p[n + j] - p[j] * p[n + i];
    }
    return twice_area;
}

/* m: how far off a surface a point the stages put on it may lie, the round-off of its coordinates (x, y):
 * 1e-12 (1 + |x| + |y|), some 10⁴ ulps and far below any motion a stage makes. A test of which side of a surface
 * such a point is on reads it within this, so that it comes out alike on every face (bc_rows_contain alone does
 * not). */
static inline double bc_surface_roundoff(double x, double y) { return 1e-12 * (1.0 + fabs(x) + fabs(y)); }

/* Whether edge a→b crosses the ray from (x, y) toward +x (one step of the crossing-number test) */
static inline bool bc_crosses_ray(double ax, double ay, double bx, double by, double x, double y) {
    return (ay > y) != (by > y) && x < ax + (y - ay) * (bx - ax) / (by - ay);
}

/* Crossing-number test against the edge rows start .. stop of a collider polygon (rows of 4: ax, ay, bx, by).
 * Half-open: a point exactly on a face counts as inside where the solid is toward +x or +y of the face, as outside
 * where it is toward -x or -y. */
static inline bool bc_rows_contain(const double *rows, int64_t start, int64_t stop, double x, double y) {
    bool inside = false;
    for (int64_t k = start; k < stop; k++) {
        const double *e = rows + 4 * k;
        if (bc_crosses_ray(e[0], e[1], e[2], e[3], x, y)) inside = !inside;
    }
    return inside;
}

/* The bounding box of ring o..e: box = (x0, y0, x1, y1) */
static inline void bc_ring_bounds(const double *p, int64_t n, int64_t o, int64_t e, double box[4]) {
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int64_t i = o; i < e; i++) {
        x0 = bc_min(x0, p[i]);
        y0 = bc_min(y0, p[n + i]);
        x1 = bc_max(x1, p[i]);
        y1 = bc_max(y1, p[n + i]);
    }
    box[0] = x0;
    box[1] = y0;
    box[2] = x1;
    box[3] = y1;
}

/* Crossing-number test: is (x, y) inside the closed polygon of ring o..e? */
static inline bool bc_ring_contains(const double *p, int64_t n, int64_t o, int64_t e, double x, double y) {
    bool inside = false;
    int64_t j = e - 1;
    for (int64_t i = o; i < e; i++) {
        if (bc_crosses_ray(p[j], p[n + j], p[i], p[n + i], x, y)) inside = !inside;
        j = i;
    }
    return inside;
}

#endif
