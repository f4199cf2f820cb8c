"""A container (a circle with inside = true) turned by its surface velocity: a rotating drum."""

from pathlib import Path

import numpy as np
from conftest import STATIC_PENETRATION

from blobcli import build, build_params, parse_scene
from blobcli.sim.pipeline import advance

DRUM = Path(__file__).resolve().parent.parent / "scenes" / "drum.toml"


def tumble(friction: float, seconds: float = 4.0):
    """The drum of scenes/drum.toml with this friction (blobs and wall): the pile's mean centre over
    the last 2 s (m), and the farthest any vertex got from the drum's centre (m)."""
    sc = parse_scene(DRUM.read_text().replace("friction = 0.8", f"friction = {friction}"), "drum")
    model, state = build(sc)
    params = build_params(sc)
    steps = int(round(seconds / params.dt))
    centres, farthest = [], 0.0
    for n in range(steps):
        advance(state, model, params, 1)
        farthest = max(farthest, float(np.hypot(*state.pos.T).max()))
        if n >= steps - int(round(2.0 / params.dt)):
            centres.append(state.pos.mean(axis=0))
    return np.mean(centres, axis=0), farthest


def test_a_turning_drum_lifts_its_pile_up_the_rising_side_more_with_more_friction():
    """Counter-clockwise: the bottom moves toward +x, the right side rises. No blob leaves the drum."""
    rough, rough_far = tumble(0.8)
    smooth, smooth_far = tumble(0.2)
    assert rough[0] > smooth[0] > 0.0 and rough[1] > smooth[1]  # measured x 0.46 / 0.33 m, y -0.64 / -0.85 m
    assert abs(tumble(0.0)[0][0]) < 0.05  # frictionless, the wall slides under the pile: it stays centred
    assert max(rough_far, smooth_far) <= 1.6 + STATIC_PENETRATION
