"""Physical invariants of the solver, each with its tolerance from conftest."""

import numpy as np
from conftest import (
    AREA_ROUNDOFF,
    COM_ROUNDOFF,
    COULOMB_SLIDE,
    FIRST_ORDER,
    FLOOR,
    FLOOR_ROUNDOFF,
    FREE_FALL_ROUNDOFF,
    MOMENTUM_ROUNDOFF,
    REBOUND_E0,
    REBOUND_E05,
    REBOUND_E1,
    REST_CREEP,
    REST_SPEED,
    STATIC_PENETRATION,
    com,
    momentum,
    scene,
    self_intersects,
    simulate_steps,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from blobcli import blob_measures, build, build_params, step
from blobcli.geometry import depth_inside_polygon


def free_blob(vertices, pressure, compliance, clockwise, damping=1.0, gravity="[0.0, 0.0]"):
    theta = 2 * np.pi * np.arange(vertices) / vertices
    pts = [[float(np.cos(t)) * 0.5, float(np.sin(t)) * 0.5] for t in theta]
    if clockwise:
        pts = pts[::-1]
    return f"""
[scene]
gravity = {gravity}
damping = {damping}
[[blob]]
points = {pts}
pressure = {pressure}
compliance = {compliance}
"""


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 48), pressure=st.floats(0.6, 1.4),
       compliance=st.sampled_from([0.0, 1e-5, 2e-4, 1e-2]), clockwise=st.booleans(),
       damping=st.sampled_from([0.0, 1.0, 20.0]))
def test_free_blob_never_moves_its_centre_of_mass(seed, n, pressure, compliance, clockwise, damping):
    """However deformed and shaken, no internal stage propels a blob."""
    sc = scene(free_blob(n, pressure, compliance, clockwise, damping))
    model, state = build(sc)
    params = build_params(sc)
    rng = np.random.default_rng(seed)
    state.pos[...] += rng.normal(0, 0.05, state.pos.shape)  # deform it
    state.vel[:] = rng.normal(0, 2.0, state.vel.shape)
    state.vel[...] -= state.vel.mean(axis=0)  # zero momentum (equal vertex masses)
    c0 = com(state, model)
    for _ in range(60):
        step(state, model, params)
        assert np.all(np.abs(com(state, model) - c0) <= COM_ROUNDOFF)
        assert np.all(np.abs(momentum(state, model)) <= MOMENTUM_ROUNDOFF)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(3, 64), pressure=st.floats(0.5, 1.5), compliance=st.sampled_from([0.0, 2e-4, 1e-2]),
       clockwise=st.booleans(), iterations=st.integers(1, 4))
def test_free_blob_area_is_target_after_every_step(n, pressure, compliance, clockwise, iterations):
    text = free_blob(n, pressure, compliance, clockwise, gravity="[0.0, -9.81]").replace(
        "[scene]", f"[scene]\niterations = {iterations}")
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    for _ in range(30):
        step(state, model, params)
        area, _ = blob_measures(state, model)
        assert abs(area[0] - model.target_area[0]) <= AREA_ROUNDOFF * abs(model.target_area[0])


def free_fall(substeps):
    text = f"""
[scene]
substeps = {substeps}
gravity = [0.5, -9.81]
[[blob]]
center = [1.0, 2.0]
radius = 0.3
velocity = [3.0, 4.0]
"""
    model, state, params = simulate_steps(text, 60)
    return com(state, model), params


def test_free_fall_follows_the_integrator_exactly():
    """Symplectic Euler over K substeps of h: x = x0 + v0 t + g t²/2 + g h t/2, to round-off."""
    c, params = free_fall(4)
    h = params.dt / params.substeps
    t = 60 * params.dt
    g = params.gravity
    expected = np.array([1.0, 2.0]) + np.array([3.0, 4.0]) * t + 0.5 * g * t * t + 0.5 * g * h * t
    np.testing.assert_allclose(c, expected, rtol=0, atol=FREE_FALL_ROUNDOFF)


def test_free_fall_converges_to_the_parabola_at_first_order():
    t = 1.0
    exact = np.array([1.0, 2.0]) + np.array([3.0, 4.0]) * t + 0.5 * np.array([0.5, -9.81]) * t * t
    errors = [np.linalg.norm(free_fall(k)[0] - exact) for k in (2, 4, 8)]
    assert abs(errors[0] / errors[1] - 2.0) < FIRST_ORDER
    assert abs(errors[1] / errors[2] - 2.0) < FIRST_ORDER


def test_internal_stages_conserve_momentum():
    """Zero gravity, no statics: Σ m v stays what it was, to round-off, while the blob wobbles."""
    text = free_blob(24, 0.8, 1e-3, False, damping=3.0)
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    rng = np.random.default_rng(7)
    state.vel[:] = rng.normal(0, 1.0, state.vel.shape) + np.array([2.0, -1.0])
    p0 = momentum(state, model)
    for _ in range(120):
        step(state, model, params)
    np.testing.assert_allclose(momentum(state, model), p0, rtol=0, atol=MOMENTUM_ROUNDOFF * 100)


def test_blob_dropped_on_floor_comes_to_rest_without_jitter_or_creep():
    text = """
[[blob]]
center = [0.0, 1.2]
radius = 0.5
""" + FLOOR
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    for _ in range(720):  # 12 s
        step(state, model, params)
    c0 = com(state, model)
    speeds = []
    for _ in range(120):  # 2 more seconds, watched every step
        step(state, model, params)
        speeds.append(np.abs(state.vel).max())
        assert state.pos[:, 1].min() >= -FLOOR_ROUNDOFF  # on, never in, the floor
    assert max(speeds) < REST_SPEED
    assert np.linalg.norm(com(state, model) - c0) < REST_CREEP


def slab_points(width=1.2, height=0.25, per_edge=8):
    """A rectangle's outline, each side cut into `per_edge` edges, counter-clockwise."""
    corners = np.array([[-width / 2, 0.001], [width / 2, 0.001], [width / 2, 0.001 + height], [-width / 2, 0.001 + height]])
    pts = [corners[k] + (corners[(k + 1) % 4] - corners[k]) * i / per_edge for k in range(4) for i in range(per_edge)]
    return [[float(x), float(y)] for x, y in pts]


def slab_on_slope(friction, static_friction):
    """A wide flat blob (it cannot roll) resting on a 10° slope."""
    return f"""
[scene]
duration = 3.0
gravity = [{9.81 * np.sin(np.radians(10)):.17g}, {-9.81 * np.cos(np.radians(10)):.17g}]
[[blob]]
points = {slab_points()}
friction = {friction}
static_friction = {static_friction}
compliance = 0.0
""" + FLOOR


def travel_on_slope(friction, static_friction):
    """Distance the slab's centre of mass moves along the slope in 3 s, after 4 s to settle.
    (While settling, the slack slab spreads downhill like a water bag; that is not sliding.)"""
    sc = scene(slab_on_slope(friction, static_friction))
    model, state = build(sc)
    params = build_params(sc)
    for _ in range(240):
        step(state, model, params)
    x0 = com(state, model)[0]
    for _ in range(180):
        step(state, model, params)
    return com(state, model)[0] - x0


def test_static_friction_holds_below_the_coulomb_angle():
    """tan 10° = 0.18 < μ_s = √(0.6 · 0.6): once settled, the slab does not creep."""
    assert abs(travel_on_slope(0.5, 0.6)) < REST_CREEP


def test_kinetic_friction_lets_it_slide_above_the_coulomb_angle():
    """μ = 0.02 on the slab and 0.5 on the floor combine to √(0.02 · 0.5) = 0.1 < tan 10°:
    it slides at a = g (sin 10° - 0.1 cos 10°) = 0.737 m/s², so from t = 4 s to 7 s it
    travels a (7² - 4²) / 2 = 12.2 m (Coulomb, within 10%)."""
    a = 9.81 * (np.sin(np.radians(10)) - 0.1 * np.cos(np.radians(10)))
    expected = a * (7 ** 2 - 4 ** 2) / 2
    assert abs(travel_on_slope(0.02, 0.02) / expected - 1) < COULOMB_SLIDE


def rebound_ratio(restitution):
    """Rebound height / drop height of a stiff blob's centre of mass (rest height 0.3 m)."""
    text = f"""
[[blob]]
center = [0.0, 2.0]
radius = 0.3
compliance = 0.0
restitution = {restitution}
""" + FLOOR
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    landed, peak = False, 0.0
    for _ in range(150):
        step(state, model, params)
        landed = landed or state.contact_depth.max() > 0
        if landed:
            peak = max(peak, com(state, model)[1])
    return (peak - 0.3) / (2.0 - 0.3)


def test_restitution_sets_the_rebound_height():
    """A rigid ball would rebound to e² of its drop; the blob loses a little more to deformation."""
    assert rebound_ratio(0.0) < REBOUND_E0
    assert REBOUND_E05[0] < rebound_ratio(0.5) < REBOUND_E05[1]
    assert rebound_ratio(1.0) > REBOUND_E1


def test_no_vertex_inside_static_colliders_after_a_step():
    """Blobs thrown onto a concave polygon and a circle: after every step, every vertex is outside."""
    text = """
[scene]
duration = 3.0
[[blob]]
center = [-1.0, 2.0]
radius = 0.3
grid = [4, 1]
spacing = [0.7, 0.0]
velocity = [0.0, -8.0]
[[static]]
kind = "polygon"
points = [[-2.0, -1.0], [3.0, -1.0], [3.0, 0.5], [1.5, 0.0], [0.5, 0.4], [-2.0, 0.2]]
[[static]]
kind = "circle"
center = [0.4, 1.0]
radius = 0.2
"""
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    poly = np.array(sc.statics[0].points)
    for _ in range(180):
        step(state, model, params)
        assert depth_inside_polygon(state.pos, poly).max() <= STATIC_PENETRATION
        assert (0.2 - np.hypot(*(state.pos - [0.4, 1.0]).T)).max() <= STATIC_PENETRATION


def test_segment_and_thin_box_stop_a_blob_at_100_m_per_s():
    """At the default dt, 0.42 m per substep: the swept tests must catch every vertex."""
    text = """
[scene]
gravity = [0.0, 0.0]
[[blob]]
center = [-1.0, 1.0]
radius = 0.3
velocity = [100.0, 0.0]
[[blob]]
center = [-1.0, -1.0]
radius = 0.3
velocity = [100.0, 0.0]
[[static]]
kind = "segment"
a = [0.5, 0.2]
b = [0.5, 1.8]
[[static]]
kind = "box"
center = [0.5, -1.0]
size = [0.02, 1.6]
"""
    model, state, params = simulate_steps(text, 60)
    assert np.all(np.isfinite(state.pos))
    assert state.pos[:, 0].max() < 0.5  # no vertex of either blob got past x = 0.49 / 0.5
    for b in range(2):
        ring = state.pos[model.offsets[b]:model.offsets[b + 1]]
        assert not self_intersects(ring)
