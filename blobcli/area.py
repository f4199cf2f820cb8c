"""Area stages: give every blob its target area back. One signature, picked by name.

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

from .jit import kernel
from .scene import METHODS


@kernel
def _area_kot(pos, inv_mass, offsets, target_area):
    for blob in range(offsets.shape[0] - 1):
        o, e = offsets[blob], offsets[blob + 1]
        n = e - o
        # Pass 1: a, b, c, carrying p_i from one edge to the next.
        xl, yl = pos[e - 1, 0], pos[e - 1, 1]  # x_{i-1}
        x0, y0 = pos[o, 0], pos[o, 1]
        x1, y1 = pos[o + 1, 0], pos[o + 1, 1]
        px = 0.5 * inv_mass[o] * (y1 - yl)
        py = 0.5 * inv_mass[o] * (xl - x1)
        a = b = c = 0.0
        for k in range(n):
            i = o + k
            j = o + (k + 1) % n
            jj = o + (k + 2) % n
            xi, yi = pos[i, 0], pos[i, 1]
            xj, yj = pos[j, 0], pos[j, 1]
            qx = 0.5 * inv_mass[j] * (pos[jj, 1] - yi)  # p_{i+1}
            qy = 0.5 * inv_mass[j] * (xi - pos[jj, 0])
            a += px * qy - py * qx
            b += (xi * qy - yi * qx) + (px * yj - py * xj)
            c += xi * yj - yi * xj
            px, py = qx, qy
        c -= 2.0 * target_area[blob]
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            h = -b / (2.0 * a)
        else:
            q = -0.5 * (b + (disc ** 0.5 if b >= 0.0 else -(disc ** 0.5)))
            h = c / q if q != 0.0 else 0.0
        # Pass 2: x_i += h p_i, with p_i from the old neighbours (kept in xl, yl / x0, y0).
        xl, yl = pos[e - 1, 0], pos[e - 1, 1]
        for k in range(n):
            i = o + k
            if k + 1 < n:
                xn, yn = pos[i + 1, 0], pos[i + 1, 1]
            else:
                xn, yn = x0, y0
            sx, sy = pos[i, 0], pos[i, 1]
            pos[i, 0] = sx + h * 0.5 * inv_mass[i] * (yn - yl)
            pos[i, 1] = sy + h * 0.5 * inv_mass[i] * (xl - xn)
            xl, yl = sx, sy


def area_kot(state, model, params, h):
    """Exact area projection (see the module docstring)."""
    _area_kot(state.pos, model.inv_mass, model.offsets, model.target_area)


AREA_METHODS = {"kot": area_kot}
assert tuple(AREA_METHODS) == METHODS
