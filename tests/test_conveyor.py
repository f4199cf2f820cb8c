"""Conveyor surfaces (`surface_velocity`): friction acts on the slip relative
to the moving surface, so a scene on a belt is the same scene on a fixed floor seen from a frame moving
with the belt."""

import numpy as np
import pytest
from conftest import GALILEAN, scene

from blobcli import build, build_params
from blobcli.scene.schema import SceneError
from blobcli.sim.pipeline import advance

BELT = """[scene]
sleep = {sleep}
duration = 3.0
[[blob]]
center = [0.0, 0.4001]
radius = 0.4
velocity = [{v}, 0.0]
friction = 0.8
[[static]]
kind = "{kind}"
{geometry}
friction = 0.8
surface_velocity = {u}
"""
FLOOR = 'point = [0.0, 0.0]\nnormal = [0.0, 1.0]'
BOX = 'center = [0.0, -0.5]\nsize = [40.0, 1.0]'  # its top face at y = 0


def centres(u, v, kind="plane", geometry=FLOOR, sleep="false", steps=180):
    """The blob's centre after each step (m), and dt (s)."""
    sc = scene(BELT.format(u=u, v=v, kind=kind, geometry=geometry, sleep=sleep))
    model, state = build(sc)
    params = build_params(sc)
    out = []
    for _ in range(steps):
        advance(state, model, params, 1)
        out.append(state.pos.mean(axis=0))
    return np.array(out), params.dt, state


@pytest.mark.parametrize("kind, geometry", [("plane", FLOOR), ("box", BOX)])
def test_a_blob_set_down_on_a_belt_moves_as_one_launched_backwards_on_a_fixed_floor(kind, geometry):
    """x_belt(t) - V t = x_fixed(t) and the same y, within GALILEAN over 3 s: it slides, then rolls."""
    belt, dt, _ = centres(1.0, 0.0, kind, geometry)
    fixed, _, _ = centres(0.0, -1.0, kind, geometry)
    t = dt * np.arange(1, len(belt) + 1)
    assert np.abs(belt[:, 0] - t - fixed[:, 0]).max() < GALILEAN
    assert np.abs(belt[:, 1] - fixed[:, 1]).max() < GALILEAN
    speed = (belt[-1, 0] - belt[-2, 0]) / dt
    assert 0.45 < speed < 0.75  # a ring dragged from rest by a belt rolls at about V/2, not V


def test_a_blob_riding_a_belt_never_falls_asleep():
    _, _, state = centres(1.0, 0.0, sleep="true", steps=300)
    assert state.awake.all()


def test_surface_velocity_is_bounded():
    with pytest.raises(SceneError, match=r"static\[0\].surface_velocity: must be <= 1,000.0 \(got 1000000.0\)"):
        scene(BELT.format(u=1e6, v=0.0, kind="plane", geometry=FLOOR, sleep="false"))
