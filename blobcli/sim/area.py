"""Area stages: how a blob keeps its volume, picked by the scene's `method` (KOT, ... below); each
reads its own model arrays, and the step (sim/pipeline.py) calls the one a scene names.

    kot      exact projection onto the target area (the default; below)
    xpbd     the area as one compliant XPBD constraint per blob, solved iteratively
    gas      no target area: an ideal-gas pressure force P = P₀ A_target / A
    springs  no pressure at all: internal springs across the blob, the classic spring blob

Method "kot" (Grant Kot, "Fast and Stable Blob Physics"): move every vertex along a
direction p_i by the same amount h, with h chosen so the area is exactly the target.

Shoelace area, 2A = Σ x_i × x_{i+1} (2D cross product, > 0 counter-clockwise). With
x_i -> x_i + h p_i it is a quadratic in h:
    2A(h) = Σ x_i × x_{i+1} + h Σ (x_i × p_{i+1} + p_i × x_{i+1}) + h² Σ p_i × p_{i+1},
so 2A(h) = 2A₀ is  a h² + b h + c = 0  with
    a = Σ p_i × p_{i+1},  b = Σ (x_i × p_{i+1} + p_i × x_{i+1}),  c = Σ x_i × x_{i+1} - 2A₀.

Direction. The seed uses unit vertex normals; we use p_i = w_i ∇_i A, the inverse-mass
weighted area gradient, ∇_i A = ½ (y_{i+1} - y_{i-1}, x_{i-1} - x_{i+1}). It is the
outward normal scaled by half the neighbouring edge lengths, so:
  - Σ m_i Δx_i = h Σ ∇_i A = 0: a closed polygon's gradients sum to zero, so the area
    stage never moves the centre of mass (unit normals do not sum to zero, and would
    let a deformed blob propel itself);
  - it is the steepest direction for A, the same one XPBD's area constraint uses;
  - its sign follows the winding, so clockwise blobs (A₀ < 0) need no special case.

Root. The root of least |h| (the smallest move), in a form that never cancels:
    q = -(b + sign(b) √(b² - 4ac)) / 2,   h = c / q.
(The roots are q/a and c/q; |q| >= √|ac| makes c/q the smaller.) It is also right when
a ≈ 0, where it gives h = -c/b. If b² - 4ac < 0 no h reaches A₀; then h = -b / 2a, the
vertex of the parabola, moves the blob to the nearest area it can reach.
"""

import numba

from ..jit import inline_kernel, kernel, stage_kernel
from ..scene.schema import METHODS
from .perimeter import solve_distance
from .ring import next_in_ring, twice_ring_area


@inline_kernel
def _gradient_step(pos, inv_mass, o, e, scale):
    """x_i += scale w_i ∇_i A for one blob, with ∇_i from the positions before the move."""
    n = e - o
    x, y, w = pos[0, o:e], pos[1, o:e], inv_mass[o:e]  # (views indexed from 0: see perimeter.solve_perimeter)
    xl, yl = x[n - 1], y[n - 1]
    x0, y0 = x[0], y[0]
    for k in range(n):
        if k + 1 < n:
            xn, yn = x[k + 1], y[k + 1]
        else:
            xn, yn = x0, y0
        sx, sy = x[k], y[k]
        x[k] = sx + scale * 0.5 * w[k] * (yn - yl)
        y[k] = sy + scale * 0.5 * w[k] * (xl - xn)
        xl, yl = sx, sy


@stage_kernel
def area_kot(pos, inv_mass, offsets, awake, target_area):
    """Exact area projection (see the module docstring)."""
    for blob in numba.prange(offsets.shape[0] - 1):
        if not awake[blob]:
            continue
        project_area(pos, inv_mass, offsets[blob], offsets[blob + 1], target_area[blob])


@inline_kernel
def project_area(pos, inv_mass, o, e, target):
    """Ring o..e moved along x_i += h w_i ∇_i A to the area `target` (see the module docstring)."""
    n = e - o
    x, y, w = pos[0, o:e], pos[1, o:e], inv_mass[o:e]  # (views indexed from 0: see perimeter.solve_perimeter)
    # Pass 1: a, b, c, carrying p_i from one edge to the next.
    xl, yl = x[n - 1], y[n - 1]  # x_{i-1}
    x1, y1 = x[1], y[1]
    px = 0.5 * w[0] * (y1 - yl)
    py = 0.5 * w[0] * (xl - x1)
    a = b = c = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else i + 1 - n  # (i + 1) % n, without dividing
        jj = i + 2 if i + 2 < n else i + 2 - n
        xi, yi = x[i], y[i]
        xj, yj = x[j], y[j]
        qx = 0.5 * w[j] * (y[jj] - yi)  # p_{i+1}
        qy = 0.5 * w[j] * (xi - x[jj])
        a += px * qy - py * qx
        b += (xi * qy - yi * qx) + (px * yj - py * xj)
        c += xi * yj - yi * xj
        px, py = qx, qy
    c -= 2.0 * target
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        h = -b / (2.0 * a)
    else:
        q = -0.5 * (b + (disc ** 0.5 if b >= 0.0 else -(disc ** 0.5)))
        h = c / q if q != 0.0 else 0.0
    # Pass 2: x_i += h p_i = h w_i ∇_i A.
    _gradient_step(pos, inv_mass, o, e, h)


@kernel
def _area_and_gradient_norm(pos, inv_mass, o, e):
    """(A, Σ w_i |∇_i A|²) of one blob."""
    norm = 0.0
    for i in range(o, e):
        j = next_in_ring(i, o, e)
        l = i - 1 if i > o else e - 1
        gx, gy = 0.5 * (pos[1, j] - pos[1, l]), 0.5 * (pos[0, l] - pos[0, j])
        norm += inv_mass[i] * (gx * gx + gy * gy)
    return 0.5 * twice_ring_area(pos, o, e), norm


@stage_kernel
def area_xpbd(pos, inv_mass, offsets, awake, target_area, compliance, lam, h):
    """The area as a compliant XPBD constraint, one linearized step per iteration."""
    # XPBD (Macklin et al. 2016) for C = A - A₀ with ∇_i C = ∇_i A:
    #   Δλ = (-C - α̃ λ) / (Σ w_i |∇_i A|² + α̃),  x_i += w_i ∇_i A Δλ,  α̃ = α / h².
    # One linearized step per call: the area converges over the iterations, not exactly.
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        area, norm = _area_and_gradient_norm(pos, inv_mass, o, e)
        alpha = compliance[b] / (h * h)
        if norm + alpha == 0.0:
            continue
        dlam = (-(area - target_area[b]) - alpha * lam[b]) / (norm + alpha)
        lam[b] += dlam
        _gradient_step(pos, inv_mass, o, e, dlam)


@stage_kernel
def area_gas(pos, inv_mass, offsets, awake, target_area, gas_pressure, scale):
    """Ideal-gas pressure force; the area settles where the skin's tension balances it."""
    # Ideal gas (Matyka 2004): P = nRT / A, here P = P₀ A₀ / A. The pressure on an edge is
    # P |e| along its outward normal, half to each end; summed at vertex i that is exactly
    # P ∇_i A. Applied as a force over the substep, x_i += h² w_i f_i (here split over the
    # iterations: `scale` = h² / iterations), which symplectic Euler would also give.
    # The area is the true shoelace area (the 2D "volume" formula of the article is not).
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        area, _ = _area_and_gradient_norm(pos, inv_mass, o, e)
        if area * target_area[b] <= 0.0:  # turned inside out: no meaningful pressure
            continue
        pressure = gas_pressure[b] * target_area[b] / area
        _gradient_step(pos, inv_mass, o, e, scale * pressure)


@kernel
def area_springs(pos, inv_mass, blob_of, awake, pairs, rest, compliance, lam, h):
    """No pressure: internal springs hold the shape (and can let it invert)."""
    # XPBD distance constraints, like the perimeter's, across the blob: each vertex to the
    # opposite one and to its neighbours' neighbours (Gish's and JellyCar's spring bodies).
    for s in range(pairs.shape[0]):
        i, j = pairs[s, 0], pairs[s, 1]
        if not awake[blob_of[i]]:
            continue
        solve_distance(pos, inv_mass, i, j, rest[s], lam, s, compliance[blob_of[i]] / (h * h))


# The compiled step cannot look a kernel up in a dict: it picks the method by its index in
# METHODS (sim/pipeline.py, one branch per method), so the names and indices must agree.
assert METHODS == ("kot", "xpbd", "gas", "springs")
KOT, XPBD, GAS, SPRINGS = range(len(METHODS))
