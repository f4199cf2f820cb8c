"""The static collider kinds, in one table: each kind's scene keys, the rows its solver kernel
reads, its outline for drawing, and how deep a point lies inside it.

Everything that knows about collider kinds reads this table: scene validation (the keys),
the model builder (kernel rows and bounding boxes), the recording and the filmstrip (the
outline) and the stress detectors (the depth). The solver kernels themselves live in
blobcli/core/statics.c, one per `solver` name, all run by its `bc_collide_statics`.

Kernel rows, 4 float64 each: plane (px, py, nx, ny) with unit n out of the solid side;
circle (cx, cy, r, inside: 1 for a container, solid outside the circle, else 0); segment and
polygon edge (ax, ay, bx, by). Polygons (boxes too) are counter-clockwise, so an edge's outward
normal is its right-hand side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .geometry import depth_inside_polygon, signed_area


@dataclass(frozen=True)
class ColliderKind:
    keys: tuple[str, ...]  # geometry keys of its [[static]] table (all required, except box.angle)
    solver: str  # the solver in blobcli/core/statics.c that runs it
    rows: Callable  # StaticDef -> (kernel rows (r, 4), aabb [xmin, ymin, xmax, ymax])
    outline: Callable  # (StaticDef, extent m) -> closed polyline (k, 2); a plane is cut at ±extent
    depth: Callable  # (points (M, 2), StaticDef) -> (M,) m inside it (0 outside; a segment has no inside)


def polygon_outline(s) -> np.ndarray:
    """Counter-clockwise corner points of a box or polygon."""
    if s.kind == "box":
        w, h = s.size[0] / 2, s.size[1] / 2
        corners = np.array([[-w, -h], [w, -h], [w, h], [-w, h]])
        c, t = math.cos(math.radians(s.angle)), math.sin(math.radians(s.angle))
        return corners @ np.array([[c, t], [-t, c]]) + np.array(s.center)
    pts = np.array(s.points, dtype=np.float64)
    return pts if signed_area(pts) > 0 else pts[::-1].copy()


def _unit_normal(s) -> np.ndarray:
    return np.array(s.normal) / math.hypot(*s.normal)


def _plane_rows(s):
    return np.array([[*s.point, *_unit_normal(s)]]), [-np.inf, -np.inf, np.inf, np.inf]


def _plane_outline(s, extent):
    n = _unit_normal(s)
    t = np.array([-n[1], n[0]])
    return np.array([np.array(s.point) - extent * t, np.array(s.point) + extent * t])


def _plane_depth(points, s):
    return np.maximum(-(np.asarray(points) - s.point) @ _unit_normal(s), 0.0)


def _segment_rows(s):
    return (np.array([[*s.a, *s.b]]),
            [min(s.a[0], s.b[0]), min(s.a[1], s.b[1]), max(s.a[0], s.b[0]), max(s.a[1], s.b[1])])


def _circle_rows(s):
    r = s.radius
    if s.inside:  # a container: solid everywhere outside, so its bounding box is the whole plane
        return np.array([[*s.center, r, 1.0]]), [-np.inf, -np.inf, np.inf, np.inf]
    return np.array([[*s.center, r, 0.0]]), [s.center[0] - r, s.center[1] - r, s.center[0] + r, s.center[1] + r]


def _circle_outline(s, extent):
    theta = np.linspace(0.0, 2.0 * np.pi, 65)
    return np.stack([s.center[0] + s.radius * np.cos(theta), s.center[1] + s.radius * np.sin(theta)], axis=1)


def _circle_depth(points, s):
    out = np.hypot(*(np.asarray(points) - s.center).T) - s.radius  # > 0 outside the circle
    return np.maximum(out if s.inside else -out, 0.0)


def _polygon_rows(s):
    pts = polygon_outline(s)
    return np.concatenate([pts, np.roll(pts, -1, axis=0)], axis=1), [*pts.min(axis=0), *pts.max(axis=0)]


def _polygon_outline(s, extent):
    pts = polygon_outline(s)
    return np.vstack([pts, pts[:1]])


def default_pivot(s) -> tuple[float, float]:
    """The point a collider turns about and is recorded at, unless the scene gives `pivot`: a plane's
    point, a segment's midpoint, a box's or circle's centre, a polygon's centroid."""
    if s.pivot is not None:
        return s.pivot
    if s.kind == "plane":
        return s.point
    if s.kind == "segment":
        return ((s.a[0] + s.b[0]) / 2, (s.a[1] + s.b[1]) / 2)
    if s.kind in ("box", "circle"):
        return s.center
    p = polygon_outline(s)
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]  # centroid: Σ (p + q) (p × q) / (6 A)
    return tuple(((p + q) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum()))


def surface_reach(s, world: float) -> float:
    """The farthest point of a collider's surface from its pivot (m): where it moves fastest when it turns, at
    |ω| × this. A plane's surface has no end: its farthest point a blob can reach, where it leaves the world
    [-world, world]² (positions beyond stop a run)."""
    pivot = np.array(default_pivot(s))
    if s.kind == "circle":
        return float(np.hypot(*(np.array(s.center) - pivot)) + s.radius)
    if s.kind == "plane":  # its line p + t u, cut where it leaves the world's square
        p, n = np.array(s.point), _unit_normal(s)
        u = np.array([-n[1], n[0]])
        ends = [t for i in range(2) if u[i] != 0.0 for t in ((world - p[i]) / u[i], (-world - p[i]) / u[i])]
        inside = [p + t * u for t in ends if np.all(np.abs(p + t * u) <= world * (1.0 + 1e-12))]
        return float(max(np.hypot(*(q - pivot)) for q in inside))
    corners = np.array([s.a, s.b]) if s.kind == "segment" else polygon_outline(s)
    return float(np.hypot(*(corners - pivot).T).max())


COLLIDERS = {
    "plane": ColliderKind(("point", "normal"), "plane", _plane_rows, _plane_outline, _plane_depth),
    "segment": ColliderKind(("a", "b"), "segment", _segment_rows, lambda s, extent: np.array([s.a, s.b]),
                            lambda points, s: np.zeros(len(points))),
    "box": ColliderKind(("center", "size", "angle"), "polygon", _polygon_rows, _polygon_outline,
                        lambda points, s: depth_inside_polygon(points, polygon_outline(s))),
    "circle": ColliderKind(("center", "radius", "inside"), "circle", _circle_rows, _circle_outline, _circle_depth),
    "polygon": ColliderKind(("points",), "polygon", _polygon_rows, _polygon_outline,
                            lambda points, s: depth_inside_polygon(points, polygon_outline(s))),
}
SOLVERS = ("plane", "segment", "circle", "polygon")  # the order the statics stage runs them in
