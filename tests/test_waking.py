"""A moving collider wakes the sleeping blobs it reaches and those it leaves: a blob asleep on a platform that
drops away falls after it, one asleep under a press that lifts comes back round."""

from pathlib import Path

import numpy as np
import pytest
from conftest import ROUND_AGAIN, STATIC_PENETRATION
from conftest import run_each as run

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def test_a_sleeping_blob_on_a_platform_that_drops_away_falls_after_it():
    """A blob asleep on a platform that then drops 0.5 m at 1 m/s: the platform leaves it, which wakes it (asleep it
    would hang in the air where the platform was), and it lands on the platform again."""
    text = """[scene]
duration = 4.0
[[blob]]
center = [0.0, 0.3]
radius = 0.3
[[static]]
kind = "box"
center = [0.0, -0.5]
size = [4.0, 1.0]
path = [[2.5, 0.0, 0.0, 0.0], [3.0, 0.0, -0.5, 0.0]]
"""
    awake = []
    _, state, _ = run(text, each=lambda n, s: awake.append(int(s.awake[0])))
    assert awake[145] == 0  # asleep at 2.43 s, before the platform moves
    assert state.pos[:, 1].min() == pytest.approx(-0.5, abs=STATIC_PENETRATION)  # on the platform, where it is now


def test_a_press_that_lifts_off_a_sleeping_blob_wakes_it_and_it_comes_back_round():
    """scenes/press.toml with the press held at its lowest for 2 s instead of 1 (from 2 s to 4 s, lifted by 4.5 s):
    Gish falls asleep flattened under it; the press lifting off it wakes it, and it is round again 2.5 s later."""
    text = (SCENES / "press.toml").read_text().replace("duration = 5.0", "duration = 7.0").replace(
        "[3.0, 0.0, -0.6, 0.0], [3.5, 0.0, 0.0, 0.0]", "[4.0, 0.0, -0.6, 0.0], [4.5, 0.0, 0.0, 0.0]")
    assert "[4.5, 0.0, 0.0, 0.0]" in text
    flat, shapes = [], {}

    def each(n, s):
        if n + 1 == 230:  # 3.83 s: under the press, which holds still
            flat.append(int(s.awake[0]))
        if n + 1 in (60, 420):  # before the press comes down (t = 1 s), and 2.5 s after it is gone
            shapes[n + 1] = np.ptp(s.pos, axis=0)

    run(text, each=each)
    assert flat == [0]
    assert np.abs(shapes[420] / shapes[60] - 1.0).max() < ROUND_AGAIN
