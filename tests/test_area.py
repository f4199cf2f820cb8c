"""The exact area projection ("kot", core/area.c: bc_area_kot): random and degenerate polygons, both windings."""

import numpy as np
import pytest
from conftest import AREA_ROUNDOFF, MOMENTUM_ROUNDOFF, PROJECTION_ROUNDOFF, Stage, polygon_area, scene
from hypothesis import given, settings
from hypothesis import strategies as st

from blobcli import build


def star_polygon(rng, n, wobble):
    """A simple (star-shaped) polygon: radius varies with angle, angles increase."""
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 1.0 + wobble * rng.uniform(-1, 1, n)
    return np.stack([r * np.cos(theta), r * np.sin(theta)], axis=1) + rng.normal(0, 3, 2)


def project(points, target, inv_mass=None):
    """The polygon `points` (n, 2) after bc_area_kot, as one blob of n vertices with these inverse masses (unit by
    default) and target area: the positions are the state's (2, n), as the core reads them."""
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    model, state = build(scene(f"[[blob]]\ncenter = [0.0, 0.0]\nradius = 1.0\nvertices = {n}\n"))
    state.position[...] = points.T
    inv_mass = np.ones(n) if inv_mass is None else np.ascontiguousarray(inv_mass, dtype=np.float64)
    arrays = model.arrays._replace(inv_mass=inv_mass, target_area=np.array([float(target)]))
    Stage(model, state, arrays=arrays).call("area_kot")
    return state.position.T.copy()


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 80), wobble=st.floats(0.0, 0.6),
       ratio=st.floats(0.5, 1.5), clockwise=st.booleans())
def test_projection_hits_target_area_exactly(seed, n, wobble, ratio, clockwise):
    rng = np.random.default_rng(seed)
    p = star_polygon(rng, n, wobble)
    if clockwise:
        p = p[::-1]
    target = ratio * polygon_area(p)  # same sign as the winding
    out = project(p, target)
    # The shoelace sum's roundoff scales with its terms |x_i × x_{i+1}|, not with the area
    # they cancel down to (a thin triangle far from the origin: terms ~10 m², area 3e-6 m²).
    nxt = np.roll(out, -1, axis=0)
    terms = 0.5 * np.abs(out[:, 0] * nxt[:, 1] - out[:, 1] * nxt[:, 0]).sum()
    assert abs(polygon_area(out) - target) <= AREA_ROUNDOFF * max(abs(target), terms) * 10


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 60), ratio=st.floats(0.7, 1.3))
def test_projection_conserves_momentum_with_unequal_masses(seed, n, ratio):
    rng = np.random.default_rng(seed)
    p = star_polygon(rng, n, 0.3)
    inv_mass = rng.uniform(0.5, 4.0, n)
    out = project(p, ratio * polygon_area(p), inv_mass)
    moved = ((out - p) / inv_mass[:, None]).sum(axis=0)  # Σ m Δx
    assert np.all(np.abs(moved) <= MOMENTUM_ROUNDOFF * np.abs(p).max() * n)


def test_projection_is_identity_at_target():
    p = star_polygon(np.random.default_rng(1), 20, 0.2)
    out = project(p, polygon_area(p))
    assert np.max(np.abs(out - p)) < PROJECTION_ROUNDOFF * np.abs(p).max() * 10


def test_smallest_root_is_taken():
    # A square of area 4 to area 4.41: moving each vertex outward by the least h.
    p = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    out = project(p, 4.41)
    np.testing.assert_allclose(out, p * 1.05, rtol=PROJECTION_ROUNDOFF)


def test_a_zero_the_quadratic_is_linear():
    # Two of three vertices pinned (w = 0): only p_2 = ½ w_2 (y_0 − y_1, x_1 − x_0) is non-zero,
    # so a = Σ (p_i × p_{i+1}) = 0 exactly and A(h) = A + ½ b h is linear: h = −c / b. The
    # free vertex moves along its gradient (perpendicular to the opposite edge) to hit A = 2.
    p = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    inv_mass = np.array([0.0, 0.0, 1.0])
    gx, gy = 0.5 * (p[0, 1] - p[1, 1]), 0.5 * (p[1, 0] - p[0, 0])
    assert gx * 0.0 - gy * 0.0 == 0.0  # a's terms all multiply a zero p
    out = project(p, 2.0, inv_mass)
    np.testing.assert_array_equal(out[:2], p[:2])  # the pinned vertices stay
    assert out[2, 0] == 0.0 and out[2, 1] == pytest.approx(2.0, rel=PROJECTION_ROUNDOFF)  # A = ½ · 2 · y
    assert abs(polygon_area(out) - 2.0) < PROJECTION_ROUNDOFF * 2.0


def test_unreachable_target_moves_to_nearest_area_without_nan():
    # A polygon collapsed onto a line (area 0): the result must stay finite.
    p = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    out = project(p, 1.0)
    assert np.all(np.isfinite(out))
    # A flipped (inverted) polygon with negative discriminant: target far beyond reach.
    q = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    out = project(q, -50.0)
    assert np.all(np.isfinite(out))
    assert polygon_area(out) < polygon_area(q)  # moved toward the target, as far as the parabola allows


def test_negative_discriminant_takes_parabola_vertex():
    # Square, unit masses: A(h) = 4 + 4h·... ; ask for an area below the parabola's minimum.
    p = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    # p_i = ½(y_{i+1}-y_{i-1}, x_{i-1}-x_{i+1}) = (x_i, y_i) here, so A(h) = 4 (1 + h)²,
    # minimum 0 at h = -1. Any negative target is unreachable: expect the vertex h = -1.
    out = project(p, -1.0)
    np.testing.assert_allclose(out, 0.0, atol=PROJECTION_ROUNDOFF / 10)
