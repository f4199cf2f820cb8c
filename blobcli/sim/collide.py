"""Blob–blob collision stages: broad phase, contacts, deep-overlap fallback, friction.

Broad phase (once per substep): each blob's centre is the plain average of its vertices
(not the polygon centroid, which breaks when a polygon self-intersects) and its radius is
its farthest vertex. A uniform grid of cells one largest diameter wide bins the centres, so
only blobs in neighbouring cells are compared: linear in the blob count. Pairs farther apart
than r_a + r_b + margin are skipped. Pairs come out in a fixed order (by first blob, then
grid neighbour, then blob index), so runs are bit-identical.

Narrow phase (both directions), after Box2D v3, which builds its contacts once per step with a
speculative margin and solves them in every substep. Contacts are found once per step
(keep_blob_contacts): each vertex p of A keeps up to CONTACTS_PER_VERTEX contacts, one per
neighbouring blob B, nearest first: B's nearest edge, if p is inside B or outside it by less
than the pair's margin m_A + m_B. Inside, edges whose outward normal opposes p's own are
preferred (as JellyCar's and Gish's engines do), so a vertex is not pulled through to B's far
side. Each blob's budget m (see _renew) covers the motion the step can bring; before every
iteration, a blob with a vertex farther than m from where its contacts were found has them
found again, with its partners (whose contacts with it are stale too); the rest keep theirs.
Every iteration, a kept contact follows p along B's ring to the locally nearest point (see
_contact_push) and acts only while p is inside there: a one-sided constraint. The
point–edge constraint, with q = (1 - t) x_0 + t x_1 the closest point on edge (x_0, x_1) and
n its outward normal:
    C = (p - q) · n >= 0,   ∇_p C = n,   ∇_0 C = -(1 - t) n,   ∇_1 C = -t n,
    λ = -C / (w_p + (1 - t)² w_0 + t² w_1),
    Δp = w_p λ n,   Δx_0 = -(1 - t) w_0 λ n,   Δx_1 = -t w_1 λ n.
Σ m Δx = λ n (1 - (1 - t) - t) = 0: contacts never change total momentum, with one exception
under gravity. Gauss-Seidel moves a heavy blob resting on a much lighter one by only
w_heavy / (w_heavy + w_light) of their overlap per iteration (1/150 at a mass ratio of 150), so
the heavy one ploughed through the light one and tangled its polygon. So when a lighter blob
is below a heavier one, its inverse mass in their contacts becomes w_light (w_heavy / w_light)^2f,
with f = Δz / (r_a + r_b) in [0, 1]: directly below, it acts as much heavier than the upper blob
as it really is lighter, and carries the load to the ground (mass scaling for stacks, after
Macklin et al. 2014, but only where it is needed: applied to every contact it pumped momentum
into a pile of equal blobs and blew it apart). Side by side, equal masses, or zero gravity: f or
the ratio is 1, and momentum is exact.

Near a convex corner of B, where p is behind both edges' lines, the push turns from the nearer edge's
normal toward the corner's bisector as p nears it (_near_convex_corner): the nearer edge alone flips
the push from one normal to the other where p crosses the bisector, and threw a vertex on it to one
side. The velocity stage acts along each contact's last push normal (c_normal), not its edge's.

Resolution order: blob by blob (Gauss-Seidel across blobs, every second iteration in the
reverse order), and within a blob all its vertices' contacts together (Jacobi): every push
found from the same positions, then each scaled by 1 / k, k the most pushes any of its three
vertices is in (an edge's end counted by its weight, 1 - t or t, so that a mirror image of the
pushes counts the same; k at least 1), and added. A mirror image of a blob's contacts so gets
the mirror image of its pushes: solved one after another in ring order instead, the contacts
visited first were favoured, and two equal frictionless blobs meeting head-on were 21 mm off
their axis 0.8 s later (now 1e-14 m; tests/test_collide.py holds it to 1e-9 m). Across blobs the order
stays Gauss-Seidel: every contact solved from the same positions (a Jacobi pass over all of
them) kept that pair on its axis too, but left piles creeping (a 60-blob pile's centres at
6-7 mm/s 13 s after the drop, under 0.01 mm/s here): a blob's load reaches the next blob within
one pass this way. Scenes of 64 blobs or more are cut into vertical strips (see _resolve),
and contacts that share no blob run in parallel; smaller scenes keep one strip, so their
blobs go in index order. Either way the order is set by the scene, not by the number of
threads.

Periodic box (`[scene] periodic`, with Lees–Edwards shear γ): positions stay continuous, and every
stage that reads a partner's vertices or centre meets it as the image nearest it (`image`: a vertex p
of a meets b's vertices as p + s); the broad phase tiles the box and wraps round it
(`_find_pairs_periodic`). In an open world s = 0 and no arithmetic is done: the same bits. Each
contact's impulses also go into the blobs' virial there, for the stress (sim/packing.py).

Deep overlap (a blob driven far into another, or spawned overlapping): when either centre is
inside the other polygon, vertex–edge pushes have no sensible "nearest" side. Then, as the
seed author's own code does, a line perpendicular to c_B - c_A splits the two, placed at
c_A + (c_B - c_A) r_A / (r_A + r_B); each blob's vertices beyond it are put back on it, and
both blobs are shifted by one common Δx that cancels the momentum this added.

Friction (with each push, Müller et al. 2020): Coulomb on the relative tangential slip Δx_t of
the vertex against the other blob, with the same generalized masses as the push: undone entirely
if |Δx_t| <= μ_s D, where D is the vertex's total push-out this substep (static); else cut by
μ_k D (kinetic). It runs inside the iteration so that the statics, which come after it, always
have the last word (friction applied after them pushed a crushed blob through a wall).
Coefficients of the two blobs combine as √(μ_a μ_b).

The slip is measured from a stick point, a material point of the other blob (an edge and t along
it: stick_edge, stick_t) that the contact keeps while it holds: set where the vertex touches after
its first push, and again after every kinetic slide; kept from substep to substep and step to
step (a new detection carries it to the contact with the same blob); let go when the contact
does not push for a whole substep (release_sticks). Measured from where the substep began
instead (the statics' rule), static friction held only within a substep: what the Gauss-Seidel
order left (the contacts of the edge's own vertices, solved after this one, move the edge point
on) was never undone, so a vertex wedged in a pile crept 0.016 mm per step along its contact for
a quarter of a second and snapped back 0.24 mm, and piles of 80 and 120 blobs kept vertices
flickering at 24-34 mm/s long after they had settled (docs/physics.md, "Blob–blob collisions").
"""

import math

import numba
import numpy as np

from ..jit import inline_kernel, ir_inline_kernel, kernel, stage_kernel
from .integrate import NO_BOUNCE, bounce
from .ring import centre_motion, most_vertices, next_in_ring, prev_in_ring, ring_contains, ring_radius, vertex_normal

PAIRS_PER_BLOB = 64  # a pile has ~3 close pairs per blob; past 64 (blobs spawned on top of each other)
#                     the pair lists would exhaust memory, so the run stops instead
BROAD_MARGIN = 0.25  # × the larger radius: pairs closer than r_a + r_b + margin are tested
FOUND_PER_BLOB = 8  # the broad phase keeps this many of each blob's pairs as it counts them (a blob has ~3
#                     pairs b > a in a pile or a packing), so that listing them is a copy, not a second search
NO_EDGE = np.iinfo(np.int64).max  # above the bits of any squared distance
CONTACTS_PER_VERTEX = 2  # a vertex keeps contacts with its two nearest neighbouring blobs (three blobs meet at
#                          a junction of a pile)
CONTACT_SLOP = 0.02  # × the blob's radius: room in the kept contacts' margin for the solver's own corrections
BLOBS_PER_STRIP = 32  # the resolution cuts a scene into B // 32 vertical strips (at least 1) ...
MAX_STRIPS = 8  # ... and at most 8: a number set by the scene, never by the thread count
# Configuration name (pipeline.Configuration), bound by jit.build: a periodic box. Only the broad phase reads
# it; the narrow phase's `image` shifts read the box's sides (0 in an open world) at run time.
PERIODIC = True


@stage_kernel
def _blob_bounds(pos, offsets, awake, everyone, center, radius, edges):
    """Each blob's centre, radius and edge table; without `everyone`, only the awake blobs' (a sleeping
    blob's have not changed since the broad phase computed them from its frozen positions)."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not (everyone or awake[b]):
            continue
        o, e = offsets[b], offsets[b + 1]
        cx = cy = 0.0
        for i in range(o, e):
            x, y = pos[0, i], pos[1, i]
            j = next_in_ring(i, o, e)
            ex, ey = pos[0, j] - x, pos[1, j] - y
            len2 = ex * ex + ey * ey
            # The edge table the narrow phase reads, one row per quantity so that its loop
            # over a blob's edges reads contiguous memory and vectorizes.
            edges[0, i], edges[1, i], edges[2, i], edges[3, i] = x, y, ex, ey
            edges[4, i] = 1.0 / len2 if len2 > 0.0 else 0.0
            cx += x
            cy += y
        cx /= e - o
        cy /= e - o
        center[b, 0], center[b, 1], radius[b] = cx, cy, ring_radius(pos, o, e, cx, cy)


@stage_kernel
def _find_pairs(center, radius, max_pairs):
    """(pairs (P, 2), P): the candidate pairs; none are filled when P > max_pairs."""
    B = center.shape[0]
    r_max = radius.max()
    cell = 2.0 * r_max * (1.0 + BROAD_MARGIN)
    x0, y0 = center[:, 0].min(), center[:, 1].min()
    nx = int((center[:, 0].max() - x0) / cell) + 1
    ny = int((center[:, 1].max() - y0) / cell) + 1
    while nx * ny > 4 * B + 64:  # blobs spread far apart: coarser cells keep memory O(B)
        cell *= 2.0
        nx = int((center[:, 0].max() - x0) / cell) + 1
        ny = int((center[:, 1].max() - y0) / cell) + 1
    cell_of = np.empty(B, np.int64)
    for b in range(B):
        cell_of[b] = int((center[b, 1] - y0) / cell) * nx + int((center[b, 0] - x0) / cell)
    start, order = _bucket(cell_of, nx * ny)
    # Each blob's 3 × 3 neighbourhood, in parallel over blobs: its pairs are counted and kept in its
    # own rows of `found` (up to FOUND_PER_BLOB), then copied from each blob's own offset, so the
    # order is the same for any thread count. A blob with more is searched again for the copy.
    first = np.zeros(B + 1, np.int64)
    found = np.empty((B * FOUND_PER_BLOB, 2), np.int64)
    for a in numba.prange(B):
        first[a + 1] = _near_blobs(a, center, radius, cell_of, start, order, nx, ny, found, a * FOUND_PER_BLOB,
                                   FOUND_PER_BLOB)
    for a in range(B):
        first[a + 1] += first[a]
    if first[B] > max_pairs:
        return np.empty((0, 2), np.int64), first[B]
    pairs = np.empty((first[B], 2), np.int64)
    for a in numba.prange(B):
        _copy_found(a, first, found, pairs)
        if first[a + 1] - first[a] > FOUND_PER_BLOB:
            _near_blobs(a, center, radius, cell_of, start, order, nx, ny, pairs, first[a], first[a + 1] - first[a])
    return pairs, first[B]


@inline_kernel
def _copy_found(a, first, found, pairs):
    """Blob a's pairs kept in `found` (its first FOUND_PER_BLOB) into pairs[first[a]:]."""
    row = a * FOUND_PER_BLOB
    for k in range(min(first[a + 1] - first[a], FOUND_PER_BLOB)):
        pairs[first[a] + k, 0], pairs[first[a] + k, 1] = found[row + k, 0], found[row + k, 1]


@stage_kernel
def _find_pairs_periodic(center, radius, max_pairs, box):
    """_find_pairs in a periodic box: nx × ny cells tile the box exactly, each at least as wide as
    _find_pairs' cells, a centre's cell read from its position wrapped into the box; each blob looks
    at the 3 × 3 cells around its own, wrapped (every cell of an axis with fewer than 3), and
    measures distances to the nearest image (see `image`). The box is at least 5 largest radii
    wide (scene/schema.py), so a pair has one image close enough to touch."""
    B = center.shape[0]
    cell = 2.0 * radius.max() * (1.0 + BROAD_MARGIN)
    nx, ny = max(1, int(box[0] / cell)), max(1, int(box[1] / cell))
    cell_of = np.empty(B, np.int64)
    for b in range(B):  # the centre's place in the box: its row of images first, then along x in that row
        fy = center[b, 1] / box[1] + 0.5
        fx = (center[b, 0] - math.floor(fy) * box[2]) / box[0] + 0.5
        ix = min(int((fx - math.floor(fx)) * nx), nx - 1)
        iy = min(int((fy - math.floor(fy)) * ny), ny - 1)
        cell_of[b] = iy * nx + ix
    start, order = _bucket(cell_of, nx * ny)
    first = np.zeros(B + 1, np.int64)  # counted and kept, then copied: as _find_pairs
    found = np.empty((B * FOUND_PER_BLOB, 2), np.int64)
    for a in numba.prange(B):
        first[a + 1] = _near_images(a, center, radius, cell_of, start, order, nx, ny, found, a * FOUND_PER_BLOB,
                                    FOUND_PER_BLOB, box)
    for a in range(B):
        first[a + 1] += first[a]
    if first[B] > max_pairs:
        return np.empty((0, 2), np.int64), first[B]
    pairs = np.empty((first[B], 2), np.int64)
    for a in numba.prange(B):
        _copy_found(a, first, found, pairs)
        if first[a + 1] - first[a] > FOUND_PER_BLOB:
            _near_images(a, center, radius, cell_of, start, order, nx, ny, pairs, first[a], first[a + 1] - first[a],
                         box)
    return pairs, first[B]


@inline_kernel
def _near_images(a, center, radius, cell_of, start, order, nx, ny, out, row, most, box):
    """_near_blobs in a periodic box. Across the top and bottom edges of a sheared box the row of
    images is shifted along x by γ L_y: there every cell of the row is looked at."""
    count = 0
    ix, iy = cell_of[a] % nx, cell_of[a] // nx
    for dy in range(-1, 2) if ny >= 3 else range(ny):
        jy = (iy + dy) % ny if ny >= 3 else dy
        whole_row = nx < 3 or (box[2] != 0.0 and (iy + dy < 0 or iy + dy >= ny or ny < 3))
        for dx in range(nx) if whole_row else range(-1, 2):
            jx = dx if whole_row else (ix + dx) % nx
            c = jy * nx + jx
            for k in range(start[c], start[c + 1]):
                b = order[k]
                if b <= a:
                    continue
                sx, sy = image(center, a, b, box)
                reach = radius[a] + radius[b] + BROAD_MARGIN * max(radius[a], radius[b])
                if (center[a, 0] + sx - center[b, 0]) ** 2 + (center[a, 1] + sy - center[b, 1]) ** 2 < reach * reach:
                    if count < most:
                        out[row + count, 0], out[row + count, 1] = a, b
                    count += 1
    return count


@inline_kernel
def image(center, a, b, box):
    """(s_x, s_y), the shift that carries blob a to the image of it nearest blob b in a periodic box
    (box = (L_x, L_y, γ L_y)), so that a vertex p of a meets b's vertices as p + s. The box's images
    lie at n_x e_1 + n_y e_2, e_1 = (L_x, 0), e_2 = (γ L_y, L_y) (Lees–Edwards: the row of images above
    is shifted by γ L_y; γ = 0: a plain box): n_y = round(d_y / L_y), n_x = round((d_x - n_y γ L_y) / L_x),
    d = c_b - c_a. (0, 0) in an open world (box = (0, 0, 0)): no arithmetic, so it keeps its bits; and,
    without its divisions, for d within a quarter box of 0, where both roundings give n = 0 (most pairs)."""
    if box[0] == 0.0:
        return 0.0, 0.0
    dx, dy = center[b, 0] - center[a, 0], center[b, 1] - center[a, 1]
    if abs(dy) < 0.25 * box[1] and abs(dx) < 0.25 * box[0]:
        return 0.0, 0.0
    ny = math.floor(dy / box[1] + 0.5)
    nx = math.floor((dx - ny * box[2]) / box[0] + 0.5)
    return nx * box[0] + ny * box[2], ny * box[1]


@inline_kernel
def _near_blobs(a, center, radius, cell_of, start, order, nx, ny, out, row, most):
    """Blobs b > a in the cells around a's, closer than r_a + r_b + margin: the first `most` of them
    written as pairs (a, b) to out[row:] (in cell order, then by index). Returns how many in all."""
    count = 0
    ix, iy = cell_of[a] % nx, cell_of[a] // nx
    for jy in range(max(iy - 1, 0), min(iy + 2, ny)):
        for jx in range(max(ix - 1, 0), min(ix + 2, nx)):
            c = jy * nx + jx
            for k in range(start[c], start[c + 1]):
                b = order[k]
                if b <= a:
                    continue
                reach = radius[a] + radius[b] + BROAD_MARGIN * max(radius[a], radius[b])
                if (center[a, 0] - center[b, 0]) ** 2 + (center[a, 1] - center[b, 1]) ** 2 < reach * reach:
                    if count < most:
                        out[row + count, 0], out[row + count, 1] = a, b
                    count += 1
    return count


@stage_kernel
def find_blob_pairs(pos, offsets, awake, center, radius, edges, blob_contact_depth, c_hit, box):
    """Broad phase: the pairs of blobs close enough to touch this substep, sleeping or not, as (pairs
    (P, 2), each blob's partners (CSR, see _partners), the strips of the resolution (see _strips), P).
    Past PAIRS_PER_BLOB pairs per blob none are listed (the step must stop: see the constant).

    Every blob's bounds are computed, sleeping ones' too: from their frozen positions they come out
    the same bits every substep, so the narrow phase reads the same sleeping edges however the
    steps are split into compiled calls (and after a resume, when the scratch starts empty)."""
    _blob_bounds(pos, offsets, awake, True, center, radius, edges)
    blob_count = offsets.shape[0] - 1
    if PERIODIC and box[0] > 0.0:  # cells tile the box; neighbours and distances wrap round it
        pairs, count = _find_pairs_periodic(center, radius, PAIRS_PER_BLOB * blob_count, box)
    else:
        pairs, count = _find_pairs(center, radius, PAIRS_PER_BLOB * blob_count)
    blob_contact_depth[:] = 0.0  # no contact has pushed yet this substep
    c_hit[:] = 0
    return pairs, _partners(pairs, blob_count), _strips(center, pairs), count


@inline_kernel
def _separate_deep(pos, inv_mass, offsets, a, b, center, radius, box):
    """Deep-overlap fallback for pair (a, b): split them along a line between the centres (a's nearest
    image of b's, in a periodic box)."""
    ox, oy = image(center, b, a, box)  # b's vertices, seen from a: x + o
    bx, by = center[b, 0] + ox, center[b, 1] + oy
    ux, uy = bx - center[a, 0], by - center[a, 1]
    dist = math.sqrt(ux * ux + uy * uy)
    if dist > 0.0:
        ux, uy = ux / dist, uy / dist
    else:
        ux, uy = 1.0, 0.0
    share = radius[a] / (radius[a] + radius[b])
    sx, sy = center[a, 0] + (bx - center[a, 0]) * share, center[a, 1] + (by - center[a, 1]) * share
    px = py = m_sum = 0.0
    for blob, side, fx, fy in ((a, 1.0, 0.0, 0.0), (b, -1.0, ox, oy)):
        for i in range(offsets[blob], offsets[blob + 1]):
            m = 1.0 / inv_mass[i]
            m_sum += m
            d = ((pos[0, i] + fx - sx) * ux + (pos[1, i] + fy - sy) * uy) * side  # > 0: beyond the line
            if d > 0.0:
                pos[0, i] -= d * side * ux
                pos[1, i] -= d * side * uy
                px -= m * d * side * ux
                py -= m * d * side * uy
    # One common shift of both blobs removes the momentum the pushes added.
    for blob in (a, b):
        for i in range(offsets[blob], offsets[blob + 1]):
            pos[0, i] -= px / m_sum
            pos[1, i] -= py / m_sum


@kernel
def _partners(pairs, blob_count):
    """Each blob's partners as CSR lists (start, partner, pair index), in pair order."""
    start = np.zeros(blob_count + 1, np.int64)
    for k in range(pairs.shape[0]):
        start[pairs[k, 0] + 1] += 1
        start[pairs[k, 1] + 1] += 1
    for b in range(blob_count):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    partner = np.empty(2 * pairs.shape[0], np.int64)
    pair_of = np.empty(2 * pairs.shape[0], np.int64)
    for k in range(pairs.shape[0]):
        for a, b in ((pairs[k, 0], pairs[k, 1]), (pairs[k, 1], pairs[k, 0])):
            partner[fill[a]] = b
            pair_of[fill[a]] = k
            fill[a] += 1
    return start, partner, pair_of


@kernel
def _strips(center, pairs):
    """Blobs cut into vertical strips of equal width by centre x: each blob's strip, each strip's
    blobs in index order (CSR: start, blobs), how many strips apart each blob's farthest partner is
    (crossing: 0, none in another strip), and whether any pair spans two strips or more (far). Only
    blobs that cross have contacts across strips, and only those that cross two or more have far ones:
    the resolution scans no other blob's contacts for them (see _resolve)."""
    B = center.shape[0]
    count = max(1, min(MAX_STRIPS, B // BLOBS_PER_STRIP))
    x0 = center[:, 0].min()
    width = (center[:, 0].max() - x0) / count
    strip_of = np.zeros(B, np.int64)
    if width > 0.0:
        for b in range(B):
            strip_of[b] = min(int((center[b, 0] - x0) / width), count - 1)
    start, blobs = _bucket(strip_of, count)
    crossing = np.zeros(B, np.int64)
    far = False
    for k in range(pairs.shape[0]):
        a, b = pairs[k, 0], pairs[k, 1]
        apart = abs(strip_of[a] - strip_of[b])
        crossing[a], crossing[b] = max(crossing[a], apart), max(crossing[b], apart)
        far |= apart >= 2
    return strip_of, start, blobs, crossing, far


@inline_kernel
def _bucket(key, buckets):
    """Counting sort of 0..len(key)-1 by key (stable: within a bucket, by index). Returns
    (start, order): bucket k holds order[start[k]:start[k + 1]]."""
    start = np.zeros(buckets + 1, np.int64)
    for b in range(key.shape[0]):
        start[key[b] + 1] += 1
    for k in range(buckets):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(key.shape[0], np.int64)
    for b in range(key.shape[0]):
        order[fill[key[b]]] = b
        fill[key[b]] += 1
    return start, order


@stage_kernel
def _deep_pairs(pos, offsets, awake, pairs, center, radius, deep, box):
    """deep[k]: either centre of pair k lies inside the other blob, both awake (one awake blob
    deep in a sleeping one wakes its island at the end of the step, and is split from it then)."""
    for k in numba.prange(pairs.shape[0]):
        a, b = pairs[k, 0], pairs[k, 1]
        if not (awake[a] and awake[b]):
            deep[k] = False
            continue
        # A centre farther from the other's centre than its radius cannot be inside it.
        sx, sy = image(center, a, b, box)
        d2 = (center[a, 0] + sx - center[b, 0]) ** 2 + (center[a, 1] + sy - center[b, 1]) ** 2
        deep[k] = ((d2 <= radius[b] ** 2
                    and ring_contains(pos, offsets[b], offsets[b + 1], center[a, 0] + sx, center[a, 1] + sy))
                   or (d2 <= radius[a] ** 2
                       and ring_contains(pos, offsets[a], offsets[a + 1], center[b, 0] - sx, center[b, 1] - sy)))


@stage_kernel
def _moved(pos, anchor, offsets, awake, center, radius, moved):
    """For each awake blob b: its centre and radius now, and moved[b], how far its vertices are, at
    most, from where its contacts were found."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        d2 = cx = cy = 0.0
        for i in range(o, e):
            d2 = max(d2, (pos[0, i] - anchor[0, i]) ** 2 + (pos[1, i] - anchor[1, i]) ** 2)
            cx += pos[0, i]
            cy += pos[1, i]
        moved[b] = math.sqrt(d2)
        center[b, 0], center[b, 1] = cx / (e - o), cy / (e - o)
        radius[b] = ring_radius(pos, o, e, center[b, 0], center[b, 1])


@stage_kernel
def _renew(pos, vel, offsets, awake, radius, outgrown, reach_time, g, anchor, budget, moved):
    """Outgrown blobs start afresh: anchor here, moved 0, and the budget
    m = min(CONTACT_SLOP r + |v|_max T + |g| T², BROAD_MARGIN r / 2), T the time left in the step: the
    motion the step can bring, with room for the solver's corrections; the cap keeps every margin within
    the broad phase's, so a pair that was not listed when contacts were found cannot touch unseen."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not (awake[b] and outgrown[b]):
            continue
        v2 = 0.0
        for i in range(offsets[b], offsets[b + 1]):
            anchor[0, i], anchor[1, i] = pos[0, i], pos[1, i]
            v2 = max(v2, vel[0, i] ** 2 + vel[1, i] ** 2)
        moved[b] = 0.0
        budget[b] = min(CONTACT_SLOP * radius[b] + math.sqrt(v2) * reach_time + g * reach_time ** 2,
                        0.5 * BROAD_MARGIN * radius[b])


@stage_kernel
def _detect(pos, offsets, blob_of, awake, stale, orient, center, radius, edges, start, partner, pair_of, deep, reach,
            c_edge, stick_edge, stick_t, box):
    """For every vertex of a stale blob A: its contacts (the edge), at most CONTACTS_PER_VERTEX, each
    with another blob, nearest first (inside before outside): every blob B whose boundary the vertex
    is inside of, or outside of by less than the pair's margin reach[A] + reach[B], how far each may
    go from here before it outgrows its budget.

    A contact with a blob that the vertex had a contact with before keeps that one's stick point (see
    the module docstring); the others start without. Parallel over blobs; each blob writes only its own
    vertices' slots, so the result does not depend on the number of threads."""
    longest = most_vertices(offsets)
    for A in numba.prange(offsets.shape[0] - 1):
        if not stale[A]:
            continue
        d2 = np.empty(longest)  # per edge of the partner: squared distance, t, normal opposes
        t = np.empty(longest)
        opposes = np.empty(longest, np.bool_)
        # d2 >= 0, and the bit patterns of non-negative doubles order as integers do: the
        # minima below are integer minima over contiguous arrays, which vectorize.
        bits = d2.view(np.int64)
        opposing_bits = np.empty(longest, np.int64)  # bits, or NO_EDGE where the normal does not oppose
        oa, ea = offsets[A], offsets[A + 1]
        key = np.empty((CONTACTS_PER_VERTEX, ea - oa))  # signed distance: < 0 inside
        # the stick points of the contacts found before, to carry over to the same blobs' contacts
        old_edge = np.empty((CONTACTS_PER_VERTEX, ea - oa), np.int64)
        old_t = np.empty((CONTACTS_PER_VERTEX, ea - oa))
        for i in range(oa, ea):
            for s in range(CONTACTS_PER_VERTEX):
                old_edge[s, i - oa], old_t[s, i - oa] = stick_edge[s, i], stick_t[s, i]
                c_edge[s, i] = stick_edge[s, i] = -1
        for k in range(start[A], start[A + 1]):
            if deep[pair_of[k]]:
                continue
            B = partner[k]
            sx, sy = image(center, A, B, box)  # A's vertices as B's nearest image of A has them
            ob, eb = offsets[B], offsets[B + 1]
            n = eb - ob
            margin = reach[A] + reach[B]
            cx, cy, reach2 = center[B, 0], center[B, 1], (radius[B] + margin) ** 2
            ax, ay, ex, ey, inv_len2 = (edges[0, ob:eb], edges[1, ob:eb], edges[2, ob:eb], edges[3, ob:eb],
                                        edges[4, ob:eb])
            for i in range(oa, ea):
                x, y = pos[0, i] + sx, pos[1, i] + sy
                if (x - cx) ** 2 + (y - cy) ** 2 > reach2:  # beyond B's bounding circle and the margin
                    continue
                vnx, vny = vertex_normal(pos, orient[A], i, oa, ea)
                # Pass 1, over B's edges with no branches (it vectorizes): crossing parity,
                # each edge's nearest point and whether its normal opposes p's.
                crossings = 0
                for m in range(n):
                    rx, ry = x - ax[m], y - ay[m]
                    # crossing number, without dividing: the ray x' > x crosses this edge
                    crossings += ((ay[m] > y) != (ay[m] + ey[m] > y)) & ((rx * ey[m] - ry * ex[m]) * ey[m] < 0.0)
                    t[m] = min(max((rx * ex[m] + ry * ey[m]) * inv_len2[m], 0.0), 1.0)
                    d2[m] = (t[m] * ex[m] - rx) ** 2 + (t[m] * ey[m] - ry) ** 2
                    opposes[m] = orient[B] * (ey[m] * vnx - ex[m] * vny) < 0.0
                    opposing_bits[m] = bits[m] if opposes[m] else NO_EDGE
                inside = crossings % 2 == 1
                # Pass 2: the least squared distance over all edges and (inside B) over the opposing
                # ones; the contact is the first edge with that distance (opposing, if any edge is)
                # in ring order from the closing edge: n - 1, 0, 1, ..., n - 2.
                least = least_opposing = NO_EDGE
                for m in range(n):
                    least = min(least, bits[m])
                    least_opposing = min(least_opposing, opposing_bits[m])
                if least == NO_EDGE:
                    continue
                any_opposing = inside and least_opposing != NO_EDGE
                if not any_opposing:
                    least_opposing = least
                m = n - 1
                while bits[m] != least_opposing or (any_opposing and not opposes[m]):
                    m = m + 1 if m < n - 1 else 0
                distance = math.sqrt(d2[m])
                if not inside and distance >= margin:
                    continue
                # keep the nearest CONTACTS_PER_VERTEX, by signed distance (ties: the first found)
                signed, edge = -distance if inside else distance, ob + m
                for s in range(CONTACTS_PER_VERTEX):
                    if c_edge[s, i] < 0 or signed < key[s, i - oa]:
                        signed, key[s, i - oa] = key[s, i - oa], signed
                        edge, c_edge[s, i] = c_edge[s, i], edge
                        if edge < 0:
                            break
        for i in range(oa, ea):
            for s in range(CONTACTS_PER_VERTEX):
                if c_edge[s, i] < 0:
                    continue
                for r in range(CONTACTS_PER_VERTEX):
                    if old_edge[r, i - oa] >= 0 and blob_of[old_edge[r, i - oa]] == blob_of[c_edge[s, i]]:
                        stick_edge[s, i], stick_t[s, i] = old_edge[r, i - oa], old_t[r, i - oa]


@stage_kernel
def _resolve(pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge, c_hit, c_normal, contact_depth,
             center, radius, up_x, up_y, strip_of, strip_start, strip_blobs, crossing, far, backward, stick_edge,
             stick_t, box, virial, h, scratch):
    """The contacts blob by blob (each blob's together: see the module docstring), in parallel where
    they share no blob. scratch: (push (tasks, slots, 8), listed (tasks, slots) int64, share (N,),
    rows (2, CONTACTS_PER_VERTEX N) int64, row_count (B,) int64): one row of the first two for each
    parallel task (slots: CONTACTS_PER_VERTEX times the most vertices a blob has), share all zero
    between blobs (see _resolve_between); rows and row_count, each blob's contacts (see below).

    A contact moves only its own two blobs, so contacts within different strips are
    independent, and so are contacts across the strip boundaries s|s+1 and s+2|s+3. Order:
    (1) contacts across strips two or more apart (a strip narrower than a pair's reach;
    rare), in vertex order; (2) contacts across neighbouring strips s, s+1, even s in
    parallel, then odd s; (3) contacts within a strip, even strips in parallel, then odd ones,
    each in blob order. The contacts within strips, nearly all of them, go last:
    with the boundary contacts last instead, the deepest overlap in the settled `pile` tripled (dev: median 0.47 mm
    against 0.14 mm over seconds 6-10). The strips are set by the scene (see _strips), so the
    result is the same for any number of threads. Contacts across strips are looked for only where
    the pairs say there are some (crossing, far: see _strips)."""
    strips = strip_start.shape[0] - 1
    # Each blob's contacts, read once here for the five phases (its slots scanned in each phase instead, a blob
    # in two or three of them, were a quarter of this stage, dev 2026-11-27): rows[0, CONTACTS_PER_VERTEX o + k],
    # k < row_count[a], the slot r = CONTACTS_PER_VERTEX (p - o) + c of a's k-th contact, in vertex order, and
    # rows[1, ...] the strip of the blob it touches (a contact follows the other blob's ring, never to another
    # blob: both hold for the whole stage).
    rows, row_count = scratch[3], scratch[4]
    for a in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[a], offsets[a + 1]
        k = CONTACTS_PER_VERTEX * o
        for p in range(o, e):
            for c in range(CONTACTS_PER_VERTEX):
                if c_edge[c, p] >= 0:
                    rows[0, k], rows[1, k] = CONTACTS_PER_VERTEX * (p - o) + c, strip_of[blob_of[c_edge[c, p]]]
                    k += 1
        row_count[a] = k - CONTACTS_PER_VERTEX * o
    # phase 0 is (1), phases 1-4 are (2) then (3), each even s then odd s: one prange loop with one call of
    # the inlined contact code (jit.ir_inline_kernel), so that it is typed and compiled once (a loop per
    # phase compiled it once each: 25 s of a cold compile in the parallel build; the far contacts' loop of
    # its own took the serial build's _resolve from 19 to 36 s, dev 2026-11-26)
    for phase in range(5):
        shift, parity = 1 - (phase - 1) // 2, (phase - 1) % 2  # s|s+1 (shift 1), then s|s (shift 0)
        tasks = (1 if far else 0) if phase == 0 else (strips - parity + 1 - shift) // 2
        for q in numba.prange(tasks):  # (phase 0 has one task: that order is sequential)
            s = parity + 2 * q
            _resolve_between(phase == 0, s, s + shift, pos, prev, inv_mass, offsets, blob_of, awake, orient,
                             material, c_edge, c_hit, c_normal, contact_depth, center, radius, up_x, up_y, strip_of,
                             strip_start, strip_blobs, crossing, backward, stick_edge, stick_t, box, virial, h,
                             (scratch[0][q], scratch[1][q], scratch[2], rows, row_count))


@ir_inline_kernel
def _resolve_between(far, s, other, pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge,
                     c_hit, c_normal, contact_depth, center, radius, up_x, up_y, strip_of, strip_start, strip_blobs,
                     crossing, backward, stick_edge, stick_t, box, virial, h, scratch):
    """The contacts of a vertex in strip s with an edge in strip `other`, then (if other != s)
    those of a vertex in `other` with an edge in s (only crossing blobs have such contacts);
    backward: each strip's blobs in reverse order. far: instead, the contacts across strips two or
    more apart, blobs in index order. A blob's contacts go together, Jacobi (see _resolve); scratch:
    (push, listed, share, rows, row_count), see there. (One argument for five: a call of over 30
    arguments is compiled by CPython as f(*args), which numba cannot inline.)"""
    push, listed, share, rows, row_count = scratch
    blob_count = offsets.shape[0] - 1
    for side in range(1 if other == s or far else 2):
        here, there = (s, other) if side == 0 else (other, s)
        first, last = (0, blob_count) if far else (strip_start[here], strip_start[here + 1])
        for k in range(first, last):
            j = first + last - 1 - k if backward else k
            a = j if far else strip_blobs[j]
            if crossing[a] < (2 if far else 1 if other != s else 0):  # (a has no contacts here)
                continue
            o = offsets[a]
            # a's contacts here, their slots r in vertex order (listed[:here_rows]), from its list (see _resolve;
            # a loop of their own: with the push's code in the loop over a blob's slots, each slot looked at, most
            # of them empty, cost the push's set-up, over half of this stage, dev 2026-11-27) ...
            here_rows = 0
            for m in range(CONTACTS_PER_VERTEX * o, CONTACTS_PER_VERTEX * o + row_count[a]):
                theirs = rows[1, m]
                if abs(theirs - strip_of[a]) >= 2 if far else theirs == there:
                    listed[here_rows] = rows[0, m]
                    here_rows += 1
            # ... every push of those, found from the same positions (push[r]; listed[:pushes] the rows that
            # push, written over the rows already read), and how many of them each vertex is in (an edge's end by
            # its weight in the push, 1 - t or t: a mirror image of the pushes counts the same) ...
            pushes = 0
            for k in range(here_rows):
                r = listed[k]
                p, c = o + r // CONTACTS_PER_VERTEX, r % CONTACTS_PER_VERTEX
                if _contact_push(p, c, pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge, c_hit,
                                 c_normal, contact_depth, center, radius, up_x, up_y, stick_edge, stick_t, box,
                                 push[r]):
                    listed[pushes] = r
                    pushes += 1
                    _, _, _, e0, e1 = _pushed(r, o, c_edge, blob_of, offsets)
                    share[p] += 1.0
                    share[e0] += 1.0 - push[r, 4]
                    share[e1] += push[r, 4]
            # ... then each, scaled by 1 / k (k at least 1), added in vertex order
            for k in range(pushes):
                r = listed[k]
                p, c, b, e0, e1 = _pushed(r, o, c_edge, blob_of, offsets)
                _apply_push(p, e0, e1, a, b, 1.0 / max(share[p], share[e0], share[e1], 1.0), pos, inv_mass,
                            center, contact_depth, box, virial, h, push[r])
            for k in range(pushes):
                r = listed[k]
                p, c, b, e0, e1 = _pushed(r, o, c_edge, blob_of, offsets)
                share[p] = share[e0] = share[e1] = 0.0
                if push[r, 5] != 0.0:  # held from now on where it touches now (after a slide: where it slid to)
                    sx, sy = image(center, a, b, box)
                    stick_edge[c, p] = e0
                    stick_t[c, p] = min(max(_along(pos, e0, e1, pos[0, p] + sx, pos[1, p] + sy), 0.0), 1.0)


@inline_kernel
def _pushed(r, o, c_edge, blob_of, offsets):
    """The contact of push row r of the blob whose vertices start at o: (p, c, the other blob b, the
    edge e0 -> e1 it pushes)."""
    p, c = o + r // CONTACTS_PER_VERTEX, r % CONTACTS_PER_VERTEX
    e0 = c_edge[c, p]
    b = blob_of[e0]
    return p, c, b, e0, next_in_ring(e0, offsets[b], offsets[b + 1])


@inline_kernel
def _apply_push(p, e0, e1, a, b, scale, pos, inv_mass, center, contact_depth, box, virial, h, push):
    """A push (push: its row, see _contact_push), scaled: p moves by w_p Δ, the edge's ends by -(1 - t)
    w_e Δ and -t w_e Δ. In a periodic box its impulses go into the virial (sim/packing.py): m Δx / h on
    p's blob at p, and on the other at the edge point."""
    dx, dy, wp, we, t = scale * push[0], scale * push[1], push[2], push[3], push[4]
    if box[0] > 0.0:
        qx, qy = (1.0 - t) * pos[0, e0] + t * pos[0, e1], (1.0 - t) * pos[1, e0] + t * pos[1, e1]
        _add_virial(virial, a, pos[0, p] - center[a, 0], pos[1, p] - center[a, 1], wp * dx / (inv_mass[p] * h),
                    wp * dy / (inv_mass[p] * h))
        _add_virial(virial, b, qx - center[b, 0], qy - center[b, 1], -we * dx / (inv_mass[e0] * h),
                    -we * dy / (inv_mass[e0] * h))
    _apply(pos, p, e0, e1, wp, (1.0 - t) * we, t * we, dx, dy)
    contact_depth[p] += scale * push[6]


@ir_inline_kernel
def _contact_push(p, s, pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge, c_hit, c_normal,
                  contact_depth, center, radius, up_x, up_y, stick_edge, stick_t, box, push):
    """Vertex p's contact s: follow it to the nearest point of the other blob's ring, and if p is
    inside there, the push that puts it out, with friction, not yet applied (see _apply_push): push (a
    row) = Δ_x, Δ_y, w_p, w_e, t, whether the stick point is set anew after it, the depth -C, and
    c_edge[s, p] the edge it pushes. Returns whether it pushes. (px, py): p where the other blob
    meets it (in a periodic box, the image of p's blob nearest the other). Writes only p's slots."""
    e0 = c_edge[s, p]
    blob = blob_of[e0]
    a = blob_of[p]
    o, e = offsets[blob], offsets[blob + 1]
    sx, sy = image(center, a, blob, box)
    px, py = pos[0, p] + sx, pos[1, p] + sy
    # Walk along the ring to the locally nearest point q = (1 - t) x_0 + t x_1: while p projects
    # before the kept edge's start (t < 0) and onto the previous edge short of their shared corner,
    # step back; likewise forward. Each step strictly shortens |p - q|, so it cannot cycle; it stops
    # on an edge (0 < t < 1) or at a corner between two edges (t = 0 or 1). It steps only onto edges
    # facing p's own outward normal v (the rule of _detect): a vertex deep inside must not walk round
    # to the far side and be pushed out through it.
    e1 = next_in_ring(e0, o, e)
    t = _along(pos, e0, e1, px, py)
    vnx = vny = 0.0  # p's normal, found only if the walk steps (most contacts stay on their edge)
    if t < 0.0 or t > 1.0:
        vnx, vny = vertex_normal(pos, orient[a], p, offsets[a], offsets[a + 1])
    for _ in range(e - o):
        if t < 0.0:
            before = prev_in_ring(e0, o, e)
            t_before = _along(pos, before, e0, px, py)
            if t_before < 1.0 and _faces(pos, orient[blob], before, e0, vnx, vny):
                e0, e1, t = before, e0, t_before
                continue
        elif t > 1.0:
            after = next_in_ring(e1, o, e)
            t_after = _along(pos, e1, after, px, py)
            if t_after > 0.0 and _faces(pos, orient[blob], e1, after, vnx, vny):
                e0, e1, t = e1, after, t_after
                continue
        break
    t = min(max(t, 0.0), 1.0)
    c_edge[s, p] = e0
    ex, ey = pos[0, e1] - pos[0, e0], pos[1, e1] - pos[1, e0]
    length = math.sqrt(ex * ex + ey * ey)
    if length == 0.0:
        return False
    nx, ny = orient[blob] * ey / length, -orient[blob] * ex / length  # outward normal of the edge
    qx, qy = pos[0, e0] + t * ex, pos[1, e0] + t * ey
    C = (px - qx) * nx + (py - qy) * ny
    if t == 0.0 or t == 1.0:
        # q is the corner k between this edge and its neighbour. p is inside when it lies behind the
        # corner's pseudo-normal, the sum of the two edges' outward normals (in the corner's region
        # that is the polygon's side, convex corner or reflex). Push toward the corner, along q - p
        # (along the normal of whichever edge came first, every push was turned the same way round
        # the ring, and stacked blobs slid off each other).
        k, other = (e0, prev_in_ring(e0, o, e)) if t == 0.0 else (e1, next_in_ring(e1, o, e))
        fx, fy = pos[0, other] - pos[0, k], pos[1, other] - pos[1, k]  # along the neighbouring edge, from k
        f = math.sqrt(fx * fx + fy * fy)
        if f > 0.0:
            # its outward normal: the edge k→other turned like e0→e1 when t = 1, reversed when t = 0
            side = 1.0 if t == 1.0 else -1.0
            mx, my = side * orient[blob] * fy / f, -side * orient[blob] * fx / f
        else:
            mx, my = nx, ny
        dx, dy = qx - px, qy - py
        if dx * (nx + mx) + dy * (ny + my) <= 0.0:  # p - q along the pseudo-normal: outside
            return False
        dist = math.sqrt(dx * dx + dy * dy)
        if dist == 0.0:
            return False
        nx, ny, C = dx / dist, dy / dist, -dist
    elif C >= 0.0:
        return False
    else:
        e0, e1, t, nx, ny, C = _near_convex_corner(pos, orient[blob], o, e, e0, e1, t, nx, ny, C, px, py)
        qx, qy = px - C * nx, py - C * ny  # where p leaves the corner's wedge
        c_edge[s, p] = e0
    c_hit[s, p] = 1
    c_normal[0, s, p], c_normal[1, s, p] = nx, ny
    wp, we = inv_mass[p], inv_mass[e0]  # vertex masses are uniform within a blob
    # Heavy on light: a lighter blob below a heavier one acts heavier (see the module
    # docstring), by how directly it is below: f = Δz / (r_a + r_b), along -g.
    if not awake[blob]:  # a sleeping blob does not move (sim/sleep.py)
        we = 0.0
    elif we != wp:  # (equal masses: no scaling, so f is not needed)
        dz = (center[a, 0] - center[blob, 0]) * up_x + (center[a, 1] - center[blob, 1]) * up_y
        f = dz / (radius[a] + radius[blob])
        if f > 0.0 and we > wp:  # the vertex's blob is above and heavier
            we *= (wp / we) ** min(2.0 * f, 2.0)
        elif f < 0.0 and wp > we:  # the edge's blob is above and heavier
            wp *= (we / wp) ** min(-2.0 * f, 2.0)
    w0, w1 = (1.0 - t) * we, t * we
    W = wp + (1.0 - t) * w0 + t * w1
    # Friction on the relative slip r of p: from its stick point on the other blob, or for a contact
    # that has none yet, against q since the substep began. The normal push changes r by -C n only,
    # so r's tangential part t_r can be read before it, and push and friction go in one move:
    # Δ = (-C n - cut t_r) / W (one dependent chain of square roots and divisions per contact
    # instead of two: this loop is sequential).
    a0 = stick_edge[s, p]
    if a0 >= 0:  # held at a stick point: the slip is p's way from it
        a1, ta = next_in_ring(a0, o, e), stick_t[s, p]
        rx = px - (1.0 - ta) * pos[0, a0] - ta * pos[0, a1]
        ry = py - (1.0 - ta) * pos[1, a0] - ta * pos[1, a1]
    else:
        rx = (pos[0, p] - prev[0, p]) - (1.0 - t) * (pos[0, e0] - prev[0, e0]) - t * (pos[0, e1] - prev[0, e1])
        ry = (pos[1, p] - prev[1, p]) - (1.0 - t) * (pos[1, e0] - prev[1, e0]) - t * (pos[1, e1] - prev[1, e1])
    rn = rx * nx + ry * ny
    tx, ty = rx - rn * nx, ry - rn * ny
    cut = 0.0
    # the slip, where there is friction (frictionless, both limits are 0 and so is the cut, whatever the slip)
    frictional = material[a, 0] * material[blob, 0] > 0.0 or material[a, 1] * material[blob, 1] > 0.0
    slip = math.sqrt(tx * tx + ty * ty) if frictional else 0.0
    if slip > 0.0:
        # Static: undo the whole slip; kinetic: cut it by μ_k D (|f_t| <= μ |f_n|), D the push-out summed
        # over the substep, as in the static rule and at the static colliders. (With this iteration's push
        # -C instead, a contact going from stick to slip suddenly kept millimetres of slip that
        # v = (x - x_prev) / h turned into vertex spikes of 0.1-0.5 m/s in a resting pile.)
        static, kinetic = _friction_limits(material, a, blob, contact_depth[p] - C)
        cut = _coulomb_cut(slip, static, kinetic)
    push[0], push[1] = (-C * nx - cut * tx) / W, (-C * ny - cut * ty) / W
    push[2], push[3], push[4] = wp, we, t
    push[5] = 1.0 if a0 < 0 or cut < 1.0 else 0.0  # whether the stick point is set anew after it
    push[6] = -C
    return True


@inline_kernel
def _near_convex_corner(pos, orient, o, e, e0, e1, t, nx, ny, C, px, py):
    """A vertex p inside the other blob, behind edge E = e0→e1 (C < 0, normal n_E): near a convex corner k
    of E, where p is also behind the neighbouring edge F's line, the push turns toward F's normal, so
    that it does not jump where p crosses the corner's bisector (the edge nearer to p pushing along its
    own normal throws a vertex on the bisector to one side: which side, the ring's order decided).

    With d_E = -C and d_F = -(p - k) · n_F the depths behind the two lines, d = min and D = max,
    u = (D - d) / d: the push goes along n = (n_near + max(1 - u, 0) n_far) / |...|, the bisector on it
    (u = 0), the nearer edge's normal from u = 1 on (D >= 2 d; in a polygon's flat middle, D - d is
    the edge's length times the turn of the corner, far above the depth of a contact). Symmetric in
    the two edges, so a mirror image of the pair gets the mirror image of the push. p goes along n by
    s, to where it first leaves the corner's wedge: s = min over the lines L of d_L / (n · n_L); the
    edge of that line takes the reaction, at the exit point. Returns (e0, e1, t, n_x, n_y, C) of the
    contact, C = -s."""
    ex, ey = pos[0, e1] - pos[0, e0], pos[1, e1] - pos[1, e0]
    if t < 0.5:  # corner k = e0, F = kf→k
        k, kf = e0, prev_in_ring(e0, o, e)
        fx, fy = pos[0, k] - pos[0, kf], pos[1, k] - pos[1, kf]
        turn = fx * ey - fy * ex  # F then E
    else:  # corner k = e1, F = k→kf
        k, kf = e1, next_in_ring(e1, o, e)
        fx, fy = pos[0, kf] - pos[0, k], pos[1, kf] - pos[1, k]
        turn = ex * fy - ey * fx  # E then F
    f = math.sqrt(fx * fx + fy * fy)
    if orient * turn <= 0.0 or f == 0.0:  # reflex or straight corner: the nearest side is continuous there
        return e0, e1, t, nx, ny, C
    mx, my = orient * fy / f, -orient * fx / f
    dE, dF = -C, -((px - pos[0, k]) * mx + (py - pos[1, k]) * my)
    if dF <= 0.0:  # in front of F's line
        return e0, e1, t, nx, ny, C
    near, far = min(dE, dF), max(dE, dF)
    w = 1.0 - (far - near) / near
    if w <= 0.0:
        return e0, e1, t, nx, ny, C
    if dE <= dF:
        bx, by = nx + w * mx, ny + w * my
    else:
        bx, by = mx + w * nx, my + w * ny
    b = math.sqrt(bx * bx + by * by)
    bx, by = bx / b, by / b
    cE, cF = bx * nx + by * ny, bx * mx + by * my
    sE = dE / cE if cE > 0.0 else math.inf
    sF = dF / cF if cF > 0.0 else math.inf
    if sE == math.inf and sF == math.inf:  # (a corner too sharp for the turned push to leave by)
        return e0, e1, t, nx, ny, C
    if sE <= sF:
        q0, q1, depth = e0, e1, sE
    else:
        q0, q1, depth = (kf, k, sF) if t < 0.5 else (k, kf, sF)
    x, y = px + depth * bx, py + depth * by
    return q0, q1, min(max(_along(pos, q0, q1, x, y), 0.0), 1.0), bx, by, -depth


@inline_kernel
def _add_virial(virial, b, rx, ry, jx, jy):
    """virial[b] += r ⊗ J (xx, xy, yx, yy): an impulse J on blob b at r from its centre."""
    virial[b, 0] += rx * jx
    virial[b, 1] += rx * jy
    virial[b, 2] += ry * jx
    virial[b, 3] += ry * jy


@inline_kernel
def _friction_limits(material, a, b, D):
    """(μ_s D, μ_k D) of a contact between blobs a and b, their coefficients combined as √(μ_a μ_b)."""
    return math.sqrt(material[a, 0] * material[b, 0]) * D, math.sqrt(material[a, 1] * material[b, 1]) * D


@inline_kernel
def _coulomb_cut(slip, static, kinetic):
    """The share of a slip that Coulomb's rule removes: all of it within the static limit, else the
    kinetic limit's worth (at most all)."""
    return 1.0 if slip <= static else min(kinetic / slip, 1.0)


@inline_kernel
def _along(pos, e0, e1, px, py):
    """Where p projects onto the line of edge e0→e1, as t (0 at x_0, 1 at x_1; 0 for a zero-length edge)."""
    ex, ey = pos[0, e1] - pos[0, e0], pos[1, e1] - pos[1, e0]
    len2 = ex * ex + ey * ey
    return ((px - pos[0, e0]) * ex + (py - pos[1, e0]) * ey) / len2 if len2 > 0.0 else 0.0


@inline_kernel
def _faces(pos, orient, e0, e1, vnx, vny):
    """Whether edge e0→e1's outward normal (the sign of its ring's winding, orient) opposes v."""
    return orient * ((pos[1, e1] - pos[1, e0]) * vnx - (pos[0, e1] - pos[0, e0]) * vny) < 0.0


@inline_kernel
def _apply(pos, p, e0, e1, wp, w0, w1, dx, dy):
    """Move p by wp d and the edge ends by -w d: the relative motion changes by W d, momentum by 0."""
    pos[0, p] += wp * dx
    pos[1, p] += wp * dy
    pos[0, e0] -= w0 * dx
    pos[1, e0] -= w0 * dy
    pos[0, e1] -= w1 * dx
    pos[1, e1] -= w1 * dy


@stage_kernel
def keep_blob_contacts(pos, vel, inv_mass, offsets, blob_of, awake, orient, center, radius, edges, pairs, partners,
                       everyone, reach_time, g, anchor, budget, moved, c_edge, stick_edge, stick_t, box):
    """Narrow phase, every iteration: split deeply overlapping pairs; then find the contacts (c_edge) of
    every awake blob (everyone: at the start of the step), or only of those whose vertices went farther
    than their budget from where theirs were found, or were split, and of their partners; the rest keep
    theirs. `reach_time`: the time left in the step."""
    B = offsets.shape[0] - 1
    _moved(pos, anchor, offsets, awake, center, radius, moved)
    outgrown = np.empty(B, np.bool_)
    for b in range(B):
        outgrown[b] = awake[b] and (everyone or moved[b] > budget[b])
    deep = np.empty(pairs.shape[0], dtype=np.bool_)
    _deep_pairs(pos, offsets, awake, pairs, center, radius, deep, box)
    for k in range(pairs.shape[0]):  # rare: separate them first, in pair order
        if deep[k]:
            _separate_deep(pos, inv_mass, offsets, pairs[k, 0], pairs[k, 1], center, radius, box)
            outgrown[pairs[k, 0]] = outgrown[pairs[k, 1]] = True
    if not outgrown.any():
        return
    stale = outgrown.copy()  # a partner's contacts with an outgrown blob are stale too
    for k in range(pairs.shape[0]):
        a, b = pairs[k, 0], pairs[k, 1]
        stale[a] |= outgrown[b] and awake[a]
        stale[b] |= outgrown[a] and awake[b]
    _blob_bounds(pos, offsets, awake, False, center, radius, edges)
    _renew(pos, vel, offsets, awake, radius, outgrown, reach_time, g, anchor, budget, moved)
    # How far each blob may still go from here: its budget, plus what it has moved already (its
    # anchor stays where it was, so its partners' contacts found before stay valid).
    reach = np.zeros(B)  # a sleeping blob does not move
    for b in range(B):
        if awake[b]:
            reach[b] = budget[b] + moved[b]
    _detect(pos, offsets, blob_of, awake, stale, orient, center, radius, edges, partners[0], partners[1], partners[2],
            deep, reach, c_edge, stick_edge, stick_t, box)


@stage_kernel
def resolve_blob_contacts(pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge, c_hit, c_normal,
                          blob_contact_depth, center, radius, up_x, up_y, strips, backward, stick_edge, stick_t,
                          box, virial, h, scratch):
    """Push every kept contact's vertex out of the other blob where it is inside, with friction
    (blob by blob, by strips, each blob's contacts together; backward: blobs in reverse order)."""
    _resolve(pos, prev, inv_mass, offsets, blob_of, awake, orient, material, c_edge, c_hit, c_normal,
             blob_contact_depth, center, radius, up_x, up_y, strips[0], strips[1], strips[2], strips[3], strips[4],
             backward, stick_edge, stick_t, box, virial, h, scratch)


VELOCITY_PASSES = 2  # Jacobi passes of blob_contact_velocities


@stage_kernel
def blob_contact_velocities(pos, vel, inv_mass, offsets, blob_of, awake, material, c_edge, c_hit, c_normal,
                            blob_contact_depth, h, center, box, virial):
    """Contact velocities between blobs: at every contact that pushed this substep (c_hit), the
    relative velocity of vertex p and the edge point q = (1 - t) x_0 + t x_1 it touches, u = v_p - v_q,
    loses its approach along the normal n of its last push (u · n < 0: one-sided, as the push) and its
    tangential part u_t by Coulomb's rule at velocity level: all of it if |u_t| h <= μ_s D (static),
    else μ_k D / h of it, D the vertex's push-out summed over the substep (the rule of the push).

    Why: the push and the friction act on positions, one contact after another, and a vertex in a
    pile is in several (two rings interpenetrating as a zipper: p in the other's edge, the edge's
    ends in p's). Each iteration the skin pulls such a vertex ~1 mm along the contact and the area
    stage ~1 mm into it, and the contacts put it back; what the Gauss-Seidel order leaves is a
    sawtooth of 0.05-0.15 mm per substep, which v = (x - x_prev) / h reads as 20-40 mm/s in a pile at
    rest. Removing the relative velocity each contact should not have, at velocity level, removes
    most of it (docs/physics.md, "Known limits").

    The impulse that zeroes the component of u along a unit vector d is J = -(u · d) / W, with
    W = w_p + ((1 - t)² + t²) w_e the generalized inverse mass (as for the push), applied as
    Δv_p = w_p J d, Δv_0 = -(1 - t) w_e J d, Δv_1 = -t w_e J d: Σ m Δv = 0, so momentum is unchanged.
    Jacobi: every contact's J is found from the same velocities, then scaled by 1 / k, k the most
    contacts any of its three vertices is in (an edge's end counted by its weight, 1 - t or t; k at
    least 1), so that a vertex is not over-corrected (one factor per contact keeps momentum exact),
    and the results are added in vertex order: the same for any thread count. A sleeping blob does
    not move (w_e = 0)."""
    B = offsets.shape[0] - 1
    # The pushed contacts, as vertex p and edge e0 -> e1 (columns of `which`), blob by blob: counted,
    # then filled from each blob's own offset (in parallel, in the same order for any thread count).
    first = np.zeros(B + 1, np.int64)
    for a in numba.prange(B):
        n = 0
        if awake[a]:
            for p in range(offsets[a], offsets[a + 1]):
                for c in range(CONTACTS_PER_VERTEX):
                    n += c_hit[c, p] != 0
        first[a + 1] = n
    for a in range(B):
        first[a + 1] += first[a]
    K = first[B]
    which = np.empty((4, K), np.int64)
    for a in numba.prange(B):
        if not awake[a]:
            continue
        k = first[a]
        for p in range(offsets[a], offsets[a + 1]):
            for c in range(CONTACTS_PER_VERTEX):
                if c_hit[c, p] != 0:
                    e0 = c_edge[c, p]
                    b = blob_of[e0]
                    which[0, k], which[1, k], which[2, k] = p, e0, next_in_ring(e0, offsets[b], offsets[b + 1])
                    which[3, k] = c
                    k += 1
    # Positions do not change in this stage, so each contact's geometry is found once: t, n, the
    # scale 1 / (W k), the edge's inverse mass, and the static and kinetic limits μ_s D / h, μ_k D / h
    # (rows of `geometry`; row 3 holds 1 / W until k is known).
    geometry = np.empty((7, K))
    for k in numba.prange(K):
        (geometry[0, k], geometry[1, k], geometry[2, k], geometry[3, k], geometry[4, k], geometry[5, k],
         geometry[6, k]) = _contact_geometry(which[0, k], which[1, k], which[2, k], which[3, k], pos, inv_mass,
                                             blob_of, awake, c_normal, material, blob_contact_depth, h, center, box)
    # k: how many of the contacts each vertex is in, an edge's end by its weight in the contact (so
    # that a mirror image of the contacts counts the same), at least 1
    share = np.zeros(pos.shape[1])
    for k in range(K):
        share[which[0, k]] += 1.0
        share[which[1, k]] += 1.0 - geometry[0, k]
        share[which[2, k]] += geometry[0, k]
    for k in numba.prange(K):
        geometry[3, k] /= max(share[which[0, k]], share[which[1, k]], share[which[2, k]], 1.0)
    impulse = np.empty((2, K))
    for _ in range(VELOCITY_PASSES):
        for k in numba.prange(K):  # every impulse from the same velocities
            impulse[0, k], impulse[1, k] = _contact_impulse(which[0, k], which[1, k], which[2, k], vel,
                                                            geometry[0, k], geometry[1, k], geometry[2, k],
                                                            geometry[3, k], geometry[5, k], geometry[6, k])
        for k in range(K):  # then added, in contact order
            p, e0, e1 = which[0, k], which[1, k], which[2, k]
            t, we, jx, jy = geometry[0, k], geometry[4, k], impulse[0, k], impulse[1, k]
            vel[0, p] += inv_mass[p] * jx
            vel[1, p] += inv_mass[p] * jy
            vel[0, e0] -= (1.0 - t) * we * jx
            vel[1, e0] -= (1.0 - t) * we * jy
            vel[0, e1] -= t * we * jx
            vel[1, e1] -= t * we * jy
            if box[0] > 0.0:  # the virial (sim/packing.py): J on p's blob at p, -m_e w_e J on the other's at q
                a, b = blob_of[p], blob_of[e0]
                _add_virial(virial, a, pos[0, p] - center[a, 0], pos[1, p] - center[a, 1], jx, jy)
                qx, qy = (1.0 - t) * pos[0, e0] + t * pos[0, e1], (1.0 - t) * pos[1, e0] + t * pos[1, e1]
                _add_virial(virial, b, qx - center[b, 0], qy - center[b, 1], -we * jx / inv_mass[e0],
                            -we * jy / inv_mass[e0])


@ir_inline_kernel
def _contact_geometry(p, e0, e1, c, pos, inv_mass, blob_of, awake, c_normal, material, depth, h, center, box):
    """(t, n_x, n_y, 1 / W, w_e, μ_s D / h, μ_k D / h) of vertex p's contact c with edge e0→e1
    (see blob_contact_velocities), n the normal of its last push; a zero-length edge gets scale 0 (no
    impulse)."""
    a, blob = blob_of[p], blob_of[e0]
    ex, ey = pos[0, e1] - pos[0, e0], pos[1, e1] - pos[1, e0]
    len2 = ex * ex + ey * ey
    if len2 == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    sx, sy = image(center, a, blob, box)
    t = min(max(_along(pos, e0, e1, pos[0, p] + sx, pos[1, p] + sy), 0.0), 1.0)
    we = inv_mass[e0] if awake[blob] else 0.0
    W = inv_mass[p] + ((1.0 - t) ** 2 + t * t) * we
    static, kinetic = _friction_limits(material, a, blob, depth[p] / h)
    return t, c_normal[0, c, p], c_normal[1, c, p], 1.0 / W, we, static, kinetic


@ir_inline_kernel
def _contact_impulse(p, e0, e1, vel, t, nx, ny, scale, static, kinetic):
    """The impulse J (see blob_contact_velocities) of a contact with edge point t, normal n, the scale
    1 / (W k) and the static and kinetic limits (see _contact_geometry)."""
    ux = vel[0, p] - (1.0 - t) * vel[0, e0] - t * vel[0, e1]
    uy = vel[1, p] - (1.0 - t) * vel[1, e0] - t * vel[1, e1]
    un = ux * nx + uy * ny
    tx, ty = ux - un * nx, uy - un * ny
    speed = math.sqrt(tx * tx + ty * ty)
    cut = 0.0
    if speed > 0.0:
        cut = _coulomb_cut(speed, static, kinetic)
    approach = min(un, 0.0)
    return -(approach * nx + cut * tx) * scale, -(approach * ny + cut * ty) * scale


@kernel
def release_sticks(c_hit, stick_edge):
    """At the end of a substep: a contact that did not push in it lets go of its stick point (it
    touches afresh, wherever it next pushes)."""
    for c in range(c_hit.shape[0]):
        for p in range(c_hit.shape[1]):
            if c_hit[c, p] == 0:
                stick_edge[c, p] = -1


@kernel
def carry_impacts(pairs, blob_count, keys, records, count):
    """The impact records (integrate.bounce) of this substep's pairs: each pair's from the kept ones
    (keys[:count[0]], sorted pair keys a B + b), or a fresh record. The pairs come by first blob a,
    as the broad phase lists them, so one pass through the keys finds them all: a merge, not a search
    per pair."""
    out = np.empty((pairs.shape[0], records.shape[1]))
    n = count[0]
    j = 0  # the first kept key of blob a or a later blob
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        key = a * blob_count + pairs[k, 1]
        while j < n and keys[j] < a * blob_count:
            j += 1
        i = j  # blob a's few keys, in order
        while i < n and keys[i] < key:
            i += 1
        if i < n and keys[i] == key:
            for f in range(records.shape[1]):
                out[k, f] = records[i, f]
        else:
            out[k, 0], out[k, 1], out[k, 2], out[k, 3] = 0.0, NO_BOUNCE, 0.0, 0.0
    return out


@kernel
def keep_impacts(pairs, blob_count, pair_records, keys, records, count):
    """Keep the records of the pairs that have had an impact (V > 0), sorted by key, for the next
    substep and for /restart. The pairs come by first blob a (see carry_impacts), so only each blob's
    few keys are out of order: an insertion sort is linear here."""
    order = np.empty(pairs.shape[0], np.int64)  # the kept pairs, by key
    key = np.empty(pairs.shape[0], np.int64)
    n = 0
    for k in range(pairs.shape[0]):
        if pair_records[k, 0] > 0.0:
            j = n
            this = pairs[k, 0] * blob_count + pairs[k, 1]
            while j > 0 and key[j - 1] > this:  # keys are distinct
                key[j], order[j] = key[j - 1], order[j - 1]
                j -= 1
            key[j], order[j] = this, k
            n += 1
    for j in range(n):
        keys[j] = key[j]
        for f in range(records.shape[1]):
            records[j, f] = pair_records[order[j], f]
    count[0] = n


@kernel
def _centre_motion_into(pos, vel, o, e, out):
    """ring.centre_motion of ring o..e, written to out[:5] as cx, cy, v̄x, v̄y, k (a call, not
    inlined: numba's parallel analysis cannot unpack its tuples inside a prange)."""
    (out[0], out[1]), (out[2], out[3]), out[4] = centre_motion(pos, vel, o, e)


@stage_kernel
def _touching(offsets, blob_of, awake, c_edge, c_hit, pairs, start, partner, pair_of, need_awake=True):
    """Whether a contact between the two blobs of each pair pushed this substep, both awake (a
    sleeping blob does not move: sim/sleep.py) unless not need_awake. Each blob reads its own
    vertices' contacts once and marks its own partner slots (start, partner, pair_of: CSR, see
    _partners), in parallel."""
    pushed = np.zeros(partner.shape[0], np.bool_)
    for a in numba.prange(offsets.shape[0] - 1):
        for p in range(offsets[a], offsets[a + 1]):
            for c in range(CONTACTS_PER_VERTEX):
                if c_hit[c, p] != 0:
                    other = blob_of[c_edge[c, p]]
                    for j in range(start[a], start[a + 1]):  # a blob has a few partners
                        if partner[j] == other:
                            pushed[j] = True
                            break
    touching = np.zeros(pairs.shape[0], np.bool_)
    for j in range(partner.shape[0]):
        touching[pair_of[j]] |= pushed[j]
    if need_awake:
        for k in range(pairs.shape[0]):
            touching[k] &= awake[pairs[k, 0]] and awake[pairs[k, 1]]
    return touching


@stage_kernel
def keep_touching(offsets, blob_of, awake, c_edge, c_hit, pairs, partners, touching_pairs, touching_count):
    """The pairs whose contacts pushed in the step's last substep, asleep or not, into touching_pairs, in
    pair order, and how many (sim/packing.py counts each blob's contacts from them)."""
    touching = _touching(offsets, blob_of, awake, c_edge, c_hit, pairs, partners[0], partners[1], partners[2], False)
    n = 0
    for k in range(pairs.shape[0]):
        if touching[k]:
            touching_pairs[n, 0], touching_pairs[n, 1] = pairs[k, 0], pairs[k, 1]
            n += 1
    touching_count[0] = n


@stage_kernel
def blob_restitution(pos, vel, offsets, inv_mass, blob_of, awake, material, c_edge, c_hit, pairs, partners,
                     predicted, pair_records, rest_speed, box, virial):
    """Bounce between blobs: the rule of integrate.bounce for each touching pair, along n̄, the unit
    vector between their centres, on their relative normal speed u = (v_b - v_a) · n̄, with
    e = max(e_a, e_b) (as statics combine). Energies are in the pair's centre-of-mass frame, per
    unit of its reduced mass μ = m_a m_b / (m_a + m_b); gravity does not change relative motion
    (P = 0). Δu goes to the two blobs as uniform velocity changes -Δu m_b/(m_a + m_b) n̄ and
    +Δu m_a/(m_a + m_b) n̄: momentum is unchanged. Pairs run one after another, in pair order, on
    each blob's centre motion (c, v̄, k = ½ mean |v|²), found once in parallel and carried through a
    uniform change δ exactly: v̄ += δ, k += v̄ · δ + ½ |δ|²; the vertices get the sum at the end."""
    B = offsets.shape[0] - 1
    touching = _touching(offsets, blob_of, awake, c_edge, c_hit, pairs, partners[0], partners[1], partners[2])
    motion = np.zeros((B, 5))  # cx, cy, v̄x, v̄y, k of the blobs in a touching pair
    shift = np.zeros((B, 2))  # δ: the velocity change of each blob
    involved = np.zeros(B, np.bool_)
    for k in range(pairs.shape[0]):
        if touching[k]:
            involved[pairs[k, 0]] = involved[pairs[k, 1]] = True
    for b in numba.prange(B):
        if involved[b]:
            _centre_motion_into(pos, vel, offsets[b], offsets[b + 1], motion[b])
    for k in range(pairs.shape[0]):
        if not touching[k]:
            continue
        a, b = pairs[k, 0], pairs[k, 1]
        ma = (offsets[a + 1] - offsets[a]) / inv_mass[offsets[a]]
        mb = (offsets[b + 1] - offsets[b]) / inv_mass[offsets[b]]
        mu = ma * mb / (ma + mb)
        sx, sy = image(motion, a, b, box)  # (the centres are motion's first two columns)
        nx, ny = motion[b, 0] - (motion[a, 0] + sx), motion[b, 1] - (motion[a, 1] + sy)
        length = math.sqrt(nx * nx + ny * ny)
        if length == 0.0:
            continue
        nx, ny = nx / length, ny / length
        vax, vay, ka, vbx, vby, kb = motion[a, 2], motion[a, 3], motion[a, 4], motion[b, 2], motion[b, 3], motion[b, 4]
        # kinetic energy in the pair's centre-of-mass frame: Σ m k - ½ (m_a + m_b) |v_cm|², per μ
        before = (ma * predicted[a, 2] + mb * predicted[b, 2]
                  - 0.5 * ((ma * predicted[a, 0] + mb * predicted[b, 0]) ** 2
                           + (ma * predicted[a, 1] + mb * predicted[b, 1]) ** 2) / (ma + mb)) / mu
        after = (ma * ka + mb * kb - 0.5 * ((ma * vax + mb * vbx) ** 2 + (ma * vay + mb * vby) ** 2) / (ma + mb)) / mu
        approach = (predicted[a, 0] - predicted[b, 0]) * nx + (predicted[a, 1] - predicted[b, 1]) * ny
        u = (vbx - vax) * nx + (vby - vay) * ny
        du = bounce(pair_records, k, approach, before, 0.0, 0.0, u, after - 0.5 * u * u,
                    max(material[a, 2], material[b, 2]), rest_speed)
        if du != 0.0:
            if box[0] > 0.0:  # the virial (sim/packing.py): ∓μ Δu n̄ on a and b, at the midpoint between them
                for blob, side in ((a, 0.5), (b, -0.5)):
                    _add_virial(virial, blob, side * length * nx, side * length * ny, -side * 2.0 * mu * du * nx,
                                -side * 2.0 * mu * du * ny)
            for blob, share in ((a, -mb / (ma + mb)), (b, ma / (ma + mb))):
                dx, dy = du * share * nx, du * share * ny
                motion[blob, 4] += motion[blob, 2] * dx + motion[blob, 3] * dy + 0.5 * (dx * dx + dy * dy)
                motion[blob, 2] += dx
                motion[blob, 3] += dy
                shift[blob, 0] += dx
                shift[blob, 1] += dy
    for b in numba.prange(B):
        if shift[b, 0] != 0.0 or shift[b, 1] != 0.0:
            for p in range(offsets[b], offsets[b + 1]):
                vel[0, p] += shift[b, 0]
                vel[1, p] += shift[b, 1]
