"""Ring geometry for the kernels: the formulas of `blobcli.geometry`, as inlined numba helpers.

Blob b's ring is pos[o:e] with o, e = offsets[b], offsets[b + 1]; vertex i's edge joins it
to `next_in_ring(i, o, e)`.
"""

import math

from ..jit import inline_kernel


@inline_kernel
def next_in_ring(i, o, e):
    """The vertex after i in the ring o..e-1 (the last joins the first)."""
    return i + 1 if i + 1 < e else o


@inline_kernel
def prev_in_ring(i, o, e):
    """The vertex before i in the ring o..e-1 (the first follows the last)."""
    return i - 1 if i > o else e - 1


@inline_kernel
def most_vertices(offsets):
    """The most vertices any ring has (0 with no ring). A loop, not np.diff(offsets).max(): in the step's
    driver, numba's np.diff and its shape checks made a cold gish run cost about a fifth more CPU
    (docs/performance.md)."""
    most = 0
    for b in range(offsets.shape[0] - 1):
        most = max(most, offsets[b + 1] - offsets[b])
    return most


@inline_kernel
def turn(pos, a, b, c):
    """The sign of the turn a → b → c: +1 left (counter-clockwise), -1 right, 0 straight on."""
    d = (pos[0, b] - pos[0, a]) * (pos[1, c] - pos[1, a]) - (pos[1, b] - pos[1, a]) * (pos[0, c] - pos[0, a])
    return (d > 0.0) - (d < 0.0)


@inline_kernel
def vertex_normal(pos, orient, i, o, e):
    """Vertex i's outward normal (not unit): its neighbours' difference turned by the ring's winding."""
    before, after = prev_in_ring(i, o, e), next_in_ring(i, o, e)
    return orient * (pos[1, after] - pos[1, before]), -orient * (pos[0, after] - pos[0, before])


@inline_kernel
def ring_means(a, b, o, e):
    """The means over ring o..e of two (2, N) arrays (positions, velocities): (ā_x, ā_y, b̄_x, b̄_y)."""
    n = e - o
    a0, a1, b0, b1 = a[0, o:e], a[1, o:e], b[0, o:e], b[1, o:e]  # views indexed from 0 (perimeter.solve_perimeter)
    ax = ay = bx = by = 0.0
    for i in range(n):
        ax += a0[i]
        ay += a1[i]
        bx += b0[i]
        by += b1[i]
    return ax / n, ay / n, bx / n, by / n


@inline_kernel
def centre_motion(pos, vel, o, e):
    """Centre, centre velocity and kinetic energy per unit mass (½ mean |v|²) of ring o..e
    (vertex masses are equal within a blob)."""
    cx, cy, vx, vy = ring_means(pos, vel, o, e)
    k = 0.0
    for i in range(o, e):
        k += vel[0, i] ** 2 + vel[1, i] ** 2
    return (cx, cy), (vx, vy), 0.5 * k / (e - o)


@inline_kernel
def ring_radius(pos, o, e, cx, cy):
    """The distance from (cx, cy) to the farthest vertex of ring o..e."""
    r2 = 0.0
    for i in range(o, e):
        r2 = max(r2, (pos[0, i] - cx) ** 2 + (pos[1, i] - cy) ** 2)
    return math.sqrt(r2)


@inline_kernel
def twice_ring_area(pos, o, e):
    """2A = Σ (x_i y_{i+1} − x_{i+1} y_i) of the ring pos[o:e], summed in ring order."""
    twice_area = 0.0
    for i in range(o, e):
        j = next_in_ring(i, o, e)
        twice_area += pos[0, i] * pos[1, j] - pos[0, j] * pos[1, i]
    return twice_area


@inline_kernel
def crosses_ray(ax, ay, bx, by, x, y):
    """Whether edge a→b crosses the ray from (x, y) toward +x (one step of the crossing-number
    test: a point is inside a polygon when the ray crosses its boundary an odd number of times)."""
    return (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay)


@inline_kernel
def ring_contains(pos, o, e, x, y):
    """Crossing-number test: is (x, y) inside the closed polygon pos[o:e]?"""
    inside = False
    j = e - 1
    for i in range(o, e):
        if crosses_ray(pos[0, j], pos[1, j], pos[0, i], pos[1, i], x, y):
            inside = not inside
        j = i
    return inside
