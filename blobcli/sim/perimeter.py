"""Perimeter stage: every edge keeps its rest length, with XPBD compliance.

For edge (i, j): C = |x_j - x_i| - L, ∇_j C = n = (x_j - x_i)/|x_j - x_i|, ∇_i C = -n.
XPBD (Macklin et al. 2016) with α̃ = α / h²:
    Δλ = (-C - α̃ λ) / (w_i + w_j + α̃),   x_i -= w_i Δλ n,   x_j += w_j Δλ n.
The two corrections are equal and opposite in momentum (m_i w_i = m_j w_j = 1), so
this stage never moves a blob's centre of mass. α = 0 makes the edge inextensible.
"""

import math

import numba
import numpy as np

from ..jit import inline_kernel, stage_kernel


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


@inline_kernel
def edge_step(x, y, i, j, rest, lam, alpha, inv_weight):
    """Δλ n of one XPBD step of C = |x_j - x_i| - rest (see above), with multiplier lam[i] and
    inv_weight = 1 / (w_i + w_j + α̃); x, y: the ring's coordinates."""
    dx, dy = x[j] - x[i], y[j] - y[i]
    length = math.sqrt(dx * dx + dy * dy)
    if length == 0.0:
        return 0.0, 0.0
    dlam = (-(length - rest) - alpha * lam[i]) * inv_weight
    lam[i] += dlam
    scale = dlam / length
    return scale * dx, scale * dy


TOTAL_STEP = 0.4  # the total-length step moves no vertex more than this × a mean rest edge
SWEEPS = 2  # Jacobi passes per iteration: a Jacobi pass converges about half as fast as a Gauss-Seidel one


@stage_kernel
def solve_perimeter(pos, inv_mass, offsets, awake, rest_length, rest_total, compliance, lam, total_lam, h):
    # Jacobi: every edge's correction is computed from the same positions, and each vertex
    # moves by the sum of its two edges' (x_i -= w_i Δλ_i n_i, x_{i+1} += w_{i+1} Δλ_i n_i).
    # The result does not depend on the order of the edges, so a mirror-symmetric blob stays
    # mirror-symmetric. Any sweep order leaks into the result: a plain sweep i = 0..n-1
    # passes each correction on to the next edge and pumps material round the ring like a
    # tank tread; red-black (even edges, then odd) is not mirror-symmetric either (a mirror
    # maps even edges to odd), and with friction that small asymmetry made a blob dropped
    # straight onto a floor roll 0.1 m aside. One pass round the ring: edge i's correction is
    # computed before vertex i moves, and the closing edge's first, before vertex o does.
    # Then the ring's total length, as one constraint (see _solve_total_length).
    # Each ring's arrays are taken as views indexed from 0 (x[k] = pos[0, o + k]): k runs over range(n), so
    # LLVM knows k >= 0 and drops numba's handling of negative indices, which was a third of this loop's
    # instructions (the same arithmetic in the same order: the same bits).
    unit = np.empty((2, pos.shape[1]))  # its unit edge vectors t_i, each blob in its own columns
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        n = e - o
        x, y, rest, ring_lam = pos[0, o:e], pos[1, o:e], rest_length[o:e], lam[o:e]
        w = inv_mass[o]  # vertex masses are equal within a blob
        alpha = compliance[b] / (h * h)
        inv_weight = 1.0 / (w + w + alpha)
        for _ in range(SWEEPS):
            last_x, last_y = edge_step(x, y, n - 1, 0, rest[n - 1], ring_lam, alpha, inv_weight)
            before_x, before_y = last_x, last_y  # the correction of the edge ending at vertex k
            for k in range(n):
                if k < n - 1:
                    gx, gy = edge_step(x, y, k, k + 1, rest[k], ring_lam, alpha, inv_weight)
                else:
                    gx, gy = last_x, last_y
                x[k] += w * (before_x - gx)
                y[k] += w * (before_y - gy)
                before_x, before_y = gx, gy
        _solve_total_length(x, y, w, rest_total[b], compliance[b] * n / (h * h), total_lam, b, unit[0, o:e],
                            unit[1, o:e])


@inline_kernel
def _solve_total_length(x, y, w, rest, alpha, lam, b, unit_x, unit_y):
    """One XPBD step of the ring's total length, C = Σ |e_k| - Σ L_k, with α̃ = n α / h² (the
    compliance of its n edges in series) and multiplier lam[b]; x, y: the ring's coordinates, w its
    vertices' inverse mass; unit_x, unit_y: scratch for the t_i.

    A pass over the edges moves a correction one edge along the ring, so a ring of n vertices
    needs O(n) iterations to resist a stretch spread over all of it: under its own weight a
    128-vertex blob sagged to a flat patch of a third of its perimeter (stretched 17 %) at 2
    iterations. This one scalar constraint resists that mode in one step, whatever n.
    ∇_i C = t_{i-1} - t_i (t_k the unit vector along edge k, from x_k to x_{k+1}):
        Δλ = (-C - α̃ λ) / (Σ w_i |∇_i C|² + α̃),   Δx_i = w_i Δλ ∇_i C.
    Σ m_i Δx_i = Δλ Σ (t_{i-1} - t_i) = 0: momentum is unchanged; C is a sum over the ring,
    so it has no order and keeps mirror symmetry."""
    n = x.shape[0]
    C = -rest
    weight = steepest = 0.0  # Σ w_i |∇_i C|², and the largest |∇_i C|² ...
    tx0, ty0, _ = _unit(x[0] - x[n - 1], y[0] - y[n - 1])
    tx, ty = tx0, ty0  # t_{i-1}
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        ux, uy, length = _unit(x[j] - x[i], y[j] - y[i])
        unit_x[i], unit_y[i] = ux, uy
        C += length
        g2 = (tx - ux) ** 2 + (ty - uy) ** 2
        weight += w * g2
        steepest = max(steepest, g2)
        tx, ty = ux, uy
    # ... whose root, times w, is the largest w |∇_i C|: √ and the product by w never decrease, so the
    # largest of the products is the product of the largest, to the bit (one root, not n)
    steepest = w * math.sqrt(steepest)
    if weight + alpha == 0.0:
        return
    dlam = (-C - alpha * lam[b]) / (weight + alpha)
    # C is far from linear where the ring turns sharply (∇C concentrates there): a full step
    # overshot and blew up an over-pressured blob (pressure 2) landing on a floor. So no
    # vertex moves more than TOTAL_STEP of a mean rest edge per step (a trust region). Its size
    # trades two things: too small and a long ring sags (a hard 128-vertex blob rolled at 0.893
    # of a ring's acceleration with 0.2, 0.909 with 0.4) and a squashed blob re-rounds slowly;
    # too large and the over-pressured blob rings (kinetic energy still 4 mJ after 4 s with
    # 0.5, 1 J peaks with 1.0; at rest and asleep by 1.5 s with 0.4).
    most = TOTAL_STEP * rest / n
    if abs(dlam) * steepest > most:
        dlam = math.copysign(most / steepest, dlam)
    lam[b] += dlam
    # Δx_i needs t_{i-1} and t_i at the positions C was measured at: the t_i kept from the sum above
    # (recomputing them, a square root and a division per edge, cost 11% of this stage).
    tx, ty = tx0, ty0
    for i in range(n):
        ux, uy = unit_x[i], unit_y[i]
        x[i] += w * dlam * (tx - ux)
        y[i] += w * dlam * (ty - uy)
        tx, ty = ux, uy


@inline_kernel
def _unit(dx, dy):
    """(d / |d|, |d|); (0, 0, 0) for d = 0."""
    length = math.sqrt(dx * dx + dy * dy)
    if length == 0.0:
        return 0.0, 0.0, 0.0
    inv = 1.0 / length
    return dx * inv, dy * inv, length
