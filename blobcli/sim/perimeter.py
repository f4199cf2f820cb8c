"""Perimeter stage: every edge keeps its rest length, with XPBD compliance.

For edge (i, j): C = |x_j - x_i| - L, ∇_j C = n = (x_j - x_i)/|x_j - x_i|, ∇_i C = -n.
XPBD (Macklin et al. 2016) with α̃ = α / h²:
    Δλ = (-C - α̃ λ) / (w_i + w_j + α̃),   x_i -= w_i Δλ n,   x_j += w_j Δλ n.
The two corrections are equal and opposite in momentum (m_i w_i = m_j w_j = 1), so
this stage never moves a blob's centre of mass. α = 0 makes the edge inextensible.
"""

import math

import numba

from ..jit import inline_kernel, stage_kernel
from .ring import next_in_ring


@inline_kernel
def solve_distance(pos, inv_mass, i, j, rest, lam, k, alpha):
    """One XPBD step of C = |x_j - x_i| - rest, with multiplier lam[k] (see above)."""
    dx, dy = pos[0, j] - pos[0, i], pos[1, j] - pos[1, i]
    length = math.sqrt(dx * dx + dy * dy)
    if length == 0.0:
        return
    C = length - rest
    dlam = (-C - alpha * lam[k]) / (inv_mass[i] + inv_mass[j] + alpha)
    lam[k] += dlam
    nx, ny = dx / length, dy / length
    pos[0, i] -= inv_mass[i] * dlam * nx
    pos[1, i] -= inv_mass[i] * dlam * ny
    pos[0, j] += inv_mass[j] * dlam * nx
    pos[1, j] += inv_mass[j] * dlam * ny


@stage_kernel
def solve_perimeter(pos, inv_mass, offsets, rest_length, compliance, lam, h):
    # Red-black order: even edges, then odd edges, then (odd rings only) the closing edge.
    # Within a colour no two edges share a vertex, so the order inside it does not matter
    # and no direction around the ring is favoured. A plain sweep i = 0..n-1 is biased:
    # each correction is passed on to the next edge, which pumps material around the ring
    # like a tank tread and makes a resting blob spin up and roll away. (Alternating
    # even-first and odd-first between calls looks more symmetric, but that period-2
    # forcing excites a wobble that grows without bound at one iteration per substep.)
    for b in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        n = e - o
        alpha = compliance[b] / (h * h)
        paired = n - (n % 2)
        for start in range(2):
            for k in range(start, paired, 2):
                i = o + k
                solve_distance(pos, inv_mass, i, next_in_ring(i, o, e), rest_length[i], lam, i, alpha)
        if n % 2 == 1:
            solve_distance(pos, inv_mass, e - 1, o, rest_length[e - 1], lam, e - 1, alpha)

