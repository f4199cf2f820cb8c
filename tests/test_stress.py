"""Stress runs and their failure detectors, each detector shown a constructed failure."""

import numpy as np
import pytest

from blobcli.scene.schema import METHODS, parse_scene
from blobcli.tools.stress import (
    AREA_DRIFT,
    STRESS_DIR,
    detect_area_drift,
    detect_energy_growth,
    detect_inside_out,
    detect_nonfinite,
    detect_tunnelled,
    run_stress,
)


def ring(n=16, r=1.0, c=(0.0, 2.0)):
    t = 2 * np.pi * np.arange(n) / n
    return np.stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t)], axis=1)


OFFSETS = np.array([0, 16])


def test_nonfinite_detector():
    p = ring()[None].repeat(3, axis=0)
    assert detect_nonfinite("complete", p) is None
    p[2, 5, 0] = np.nan
    assert detect_nonfinite("complete", p) == "non-finite"
    assert detect_nonfinite("runaway", ring()[None]) == "non-finite"


def test_inside_out_detector_catches_a_flipped_and_a_crossed_polygon():
    good = ring()
    assert detect_inside_out(good[None], OFFSETS, np.array([1.0])) is None
    flipped = np.stack([good, good[::-1]])  # frame 1: same points, opposite winding
    assert detect_inside_out(flipped, OFFSETS, np.array([1.0])).startswith("inside out (blob 0, frame 1)")
    crossed = good.copy()
    crossed[[3, 6]] = crossed[[6, 3]]  # two vertices swapped: edges cross, area keeps its sign
    assert detect_inside_out(np.stack([good, crossed]), OFFSETS, np.array([1.0])).startswith(
        "self-intersecting (blob 0, frame 1)")


def test_tunnelling_detector_catches_a_vertex_through_each_kind_of_wall():
    scene = parse_scene("""
[[blob]]
center = [0.0, 2.0]
radius = 1.0
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "segment"
a = [3.0, -5.0]
b = [3.0, 5.0]
[[static]]
kind = "box"
center = [-5.0, 2.0]
size = [1.0, 1.0]
""")
    good = ring()
    assert detect_tunnelled(np.stack([good, good]), scene.statics) is None
    below = good.copy()
    below[4, 1] = -0.1  # through the floor
    assert detect_tunnelled(np.stack([good, below]), scene.statics) == "tunnelled (static 0, frame 1)"
    across = good.copy()
    across[0, 0] = 3.5  # jumped across the segment x = 3 within its extent
    assert detect_tunnelled(np.stack([good, across]), scene.statics) == "tunnelled (static 1, frame 1)"
    inside = good.copy()
    inside[8] = [-5.0, 2.0]  # in the middle of the box
    assert detect_tunnelled(np.stack([good, inside]), scene.statics) == "tunnelled (static 2, frame 1)"


def test_area_drift_and_energy_growth_detectors():
    time = np.array([0.0, 0.5, 1.0])
    target = np.array([2.0])
    assert detect_area_drift(np.array([[1.0], [2.0], [2.0 * (1 + AREA_DRIFT / 2)]]), target, time) is None
    assert detect_area_drift(np.array([[2.0], [2.0], [2.6]]), target, time) == "area drift 30%"
    g = np.array([0.0, -9.81])
    mass = np.full(16, 1 / 16)
    still = np.stack([ring()] * 3)
    assert detect_energy_growth(np.zeros((3, 1)), still, mass, g, time) is None
    rising = still.copy()
    rising[2, :, 1] += 1.0  # lifted by 1 m with nothing doing the work: +9.81 J
    assert detect_energy_growth(np.zeros((3, 1)), rising, mass, g, time).startswith("energy growth 9.81")


@pytest.mark.slow
def test_every_method_runs_every_stress_scene_to_a_verdict(tmp_path):
    result = run_stress(METHODS, tmp_path, quick=True)
    verdicts = result["verdicts"]
    assert len(verdicts) == len(list(STRESS_DIR.glob("*.toml"))) * len(METHODS)
    known = ("non-finite", "inside out", "self-intersecting", "tunnelled", "area drift", "energy growth")
    for v in verdicts:  # a failure names one of the detectors, with where it fired
        assert all(reason.startswith(known) for reason in v.failures), v.failures
    by_method = {m: [v for v in verdicts if v.method == m] for m in METHODS}
    assert {v.scene for v in by_method["kot"]} == {v.scene for v in by_method["gas"]}  # every scene, every method
    assert (tmp_path / "stress.csv").exists() and (tmp_path / "stability_map.png").exists()
    assert "| scene | kot | xpbd | gas | springs |" in result["table"]
    # the exact method passes the scenes built for it (area kept, nothing tunnels)
    by = {(v.scene, v.method): v for v in verdicts}
    assert by[("crushed", "kot")].passed and by[("tall_stack", "kot")].passed
    # ... and no ring of it crosses itself or turns inside out, in any scene (self-contact, sim/self_contact.py)
    assert not any(reason.startswith(("self-intersecting", "inside out"))
                   for v in by_method["kot"] for reason in v.failures), [v.failures for v in by_method["kot"]]
