/* wall_shapes.h: what the moving-wall stages share (walls.c, loaded_walls.c, wall_checks.c): the solver kinds,
 * the pose columns, a collider's corners and the inside test of its rows (not read by cffi) */
#ifndef BC_WALL_SHAPES_H
#define BC_WALL_SHAPES_H

#include <stdbool.h>
#include <stdint.h>

#include "blobcore.h"
#include "ring.h"
#include "walls.h"

enum { PLANE, SEGMENT, CIRCLE, POLYGON }; /* the solver kinds, colliders.SOLVERS */
static const int64_t POSE = BC_WALL_POSE_COLUMNS;

/* Collider k's corner c, where it is now: a polygon's row c's first point, a segment's end c (0: a, 1: b) */
static inline void corner_of(const bcContext *ctx, int64_t kind, int64_t shape, int64_t c, double *qx, double *qy) {
    const double *geom = ctx->s->placed[kind].geom;
    int64_t first = ctx->m->statics[kind].shape_offsets[shape];
    const double *row = kind == POLYGON ? geom + 4 * (first + c) : geom + 4 * first + 2 * c;
    *qx = row[0];
    *qy = row[1];
}

/* The corners collider k has: a polygon's rows, a segment's two ends, none for a plane or circle */
static inline int64_t corner_count(const bcContext *ctx, int64_t kind, int64_t shape) {
    const int64_t *offsets = ctx->m->statics[kind].shape_offsets;
    if (kind == POLYGON) return offsets[shape + 1] - offsets[shape];
    return kind == SEGMENT ? 2 : 0;
}

#endif
