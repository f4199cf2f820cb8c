/* Broad phase (once per substep) and the blob contacts' bookkeeping between substeps.
 *
 * Each blob's centre is the plain average of its vertices (not the polygon centroid, which breaks when a
 * polygon self-intersects) and its radius is its farthest vertex. A uniform grid of cells one largest diameter
 * (and the margin) wide bins the centres, so only blobs in neighbouring cells are compared: linear in the blob
 * count. Pairs farther apart than r_a + r_b + margin are skipped. Pairs come out in a fixed order (by first
 * blob, then grid neighbour, then blob index), so runs are bit-identical, for any thread count.
 *
 * Periodic box: the cells tile the box and a blob's neighbourhood wraps round it; distances are to the nearest
 * image (periodic.h: bc_image). A box of many more cells than blobs (a dilute gas) keeps its cells in a sorted
 * list of the occupied ones instead of a table of every cell: the same cells, so the same pairs in the same order.
 *
 * Arrays (blobcore.h): positions (2, N), centres (B, 2), the edge table (5, N); the scratch's pairs (capacity, 2)
 * (scratch.h).
 */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "broad_phase.h"
#include "collide_limits.h"
#include "parallel.h"
#include "periodic.h"
#include "ring.h"
#include "scratch.h"

static const double BROAD_MARGIN = 0.25;  /* × the larger radius: pairs closer than r_a + r_b + margin are tested */
static const double NO_BOUNCE = -INFINITY; /* the leave energy of a record that has not bounced (integrate.bounce) */
/* The most cells a side of a periodic box's grid has: 2^31, so that a cell's index iy nx + ix fits an int64
 * (a box that many cells wide would need a table of 16 GB, which the reference could not allocate either) */
static const int64_t MOST_CELLS_A_SIDE = INT64_C(1) << 31;

/* int(x) of a float as the reference step computes it: toward zero, and INT64_MIN (x86's "integer indefinite",
 * what its conversion gives) for NaN or beyond the int64 range, where a C cast is undefined */
static int64_t py_int(double x) {
    if (!(x > -9223372036854775808.0 && x < 9223372036854775808.0)) return INT64_MIN;
    return (int64_t)x;
}

/* Python's a % n for n > 0: the sign of n */
static int64_t floor_mod(int64_t a, int64_t n) {
    int64_t r = a % n;
    return r < 0 ? r + n : r;
}

/* numpy's min and max of column `col` of a (B, 2) table as numba computes them: the first NaN, else the
 * first of the least (greatest) values */
static double column_min(const double *table, int64_t rows, int64_t col) {
    double least = table[col];
    if (isnan(least)) return least;
    for (int64_t b = 1; b < rows; b++) {
        double v = table[2 * b + col];
        if (isnan(v)) return v;
        if (v < least) least = v;
    }
    return least;
}

static double column_max(const double *table, int64_t rows, int64_t col) {
    double most = table[col];
    if (isnan(most)) return most;
    for (int64_t b = 1; b < rows; b++) {
        double v = table[2 * b + col];
        if (isnan(v)) return v;
        if (v > most) most = v;
    }
    return most;
}

/* radius.max(), as column_max */
static double array_max(const double *a, int64_t n) {
    double most = a[0];
    if (isnan(most)) return most;
    for (int64_t b = 1; b < n; b++) {
        if (isnan(a[b])) return a[b];
        if (a[b] > most) most = a[b];
    }
    return most;
}

/* Each blob's centre, radius and edge table; with `everyone`, sleeping ones' too (the broad phase: from their
 * frozen positions they come out the same bits every substep, so the narrow phase reads the same sleeping edges
 * however the steps are split into calls, and after a resume, when the scratch starts empty); without, only the
 * awake blobs' (the narrow phase: a sleeping blob's have not changed since). */
void bc_blob_bounds(const bcContext *ctx, int everyone) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t N = m->vertex_count;
    const double *pos = s->position;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t b = 0; b < m->blob_count; b++), {
        if (!(everyone || s->awake[b])) continue;
        int64_t o = m->offsets[b], e = m->offsets[b + 1];
        double cx = 0.0, cy = 0.0;
        for (int64_t i = o; i < e; i++) {
            double x = pos[i], y = pos[N + i];
            int64_t j = bc_next_in_ring(i, o, e);
            double ex = pos[j] - x, ey = pos[N + j] - y;
            double len2 = ex * ex + ey * ey;
            /* The edge table the narrow phase reads, one row per quantity, so that its loop over a blob's edges
             * reads contiguous memory and vectorizes: x_0, y_0, e_x, e_y, 1 / |e|² */
            s->edges[i] = x;
            s->edges[N + i] = y;
            s->edges[2 * N + i] = ex;
            s->edges[3 * N + i] = ey;
            s->edges[4 * N + i] = len2 > 0.0 ? 1.0 / len2 : 0.0;
            cx += x;
            cy += y;
        }
        cx /= (double)(e - o);
        cy /= (double)(e - o);
        s->center[2 * b] = cx;
        s->center[2 * b + 1] = cy;
        s->radius[b] = bc_ring_radius(pos, N, o, e, cx, cy);
    });
}

/* Counting sort of 0..n-1 by key (stable: within a bucket, by index): bucket k holds order[start[k] ..
 * start[k + 1]). fill holds `buckets` slots. */
static void bucket(const int64_t *key, int64_t n, int64_t buckets, int64_t *start, int64_t *order, int64_t *fill) {
    for (int64_t k = 0; k <= buckets; k++) start[k] = 0;
    for (int64_t b = 0; b < n; b++) start[key[b] + 1] += 1;
    for (int64_t k = 0; k < buckets; k++) start[k + 1] += start[k];
    for (int64_t k = 0; k < buckets; k++) fill[k] = start[k];
    for (int64_t b = 0; b < n; b++) {
        order[fill[key[b]]] = b;
        fill[key[b]] += 1;
    }
}

/* The blobs 0..n-1 sorted by key, stably (a bottom-up merge sort through `other`): order, and sorted their keys.
 * The same order as `bucket`'s, for keys too many to give each a bucket. */
static void sort_by_key(const int64_t *key, int64_t n, int64_t *order, int64_t *sorted, int64_t *other) {
    int64_t *from = order, *to = other;
    for (int64_t b = 0; b < n; b++) from[b] = b;
    for (int64_t width = 1; width < n; width *= 2) {
        for (int64_t lo = 0; lo < n; lo += 2 * width) {
            int64_t mid = bc_imin(lo + width, n), hi = bc_imin(lo + 2 * width, n);
            int64_t i = lo, j = mid, k = lo;
            while (i < mid && j < hi) to[k++] = key[from[j]] < key[from[i]] ? from[j++] : from[i++];
            while (i < mid) to[k++] = from[i++];
            while (j < hi) to[k++] = from[j++];
        }
        int64_t *swap = from;
        from = to;
        to = swap;
    }
    for (int64_t k = 0; k < n; k++) {
        order[k] = from[k];
        sorted[k] = key[from[k]];
    }
}

/* The first k with sorted[k] >= value */
static int64_t lower_bound(const int64_t *sorted, int64_t n, int64_t value) {
    int64_t lo = 0, hi = n;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (sorted[mid] < value) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

/* The grid the centres are binned in: nx × ny cells, each blob's cell, the blobs by cell (then by index), and
 * where each cell's blobs are: a table of every cell (start), or, with more cells than that holds, the sorted
 * cells of the blobs (key) */
typedef struct Grid {
    int64_t nx, ny, blob_count;
    const int64_t *cell_of, *order, *start, *key;
} Grid;

/* The blobs in cells c0 .. c1 - 1, in cell order, then by index: order[*lo .. *hi) */
static void grid_span(const Grid *g, int64_t c0, int64_t c1, int64_t *lo, int64_t *hi) {
    if (g->key == NULL) {
        *lo = g->start[c0];
        *hi = g->start[c1];
    } else {
        *lo = lower_bound(g->key, g->blob_count, c0);
        *hi = lower_bound(g->key, g->blob_count, c1);
    }
}

/* Bin the blobs by w->cell_of into nx × ny cells: a table of every cell when they fit it, else sorted */
static Grid grid_of(bcScratch *w, int64_t blob_count, int64_t nx, int64_t ny) {
    Grid g = {nx, ny, blob_count, w->cell_of, w->cell_order, w->cell_start, NULL};
    if (nx * ny <= w->grid_capacity) {
        bucket(w->cell_of, blob_count, nx * ny, w->cell_start, w->cell_order, w->fill);
    } else {
        sort_by_key(w->cell_of, blob_count, w->cell_order, w->cell_key, w->cell_sorting);
        g.key = w->cell_key;
    }
    return g;
}

/* Whether an nx × ny grid has more than `most` cells (nx ny computed without overflow) */
static bool more_cells(int64_t nx, int64_t ny, int64_t most) {
    return nx >= 1 && ny >= 1 && nx > most / ny;
}

/* Blob a's pair with b, if their centres, d = (dx, dy) apart, are closer than r_a + r_b + margin: the first `most`
 * written as pairs (a, b) to out[row ..]; count is how many in all so far */
static inline void try_pair(int64_t a, int64_t b, const double *radius, double dx, double dy, int64_t *out,
                            int64_t row, int64_t most, int64_t *count) {
    double reach = radius[a] + radius[b] + BROAD_MARGIN * bc_max(radius[a], radius[b]);
    if (dx * dx + dy * dy < reach * reach) {
        if (*count < most) {
            out[2 * (row + *count)] = a;
            out[2 * (row + *count) + 1] = b;
        }
        *count += 1;
    }
}

/* Blobs b > a in the cells around a's, closer than r_a + r_b + margin: the first `most` of them written as pairs
 * (a, b) to out[row ..] (in cell order, then by index). Returns how many in all. */
static int64_t near_blobs(int64_t a, const double *center, const double *radius, const Grid *g, int64_t *out,
                          int64_t row, int64_t most) {
    int64_t count = 0;
    int64_t ix = g->cell_of[a] % g->nx, iy = g->cell_of[a] / g->nx;
    for (int64_t jy = bc_imax(iy - 1, 0); jy < bc_imin(iy + 2, g->ny); jy++) {
        for (int64_t jx = bc_imax(ix - 1, 0); jx < bc_imin(ix + 2, g->nx); jx++) {
            int64_t lo, hi;
            grid_span(g, jy * g->nx + jx, jy * g->nx + jx + 1, &lo, &hi);
            for (int64_t k = lo; k < hi; k++) {
                int64_t b = g->order[k];
                if (b <= a) continue;
                try_pair(a, b, radius, center[2 * a] - center[2 * b], center[2 * a + 1] - center[2 * b + 1], out, row,
                         most, &count);
            }
        }
    }
    return count;
}

/* near_blobs in a periodic box: the 3 × 3 cells around a's, wrapped (every cell of an axis with fewer than 3),
 * distances to the nearest image. Across the top and bottom edges of a sheared box the row of images is shifted
 * along x by γ L_y: there every cell of the row is looked at. */
static int64_t near_images(int64_t a, const double *center, const double *radius, const Grid *g, int64_t *out,
                           int64_t row, int64_t most, bcBox box) {
    int64_t count = 0;
    const int64_t nx = g->nx, ny = g->ny;
    int64_t ix = g->cell_of[a] % nx, iy = g->cell_of[a] / nx;
    for (int64_t dy = ny >= 3 ? -1 : 0; dy < (ny >= 3 ? 2 : ny); dy++) {
        int64_t jy = ny >= 3 ? floor_mod(iy + dy, ny) : dy;
        bool whole_row = nx < 3 || (box.tilt != 0.0 && (iy + dy < 0 || iy + dy >= ny || ny < 3));
        for (int64_t dx = whole_row ? 0 : -1; dx < (whole_row ? 1 : 2); dx++) {
            int64_t lo, hi;  /* the whole row's cells 0 .. nx - 1 in order, or one cell */
            if (whole_row) {
                grid_span(g, jy * nx, jy * nx + nx, &lo, &hi);
            } else {
                int64_t c = jy * nx + floor_mod(ix + dx, nx);
                grid_span(g, c, c + 1, &lo, &hi);
            }
            for (int64_t k = lo; k < hi; k++) {
                int64_t b = g->order[k];
                if (b <= a) continue;
                double sx, sy;
                bc_image(center, a, b, box, &sx, &sy);
                try_pair(a, b, radius, center[2 * a] + sx - center[2 * b], center[2 * a + 1] + sy - center[2 * b + 1],
                         out, row, most, &count);
            }
        }
    }
    return count;
}

/* Blob a's pairs near it, into out[row ..] (the first `most`); how many in all */
static int64_t near(int64_t a, const double *center, const double *radius, const Grid *g, int64_t *out,
                    int64_t row, int64_t most, bool periodic, bcBox box) {
    return periodic ? near_images(a, center, radius, g, out, row, most, box)
                    : near_blobs(a, center, radius, g, out, row, most);
}

/* The open world's grid (collide._find_pairs): cells 2 r_max (1 + margin) wide from the least centre, doubled
 * while there are more than 4 B + 64 of them (blobs spread far apart: memory stays O(B)) */
static Grid open_grid(const bcContext *ctx) {
    const int64_t B = ctx->m->blob_count;
    const double *center = ctx->s->center;
    bcScratch *w = ctx->w;
    double r_max = array_max(ctx->s->radius, B);
    double cell = 2.0 * r_max * (1.0 + BROAD_MARGIN);
    double x0 = column_min(center, B, 0), y0 = column_min(center, B, 1);
    double x1 = column_max(center, B, 0), y1 = column_max(center, B, 1);
    int64_t nx = py_int((x1 - x0) / cell) + 1;
    int64_t ny = py_int((y1 - y0) / cell) + 1;
    while (more_cells(nx, ny, 4 * B + 64)) {
        cell *= 2.0;
        nx = py_int((x1 - x0) / cell) + 1;
        ny = py_int((y1 - y0) / cell) + 1;
    }
    /* A non-finite centre or radius leaves no grid (the reference writes out of its arrays there; the step
     * reports the vertex at its end): then one cell holds every blob. */
    if (nx < 1 || ny < 1) nx = ny = 1;
    for (int64_t b = 0; b < B; b++) {
        int64_t iy = py_int((center[2 * b + 1] - y0) / cell), ix = py_int((center[2 * b] - x0) / cell);
        w->cell_of[b] = (0 <= ix && ix < nx && 0 <= iy && iy < ny) ? iy * nx + ix : 0;
    }
    return grid_of(w, B, nx, ny);
}

/* The periodic box's grid (collide._find_pairs_periodic): nx × ny cells tile the box exactly, each at least as
 * wide as the open world's; a centre's cell is read from its position wrapped into the box, its row of images
 * first, then along x in that row. The box is at least 5 largest radii wide (scene/schema.py), so a pair has one
 * image close enough to touch. */
static Grid periodic_grid(const bcContext *ctx, bcBox box) {
    const int64_t B = ctx->m->blob_count;
    const double *center = ctx->s->center;
    bcScratch *w = ctx->w;
    double cell = 2.0 * array_max(ctx->s->radius, B) * (1.0 + BROAD_MARGIN);
    int64_t nx = bc_imin(bc_imax(1, py_int(box.lx / cell)), MOST_CELLS_A_SIDE);
    int64_t ny = bc_imin(bc_imax(1, py_int(box.ly / cell)), MOST_CELLS_A_SIDE);
    for (int64_t b = 0; b < B; b++) {
        /* floor(f) stands for the reference's int64 math.floor(f): the same value for |f| < 2^63 */
        double fy = center[2 * b + 1] / box.ly + 0.5;
        double fx = (center[2 * b] - floor(fy) * box.tilt) / box.lx + 0.5;
        int64_t ix = bc_imin(py_int((fx - floor(fx)) * (double)nx), nx - 1);
        int64_t iy = bc_imin(py_int((fy - floor(fy)) * (double)ny), ny - 1);
        /* a non-finite centre has no cell (the reference writes out of its arrays): cell 0 */
        w->cell_of[b] = (0 <= ix && 0 <= iy) ? iy * nx + ix : 0;
    }
    return grid_of(w, B, nx, ny);
}

/* The pairs of the grid's neighbourhoods, counted in parallel over blobs, each blob's kept in its own rows of
 * `found` (up to FOUND_PER_BLOB), then copied from each blob's own offset, so the order is the same for any
 * thread count; a blob with more is searched again for the copy. None are listed past the capacity. Returns how
 * many there are. */
static int64_t list_pairs(const bcContext *ctx, const Grid *g, bool periodic, bcBox box) {
    const int64_t B = ctx->m->blob_count;
    const double *center = ctx->s->center, *radius = ctx->s->radius;
    bcScratch *w = ctx->w;
    int64_t *first = w->first;
    first[0] = 0;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < B; a++), {
        first[a + 1] = near(a, center, radius, g, w->found, a * BC_FOUND_PER_BLOB, BC_FOUND_PER_BLOB, periodic, box);
    });
    for (int64_t a = 0; a < B; a++) first[a + 1] += first[a];
    int64_t count = first[B];
    if (count > w->pair_capacity) {
        w->pair_count = 0;
        return count;
    }
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < B; a++), {
        int64_t listed = first[a + 1] - first[a], row = a * BC_FOUND_PER_BLOB;
        for (int64_t k = 0; k < bc_imin(listed, BC_FOUND_PER_BLOB); k++) {
            w->pairs[2 * (first[a] + k)] = w->found[2 * (row + k)];
            w->pairs[2 * (first[a] + k) + 1] = w->found[2 * (row + k) + 1];
        }
        if (listed > BC_FOUND_PER_BLOB) near(a, center, radius, g, w->pairs, first[a], listed, periodic, box);
    });
    w->pair_count = count;
    return count;
}

/* Each blob's partners as CSR lists (partner_start, partner, partner_pair: the pair's index), in pair order */
static void partners(bcScratch *w, int64_t blob_count) {
    const int64_t P = w->pair_count;
    int64_t *start = w->partner_start, *fill = w->fill;
    for (int64_t b = 0; b <= blob_count; b++) start[b] = 0;
    for (int64_t k = 0; k < P; k++) {
        start[w->pairs[2 * k] + 1] += 1;
        start[w->pairs[2 * k + 1] + 1] += 1;
    }
    for (int64_t b = 0; b < blob_count; b++) start[b + 1] += start[b];
    for (int64_t b = 0; b < blob_count; b++) fill[b] = start[b];
    for (int64_t k = 0; k < P; k++) {
        for (int side = 0; side < 2; side++) {
            int64_t a = w->pairs[2 * k + side], b = w->pairs[2 * k + 1 - side];
            w->partner[fill[a]] = b;
            w->partner_pair[fill[a]] = k;
            fill[a] += 1;
        }
    }
}

/* Blobs cut into vertical strips of equal width by centre x, B // BLOBS_PER_STRIP of them (1 to MAX_STRIPS):
 * each blob's strip, each strip's blobs in index order (CSR: strip_start, strip_blobs), how many strips apart
 * each blob's farthest partner is (crossing: 0, none in another strip), and whether any pair spans two strips or
 * more (far). Only blobs that cross have contacts across strips, and only those that cross two or more have far
 * ones: the resolution scans no other blob's contacts for them. */
static void strips(const bcContext *ctx) {
    const int64_t B = ctx->m->blob_count;
    const double *center = ctx->s->center;
    bcScratch *w = ctx->w;
    int64_t count = bc_imax(1, bc_imin(BC_MAX_STRIPS, B / BC_BLOBS_PER_STRIP));
    double x0 = column_min(center, B, 0);
    double width = (column_max(center, B, 0) - x0) / (double)count;
    for (int64_t b = 0; b < B; b++) w->strip_of[b] = 0;
    if (width > 0.0) {
        for (int64_t b = 0; b < B; b++) {
            /* (a non-finite centre's quotient has no strip: the reference writes out of its arrays; strip 0) */
            w->strip_of[b] = bc_imax(0, bc_imin(py_int((center[2 * b] - x0) / width), count - 1));
        }
    }
    w->strip_count = count;
    bucket(w->strip_of, B, count, w->strip_start, w->strip_blobs, w->fill);
    for (int64_t b = 0; b < B; b++) w->crossing[b] = 0;
    bool far = false;
    for (int64_t k = 0; k < w->pair_count; k++) {
        int64_t a = w->pairs[2 * k], b = w->pairs[2 * k + 1];
        int64_t apart = w->strip_of[a] - w->strip_of[b];
        apart = apart < 0 ? -apart : apart;
        w->crossing[a] = bc_imax(w->crossing[a], apart);
        w->crossing[b] = bc_imax(w->crossing[b], apart);
        far |= apart >= 2;
    }
    w->far = far;
}

/* Broad phase: the pairs of blobs close enough to touch this substep, sleeping or not, each blob's partners and
 * the strips of the resolution. Past PAIRS_PER_BLOB pairs per blob none are listed (the step must stop: a pile
 * has ~3 close pairs per blob; more are blobs spawned on top of each other). */
int64_t bc_find_blob_pairs(const bcContext *ctx) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    const int64_t B = m->blob_count, N = m->vertex_count;
    if (B == 0) { /* no blob, no pair (the reference's min and max of no centres raise) */
        ctx->w->pair_count = 0;
        return 0;
    }
    bc_blob_bounds(ctx, 1);
    bcBox box = bc_box(ctx->c->box_x, ctx->c->box_y, ctx->c->box_tilt);
    bool periodic = box.lx > 0.0; /* cells tile the box; neighbours and distances wrap round it */
    Grid g = periodic ? periodic_grid(ctx, box) : open_grid(ctx);
    int64_t count = list_pairs(ctx, &g, periodic, box);
    for (int64_t i = 0; i < N; i++) s->blob_contact_depth[i] = 0.0; /* no contact has pushed yet this substep */
    for (int64_t i = 0; i < BC_CONTACTS_PER_VERTEX * N; i++) s->c_hit[i] = 0;
    for (int64_t i = 0; i < 2 * BC_CONTACTS_PER_VERTEX * N; i++) ctx->w->friction_sum[i] = 0.0; /* nor corrected */
    for (int64_t k = 0; k < 2 * bc_imin(ctx->w->pair_count, ctx->w->pair_capacity); k++) {
        ctx->w->pair_impulse[k] = 0.0; /* nor given an impulse */
    }
    partners(ctx->w, B);
    strips(ctx);
    return count;
}

/* The impact records (integrate.bounce) of this substep's pairs: each pair's from the kept ones (pair_key[:count],
 * sorted keys a B + b), or a fresh record. The pairs come by first blob a, as the broad phase lists them, so one
 * pass through the keys finds them all: a merge, not a search per pair. */
void bc_carry_impacts(const bcContext *ctx) {
    const bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t B = ctx->m->blob_count;
    const int64_t *keys = s->pair_key;
    /* (a count read from a file is held to the arrays' size) */
    int64_t n = bc_imax(0, bc_imin(s->pair_count[0], w->pair_capacity));
    int64_t j = 0; /* the first kept key of blob a or a later blob */
    for (int64_t k = 0; k < w->pair_count; k++) {
        int64_t a = w->pairs[2 * k];
        int64_t key = a * B + w->pairs[2 * k + 1];
        while (j < n && keys[j] < a * B) j++;
        int64_t i = j; /* blob a's few keys, in order */
        while (i < n && keys[i] < key) i++;
        double *out = w->pair_impact + 4 * k;
        if (i < n && keys[i] == key) {
            for (int f = 0; f < 4; f++) out[f] = s->pair_impact[4 * i + f];
        } else {
            out[0] = 0.0;
            out[1] = NO_BOUNCE;
            out[2] = 0.0;
            out[3] = 0.0;
        }
    }
}

/* Keep the records of the pairs that have had an impact (V > 0), sorted by key, for the next substep and for
 * /restart. The pairs come by first blob a (see bc_carry_impacts), so only each blob's few keys are out of order:
 * an insertion sort is linear here. */
void bc_keep_impacts(const bcContext *ctx) {
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    const int64_t B = ctx->m->blob_count;
    int64_t *order = w->kept_order, *key = w->kept_key; /* the kept pairs, by key */
    int64_t n = 0;
    for (int64_t k = 0; k < w->pair_count; k++) {
        if (w->pair_impact[4 * k] > 0.0) {
            int64_t j = n;
            int64_t this = w->pairs[2 * k] * B + w->pairs[2 * k + 1];
            while (j > 0 && key[j - 1] > this) { /* keys are distinct */
                key[j] = key[j - 1];
                order[j] = order[j - 1];
                j--;
            }
            key[j] = this;
            order[j] = k;
            n++;
        }
    }
    for (int64_t j = 0; j < n; j++) {
        s->pair_key[j] = key[j];
        for (int f = 0; f < 4; f++) s->pair_impact[4 * j + f] = w->pair_impact[4 * order[j] + f];
    }
    s->pair_count[0] = n;
}

/* At the end of a substep: a contact that did not push in it lets go of its stick point (it touches afresh,
 * wherever it next pushes). */
void bc_release_sticks(const bcContext *ctx) {
    bcState *s = ctx->s;
    const int64_t N = ctx->m->vertex_count;
    for (int64_t c = 0; c < BC_CONTACTS_PER_VERTEX; c++) {
        for (int64_t p = 0; p < N; p++) {
            if (s->c_hit[c * N + p] == 0) s->stick_edge[c * N + p] = -1;
        }
    }
}

/* The pairs whose contacts pushed in the step's last substep (of length h), asleep or not, into s->touching, in pair
 * order, with their contact force over that substep, J / h on the pair's first blob, into s->touching_force, and how
 * many (sim/packing.py counts each blob's contacts and weighs their forces from them). Each blob reads its own
 * vertices' contacts once and marks its own partner slots, in parallel. */
void bc_keep_touching(const bcContext *ctx, double h) {
    const bcModel *m = ctx->m;
    bcState *s = ctx->s;
    bcScratch *w = ctx->w;
    if (s->touching == NULL || s->touching_force == NULL || s->touching_count == NULL) return; /* an open world keeps no packing records */
    const int64_t N = m->vertex_count, P = w->pair_count;
    uint8_t *pushed = w->pushed, *touching = w->touching;
    for (int64_t j = 0; j < 2 * P; j++) pushed[j] = 0;
    BC_PARALLEL_LOOP(ctx->c->parallel, (int64_t a = 0; a < m->blob_count; a++), {
        for (int64_t p = m->offsets[a]; p < m->offsets[a + 1]; p++) {
            for (int64_t c = 0; c < BC_CONTACTS_PER_VERTEX; c++) {
                int64_t edge = s->c_edge[c * N + p];
                if (s->c_hit[c * N + p] == 0 || edge < 0 || edge >= N) continue; /* (a pushed contact has an edge) */
                int64_t other = m->blob_of[edge];
                for (int64_t j = w->partner_start[a]; j < w->partner_start[a + 1]; j++) { /* a blob has a few */
                    if (w->partner[j] == other) {
                        pushed[j] = 1;
                        break;
                    }
                }
            }
        }
    });
    for (int64_t k = 0; k < P; k++) touching[k] = 0;
    for (int64_t j = 0; j < 2 * P; j++) touching[w->partner_pair[j]] |= pushed[j];
    int64_t n = 0;
    for (int64_t k = 0; k < P; k++) {
        if (touching[k]) {
            s->touching[2 * n] = w->pairs[2 * k];
            s->touching[2 * n + 1] = w->pairs[2 * k + 1];
            s->touching_force[2 * n] = w->pair_impulse[2 * k] / h;
            s->touching_force[2 * n + 1] = w->pair_impulse[2 * k + 1] / h;
            n++;
        }
    }
    s->touching_count[0] = n;
}
