"""Driving forces and torques on blobs: `force` and `torque`, constant or scheduled
(a player's input), give the momentum and angular momentum they should, resume and thread counts change no bit,
and a torque rolls a ring up a slope or lets it roll back."""

import h5py
import numpy as np
import pytest
from conftest import DRIVEN_MOMENTUM, DRIVEN_SLOPE, scene

from blobcli import build, build_params, simulate
from blobcli.core import load
from blobcli.io import threads as threads_module
from blobcli.scene.schema import SceneError, parse_scene, with_overrides
from blobcli.sim.pipeline import advance
from blobcli.sim.schedule import Schedules
from blobcli.tools.compare import compare_files
from blobcli.tools.driving import IRREGULAR, free_blob, jump, momenta, slope_speed

_, lib = load()
RADIUS = 0.5  # m: free_blob's ring (the hexagon's farthest vertex is 0.74 m from its vertex mean)
BLOB = """[scene]
gravity = [0.0, 0.0]
[[blob]]
name = "gish"
center = [0.0, 0.0]
radius = 0.5
"""


def test_a_force_gives_the_momentum_F_T():
    P, L, FT, _ = free_blob(force=(3.0, -1.5))
    assert np.hypot(*(P - FT)) < DRIVEN_MOMENTUM * np.hypot(*FT)
    assert abs(L) < DRIVEN_MOMENTUM * np.hypot(*FT) * RADIUS


SHAPES = {"ring": None, "lopsided hexagon": IRREGULAR}  # on a ring, f_i ∝ ẑ × r̂_i / |r_i| (equal tangential
#   forces) would also give τ and about no force; on the hexagon only the shares ∝ m_i |r_i| give both exactly


@pytest.mark.parametrize("shape", SHAPES)
def test_a_torque_gives_the_angular_momentum_tau_T_and_no_momentum(shape):
    P, L, _, tT = free_blob(torque=0.7, points=SHAPES[shape])
    assert abs(L - tT) < DRIVEN_MOMENTUM * tT
    assert np.hypot(*P) < DRIVEN_MOMENTUM * tT / RADIUS


@pytest.mark.parametrize("shape", SHAPES)
def test_a_force_and_a_torque_together_add(shape):
    P, L, FT, tT = free_blob(force=(3.0, -1.5), torque=-0.7, points=SHAPES[shape])
    assert np.hypot(*(P - FT)) < DRIVEN_MOMENTUM * np.hypot(*FT)
    assert abs(L - tT) < DRIVEN_MOMENTUM * abs(tT)


def test_a_blob_driven_from_rest_takes_the_substeps_its_drive_needs():
    """The substep rule counts the speed a drive adds over the step, as it counts g dt: from rest, 2,000 N on 1 kg
    (r = 0.5 m, 32 vertices, no gravity) reaches a dt = 33 m/s within a step of 1/60 s, at which a substep of the
    scene's 4 moves it 1.4 mean edges L; the rule takes ⌈a dt · dt / (½ L)⌉ = 12."""
    sc = scene(BLOB + "force = [1600.0, -1200.0]\n")
    model, state = build(sc)
    advance(state, model, build_params(sc), 1)
    edge = model.rest_perimeter[0] / 32
    assert state.substeps_taken[0] == int(np.ceil(2000.0 / 60 ** 2 / (0.5 * edge))) == 12


PULSE = """
[scene]
dt = 0.015625
gravity = [0.0, 0.0]
[[blob]]
name = "gish"
center = [0.0, 0.0]
radius = 0.5
mass = 1.5
[[schedule]]
key = "blob.gish.force"
at = [[0.25, 0.0, 0.0], [0.3125, 4.0, 2.0], [0.5, 4.0, 2.0], [0.5625, 0.0, 0.0]]
[[schedule]]
key = "blob.gish.torque"
at = [[0.125, 0.0], [0.25, -0.9], [0.375, 0.0]]
"""


def test_a_scheduled_pulse_gives_the_impulse_of_its_keyframes():
    """The schedule's value at t = step × dt acts through the step: keyframes at multiples of dt (1/64 s here),
    ramps of several steps, the pulse from 0 back to 0: the blob gains the area under the keyframes' line."""
    sc = scene(PULSE)
    model, state = build(sc)
    params = build_params(sc)
    schedules = Schedules(sc, model, params)
    for step in range(64):  # 1 s
        advance(state, model, params, 1, step_settings=schedules.apply(step, None, state), arrays=schedules.arrays)
    P, L = momenta(state, model)
    impulse = np.array([4.0, 2.0]) * (0.5 - 0.3125 + 0.0625)  # plateau + two half ramps
    assert np.hypot(*(P - impulse)) < DRIVEN_MOMENTUM * np.hypot(*impulse)
    angular = -0.9 * 0.125  # a triangle: half of 0.25 s × 0.9 N m
    assert abs(L - angular) < DRIVEN_MOMENTUM * abs(angular)


RESUMED = """
[scene]
steps = 90
[[blob]]
name = "gish"
center = [0.0, 0.6]
radius = 0.5
friction = 1.0
force = [1.5, 0.0]
[[schedule]]
key = "blob.gish.force"
at = [[0.3, 0.0, 0.0], [0.35, 0.0, 40.0], [1.0, 0.0, 40.0], [1.05, 0.0, 0.0]]
[[schedule]]
key = "blob.gish.torque"
at = [[0.0, 2.0], [1.5, -2.0]]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def test_a_run_stopped_mid_pulse_resumes_bit_identically(tmp_path):
    """A jump held from 0.35 to 1 s and a rolling torque: stopped at step 40 (0.67 s, mid-pulse, airborne), resumed
    to 90; the driving values are the schedule's at each step, so they need no place in /restart."""
    sc = parse_scene(RESUMED, "jump.toml")
    whole, first, resumed = tmp_path / "whole.h5", tmp_path / "first.h5", tmp_path / "resumed.h5"
    simulate(sc, whole)
    simulate(with_overrides(sc, steps=40), first)
    assert simulate(sc, resumed, resume=first).status == "complete"
    report = compare_files(whole, resumed)
    assert report.same and report.frames == 91, report.text()
    with h5py.File(whole) as a, h5py.File(resumed) as b:
        for name in ("restart/position", "restart/velocity"):
            assert np.array_equal(a[name][...], b[name][...]), name
        y = a["particles/blobs/position/value"][:, :, 1].mean(axis=1)
    assert y[40] > y[0] + 0.2  # it jumped: stopped mid-air


@pytest.mark.slow
def test_one_and_two_threads_give_the_same_bits(tmp_path):
    """36 driven blobs (the parallel build, from 32), each pushed, turned and pulsed, falling onto a floor for
    12 steps. (Marked slow though it takes 0.2 s: two threads wait at every stage's barrier, and with the other
    core busy a 30-step version of it took from 0.5 to 36 s.)"""
    if not lib.bc_has_openmp() or threads_module.available() < 2:
        pytest.skip("the core has one thread here")
    sc = parse_scene("""
[scene]
steps = 12
[[blob]]
name = "rain"
center = [-1.5, 0.25]
radius = 0.2
grid = [6, 6]
spacing = [0.5, 0.5]
force = [2.0, 1.0]
torque = -0.3
[[schedule]]
key = "blob.rain_*.force"
at = [[0.05, 0.0, 0.0], [0.1, 3.0, 30.0], [0.2, 0.0, 0.0]]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
""", "rain.toml")
    assert build(sc)[0].parallel
    assert simulate(sc, tmp_path / "one.h5", threads=1).status == "complete"
    assert simulate(sc, tmp_path / "two.h5", threads=2).status == "complete"
    report = compare_files(tmp_path / "one.h5", tmp_path / "two.h5")
    assert report.same, report.text()


@pytest.mark.parametrize("off", ["the floor", "another blob"])
def test_a_driven_blob_jumps_off_what_it_landed_on(off):
    """A 1 kg blob that landed (e = 0: it left its impact at 0 m/s, and the restitution rule holds it to no more
    while the contact lasts) is pushed up by 40 N for 0.3 s: 12 N s, less its weight's 3.4 N s over the pulse
    (some of which the floor bears while it still touches): 8.6 m/s and more; measured 5.5 m up off the floor,
    5.9 m off the 4 kg blob below it. The drive's work counts as energy that came in (restitution.c); without it
    the blob stayed on the floor and rose 6 cm off the blob, and without forgiving the deficit its recoil had left
    (add_work's max) it lost 4 steps of push and rose 3.0 m off the floor."""
    rise, _ = jump(off_blob=off == "another blob")
    assert rise > 4.0  # above where it rested before the push


@pytest.mark.parametrize("ratio, climbs", [(1.2, True), (0.8, False)])
def test_a_torque_rolls_a_ring_up_a_slope_or_lets_it_roll_back(ratio, climbs):
    """A default ring (friction 1) on 10°, counter-clockwise torque `ratio` × m g R sin θ: it holds at about
    1.01 (docs/physics.md, 'Driving'), so 20% above it climbs and 20% below it rolls back."""
    speed = slope_speed(ratio)  # m/s down the slope, seconds 2-6
    assert (speed < -DRIVEN_SLOPE) if climbs else (speed > DRIVEN_SLOPE)


def test_a_sleeping_blob_wakes_for_its_input():
    """A blob asleep on the floor is woken by its force schedule (a blob's schedule wakes it when its value
    changes) and jumps."""
    sc = scene("""
[scene]
steps = 240
[[blob]]
name = "gish"
center = [0.0, 0.5]
radius = 0.5
[[schedule]]
key = "blob.gish.force"
at = [[3.0, 0.0, 0.0], [3.1, 0.0, 60.0], [3.2, 0.0, 0.0]]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
""")
    model, state = build(sc)
    params = build_params(sc)
    schedules = Schedules(sc, model, params)
    highest = 0.0
    for step in range(params.steps):
        if step == 180:
            assert not state.awake[0]  # asleep by 3 s
            rest = state.pos[:, 1].mean()
        advance(state, model, params, 1, step_settings=schedules.apply(step, None, state), arrays=schedules.arrays)
        highest = max(highest, state.pos[:, 1].mean())
    assert highest > rest + 0.1


@pytest.mark.parametrize("text, message", [
    ("force = [3000.0, 0.0]\n", "s.toml:7: blob[0].force: drives gish at 3000 m/s² (|F| / M + |τ| r / I, M = 1 kg); "
     "at most 2823 m/s² here, or one step from rest moves it more than 0.5 × its edge (0.049 m) a substep at the most "
     "substeps a step takes (16) (got [3000.0, 0.0])"),
    ("torque = 1500.0\n", "s.toml:7: blob[0].torque: drives gish at 3000 m/s²"),
    ("force = [2000.0, 0.0]\n[[schedule]]\nkey = \"blob.gish.mass\"\nat = [[0.0, 1.0], [1.0, 0.5]]\n",
     "s.toml:7: blob[0].force: drives gish at 4000 m/s² (|F| / M + |τ| r / I, M = 0.5 kg)"),
    ("[[schedule]]\nkey = \"blob.gish.force\"\nat = [[0.0, 0.0, 0.0], [1.0, 0.0, 5000.0]]\n",
     "s.toml:9: schedule[0].at[1]: drives gish at 5000 m/s²"),
    ("force = [inf, 0.0]\n", "s.toml:7: blob[0].force: must be finite (got [inf, 0.0])"),
    ("torque = nan\n", "s.toml:7: blob[0].torque: must be finite (got nan)"),
    ("[[schedule]]\nkey = \"blob.gish.force\"\nat = [[0.0, 1.0]]\n",
     "s.toml:9: schedule[0].at: force keyframes are [t, Fx, Fy]: 3 numbers each (got [0.0, 1.0])"),
    ("[[schedule]]\nkey = \"blob.gish.torque\"\nat = [[0.0, 1.0, 2.0]]\n",
     "s.toml:9: schedule[0].at: keyframes are [t, value]: 2 numbers each (got [0.0, 1.0, 2.0])"),
])
def test_driving_keys_out_of_bounds_are_refused_with_their_line(text, message):
    with pytest.raises(SceneError) as e:
        parse_scene(BLOB + text, "s.toml")
    assert e.value.problems[0].startswith(message), e.value.problems


def test_a_force_a_step_can_follow_is_taken():
    parse_scene(BLOB + "force = [2800.0, 0.0]\n", "s.toml")  # just under 2823 m/s² at 16 substeps
    parse_scene(BLOB.replace("[scene]\n", "[scene]\nmax_substeps = 32\n") + "force = [5000.0, 0.0]\n", "s.toml")


def test_the_drive_bound_uses_the_substep_rules_stride():
    """scene/checks.py bounds a drive by what the substep rule can follow, with integrate.c's STRIDE: the scene layer
    does not load the step, so the two copies are held equal here."""
    import re
    from pathlib import Path

    from blobcli.scene.checks import STRIDE
    source = (Path(__file__).resolve().parents[1] / "blobcli" / "core" / "integrate.c").read_text()
    assert float(re.search(r"static const double STRIDE = ([0-9.]+);", source).group(1)) == STRIDE
