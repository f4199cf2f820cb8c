"""Self-contact: a ring's non-adjacent parts do not pass through each other.

Blob–blob contacts keep two rings apart; nothing else keeps one ring from crossing itself. A strip
folded in two (its outer surface meets itself), pinched over a post (its inner surfaces meet), or a
fine ring kinked on a bump (a loop of four edges at frame 11 of `blobsim stress`'s many_vertices)
pushes a vertex through one of its own edges, and once crossed the signed area no longer measures the
blob. So a vertex p is kept off every edge (x_0, x_1) of its own ring that is not one of p's two.

With q = (1 - t) x_0 + t x_1 the point of the edge facing p (0 <= t <= 1) and n the edge's outward
normal, s = (p - q) · n is p's signed distance from the edge: > 0 outside (two parts of the surface
folding onto each other), < 0 inside (the blob pinched between them). p keeps to the side σ = sign(s)
it was on (below), at least a gap g from the edge:
    C = σ (p - q) · n - g >= 0,   ∇_p C = σ n,   ∇_0 C = -(1 - t) σ n,   ∇_1 C = -t σ n,
    λ = -C / (w_p + (1 - t)² w_0 + t² w_1),   Δp = w_p λ σ n,   Δx_0 = -(1 - t) w_0 λ σ n,   Δx_1 = -t w_1 λ σ n:
the point–edge constraint of blob–blob contacts (sim/collide.py), one-sided; Σ m Δx = 0, so momentum is
exact. g = min(GAP L̄, |s_0|), L̄ the ring's mean rest edge and s_0 the distance when the substep began:
a push never leaves p farther out than it was, so it stops an approach and never throws the two parts
apart (no energy is created). Friction: Coulomb on the slip of p against q over the substep, with the
blob's μ_s and μ_k and D the depth this contact pushed out this substep: the slip is undone if
|slip| <= μ_s D, else cut by μ_k times each iteration's push.

The side is read where p faces the edge (0 <= t <= 1): at the substep's start, or, for p beyond the
edge's end then, where its straight path from there to its predicted place comes to face the edge, or
else where it first faces the edge in the iterations. (Beyond the end, the edge's line says nothing: at
a convex corner it runs out of the ring, and p may go round the corner outside.) While p is beyond
the edge's ends, it is kept GAP L̄ off the vertex there: the wedge beyond a convex corner faces neither
of its edges, and a vertex falling onto the corner's tip went through it. A pair acts only while p is
shallower than REACH L̄ plus how far the prediction moved it against the edge: deeper, p is a far part
of the ring whose foot happens to fall on the edge, not a crossing.

Pairs are found once per substep, after predict, so that a blob nowhere near folding pays almost
nothing. The ring is cut into chunks of CHUNK edges. Two chunks that are not neighbours are tested
vertex by edge only when their boxes, over the substep's start and its predicted end, come within the
reach R = REACH L̄. A chunk with its neighbour (and a chunk alone) is skipped when all their edges point
within 75° of one axis û, at both ends of the substep: then two points of the arc they make a length ℓ
of ring apart are at least ℓ cos 75° apart ((x_b - x_a) · û = ∫ τ · û dℓ), and a vertex is at least a
whole edge of ring from any edge not its own, so farther than R when L_min cos 75° > R, L_min their
shortest edge. (Each chunk's edges lie in a cone about its chord; two cones of half-angles α_c, α_d
whose axes are θ apart lie in one of half-angle (α_c + α_d + θ) / 2.) A round 32-gon's neighbouring
chunks turn through 90° (8 edges of 11.25°): a blob that keeps its shape has no pair to test. A pair is
kept when it is within R at either end of the substep or its path passes through the edge, up to
PER_VERTEX per vertex. A ring whose chunks were all apart keeps that shape as a skin (_in_skin): while it
only moves rigidly and deforms a little from it, it is not measured again.

What the iterations still leave crossed, keep_rings_simple mends after them (below).
"""

import math

import numba
import numpy as np

from ..jit import inline_kernel, stage_kernel
from .area import project_area
from .ring import next_in_ring, ring_means, turn

CHUNK = 4  # edges per chunk of a ring
GAP = 0.05  # × the mean rest edge: how close a vertex may come to an edge of its own ring
REACH = 0.15  # × the mean rest edge: pairs closer than this at the substep's start or end are kept
CONE = math.radians(75.0)  # β: an arc whose edges all point within β of one axis cannot touch itself
CONE_COS, CONE_COS_2, CONE_SIN_2 = math.cos(CONE), math.cos(2.0 * CONE), math.sin(2.0 * CONE)
MIN_LEVER = 0.25  # a pair acts only where the vertices free to move can move it: w > this × their largest w
APART, NEAR = 0, 1  # a ring's chunks this substep: all apart; some may meet
UNDECIDED = 0.0  # the side of a pair whose vertex has not yet faced its edge this substep
PER_VERTEX = 4  # pairs kept per vertex of a ring (the rest are dropped: a vertex faces two edges of a fold)


def self_contact_records(vertices: int, blobs: int) -> tuple:
    """State.self_contact for a scene of this many vertices and blobs: (pairs (2, PER_VERTEX N) int64:
    each pair's vertex and edge (its first vertex); values (4, PER_VERTEX N): its side σ (±1, or
    UNDECIDED), its gap g (m), the depth D it pushed out this substep (m) and the deepest it may act at
    (m); count (B,) int64: how many pairs each blob has, from slot PER_VERTEX × its first vertex on;
    near (B,) uint8: APART or NEAR (below); chunks (CHUNK_ROWS, N):
    the chunk table (below); zoned (B,) int64: in how many substeps since the run began the fail-safe
    (keep_rings_simple) moved part of each ring rigidly)."""
    return (np.zeros((2, PER_VERTEX * vertices), np.int64), np.zeros((4, PER_VERTEX * vertices)),
            np.zeros(blobs, np.int64), np.zeros(blobs, np.uint8), np.zeros((CHUNK_ROWS, vertices)),
            np.zeros(blobs, np.int64))


@inline_kernel
def _facing(pos, orient, p, j, j1):
    """Vertex p against edge (j, j1): (s, its signed distance along the edge's outward normal; t, where
    its foot falls along the edge, unclamped; d, its distance from the segment). d < 0: a degenerate edge."""
    ex, ey = pos[0, j1] - pos[0, j], pos[1, j1] - pos[1, j]
    len2 = ex * ex + ey * ey
    if len2 == 0.0:
        return 0.0, 0.0, -1.0
    rx, ry = pos[0, p] - pos[0, j], pos[1, p] - pos[1, j]
    t = (rx * ex + ry * ey) / len2
    s = orient * (rx * ey - ry * ex) / math.sqrt(len2)
    tc = min(max(t, 0.0), 1.0)
    return s, t, math.hypot(rx - tc * ex, ry - tc * ey)


@inline_kernel
def _crosses(prev, pos, p, j, j1, s0, s1):
    """Whether p passes through edge (j, j1) between the substep's start (s0) and predicted end (s1): s
    changes sign at τ = s0 / (s0 - s1), and there, with every point moved linearly, p faces the edge."""
    if s0 * s1 >= 0.0:
        return False
    tau = s0 / (s0 - s1)
    x0, y0 = prev[0, j] + tau * (pos[0, j] - prev[0, j]), prev[1, j] + tau * (pos[1, j] - prev[1, j])
    ex = prev[0, j1] + tau * (pos[0, j1] - prev[0, j1]) - x0
    ey = prev[1, j1] + tau * (pos[1, j1] - prev[1, j1]) - y0
    rx = prev[0, p] + tau * (pos[0, p] - prev[0, p]) - x0
    ry = prev[1, p] + tau * (pos[1, p] - prev[1, p]) - y0
    along = rx * ex + ry * ey
    return 0.0 <= along <= ex * ex + ey * ey


# Rows of the chunk table (State.self_contact's `chunks`, (CHUNK_ROWS, N), chunk c of ring o..e in column
# o + c CHUNK): its box over both configurations, and for each configuration the cone its edges point in
# (axis a, half-angle α as cos α and sin α) and its shortest edge, squared. The ring's skin (_in_skin): in
# each vertex's column, where it was about the ring's centre when the ring was last measured apart, and
# in the ring's first column, how far apart its parts were then (G; 0: no skin).
BOX_X0, BOX_Y0, BOX_X1, BOX_Y1, AXIS_X, AXIS_Y, COS, SIN, SHORTEST2, REF_X, REF_Y, SKIN, CHUNK_ROWS = \
    0, 1, 2, 3, 4, 6, 8, 10, 12, 14, 15, 16, 17


@inline_kernel
def _chunk_shapes(prev, pos, o, e, chunks):
    """Each chunk's box over the substep's start (prev) and end (pos) and, at each, its cone (about its
    chord u) and shortest edge."""
    for first in range(o, e, CHUNK):
        last = min(first + CHUNK, e)
        end = last if last < e else o  # the last edge's end
        x0 = y0 = math.inf
        x1 = y1 = -math.inf
        for config in range(2):
            x = prev if config == 0 else pos
            ux, uy = x[0, end] - x[0, first], x[1, end] - x[1, first]
            u2 = ux * ux + uy * uy
            cos2, shortest2 = 1.0, math.inf  # cos² α: the least (e · u)² / (|e|² |u|²); < 0: an edge turned back
            ax, ay = x[0, first], x[1, first]
            for i in range(first + 1, last + 1):
                j = i if i < e else o
                bx, by = x[0, j], x[1, j]
                ex, ey = bx - ax, by - ay
                along, e2 = ex * ux + ey * uy, ex * ex + ey * ey
                shortest2 = min(shortest2, e2)
                cos2 = min(cos2, along * abs(along) / (e2 * u2))
                x0, y0, x1, y1 = min(x0, bx), min(y0, by), max(x1, bx), max(y1, by)
                ax, ay = bx, by
            x0, y0, x1, y1 = min(x0, x[0, first]), min(y0, x[1, first]), max(x1, x[0, first]), max(y1, x[1, first])
            u = math.sqrt(u2)
            cos = math.sqrt(cos2) if cos2 > 0.0 and u > 0.0 else -1.0
            chunks[AXIS_X + config, first], chunks[AXIS_Y + config, first] = (ux / u, uy / u) if u > 0.0 else (1.0, 0.0)
            chunks[COS + config, first], chunks[SIN + config, first] = cos, math.sqrt(max(1.0 - cos * cos, 0.0))
            chunks[SHORTEST2 + config, first] = shortest2
        chunks[BOX_X0, first], chunks[BOX_Y0, first], chunks[BOX_X1, first], chunks[BOX_Y1, first] = x0, y0, x1, y1


@inline_kernel
def _chunks_apart_by(o, e, chunks, c, d, reach):
    """How far apart, at least, a vertex of chunk c (its first vertex) and an edge of chunk d not its own,
    or the reverse, are at both ends of the substep (see above); 0 where they may come within reach:
    neighbours, and a chunk alone, unless their edges point within 75° of one axis and are longer than
    reach / cos 75° (then L_min cos 75°); others unless their boxes are farther apart than reach (then
    that gap)."""
    after, before = next_chunk(c, o, e) == d, next_chunk(d, o, e) == c
    if c == d or after or before:
        if after and before:  # two chunks: their arc is the whole ring
            return 0.0
        apart = math.inf
        for config in range(2):
            apart = min(apart, math.sqrt(min(chunks[SHORTEST2 + config, c], chunks[SHORTEST2 + config, d])) * CONE_COS)
            if apart <= reach:
                return 0.0
            cos_c, sin_c = chunks[COS + config, c], chunks[SIN + config, c]
            cos_d, sin_d = chunks[COS + config, d], chunks[SIN + config, d]
            if min(cos_c, cos_d) < CONE_COS:  # a chunk's own edges spread wider than the cone
                return 0.0
            if c == d:
                continue
            # (α_c + α_d + θ) / 2 <= β: with α_c, α_d <= β, S = α_c + α_d is in [0, 2β] and θ <= 2β - S,
            # both in [0, π], exactly when cos θ >= cos(2β - S) = cos 2β cos S + sin 2β sin S
            cos_s, sin_s = cos_c * cos_d - sin_c * sin_d, sin_c * cos_d + cos_c * sin_d
            cos_t = chunks[AXIS_X + config, c] * chunks[AXIS_X + config, d] \
                + chunks[AXIS_Y + config, c] * chunks[AXIS_Y + config, d]
            if cos_t < CONE_COS_2 * cos_s + CONE_SIN_2 * sin_s:
                return 0.0
        return apart
    gap = max(chunks[BOX_X0, c] - chunks[BOX_X1, d], chunks[BOX_X0, d] - chunks[BOX_X1, c],
              chunks[BOX_Y0, c] - chunks[BOX_Y1, d], chunks[BOX_Y0, d] - chunks[BOX_Y1, c])
    return gap if gap > reach else 0.0


@inline_kernel
def next_chunk(c, o, e):
    """The chunk after chunk c (its first vertex) in ring o..e."""
    return c + CHUNK if c + CHUNK < e else o


@inline_kernel
def _keep_pairs(prev, pos, orient, o, e, vertices_from, vertices_to, edges_from, edges_to, reach, gap, pairs,
                values, slot0, count, b):
    """Test every vertex of one run of the ring against every edge of another that is not its own; keep
    the pairs that are within reach or crossed (see above)."""
    for p in range(vertices_from, vertices_to):
        for j in range(edges_from, edges_to):
            j1 = next_in_ring(j, o, e)
            if j == p or j1 == p:
                continue
            s0, t0, d0 = _facing(prev, orient, p, j, j1)
            s1, t1, d1 = _facing(pos, orient, p, j, j1)
            if d0 < 0.0 or d1 < 0.0:
                continue
            if not (d0 < reach or d1 < reach or _crosses(prev, pos, p, j, j1, s0, s1)):
                continue
            k = count[b]
            if k == PER_VERTEX * (e - o):
                return
            count[b] = k + 1
            side, s = UNDECIDED, s0
            if 0.0 <= t0 <= 1.0:
                side = 1.0 if s0 >= 0.0 else -1.0
            elif (t0 < 0.0) != (t1 < 0.0) or (t0 > 1.0) != (t1 > 1.0):  # p comes to face the edge: its side then
                tau = (-t0 if t0 < 0.0 else t0 - 1.0) / abs(t1 - t0)
                s = s0 + tau * (s1 - s0)
                side = 1.0 if s >= 0.0 else -1.0
            pairs[0, slot0 + k], pairs[1, slot0 + k] = p, j
            values[0, slot0 + k] = side
            values[1, slot0 + k] = min(gap, abs(s) if side != UNDECIDED else d0)
            values[2, slot0 + k] = 0.0
            values[3, slot0 + k] = reach + abs(s1 - s0)


@inline_kernel
def _in_skin(prev, pos, o, e, chunks, reach):
    """Whether ring o..e is still inside the skin set when it was last measured apart: then no vertex can
    come within reach of an edge not its own this substep, and it need not be measured again. With y_i
    the ring then about its centre (rows REF_X, REF_Y) and G a lower bound on how far apart its parts were
    (SKIN), each end of the substep is fitted a rigid motion x_i ≈ c + Q y_i (2D Procrustes, as
    _move_zones_rigidly) and d is the farthest any vertex is from its fit. Every point between the two
    ends is x_i(τ) = c_τ + ((1 - τ) Q_0 + τ Q_1) y_i + (at most d), and (1 - τ) Q_0 + τ Q_1 is a rotation
    scaled by s >= cos(Δθ / 2), Δθ the angle between Q_0 and Q_1: every vertex-to-edge distance is at least
    s G - 2 d all through the substep, and the ring needs no pair while that exceeds the reach (with 1% to
    spare for rounding)."""
    apart = chunks[SKIN, o]
    if apart == 0.0:
        return False
    c0x, c0y, c1x, c1y = ring_means(prev, pos, o, e)
    cross0 = dot0 = cross1 = dot1 = 0.0
    for i in range(o, e):
        yx, yy = chunks[REF_X, i], chunks[REF_Y, i]
        cross0 += yx * (prev[1, i] - c0y) - yy * (prev[0, i] - c0x)
        dot0 += yx * (prev[0, i] - c0x) + yy * (prev[1, i] - c0y)
        cross1 += yx * (pos[1, i] - c1y) - yy * (pos[0, i] - c1x)
        dot1 += yx * (pos[0, i] - c1x) + yy * (pos[1, i] - c1y)
    norm0, norm1 = math.hypot(cross0, dot0), math.hypot(cross1, dot1)
    if norm0 == 0.0 or norm1 == 0.0:
        return False
    cos0, sin0, cos1, sin1 = dot0 / norm0, cross0 / norm0, dot1 / norm1, cross1 / norm1
    scale = math.sqrt(max(0.5 * (1.0 + cos0 * cos1 + sin0 * sin1), 0.0))  # cos(Δθ / 2)
    far2 = 0.0
    for i in range(o, e):
        yx, yy = chunks[REF_X, i], chunks[REF_Y, i]
        far2 = max(far2, (prev[0, i] - c0x - cos0 * yx + sin0 * yy) ** 2
                   + (prev[1, i] - c0y - sin0 * yx - cos0 * yy) ** 2,
                   (pos[0, i] - c1x - cos1 * yx + sin1 * yy) ** 2 + (pos[1, i] - c1y - sin1 * yx - cos1 * yy) ** 2)
    return 0.99 * scale * apart - 2.0 * math.sqrt(far2) > reach


@inline_kernel
def _set_skin(pos, o, e, chunks, apart):
    """Ring o..e measured at pos with its parts at least `apart` from each other (0: some may meet): the
    skin _in_skin checks it against from now on."""
    chunks[SKIN, o] = apart
    if apart == 0.0:
        return
    cx, cy, _, _ = ring_means(pos, pos, o, e)
    for i in range(o, e):
        chunks[REF_X, i], chunks[REF_Y, i] = pos[0, i] - cx, pos[1, i] - cy


@stage_kernel
def find_self_contacts(prev, pos, offsets, awake, orient, rest_perimeter, pairs, values, count, near, chunks):
    """Each awake ring's self-contact pairs for this substep (see above); prev: positions at its start,
    pos: predicted. near[b]: NEAR where two chunks of ring b may meet (else APART: keep_rings_simple may
    skip it). A ring still in the skin of its last measurement is not measured."""
    for b in numba.prange(offsets.shape[0] - 1):
        count[b] = 0
        near[b] = APART
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        mean_edge = rest_perimeter[b] / (e - o)
        reach, gap = REACH * mean_edge, GAP * mean_edge
        if _in_skin(prev, pos, o, e, chunks, reach):
            continue
        _chunk_shapes(prev, pos, o, e, chunks)
        slot0 = PER_VERTEX * o
        apart = math.inf
        for c in range(o, e, CHUNK):
            for d in range(c, e, CHUNK):
                apart_by = _chunks_apart_by(o, e, chunks, c, d, reach)
                if apart_by > 0.0:
                    apart = min(apart, apart_by)
                    continue
                near[b] = NEAR
                c_to, d_to = min(c + CHUNK, e), min(d + CHUNK, e)
                _keep_pairs(prev, pos, orient[b], o, e, c, c_to, d, d_to, reach, gap, pairs, values, slot0, count, b)
                if d != c:
                    _keep_pairs(prev, pos, orient[b], o, e, d, d_to, c, c_to, reach, gap, pairs, values, slot0, count,
                                b)
        _set_skin(pos, o, e, chunks, apart if near[b] == APART else 0.0)


@inline_kernel
def pairs_found(count):
    """How many pairs find_self_contacts found in all (none: the resolve stage has nothing to do)."""
    found = 0
    for b in range(count.shape[0]):
        found += count[b]
    return found


@inline_kernel
def _to_collider(held, normal, inv_mass, v, share, dx, dy):
    """A held vertex v that a push would have moved by share × w_v (dx, dy) does not move: the collider
    holding it takes the push instead, and its depth D_v (held, the normal force its friction and
    bounce read) grows by the part along its normal n_v that presses v into it."""
    if held[v] == 0.0:
        return
    into = -share * inv_mass[v] * (dx * normal[0, v] + dy * normal[1, v])
    if into > 0.0:
        held[v] += into


@inline_kernel
def _free(inv_mass, held, hold, i):
    """Vertex i's inverse mass in a self-contact: with `hold`, 0 when a collider has pushed it this substep."""
    return 0.0 if hold and held[i] != 0.0 else inv_mass[i]


@inline_kernel
def _keep_off_vertex(pos, inv_mass, held, hold, p, v, gap):
    """p beyond an end of the edge is kept at least `gap` from that end's vertex v: C = |p - x_v| - g >= 0,
    ∇_p C = -∇_v C = (p - x_v) / |p - x_v| (at a convex corner, the wedge beyond both edges' ends is
    faced by neither, and a vertex falling onto the corner's tip went through it)."""
    dx, dy = pos[0, p] - pos[0, v], pos[1, p] - pos[1, v]
    distance = math.hypot(dx, dy)
    C = distance - gap
    wp, wv = _free(inv_mass, held, hold, p), _free(inv_mass, held, hold, v)
    if C >= 0.0 or distance == 0.0 or wp + wv == 0.0:
        return
    lam = -C / ((wp + wv) * distance)
    pos[0, p] += wp * lam * dx
    pos[1, p] += wp * lam * dy
    pos[0, v] -= wv * lam * dx
    pos[1, v] -= wv * lam * dy


@inline_kernel
def _resolve_pair(pos, prev, inv_mass, held, normal, hold, orient, mu_s, mu_k, p, j, j1, values, k):
    """One pair's push and friction (see above). With `hold`, only a pair a collider has pushed into."""
    if hold and held[p] == 0.0 and held[j] == 0.0 and held[j1] == 0.0:
        return
    ex, ey = pos[0, j1] - pos[0, j], pos[1, j1] - pos[1, j]
    len2 = ex * ex + ey * ey
    if len2 == 0.0:
        return
    rx, ry = pos[0, p] - pos[0, j], pos[1, p] - pos[1, j]
    t = (rx * ex + ry * ey) / len2
    if t < 0.0 or t > 1.0:
        _keep_off_vertex(pos, inv_mass, held, hold, p, j if t < 0.0 else j1, values[1, k])
        return
    length = math.sqrt(len2)
    nx, ny = orient * ey / length, -orient * ex / length
    s = rx * nx + ry * ny
    if values[0, k] == UNDECIDED:  # p faces the edge for the first time this substep: its side from now on
        values[0, k] = 1.0 if s >= 0.0 else -1.0
        values[1, k] = min(values[1, k], abs(s))
    side = values[0, k]
    C = side * s - values[1, k]
    if C < -values[3, k]:  # deeper than p could have come this substep: not a crossing, a far part of the ring
        return
    wp, w0, w1 = _free(inv_mass, held, hold, p), _free(inv_mass, held, hold, j), _free(inv_mass, held, hold, j1)
    w = wp + (1.0 - t) ** 2 * w0 + t * t * w1
    if w <= MIN_LEVER * max(wp, w0, w1):  # only a held vertex could move q: the free one would be flung by 1/lever
        return
    pushed = 0.0
    if C < 0.0:
        lam = -C / w
        dx, dy = lam * side * nx, lam * side * ny
        pos[0, p] += wp * dx
        pos[1, p] += wp * dy
        pos[0, j] -= (1.0 - t) * w0 * dx
        pos[1, j] -= (1.0 - t) * w0 * dy
        pos[0, j1] -= t * w1 * dx
        pos[1, j1] -= t * w1 * dy
        pushed = -C
        values[2, k] += pushed
        if hold:  # a held vertex's share goes to the collider that holds it (see _to_collider)
            _to_collider(held, normal, inv_mass, p, 1.0, dx, dy)
            _to_collider(held, normal, inv_mass, j, -(1.0 - t), dx, dy)
            _to_collider(held, normal, inv_mass, j1, -t, dx, dy)
    D = values[2, k]
    if D == 0.0:
        return
    # Coulomb: the slip of p against q along the edge since the substep began
    tx, ty = ex / length, ey / length
    slip = ((pos[0, p] - prev[0, p]) - (1.0 - t) * (pos[0, j] - prev[0, j]) - t * (pos[0, j1] - prev[0, j1])) * tx \
        + ((pos[1, p] - prev[1, p]) - (1.0 - t) * (pos[1, j] - prev[1, j]) - t * (pos[1, j1] - prev[1, j1])) * ty
    cut = slip if abs(slip) <= mu_s * D else math.copysign(min(abs(slip), mu_k * pushed), slip)
    if cut == 0.0:
        return
    lam = cut / w
    pos[0, p] -= wp * lam * tx
    pos[1, p] -= wp * lam * ty
    pos[0, j] += (1.0 - t) * w0 * lam * tx
    pos[1, j] += (1.0 - t) * w0 * lam * ty
    pos[0, j1] += t * w1 * lam * tx
    pos[1, j1] += t * w1 * lam * ty


@stage_kernel
def resolve_self_contacts(pos, prev, inv_mass, held, normal, hold, offsets, awake, orient, material, pairs, values,
                          count, reverse):
    """One Gauss-Seidel pass over each awake ring's self-contact pairs, in reverse order when `reverse`
    (every second iteration, as blob contacts: one order alone favours the pairs it visits first). held:
    each vertex's static push depth this substep, normal: its direction; with `hold`, only the pairs a
    collider pushed into, with the vertices it pushed held (see _free, _to_collider)."""
    for b in numba.prange(offsets.shape[0] - 1):
        pairs_here = count[b]
        if pairs_here == 0 or not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        slot0 = PER_VERTEX * o
        for m in range(pairs_here):
            k = slot0 + (pairs_here - 1 - m if reverse else m)
            j = pairs[1, k]
            _resolve_pair(pos, prev, inv_mass, held, normal, hold, orient[b], material[b, 0], material[b, 1],
                          pairs[0, k], j, next_in_ring(j, o, e), values, k)


ZONE_ROUNDS = 4  # rounds of impact zones before the whole ring moves rigidly for the substep


@inline_kernel
def _segments_touch(pos, a, a1, b, b1):
    """Whether segments (a, a1) and (b, b1) cross or touch: each one's ends not strictly on one side of the
    other's line, or all four on one line, with their boxes overlapping (geometry.first_crossing's test,
    which `blobsim stress` judges rings by)."""
    o1, o2 = turn(pos, a, a1, b), turn(pos, a, a1, b1)
    o3, o4 = turn(pos, b, b1, a), turn(pos, b, b1, a1)
    if not ((o1 != o2 and o3 != o4) or (o1 == 0 and o2 == 0)):
        return False
    return (min(pos[0, a], pos[0, a1]) <= max(pos[0, b], pos[0, b1])
            and min(pos[0, b], pos[0, b1]) <= max(pos[0, a], pos[0, a1])
            and min(pos[1, a], pos[1, a1]) <= max(pos[1, b], pos[1, b1])
            and min(pos[1, b], pos[1, b1]) <= max(pos[1, a], pos[1, a1]))


@inline_kernel
def _join(zone, a, b):
    """Union of the zones of local vertices a and b (each zone's root: its smallest member)."""
    while zone[a] != a:
        a = zone[a]
    while zone[b] != b:
        b = zone[b]
    if a < b:
        zone[b] = a
    elif b < a:
        zone[a] = b


@inline_kernel
def _crossings_into_zones(pos, o, e, chunks, zone):
    """Join the zones of the ends of every two edges of ring o..e that cross or touch, and say whether any
    do (with an empty `zone`, only say). Chunks as find_self_contacts's, at pos, with no reach."""
    _chunk_shapes(pos, pos, o, e, chunks)
    crossed = False
    for c in range(o, e, CHUNK):
        for d in range(c, e, CHUNK):
            if _chunks_apart_by(o, e, chunks, c, d, 0.0) > 0.0:
                continue
            for a in range(c, min(c + CHUNK, e)):
                a1 = next_in_ring(a, o, e)
                for b in range(d if d != c else a + 2, min(d + CHUNK, e)):
                    b1 = next_in_ring(b, o, e)
                    if b == a or b1 == a or b == a1 or not _segments_touch(pos, a, a1, b, b1):
                        continue
                    if zone.shape[0] == 0:
                        return True
                    crossed = True
                    _join(zone, a - o, a1 - o)
                    _join(zone, a - o, b - o)
                    _join(zone, a - o, b1 - o)
    return crossed


@inline_kernel
def _move_zones_rigidly(pos, prev, held, wall_velocity, o, e, zone, sums):
    """Each zone of two or more vertices moves rigidly from where it was when the substep began: its
    centre as its vertices' mean moved, turned by the angle θ that best fits their motion (2D Procrustes,
    tan θ = Σ q × r / Σ q · r, q and r about the centre before and after, as integrate.update_velocities).
    The zone's momentum is kept, and its relative motion, the part that crossed the ring, is gone. A zone
    with a vertex a fixed collider pushed this substep (held > 0) stays where it was when the substep began
    instead (moved, it would go into that collider, whose push it undid); one that a moving collider pushed
    (wall_velocity: contact_material's rows 4 and 5, the surface's velocity there) is left as it is: where
    the substep began is inside the collider now, whose push keeps the last word."""
    n = e - o
    for k in range(n):
        for column in range(sums.shape[1]):
            sums[k, column] = 0.0
    for k in range(n):
        root = k
        while zone[root] != root:
            root = zone[root]
        zone[k] = root  # (flattened: the root of every member)
        i = o + k
        sums[root, 0] += pos[0, i]
        sums[root, 1] += pos[1, i]
        sums[root, 2] += prev[0, i]
        sums[root, 3] += prev[1, i]
        sums[root, 4] += 1.0
        sums[root, 7] += held[i]
        if held[i] != 0.0 and (wall_velocity[4, i] != 0.0 or wall_velocity[5, i] != 0.0):
            sums[root, 8] += 1.0
    for k in range(n):
        root, i = zone[k], o + k
        members = sums[root, 4]
        if members < 2.0:
            continue
        rx, ry = pos[0, i] - sums[root, 0] / members, pos[1, i] - sums[root, 1] / members
        qx, qy = prev[0, i] - sums[root, 2] / members, prev[1, i] - sums[root, 3] / members
        sums[root, 5] += qx * ry - qy * rx
        sums[root, 6] += qx * rx + qy * ry
    for k in range(n):
        root, i = zone[k], o + k
        members = sums[root, 4]
        if members < 2.0:
            continue
        if sums[root, 8] > 0.0:  # a moving collider holds it: its push has the last word
            continue
        if sums[root, 7] > 0.0:
            pos[0, i], pos[1, i] = prev[0, i], prev[1, i]
            continue
        theta = math.atan2(sums[root, 5], sums[root, 6])
        cos, sin = math.cos(theta), math.sin(theta)
        qx, qy = prev[0, i] - sums[root, 2] / members, prev[1, i] - sums[root, 3] / members
        pos[0, i] = sums[root, 0] / members + cos * qx - sin * qy
        pos[1, i] = sums[root, 1] / members + sin * qx + cos * qy


@inline_kernel
def _any_held(held, o, e):
    """Whether a collider pushed any vertex of ring o..e this substep."""
    for i in range(o, e):
        if held[i] != 0.0:
            return True
    return False


STILL_SIMPLE = 0.25  # × the reach: how far from its predicted place the iterations may move a vertex of a ring
#                      whose chunks were all apart before it is checked for crossings again


@stage_kernel
def keep_rings_simple(pos, prev, vel, h, held, wall_velocity, inv_mass, offsets, awake, rest_perimeter, target_area,
                      exact_area, zoned, near, chunks):
    """The fail-safe after the substep's constraints (Bridson, Fedkiw & Anderson 2002's impact zones): where
    two edges of a ring now cross or touch, the ends of both move rigidly from where they were when the
    substep began, where they did not; zones that meet are joined, and after ZONE_ROUNDS rounds the whole
    ring moves rigidly (zones a collider pushed: see _move_zones_rigidly). A ring that began the substep
    simple ends it simple (unless a moving collider holds the crossing), with its momentum (unless a
    collider holds the zone); what is lost is the zones' relative motion (kinetic energy is never made).
    A ring that began the substep crossed is left to the constraints, which untangle it (below).
    With `exact_area` (method kot), a ring the zones moved and no collider touches is then projected onto
    its target area again, unless that crosses it again: the area stays exact wherever it can. zoned[b]
    counts the substeps in which ring b needed this. A zone moved rigidly may go into a collider (a moving
    one has gone on since the substep began): the statics act again after it (pipeline).

    A ring whose chunks were all apart (find_self_contacts: near[b] = 0) and whose vertices the iterations
    moved less than STILL_SIMPLE × the reach from their predicted places x_prev + h v is not checked: its
    parts were farther apart than the reach, and came closer by less than half of it."""
    no_zone = np.empty(0, np.int64)
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        n = e - o
        if near[b] == APART:
            bound = (STILL_SIMPLE * REACH * rest_perimeter[b] / n) ** 2
            moved = 0.0
            for i in range(o, e):
                moved = max(moved, (pos[0, i] - prev[0, i] - h * vel[0, i]) ** 2
                            + (pos[1, i] - prev[1, i] - h * vel[1, i]) ** 2)
            if moved < bound:
                continue
        if not _crossings_into_zones(pos, o, e, chunks, no_zone):
            continue
        if _crossings_into_zones(prev, o, e, chunks, no_zone):
            # it began the substep crossed (so given, or a moving collider held a crossing): there is no simple
            # shape to come back to, and the constraints untangle it (kot gives the lobe of positive area its
            # area back and shrinks the other), which zones moved from a crossed start would undo every substep
            continue
        zoned[b] += 1
        zone = np.empty(n, np.int64)
        for k in range(n):
            zone[k] = k
        _crossings_into_zones(pos, o, e, chunks, zone)
        sums = np.empty((n, 9))  # per zone root: Σ x, Σ y, Σ x_prev, Σ y_prev, members, Σ q × r, Σ q · r, Σ held,
        #                          members a moving collider holds (_move_zones_rigidly)
        for rounds in range(ZONE_ROUNDS):
            _move_zones_rigidly(pos, prev, held, wall_velocity, o, e, zone, sums)
            if not _crossings_into_zones(pos, o, e, chunks, zone):
                break
        else:  # still crossing: the whole ring, one zone
            for k in range(n):
                zone[k] = 0
            _move_zones_rigidly(pos, prev, held, wall_velocity, o, e, zone, sums)
        if not exact_area or _any_held(held, o, e):
            continue
        kept = np.empty((2, n))
        for k in range(n):
            kept[0, k], kept[1, k] = pos[0, o + k], pos[1, o + k]
        project_area(pos, inv_mass, o, e, target_area[b])
        if _crossings_into_zones(pos, o, e, chunks, no_zone):
            for k in range(n):
                pos[0, o + k], pos[1, o + k] = kept[0, k], kept[1, k]
