"""Polygon geometry in plain Python and numpy, at the bottom of the import graph.

Scene validation, the model builder, the stress detectors and the tests read polygons
through these functions; the compiled step uses the same formulas, inlined, from
blobcli/core/ring.h. A ring is a closed polygon: vertex i joins the next vertex of its ring,
and the last joins the first. Blob b owns rows offsets[b]:offsets[b+1] of a position array.
"""

from __future__ import annotations

import numpy as np


def signed_area(points) -> float:
    """Shoelace area, A = ½ Σ (x_i y_{i+1} − x_{i+1} y_i): positive for counter-clockwise winding.

    Summed left to right in Python floats, so the model's rest areas are the same bits on
    every machine (numpy's pairwise sums would round differently)."""
    n = len(points)
    return 0.5 * sum(points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1]
                     for i in range(n))


def blob_points(b) -> np.ndarray:
    """The blob's polygon as an (n, 2) array, in the winding the user gave.

    b is a blob definition (scene.schema.BlobDef or anything with its points, vertices, center
    and radius): given points, or a regular polygon of b.vertices on a circle of b.radius."""
    if b.points is not None:
        return np.array(b.points, dtype=np.float64)
    theta = 2.0 * np.pi * np.arange(b.vertices) / b.vertices
    cx, cy = b.center or (0.0, 0.0)  # no centre: a blob with count, placed at random
    return np.stack([cx + b.radius * np.cos(theta), cy + b.radius * np.sin(theta)], axis=1)


def ring_next(offsets) -> np.ndarray:
    """(N,) index of the next vertex of each vertex's ring."""
    offsets = np.asarray(offsets)
    nxt = np.arange(offsets[-1]) + 1
    nxt[offsets[1:] - 1] = offsets[:-1]
    return nxt


def ring_areas(position, offsets) -> np.ndarray:
    """Signed shoelace areas of every ring: position (..., N, 2) -> (..., B)."""
    x, y = position[..., 0], position[..., 1]
    nxt = ring_next(offsets)
    cross = x * y[..., nxt] - x[..., nxt] * y
    return 0.5 * np.add.reduceat(cross, offsets[:-1], axis=-1)


def first_crossing(points) -> tuple[int, int] | None:
    """First pair of non-adjacent edges (i, j) of a closed polygon that touch, or None."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    a, b = p, np.roll(p, -1, axis=0)

    def orient(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    for i in range(n):
        j = np.arange(i + 1, n)
        j = j[(j != (i + 1) % n) & ((j + 1) % n != i)]  # skip edges sharing a vertex with i
        if len(j) == 0:
            continue
        o1 = orient(a[i], b[i], a[j])
        o2 = orient(a[i], b[i], b[j])
        o3 = orient(a[j], b[j], a[i])
        o4 = orient(a[j], b[j], b[i])
        # Opposite sides both ways, or collinear; either way the boxes must overlap
        # (nearly collinear edges along a floor get rounding-noise signs).
        hit = ((o1 != o2) & (o3 != o4)) | ((o1 == 0) & (o2 == 0))
        hit &= _boxes_overlap(a[i], b[i], a[j], b[j])
        if hit.any():
            return i, int(j[np.argmax(hit)])
    return None


def _boxes_overlap(a, b, c, d):
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    lo2, hi2 = np.minimum(c, d), np.maximum(c, d)
    return np.all((lo2 <= hi) & (hi2 >= lo), axis=-1)


def depth_inside_polygon(points, polygon) -> np.ndarray:
    """For each point (M, 2): its distance to the polygon's boundary if inside, else 0.

    Inside is the crossing-number rule of `ring.crosses_ray`: the ray from the point toward
    +x crosses the boundary an odd number of times."""
    points, polygon = np.asarray(points), np.asarray(polygon)
    a, b = polygon, np.roll(polygon, -1, axis=0)
    x, y = points[:, :1], points[:, 1:]
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = (crosses & (x < xc)).sum(axis=1) % 2 == 1
    e = b - a
    u = np.clip(((points[:, None, :] - a) * e).sum(-1) / (e * e).sum(-1), 0, 1)
    dist = np.linalg.norm(points[:, None, :] - (a + u[..., None] * e), axis=-1).min(axis=1)
    return np.where(inside, dist, 0.0)
