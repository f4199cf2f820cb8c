"""What `check` and `run` warn about, without refusing: blobs spawned inside a static
collider or overlapping another blob (they are pushed out at once, often at hundreds of m/s,
which is rarely what the scene meant), and blobs too small for the step (below)."""

from __future__ import annotations

import numpy as np

from ..colliders import COLLIDERS
from ..geometry import blob_points, depth_inside_polygon
from .schema import Scene

MAX_PAIR_CHECK_BLOBS = 2000  # blob-blob overlap is checked pairwise up to this many blobs
MAX_VERTEX_CHECK = 200_000  # vertices tested against colliders (beyond: blob centres only)
SHOWN = 5  # warnings listed before "... and N more"
TOUCHING = 1e-9  # m: deeper than this is inside; blobs spawned exactly touching are not warned about
SMALL = 20.0  # a blob whose radius is under SMALL × g h² (how far gravity moves it in a substep, from rest)
#              loses area on contact: a blob dropped on a floor at the defaults (h = 1/240 s, g h² = 0.17 mm)
#              showed a worst area error of 1.9% at r = 10 mm, 3.8% at 3 mm, 9.5% at 1 mm, 41% at 0.1 mm


def _rings(scene: Scene):
    """(name, index in scene.blobs, polygon (n, 2)) of every blob after grids; not the random copies of
    a table with count, which are placed clear of every blob and collider (scene/placement.py)."""
    for i, b in enumerate(scene.blobs):
        if b.count > 1:
            continue
        base = blob_points(b)
        name = b.name or f"blob{i}"
        for ix in range(b.grid[0]):
            for iy in range(b.grid[1]):
                shift = np.array([ix * b.spacing[0], iy * b.spacing[1]]) if b.grid != (1, 1) else np.zeros(2)
                yield (name if b.grid == (1, 1) else f"{name}_{ix}_{iy}"), i, base + shift


def spawn_warnings(scene: Scene) -> list[str]:
    rings = list(_rings(scene))
    out = []
    whole = scene.vertex_count <= MAX_VERTEX_CHECK
    for name, i, ring in rings:
        points = ring if whole else ring.mean(axis=0, keepdims=True)
        for k, s in enumerate(scene.statics):
            inside = int(np.count_nonzero(COLLIDERS[s.kind].depth(points, s) > TOUCHING))
            if inside:
                what = f"{inside} of its {len(ring)} vertices" if whole else "its centre"
                out.append(f"{scene.source}: blob[{i}] ({name}): {what} start inside static[{k}] ({s.kind}); "
                           f"it will be pushed out at once")
    if 1 < len(rings) <= MAX_PAIR_CHECK_BLOBS:
        centers = np.array([r.mean(axis=0) for _, _, r in rings])
        radii = np.array([np.hypot(*(r - c).T).max() for (_, _, r), c in zip(rings, centers)])
        d = np.hypot(*(centers[:, None, :] - centers[None, :, :]).transpose(2, 0, 1))
        close = np.argwhere(np.triu(d < radii[:, None] + radii[None, :], 1))
        for a, b in close:
            (na, ia, ra), (nb, ib, rb) = rings[a], rings[b]
            if (depth_inside_polygon(ra, rb) > TOUCHING).any() or (depth_inside_polygon(rb, ra) > TOUCHING).any():
                out.append(f"{scene.source}: blob[{ia}] ({na}) and blob[{ib}] ({nb}) overlap at the start; "
                           f"they will be pushed apart at once")
    out += small_blob_warnings(scene)
    if len(out) > SHOWN:
        out = out[:SHOWN] + [f"... and {len(out) - SHOWN} more"]
    return out


def small_blob_warnings(scene: Scene) -> list[str]:
    """Blobs (one line per [[blob]] table) whose radius is under SMALL × g h²."""
    s = scene.settings
    h = s.dt / s.substeps
    reach = SMALL * float(np.hypot(*s.gravity)) * h * h  # m
    out = []
    for i, b in enumerate(scene.blobs):
        ring = blob_points(b)
        r = float(np.hypot(*(ring - ring.mean(axis=0)).T).max())
        if r < reach:
            out.append(f"{scene.source}: blob[{i}] ({b.name or f'blob{i}'}): radius {r:.3g} m is under {SMALL:g} g h² "
                       f"= {reach:.3g} m for this step: expect area errors of several % on contact (more substeps "
                       f"or a smaller dt fix it)")
    return out
