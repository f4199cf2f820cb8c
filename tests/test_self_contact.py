"""Self-contact: a ring's parts do not pass through each other (core/self_contact.c)."""

import numpy as np
import pytest
from conftest import FLOOR, MOMENTUM_ROUNDOFF, Stage, scene, self_intersects

from blobcli import blob_measures, build, build_params, load_scene, step
from blobcli.tools.stress import STRESS_DIR

FOLD_AREA = 0.02  # relative: the folded strip's area, the fold held open by self-contact and the post pushing into it
UNTANGLED_AREA = 1e-2  # relative: a ring crossed in its state, two steps later (measured: under 2e-3)


def test_a_strip_folded_over_a_post_never_crosses_itself():
    """The stress scene `folded` (a 2 m × 0.1 m strip dropped across a post): by 0.28 s the post had pushed
    the strip's underside through its top (without self-contact: crossed at step 17); here the first 0.6 s,
    every step."""
    sc = load_scene(STRESS_DIR / "folded.toml")
    model, state = build(sc)
    params = build_params(sc)
    for n in range(36):
        step(state, model, params)
        assert not self_intersects(state.pos), f"crossed itself at step {n + 1}"
    area = 0.5 * abs(np.sum(state.pos[:, 0] * np.roll(state.pos[:, 1], -1) - np.roll(state.pos[:, 0], -1)
                            * state.pos[:, 1]))
    assert abs(area / abs(model.target_area[0]) - 1.0) < FOLD_AREA


def test_the_fail_safe_moves_a_crossed_part_rigidly_and_keeps_the_momentum():
    """bc_keep_rings_simple (core/self_contact.c), shown a ring whose vertex went through the far side within a
    substep: the crossed part moves rigidly from where it was, the ring ends simple, Σ m Δx is kept, and a simple
    ring is not touched (same bits)."""
    n = 16
    t = 2.0 * np.pi * np.arange(n) / n
    prev = np.ascontiguousarray(np.stack([np.cos(t), np.sin(t)]))
    pos = prev + np.array([[0.3], [0.1]])  # the whole ring moved ...
    pos[0, 0] -= 2.5  # ... and one vertex through the ring's far side
    assert self_intersects(pos.T)
    # one ring of n unit masses, at rest (v = 0, h = 1: x_prev + h v = x_prev), no collider holding it (held 0, no
    # wall velocity), its chunks near (self_near 1: checked whatever it moved), no exact area afterwards
    model, state = build(scene(f"[[blob]]\ncenter = [0.0, 0.0]\nradius = 1.0\nvertices = {n}\n"))
    arrays = model.arrays._replace(inv_mass=np.ones(n), rest_perimeter=np.full(1, 2.0 * np.pi),
                                   target_area=np.zeros(1))
    state.previous[...] = prev
    state.velocity[...] = 0.0
    state.contact_depth[...] = 0.0
    state.contact_material[...] = 0.0
    state.awake[...] = 1
    _, _, _, near, chunks, zoned = state.self_contact
    near[...], chunks[...], zoned[...] = 1, 0.0, 0
    stage = Stage(model, state, arrays=arrays, scratch=True)

    def fail_safe(x):
        state.position[...] = x
        stage.call("keep_rings_simple", 1.0, 0)
        x[...] = state.position

    moved = pos.sum(axis=1)
    fail_safe(pos)
    assert not self_intersects(pos.T)
    assert np.all(np.abs(pos.sum(axis=1) - moved) <= MOMENTUM_ROUNDOFF * n)
    assert zoned[0] == 1

    simple = prev + 0.01
    before = simple.copy()
    fail_safe(simple)
    assert np.array_equal(simple, before) and zoned[0] == 1


def _tangled(kind, pos):
    """A ring of 32 crossed in place: two neighbouring vertices swapped, or 13 vertices pushed through the rest."""
    if kind == "swap":
        pos[[5, 6]] = pos[[6, 5]]
    else:
        c = pos.mean(axis=0)
        pos[10:23] = c + (pos[10:23] - c) * [1.0, -0.3] + [0.0, 0.35]


@pytest.mark.parametrize("kind", ["swap", "fold"])
def test_a_ring_that_begins_crossed_untangles_within_two_steps(kind):
    """A ring that begins a substep crossed has no simple shape to come back to: the fail-safe leaves it to the
    constraints, which untangle it (kot gives the lobe of positive area its area back and shrinks the other).
    Before, the fail-safe moved its crossing parts rigidly from their crossed start every substep: it stayed
    crossed (and the folded one at 59% of its area) until it fell asleep."""
    sc = scene("[[blob]]\ncenter = [0.0, 0.6]\nradius = 0.5\n" + FLOOR)
    model, state = build(sc)
    params = build_params(sc)
    _tangled(kind, state.pos)
    assert self_intersects(state.pos)
    for _ in range(2):
        step(state, model, params)
    area, _ = blob_measures(state, model)
    assert not self_intersects(state.pos) and abs(area[0] / model.target_area[0] - 1.0) < UNTANGLED_AREA
    for _ in range(60):
        step(state, model, params)
        assert not self_intersects(state.pos)
