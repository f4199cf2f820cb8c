"""Random starts: where the copies of a `[[blob]]` with `count` go.

Random sequential addition first, the way packings of discs are started: each copy's centre is drawn
uniformly from the positions where its bounding disc (the vertex farthest from the ring's vertex
average) lies inside `region` (in a periodic box without a region: anywhere in the box, across its
edges too), and kept if that disc overlaps no disc placed before it (every other blob of the scene,
grids and single blobs included, and the copies already placed; in a periodic box, their nearest
images) and none of its vertices, nor its centre, lies inside a collider, nor any segment collider
passes through its disc. Copies are placed table by table, in scene order. Draws are made and tested
in batches (class Discs); the copies are those that drawing and testing one at a time keeps.

Then, if random addition stops, pushed apart. Random addition covers at most about φ ≈ 0.55 of the
area (Hinrichsen, Feder & Jøssang, J. Stat. Phys. 44, 793 (1986)), and jamming protocols start denser
(the O'Hern group's deformable-polygon code at φ0 = 0.5). So when a copy finds no place in MAX_TRIES
draws, every copy of every table with count is placed again: the generator starts again from the seed,
and each copy's centre is drawn as above, table by table, overlaps allowed (colliders are still
avoided, up to MAX_TRIES draws a copy). Then the discs move to minimise the overlap energy

    U = Σ_pairs ½ max(0, r_a + r_b − d)²  +  Σ_copies Σ_edges ½ max(0, r − e)²

(d the distance of two centres, nearest images in a periodic box; e a copy's distance from an edge of
its region, which is a wall). Fixed blobs (grids, single blobs) stay where they are and push. The
minimiser is FIRE (Bitzek et al., PRL 97, 170201 (2006)): unit masses driven by F = −∇U, their velocity
turned toward F and their time step growing while they go downhill (F · v > 0), stopped and the step
halved when they go uphill; no disc moves more than MAX_MOVE × the smallest radius in a step. FIRE
minimises U for radii SKIN (10⁻⁶) larger than the discs', and stops as soon as every gap with the true
radii is at least MIN_GAP (10⁻⁹) of the two radii's sum (from an edge: of the radius): no two discs
overlap, with room for rounding, and the larger discs' overlaps need only fall below about 10⁻⁶, not
to zero, which a minimiser reaches only in the limit. Each copy is then tested against the colliders,
as a draw is; one pushed into a collider is an error.

Discs pushed apart from random places jam near φ ≈ 0.84 (O'Hern et al., PRE 68, 011306 (2003)). A
scene whose bounding discs cover more than PHI_JAM of the box (or a region) is refused at once; one
whose discs still overlap after MAX_PUSH_STEPS steps, or come to rest with overlaps left (jammed: no
force above JAMMED × the deepest overlap), is an error. Either error says the φ asked and that only
φ ≤ PHI_SURE is placed for sure (in a periodic box; a region's walls and fixed blobs leave less room).

Neighbours are found in cells at least as wide as two discs reach, so that N copies cost O(N), not
O(N²): random addition tests a batch of draws against the discs placed in the 3 × 3 cells around each
(Discs); the push lists the pairs within reach from discs sorted by cell (_pairs), and lists them again
when a disc has moved half the list's spare reach.

The draws come from numpy's PCG64 generator seeded with `[scene] seed`: the same seed, the same scene
(on any machine: the generator's stream is fixed by numpy's policy for `default_rng`, and the push uses
only IEEE operations and sums in a fixed order, with no threads).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import blob_points, signed_area

MAX_TRIES = 10_000  # draws for one copy before random addition gives up (and the copies are pushed apart)
BATCH = 1_024  # draws made and tested at once, at most
PHI_SURE = 0.8  # packing fraction (bounding discs' area / area) that pushing apart places for sure ...
PHI_JAM = 0.84  # ... and the most it may: random discs pushed apart jam near it (O'Hern et al. 2003)
SKIN = 1e-6  # discs are pushed apart as if their radii were this much (relative) larger, ...
MIN_GAP = 1e-9  # ... until every gap is at least this × (r_a + r_b) (from a region's edge: × r)
MAX_MOVE = 0.1  # × the smallest radius: the most a disc moves in one step of the push
LIST_SPARE = 0.5  # × the smallest radius: the pair list's reach beyond contact (listed again at half of it moved)
JAMMED = 1e-6  # the push gives up when no disc feels a force above this × the deepest overlap: jammed
MAX_PUSH_STEPS = 10_000  # steps of the push before it gives up (φ = 0.8: 400 for 256 discs, 1,000 for 40,000)
# FIRE (Bitzek et al. 2006): unit masses and stiffness, so times are in units of sqrt(m / k). Their values, but for
# a largest step 3 (not 10) × the first: the fewest steps for the jamming mix at φ = 0.8 of 0.15, 0.2, 0.3, 0.5, 1
FIRE_DT, FIRE_DT_MAX = 0.1, 0.3  # the first time step and the largest
FIRE_N_MIN, FIRE_INC, FIRE_DEC = 5, 1.1, 0.5  # downhill steps before dt grows (× FIRE_INC); uphill: dt × FIRE_DEC
FIRE_ALPHA, FIRE_F_ALPHA = 0.1, 0.99  # velocity turned toward the force by alpha; alpha × FIRE_F_ALPHA when it grows
AROUND = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.int64)  # a cell and its 8 neighbours
HASH = np.array([73_856_093, 19_349_663], dtype=np.int64)  # a cell's hash: HASH · cell (then the bucket: its low bits)
HASH_AROUND = AROUND @ HASH  # what the cells around add to it


class PlacementError(ValueError):
    """The copies of blob table `table` could not be placed; the message says why and what to change."""

    def __init__(self, table: int, message: str):
        super().__init__(message)
        self.table = table


def _none_fitted(table: int, placed: int, count: int, radius: float) -> PlacementError:
    return PlacementError(table, f"only {placed} of {count} copies (bounding radius {radius:.4g} m) fitted in region "
                          f"without overlap after {MAX_TRIES:,} tries for the next: enlarge region or lower count")


def ring_at_origin(b) -> np.ndarray:
    """The blob's ring with its vertex average at the origin."""
    ring = blob_points(b)
    return ring - ring.mean(axis=0)


def _blocked_by_statics(ring: np.ndarray, centre: np.ndarray, radius: float, statics) -> bool:
    if not statics:
        return False
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


def _centre_bounds(b, r: float, box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a copy's centre may be drawn: its bounding disc inside `region`, or anywhere in the periodic box."""
    if b.region is None:  # the periodic box: a disc may cross its edges
        return -box / 2, box / 2
    xmin, ymin, xmax, ymax = b.region
    return np.array([xmin + r, ymin + r]), np.array([xmax - r, ymax - r])


def random_centres(scene) -> dict[int, np.ndarray]:
    """{blob table index: (count, 2) centres} for every table with count > 1, in scene order: by random
    addition, or pushed apart when random addition finds no place for a copy (the module's docstring)."""
    discs, areas = [], []  # (x, y, r) of every blob placed or fixed, and its polygon's area
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
                areas.append(abs(signed_area(ring)))
    rings = {i: ring_at_origin(b) for i, b in enumerate(scene.blobs) if b.count > 1}
    radii = {i: float(np.hypot(*ring.T).max()) for i, ring in rings.items()}
    try:
        return _added_at_random(scene, discs, rings, radii)
    except _NoPlace as e:
        if not e.fits:  # a disc wider than its region: pushing cannot help
            raise _none_fitted(e.table, e.placed, scene.blobs[e.table].count, radii[e.table]) from None
    fixed = np.column_stack([np.array(discs, dtype=np.float64).reshape(-1, 3), areas])
    return _pushed_apart(scene, fixed, rings, radii)


class _NoPlace(Exception):
    def __init__(self, table: int, placed: int, fits: bool):
        self.table, self.placed, self.fits = table, placed, fits


def _added_at_random(scene, discs, rings, radii) -> dict[int, np.ndarray]:
    """Random sequential addition, table by table; _NoPlace when a copy finds no place."""
    placed = Discs(discs, sum(scene.blobs[i].count for i in rings), max([r for *_, r in discs] + list(radii.values())),
                   scene.settings.periodic)
    rng = np.random.default_rng(scene.settings.seed)
    box = np.array(scene.settings.periodic or (np.inf, np.inf))
    out = {}
    for i, ring in rings.items():
        b, r = scene.blobs[i], radii[i]
        low, high = _centre_bounds(b, r, box)
        if not np.all(high >= low):
            raise _NoPlace(i, 0, False)
        out[i] = _added_copies(i, b.count, ring, r, low, high, rng, placed, scene.statics)
    return out


def _added_copies(table, count, ring, r, low, high, rng, placed, statics) -> np.ndarray:
    """(count, 2) centres of one table's copies by random addition: the generator's draws are scanned in
    order, and a draw whose disc overlaps no disc placed before it and no collider is the next copy; a copy
    with no such draw in MAX_TRIES stops it (_NoPlace). The draws are made in batches, the generator left just
    past the last copy's draw: `rng.uniform(low, high, size=(m, 2))` gives the numbers that m draws of
    `rng.uniform(low, high)` give, and a batch that goes past it is drawn again up to it. A batch is tested at
    once against the discs placed before it (`placed`), then draw by draw against the copies it placed."""
    centres = np.empty((count, 2))
    placed_count, missed, size = 0, 0, min(count, BATCH)  # copies placed; draws since the last one
    while True:
        state = rng.bit_generator.state
        cs = rng.uniform(low, high, size=(size, 2))
        first, since = placed_count, 0  # the batch's first copy; the draw after its last copy's
        for t in np.flatnonzero(placed.clear(cs, r)):
            if missed + t - since >= MAX_TRIES:
                raise _NoPlace(table, placed_count, True)
            d = centres[first:placed_count] - cs[t]
            if placed.box is not None:  # the nearest image (a periodic box)
                d -= placed.box * np.round(d / placed.box)
            if np.all(np.hypot(d[:, 0], d[:, 1]) - r - r >= 0.0) and not _blocked_by_statics(ring, cs[t], r, statics):
                centres[placed_count] = cs[t]
                placed_count, missed, since = placed_count + 1, 0, t + 1
                if placed_count == count:
                    if t + 1 < size:  # back to just past this draw
                        rng.bit_generator.state = state
                        rng.uniform(low, high, size=(t + 1, 2))
                    placed.add(centres[first:], r)
                    return centres
        missed += size - since
        if missed >= MAX_TRIES:
            raise _NoPlace(table, placed_count, True)
        placed.add(centres[first:placed_count], r)
        # the next batch: as many draws as the copies left took in this one, or four times as many if none fitted
        new = placed_count - first
        size = min(BATCH, math.ceil((count - placed_count) * size / new) if new else 4 * size)


class Discs:
    """The discs placed so far, binned in a grid of cells at least as wide as any two of them can reach (2 r_max,
    and a margin for rounding), so that a draw is tested against those in the 3 × 3 cells around its centre
    only: random addition of N copies in O(N) tests, not O(N²). A disc overlaps another only if their centres
    are closer than r_a + r_b <= 2 r_max, so the others cannot overlap it and the test finds what testing every
    disc would. In a periodic box the cells tile it and wrap round it (nearest images).

    The cells are kept in a hash table: `slots[h, :filled[h]]` are the discs of the cells whose hash is h, in an
    array of (buckets, capacity) indices, so that a batch of draws is tested at once. Two cells of one hash
    only add discs to the test, which cannot overlap the draw (they are in no cell around it): the answer is
    that of the 3 × 3 cells."""

    MARGIN = 1.01  # cells 1% wider than 2 r_max: a cell index off by a rounding never misses a neighbour

    def __init__(self, discs, more: int, r_max: float, periodic):
        total = len(discs) + more
        self.xyr = np.empty((total, 3))
        self.count = 0
        self.width = 2.0 * r_max * self.MARGIN if r_max > 0 else 1.0
        self.box = None if periodic is None else np.array(periodic, dtype=np.float64)
        if self.box is not None:  # cells tiling the box exactly, each at least `width` wide
            self.cells = np.maximum(1, np.floor(self.box / self.width)).astype(np.int64)
        self.buckets = 1 << max(4, (2 * total).bit_length())  # a power of two, more than twice the discs
        self.slots = np.zeros((self.buckets, 4), dtype=np.int64)
        self.filled = np.zeros(self.buckets, dtype=np.int64)
        for x, y, r in discs:
            self.add(np.array([[x, y]]), r)

    def _cells(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) points -> (..., 2) integer cells (in a periodic box, 0 <= cell < cells)."""
        if self.box is None:
            return np.floor(xy / self.width).astype(np.int64)
        f = (xy / self.box + 0.5) % 1.0  # where in the box, from its corner, as a fraction
        return np.minimum((f * self.cells).astype(np.int64), self.cells - 1)

    def _hash(self, cells: np.ndarray) -> np.ndarray:
        """(..., 2) cells -> (...) unmasked hash, linear, so that a neighbour's is a cell's plus HASH_AROUND's
        (integer overflow only wraps: the same bucket every time)."""
        return cells[..., 0] * HASH[0] + cells[..., 1] * HASH[1]

    def add(self, xy: np.ndarray, r: float) -> None:
        """Place discs of radius r at the (k, 2) centres xy."""
        first = self.count
        self.xyr[first:first + len(xy), :2] = xy
        self.xyr[first:first + len(xy), 2] = r
        for k, h in enumerate((self._hash(self._cells(xy)) & (self.buckets - 1)).tolist(), first):
            if self.filled[h] == self.slots.shape[1]:
                self.slots = np.concatenate([self.slots, np.zeros_like(self.slots)], axis=1)
            self.slots[h, self.filled[h]] = k
            self.filled[h] += 1
        self.count += len(xy)

    def clear(self, cs: np.ndarray, r: float) -> np.ndarray:
        """(m,) bool: which of the (m, 2) centres cs a disc of radius r may take, overlapping no disc placed."""
        if self.count == 0:
            return np.ones(len(cs), dtype=bool)
        cells = self._cells(cs)
        if self.box is None:
            h = self._hash(cells)[:, None] + HASH_AROUND
        else:  # the cells around, wrapped round the box
            h = self._hash((cells[:, None, :] + AROUND) % self.cells)
        h = (h & (self.buckets - 1)).ravel()  # (9 m,) the buckets of each draw's cells, draw by draw
        count = self.filled[h]
        owner = np.repeat(np.arange(len(h)) // len(AROUND), count)  # the draw each listed disc is tested against
        slot = np.repeat(h * self.slots.shape[1] - np.cumsum(count) + count, count) + np.arange(count.sum())
        near = self.xyr[self.slots.ravel()[slot]]
        d = near[:, :2] - cs[owner]
        if self.box is not None:  # the nearest image (a periodic box)
            d -= self.box * np.round(d / self.box)
        gap = np.hypot(d[:, 0], d[:, 1]) - near[:, 2] - r
        return np.bincount(owner[~(gap >= 0.0)], minlength=len(cs)) == 0


def _sum(a: np.ndarray) -> float:
    """Σ a in a fixed order (left to right), the same on every machine."""
    return float(np.cumsum(a, axis=None)[-1]) if a.size else 0.0


def _packing(scene, rings, radii, fixed, box) -> tuple[float, float, int, str]:
    """The densest packing asked: where the copies of one region (or the box) and the fixed blobs there cover
    most of it. (φ of the blobs, φ of their bounding discs, the first table placed there, 'region' or 'the
    box'). fixed: (k, 4) x, y, r, polygon area of the fixed blobs."""
    domains: dict = {}
    for i in rings:
        domains.setdefault(scene.blobs[i].region, []).append(i)
    worst = (-1.0, -1.0, 0, "")
    for region, tables in domains.items():
        if region is None:
            area, inside = float(box[0] * box[1]), np.ones(len(fixed), dtype=bool)
        else:
            xmin, ymin, xmax, ymax = region
            area = (xmax - xmin) * (ymax - ymin)
            inside = (fixed[:, 0] > xmin) & (fixed[:, 0] < xmax) & (fixed[:, 1] > ymin) & (fixed[:, 1] < ymax)
        blobs = sum(scene.blobs[i].count * abs(signed_area(rings[i])) for i in tables) + _sum(fixed[inside, 3])
        discs = (sum(scene.blobs[i].count * math.pi * radii[i] ** 2 for i in tables)
                 + _sum(math.pi * fixed[inside, 2] ** 2))
        if discs / area > worst[1]:
            worst = (blobs / area, discs / area, tables[0], "the box" if region is None else "region")
    return worst


def _pushed_apart(scene, fixed: np.ndarray, rings, radii) -> dict[int, np.ndarray]:
    """Every copy placed at random with overlaps, then pushed apart (the module's docstring). fixed: (k, 4)
    x, y, r, polygon area of the fixed blobs."""
    box = None if scene.settings.periodic is None else np.array(scene.settings.periodic, dtype=np.float64)
    phi, phi_discs, table, where = _packing(scene, rings, radii, fixed, box)
    asked = f"blobs cover φ = {phi:.3f} of {where} (their bounding discs {phi_discs:.3f})"
    advice = (f"only φ ≤ {PHI_SURE} (of bounding discs, in a periodic box; a region's edges and fixed blobs leave "
              f"less room) is placed for sure: lower count or enlarge {where}")
    if phi_discs > PHI_JAM:
        raise PlacementError(table, f"{asked}: discs pushed apart from random places jam near φ ≈ {PHI_JAM}, "
                             f"and {advice}")
    rng = np.random.default_rng(scene.settings.seed)  # starting again, whatever random addition drew
    starts, radius, edges = [], [], []
    for i, ring in rings.items():
        b, r = scene.blobs[i], radii[i]
        low, high = _centre_bounds(b, r, box if box is not None else np.array([np.inf, np.inf]))
        if not np.all(high >= low):
            raise _none_fitted(i, 0, b.count, r)
        if not scene.statics:  # count draws at once: the numbers of count draws one at a time
            starts.append(rng.uniform(low, high, size=(b.count, 2)))
        else:  # each copy drawn until its disc is clear of the colliders
            centres = np.empty((b.count, 2))
            for k in range(b.count):
                for _ in range(MAX_TRIES):
                    centres[k] = rng.uniform(low, high)
                    if not _blocked_by_statics(ring, centres[k], r, scene.statics):
                        break
                else:
                    raise PlacementError(i, f"copy {k} found no place clear of the colliders in {MAX_TRIES:,} "
                                         f"draws: enlarge region or move the colliders")
            starts.append(centres)
        radius.append(np.full(b.count, r))
        edges.append(np.tile(b.region or (-np.inf, -np.inf, np.inf, np.inf), (b.count, 1)))
    x, radius, edges = np.concatenate(starts), np.concatenate(radius), np.concatenate(edges).astype(np.float64)
    if box is None:  # only the fixed discs a copy may reach: those near the regions
        reach = 4.0 * max(radius.max(), fixed[:, 2].max(initial=0.0))
        low, high = edges[:, :2].min(axis=0) - reach, edges[:, 2:].max(axis=0) + reach
        fixed = fixed[np.all((fixed[:, :2] >= low) & (fixed[:, :2] <= high), axis=1)]
    x, steps, outcome = push_apart(x, radius, edges, fixed[:, :3], box)
    if outcome != "apart":
        raise PlacementError(table, f"{asked}, and pushed apart from random places the discs still overlap after "
                             f"{steps:,} steps ({outcome}): {advice}")
    out, first = {}, 0
    for i, ring in rings.items():
        b, r = scene.blobs[i], radii[i]
        centres = x[first:first + b.count]
        if box is not None and b.region is None:  # back in the box, as random addition draws them
            centres = centres - box * np.floor(centres / box + 0.5)
        for k, c in enumerate(centres):
            if scene.statics and _blocked_by_statics(ring, c, r, scene.statics):
                raise PlacementError(i, f"copy {k} was pushed into a collider when the copies were pushed apart "
                                     f"(colliders do not push): lower count, enlarge {where} or move the colliders")
        out[i] = centres
        first += b.count
    return out


def push_apart(x: np.ndarray, radius: np.ndarray, edges: np.ndarray, fixed: np.ndarray, box) -> tuple:
    """The discs at x (m, 2) moved until none overlaps another, a fixed disc, or an edge of its region: U =
    Σ_pairs ½ max(0, r_a + r_b − d)² + Σ ½ max(0, r − e)² minimised with FIRE, the radii SKIN larger, until
    every gap is at least MIN_GAP (the module's docstring). radius (m,); edges (m, 4) xmin, ymin, xmax, ymax of
    each disc's region (±inf: none); fixed (k, 3) x, y, r of discs that stay; box: the periodic box's sides
    (2,), or None. Returns (centres (m, 2), steps taken, outcome): "apart", or "jammed" (at rest with overlaps
    left), or "out of steps" (MAX_PUSH_STEPS)."""
    m, n = len(x), len(x) + len(fixed)
    xy = np.concatenate([x, fixed[:, :2]])  # the movers first, then the fixed discs
    r = np.concatenate([radius, fixed[:, 2]])
    spare, max_move = LIST_SPARE * radius.min(), MAX_MOVE * radius.min()
    walled = bool(np.isfinite(edges).any())
    wall_touch, wall_push = radius[:, None] * (1.0 + MIN_GAP), radius[:, None] * (1.0 + SKIN)
    v = np.zeros_like(x)
    dt, alpha, downhill = FIRE_DT, FIRE_ALPHA, 0
    listed_at = None
    for step in range(MAX_PUSH_STEPS):
        if listed_at is None or (((xy[:m] - listed_at) ** 2).sum(axis=1) > (spare / 2) ** 2).any():
            a, b = _pairs(xy, r, m, spare, box)
            touch, push = (r[a] + r[b]) * (1.0 + MIN_GAP), (r[a] + r[b]) * (1.0 + SKIN)
            listed_at = xy[:m].copy()
        d = xy[b] - xy[a]
        if box is not None:  # the nearest image
            d -= box * np.round(d / box)
        dist = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
        if walled:
            low, high = xy[:m] - edges[:, :2], edges[:, 2:] - xy[:m]  # (m, 2) a centre's distance from its edges
        if np.all(dist >= touch) and (not walled or (np.all(low >= wall_touch) and np.all(high >= wall_touch))):
            return xy[:m], step, "apart"
        # F = −∇U: an overlap δ = (r_a + r_b)(1 + SKIN) − d pushes b along d / d and a back, with force δ
        overlap = np.maximum(push - dist, 0.0)
        if np.all(dist > 0.0):
            f = d * (overlap / dist)[:, None]
        else:  # centres on one another: pushed apart along x
            f = np.where((dist > 0.0)[:, None], d * (overlap / np.where(dist > 0.0, dist, 1.0))[:, None],
                         overlap[:, None] * [1.0, 0.0])
        force = np.stack([np.bincount(b, f[:, 0], n) - np.bincount(a, f[:, 0], n),
                          np.bincount(b, f[:, 1], n) - np.bincount(a, f[:, 1], n)], axis=1)[:m]
        deepest = overlap.max(initial=0.0)
        if walled:  # an edge closer than r pushes the centre back in, with force r (1 + SKIN) − e
            wall_low, wall_high = np.maximum(wall_push - low, 0.0), np.maximum(wall_push - high, 0.0)
            force += wall_low - wall_high
            deepest = max(deepest, wall_low.max(), wall_high.max())
        if np.abs(force).max() < JAMMED * deepest:  # at rest with overlaps left
            return xy[:m], step, "jammed"
        # FIRE: downhill (F · v > 0) the velocity is turned toward the force, and after FIRE_N_MIN such steps the
        # step grows; uphill it stops, and the step shrinks
        if _sum(force * v) > 0.0:
            v = (1.0 - alpha) * v + alpha * math.sqrt(_sum(v * v) / _sum(force * force)) * force
            if downhill > FIRE_N_MIN:
                dt, alpha = min(dt * FIRE_INC, FIRE_DT_MAX), alpha * FIRE_F_ALPHA
            downhill += 1
        else:
            v[:] = 0.0
            dt, alpha, downhill = dt * FIRE_DEC, FIRE_ALPHA, 0
        v += dt * force  # unit masses: semi-implicit Euler
        move = dt * v
        length = np.sqrt(move[:, 0] * move[:, 0] + move[:, 1] * move[:, 1])
        xy[:m] += move * (max_move / np.maximum(length, max_move))[:, None]  # no disc moves more than max_move
    return xy[:m], MAX_PUSH_STEPS, "out of steps"


def _pairs(xy: np.ndarray, r: np.ndarray, m: int, spare: float, box) -> tuple[np.ndarray, np.ndarray]:
    """(a, b), a < b, a < m: the pairs of discs (xy (n, 2), radii r (n,)) with at least one of the first m,
    whose centres are closer than (r_a + r_b)(1 + SKIN) + spare, in increasing order of (a, b). The discs are
    sorted by cell (cells at least as wide as any pair can reach), and each of the first m finds the others
    in the 3 × 3 cells around its own by binary search: O(n log n), no n × n."""
    n = len(xy)
    width = 2.0 * r.max() * (1.0 + SKIN) + spare
    if box is None:
        cells = np.floor((xy - xy.min(axis=0)) / width).astype(np.int64) + 1  # >= 1: a neighbour's is >= 0
        ny = int(cells[:, 1].max()) + 2
        key = cells[:, 0] * ny + cells[:, 1]
    else:  # cells tiling the box, wrapped round it
        sides = np.maximum(1, np.floor(box / width)).astype(np.int64)
        cells = np.minimum(((xy / box + 0.5) % 1.0 * sides).astype(np.int64), sides - 1)
        key = cells[:, 0] * sides[1] + cells[:, 1]
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    codes = []
    for dx, dy in AROUND:
        c = cells[:m] + (dx, dy)
        if box is not None:
            c %= sides
            near = c[:, 0] * sides[1] + c[:, 1]
        else:
            near = c[:, 0] * ny + c[:, 1]
        first = np.searchsorted(sorted_key, near, "left")
        count = np.searchsorted(sorted_key, near, "right") - first
        a = np.repeat(np.arange(m), count)
        b = order[np.repeat(first - np.cumsum(count) + count, count) + np.arange(count.sum())]
        codes.append(a[a < b] * n + b[a < b])
    code = np.sort(np.concatenate(codes))
    if box is not None and np.any(sides < 3):  # a small box: the cells around one wrap onto each other
        code = code[np.concatenate([[True], code[1:] != code[:-1]])]  # each pair once
    a, b = code // n, code % n
    d = xy[b] - xy[a]
    if box is not None:
        d -= box * np.round(d / box)
    reach = (r[a] + r[b]) * (1.0 + SKIN) + spare
    close = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] < reach * reach
    return a[close], b[close]
