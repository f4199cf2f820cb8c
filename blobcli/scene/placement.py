"""Random starts: where the copies of a `[[blob]]` with `count` go.

Random sequential addition, the way packings of discs are started (and the O'Hern group's
deformable-polygon code starts its cells): each copy's centre is drawn uniformly from the
positions where its bounding disc (the vertex farthest from the ring's vertex average) lies
inside `region` (in a periodic box without a region: anywhere in the box, across its edges
too), and kept if that disc overlaps no disc placed before it (every other blob of the scene,
grids and single blobs included, and the copies already placed; in a periodic box, their
nearest images) and none of its vertices, nor its centre, lies inside a collider, nor any
segment collider passes through its disc. Copies are placed table by table, in scene order; a
copy that finds no place in MAX_TRIES draws stops the placement with an error that says how
many fitted.

The draws come from numpy's PCG64 generator seeded with `[scene] seed`: the same seed, the same
scene (on any machine: the generator's stream is fixed by numpy's policy for `default_rng`).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import blob_points

MAX_TRIES = 10_000  # draws for one copy before the placement gives up


class PlacementError(ValueError):
    """A copy of blob table `table` found no place: `placed` of its `count` fitted."""

    def __init__(self, table: int, placed: int, count: int, radius: float):
        super().__init__(f"only {placed} of {count} copies (bounding radius {radius:.4g} m) fitted in region "
                         f"without overlap after {MAX_TRIES:,} tries for the next: enlarge region or lower count")
        self.table, self.placed = table, placed


def ring_at_origin(b) -> np.ndarray:
    """The blob's ring with its vertex average at the origin."""
    ring = blob_points(b)
    return ring - ring.mean(axis=0)


def _blocked_by_statics(ring: np.ndarray, centre: np.ndarray, radius: float, statics) -> bool:
    from ..colliders import COLLIDERS
    points = np.vstack([ring + centre, centre[None, :]])
    for s in statics:
        if s.kind == "segment":
            a, b = np.array(s.a), np.array(s.b)
            ab = b - a
            t = np.clip(np.dot(centre - a, ab) / np.dot(ab, ab), 0.0, 1.0)
            if np.hypot(*(a + t * ab - centre)) < radius:
                return True
        elif np.any(COLLIDERS[s.kind].depth(points, s) > 0.0):
            return True
    return False


def random_centres(scene) -> dict[int, np.ndarray]:
    """{blob table index: (count, 2) centres} for every table with count > 1, in scene order."""
    discs = []  # (x, y, r) of every blob placed or fixed
    for b in scene.blobs:
        if b.count > 1:
            continue
        ring = blob_points(b)
        centre = ring.mean(axis=0)
        r = float(np.hypot(*(ring - centre).T).max())
        nx, ny = b.grid
        for ix in range(nx):
            for iy in range(ny):
                shift = np.array([ix, iy]) * np.array(b.spacing or (0.0, 0.0))
                discs.append((*(centre + shift), r))
    rings = {i: ring_at_origin(b) for i, b in enumerate(scene.blobs) if b.count > 1}
    radii = {i: float(np.hypot(*ring.T).max()) for i, ring in rings.items()}
    placed = Discs(discs, sum(scene.blobs[i].count for i in rings), max([r for *_, r in discs] + list(radii.values())),
                   scene.settings.periodic)
    rng = np.random.default_rng(scene.settings.seed)
    box = np.array(scene.settings.periodic or (np.inf, np.inf))
    out = {}
    for i, ring in rings.items():
        b, r = scene.blobs[i], radii[i]
        if b.region is None:  # the periodic box: a disc may cross its edges
            low, high = -box / 2, box / 2
        else:
            xmin, ymin, xmax, ymax = b.region
            low, high = np.array([xmin + r, ymin + r]), np.array([xmax - r, ymax - r])
        centres = np.empty((b.count, 2))
        for k in range(b.count):
            for _ in range(MAX_TRIES):
                c = rng.uniform(low, high) if np.all(high >= low) else None
                if c is None:
                    break
                near = placed.near(c)
                d = near[:, :2] - c
                if np.isfinite(box[0]):  # the nearest image (a periodic box)
                    d -= box * np.round(d / box)
                gap = np.hypot(d[:, 0], d[:, 1]) - near[:, 2] - r
                if np.all(gap >= 0.0) and not _blocked_by_statics(ring, c, r, scene.statics):
                    break
            else:
                c = None
            if c is None:
                raise PlacementError(i, k, b.count, r)
            centres[k] = c
            placed.add(c[0], c[1], r)
        out[i] = centres
    return out


class Discs:
    """The discs placed so far, binned in a grid of cells at least as wide as any two of them can reach (2 r_max,
    and a margin for rounding), so that a new disc is tested against those in the 3 × 3 cells around its centre
    only: random addition of N copies in O(N) tests, not O(N²). A disc overlaps another only if their centres
    are closer than r_a + r_b <= 2 r_max, so the others cannot overlap it and the test finds what testing every
    disc would. In a periodic box the cells tile it and wrap round it (nearest images)."""

    MARGIN = 1.01  # cells 1% wider than 2 r_max: a cell index off by a rounding never misses a neighbour

    def __init__(self, discs, more: int, r_max: float, periodic):
        self.xyr = np.empty((len(discs) + more, 3))
        self.count = 0
        self.width = 2.0 * r_max * self.MARGIN if r_max > 0 else 1.0
        self.box = None if periodic is None else np.array(periodic, dtype=np.float64)
        if self.box is not None:  # cells tiling the box exactly, each at least `width` wide
            self.cells = np.maximum(1, np.floor(self.box / self.width)).astype(np.int64)
        self.grid: dict[tuple[int, int], list[int]] = {}
        for x, y, r in discs:
            self.add(x, y, r)

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        if self.box is None:
            return math.floor(x / self.width), math.floor(y / self.width)
        f = (np.array([x, y]) / self.box + 0.5) % 1.0  # where in the box, from its corner, as a fraction
        ix, iy = np.minimum((f * self.cells).astype(np.int64), self.cells - 1)
        return int(ix), int(iy)

    def _around(self, cell) -> list[tuple[int, int]]:
        """The cells next to `cell` and itself (wrapped, each once, in a periodic box)."""
        ix, iy = cell
        if self.box is None:
            return [(ix + dx, iy + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
        nx, ny = self.cells
        xs = sorted({(ix + dx) % nx for dx in (-1, 0, 1)})
        ys = sorted({(iy + dy) % ny for dy in (-1, 0, 1)})
        return [(x, y) for x in xs for y in ys]

    def add(self, x: float, y: float, r: float) -> None:
        self.xyr[self.count] = (x, y, r)
        self.grid.setdefault(self._cell(x, y), []).append(self.count)
        self.count += 1

    def near(self, c) -> np.ndarray:
        """(k, 3) x, y, r of the discs in the cells around the point c, in the order they were placed."""
        index = sorted(i for cell in self._around(self._cell(c[0], c[1])) for i in self.grid.get(cell, ()))
        return self.xyr[index]
