"""Adhesion: a sticky blob hangs from a ceiling until its load passes adhesion × its contact
length, and lets go on command; it stays on a wall when its adhesion holds and slides when it does not; it never
makes energy (a bouncy drop onto a sticky floor, a pull off it); two sticky blobs stay together, momentum kept; and
the Gish level (scenes/gish_level.toml) does what it says, resumes mid-climb bit for bit, on any thread count."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import (
    FACE_HOLD,
    FLAT_TOP_HOLD,
    MOMENTUM_ROUNDOFF,
    NOT_PULLED,
    RECORDED_PULL,
    WALL_HOLD,
    face_drift,
    on_face,
    scene,
)

from blobcli import build, build_params, simulate
from blobcli.core import load
from blobcli.io import threads as threads_module
from blobcli.scene.schema import SceneError, parse_scene, with_overrides
from blobcli.sim.pipeline import advance
from blobcli.tools.adhesion import (
    CEILING,
    FACE,
    LEVEL,
    G,
    drop,
    face_shares,
    flat_top,
    hang,
    pair,
    play,
    pull_off,
    range_of,
    wall_drift,
)
from blobcli.tools.compare import compare_files

_, lib = load()
ROOT = Path(__file__).resolve().parent.parent


def test_a_sticky_blob_lets_go_once_its_load_passes_adhesion_times_its_contact_length():
    """A flat-topped blob hanging by its face from a box, its mass raised 0.2 kg/s: the heaviest load it carried (its
    weight the step before a vertex left the ceiling's range, and the ceiling's recorded pull) is within adhesion ×
    its contact length then, and twice the adhesion carries about twice the load."""
    weak, strong = hang(20.0), hang(40.0)
    for a, h in ((20.0, weak), (40.0, strong)):
        assert h["let_go"] is not None and h["let_go"] > 1.0
        assert h["load"] <= a * h["length"]
        assert h["pull"] <= a * h["length"]
    assert 1.6 * weak["load"] < strong["load"] < 2.4 * weak["load"]


def test_a_flat_topped_blob_peels_from_its_corners():
    """It lets go at 0.4 of adhesion × its face (docs/physics.md, "Adhesion": the law holds each vertex to a ℓ_i, and
    the skin's tension meets the ceiling at the face's two corners, which take nearly all of the load): the
    ceiling, cut into one box per face vertex, records the corners at their cap and the face between them carrying
    a tenth of it, and the pulls add up to the weight."""
    h = hang(20.0)
    assert FLAT_TOP_HOLD[0] < h["load"] / (20.0 * FACE) < FLAT_TOP_HOLD[1]
    pulls = face_shares(20.0, 0.5)
    cap = 20.0 * 0.5 * (0.1 + np.hypot(*(np.array(flat_top()[-1]) - flat_top()[0])))  # a ℓ of a corner
    assert pulls.sum() == pytest.approx(0.5 * G, rel=RECORDED_PULL)
    assert pulls[0] == pytest.approx(cap, rel=0.02) and pulls[-1] == pytest.approx(cap, rel=0.02)
    assert pulls[1:-1].max() < 0.1 * cap


def test_a_blob_without_adhesion_falls_at_once():
    h = hang(0.0)
    assert h["let_go"] is not None and h["let_go"] < 0.1


def hold_scene(ceiling: str, blob_adhesion: float, ceiling_adhesion: float, top: float = CEILING) -> str:
    return (f"[scene]\nduration = 2.5\nsleep = false\n[[blob]]\npoints = {flat_top(top=top)}\nmass = 0.2\n"
            f"adhesion = {blob_adhesion!r}\n[[static]]\n{ceiling}\nadhesion = {ceiling_adhesion!r}\n")


KINDS = {  # each kind's underside at y = 1 (a circle's lowest point), the blob's face on it (a segment's 1 mm below)
    "plane": 'kind = "plane"\npoint = [0.0, 1.0]\nnormal = [0.0, -1.0]',
    "segment": 'kind = "segment"\na = [-1.0, 1.0]\nb = [1.0, 1.0]',
    "box": 'kind = "box"\ncenter = [0.0, 1.1]\nsize = [4.0, 0.2]',
    "polygon": 'kind = "polygon"\npoints = [[-1.0, 1.0], [1.0, 1.0], [0.0, 1.5]]',
    "circle": 'kind = "circle"\ncenter = [0.0, 2.0]\nradius = 1.0',
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("sticky", ["blob", "collider"])
def test_every_collider_kind_holds_a_sticky_blob_and_records_its_weight(kind, sticky):
    """A sticky collider holds a clean blob, a clean one a sticky blob (adhesion combines as the max), its recorded
    force the weight it holds (on average over the last second of 2.5); with neither sticky the blob falls."""
    top = CEILING - 1e-3 if kind == "segment" else CEILING  # (a vertex on a segment's line takes a side at random)
    for a in (40.0, 0.0):
        text = hold_scene(KINDS[kind], a if sticky == "blob" else 0.0, a if sticky == "collider" else 0.0, top)
        sc = scene(text)
        model, state = build(sc)
        params = build_params(sc)
        advance(state, model, params, params.steps - 60)
        pull = 0.0
        for _ in range(60):  # over the last second (a blob held at one vertex, under a circle, swings)
            advance(state, model, params, 1)
            pull -= state.static_impulse[0, 1] / params.dt / 60
        if a > 0.0:
            assert state.pos[:, 1].max() > top - range_of(model)
            assert pull == pytest.approx(0.2 * G, rel=RECORDED_PULL)
        else:
            assert state.pos[:, 1].max() < 0.0


def test_a_blob_turns_sticky_and_lets_go_on_command():
    """blob.NAME.adhesion scheduled 30 N/m until 1 s, then 0: the blob hangs, then falls within the next 0.1 s."""
    text = hold_scene(KINDS["box"], 30.0, 0.0) + ('[[schedule]]\nkey = "blob.blob0.adhesion"\n'
                                                    "at = [[1.0, 30.0], [1.0166666666666666, 0.0]]\n")
    from blobcli.sim.schedule import Schedules
    sc = scene(text)
    model, state = build(sc)
    params = build_params(sc)
    schedules = Schedules(sc, model, params)
    r, held = range_of(model), []
    for step in range(params.steps):
        advance(state, model, params, 1, step_settings=schedules.apply(step, None, state), arrays=schedules.arrays)
        held.append(CEILING - state.pos[:, 1].max() <= r)
    t = (np.arange(params.steps) + 1) * params.dt
    assert all(h for h, when in zip(held, t) if when <= 1.0)
    assert not any(h for h, when in zip(held, t) if when >= 1.1)


def test_a_sticky_blob_stays_on_a_wall_when_its_adhesion_holds_and_slides_when_it_does_not():
    """A 1 kg flat-sided blob on a vertical wall, sleeping off: at 300 N/m it stays (over 5 s after 3 s of settling);
    at 100 N/m its top corner peels and it slides down (docs/physics.md: it holds from about 150 N/m, not from the
    18 N/m that friction μ_s a L against its weight would need)."""
    assert wall_drift(300.0, settle=3.0) < WALL_HOLD
    assert wall_drift(100.0, settle=3.0) > 1.0


@pytest.mark.parametrize("collider, turn", [(c, t) for c in ("box", "polygon") for t in (0, 90, 180, 270)]
                         + [("box", 30), ("box", 210), ("polygon", 120), ("polygon", 300)])
@pytest.mark.parametrize("mirrored", [False, True])
def test_a_sticky_blob_holds_alike_on_any_face_turned_or_mirrored(collider, turn, mirrored):
    """The wall case above (1 kg, 300 N/m, its weight along the face) on the top face of a box or polygon, the whole
    scene turned and mirrored: every image of it stays (a rotation or a mirror of a scene moves its blobs the same
    way). Static friction against the adhesion's press is what holds it, at a point on the face, exactly on an
    axis-aligned one, where the crossing test's half-open rule reads a face solid toward +x or +y (turn 90, 180) as
    inside the collider."""
    points = [[-x, CEILING - y] for x, y in flat_top()]  # flat face down on y = 0
    text = on_face("adhesion = 300.0\n", points, [-G, 0.0], collider, turn, mirrored)
    assert face_drift(text) < FACE_HOLD


def test_a_blob_at_rest_near_a_sticky_surface_is_not_pulled_onto_it():
    """Zero gravity, a blob at rest 5 mm under a sticky ceiling (within range, 9.8 mm): the hold acts only against
    separation and never pulls a gap shut, so nothing moves but by round-off (a pull toward the surface would be
    energy from nowhere)."""
    sc = scene(hold_scene(KINDS["box"], 100.0, 100.0, top=CEILING - 5e-3).replace("[scene]\n",
                                                                                  "[scene]\ngravity = [0.0, 0.0]\n"))
    model, state = build(sc)
    before = state.pos.copy()
    assert CEILING - before[:, 1].max() < range_of(model)
    advance(state, model, build_params(sc), 60)
    assert np.abs(state.pos - before).max() < NOT_PULLED


def test_a_bouncy_drop_onto_a_sticky_floor_never_rebounds_higher():
    """A stiff blob at e = 1, damping 0, dropped 1 m: onto a sticky floor (50 N/m) every peak stays below the drop
    and below the first peak off a clean floor: adhesion never makes energy."""
    rest, clean = drop(0.0)
    rest_sticky, sticky = drop(50.0)
    assert len(sticky) >= 3
    assert sticky.max() - rest_sticky <= 1.0
    assert sticky[0] - rest_sticky < clean[0] - rest


def test_pulling_a_blob_off_a_sticky_floor_leaves_it_less_energy_than_the_pull_gave():
    """A blob at rest on a floor, damping 0, pulled up by 30 N for 0.3 s: its energy afterwards (kinetic and
    potential) rose by less than the drive's work, by more on a sticky floor (50 N/m) than on a clean one."""
    clean_gain, clean_work, _ = pull_off(0.0)
    gain, work, lowest = pull_off(50.0)
    assert lowest > 0.1  # it came off
    assert gain - work < 0.0
    assert gain - work < clean_gain - clean_work


def test_two_sticky_blobs_meet_and_stay_together_with_their_momentum():
    """Zero gravity, e = 1: clean blobs bounce apart, sticky ones (50 N/m) stay in contact; the total momentum
    (0.2 kg m/s) is kept to round-off, the pulls being equal and opposite."""
    apart, _, _ = pair(0.0)
    together, drift, p0 = pair(50.0)
    assert apart > 1.5
    assert together < 1.05  # centres of two r = 0.5 m blobs: touching, squashed a little
    assert p0[0] == pytest.approx(0.2)
    assert drift < MOMENTUM_ROUNDOFF * 3.0


def test_a_scene_without_adhesion_never_runs_the_stage():
    """No blob or collider sticky: the step skips the adhesion stage (its clock stays 0); a sticky blob runs it."""
    for a, runs in ((0.0, False), (10.0, True)):
        sc = scene(hold_scene(KINDS["box"], a, 0.0))
        model, state = build(sc)
        clock = {}
        advance(state, model, build_params(sc), 10, clock=clock)
        assert (clock["adhesion"] > 0.0) == runs


@pytest.mark.parametrize("text, message", [
    ("adhesion = -1.0\n", "s.toml:7: blob[0].adhesion: must be >= 0 (got -1.0)"),
    ("[[static]]\nkind = \"plane\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\nadhesion = -2.0\n",
     "s.toml:11: static[0].adhesion: must be >= 0 (got -2.0)"),
    ("[[schedule]]\nkey = \"blob.gish.adhesion\"\nat = [[0.0, 5.0], [1.0, -5.0]]\n",
     "s.toml:9: schedule[0].at[1]: adhesion must be >= 0 (got -5.0)"),
])
def test_adhesion_out_of_bounds_is_refused_with_its_line(text, message):
    base = "[scene]\ngravity = [0.0, 0.0]\n[[blob]]\nname = \"gish\"\ncenter = [0.0, 0.0]\nradius = 0.5\n"
    with pytest.raises(SceneError) as e:
        parse_scene(base + text, "s.toml")
    assert e.value.problems[0] == message, e.value.problems


# --- the Gish level ----------------------------------------------------------------------------------------------

def level_text(**changes) -> str:
    text = (ROOT / LEVEL).read_text()
    for old, new in changes.values():
        assert old in text
        text = text.replace(old, new)
    return text


NO_ADHESION = ("at = [[2.5, 0.0], [2.6, 120.0], [4.1, 120.0], [4.2, 0.0]]", "at = [[2.5, 0.0]]")
LIGHT = ("at = [[4.9, 1.0], [5.3, 4.0]]", "at = [[4.9, 1.0]]")
PIT = (0.0, 1.5)  # m: the pit between the ledge's wall and the floor Gish starts on
LEDGE = 1.5  # m: the ledge's top by the wall


def test_the_gish_level_rolls_jumps_sticks_climbs_and_pushes():
    """Gish crosses the pit in the air, climbs the wall (its centre above the ledge's top while beside the wall),
    ends on the ledge, heavy, having pushed the boulder 1 m along and up the slope; no ring crosses itself and
    every area stays within 1% at every step. Without adhesion it falls into the pit; light, it cannot push the
    boulder up the slope (it spins at its foot)."""
    run = play(level_text())
    gish, boulder = run["centres"][:, 0], run["centres"][:, 1]
    over_pit = (gish[:, 0] > PIT[0] + 0.5) & (gish[:, 0] < PIT[1]) & (gish[:, 1] > 0.3)
    assert over_pit.any()  # in the air above the pit (its floor is 3 m down)
    on_wall = (gish[:, 0] > PIT[0]) & (gish[:, 0] < PIT[0] + 0.6) & (gish[:, 1] > LEDGE - 0.2)
    assert on_wall.any()  # beside the wall, up at the ledge's height
    assert gish[-1, 0] < -2.0 and gish[-1, 1] > LEDGE + 0.3  # on the ledge
    assert run["masses"][0] == 4.0
    settled = boulder[round(1.0 / run["dt"])]  # (it sags a little at first)
    assert boulder[-1, 0] < settled[0] - 1.0 and boulder[-1, 1] > settled[1] + 0.15
    assert run["fault"] == ""
    assert run["area_error"] < 0.01
    fallen = play(level_text(adhesion=NO_ADHESION))["centres"]
    assert fallen[-1, 0, 1] < -1.0  # in the pit
    light = play(level_text(mass=LIGHT))["centres"]
    assert light[-1, 1, 0] > boulder[-1, 0] + 0.8  # the boulder is far less far along


def test_the_gish_level_resumes_mid_climb_bit_identically(tmp_path):
    """Stopped at 3.3 s (step 198: on the wall, sticky, climbing), resumed to the end: the same bits as one run."""
    sc = parse_scene(level_text(), "gish_level.toml")
    whole, first, resumed = tmp_path / "whole.h5", tmp_path / "first.h5", tmp_path / "resumed.h5"
    simulate(sc, whole)
    simulate(with_overrides(sc, steps=198), first)
    assert simulate(sc, resumed, resume=first).status == "complete"
    report = compare_files(whole, resumed)
    assert report.same, report.text()
    with h5py.File(whole) as a, h5py.File(resumed) as b:
        for name in ("restart/position", "restart/velocity"):
            assert np.array_equal(a[name][...], b[name][...]), name
        gish = a["particles/blobs/position/value"][198, :32]
    assert PIT[0] < gish[:, 0].mean() < PIT[0] + 0.6 and gish[:, 1].mean() > 0.5  # mid-climb, on the wall


@pytest.mark.slow
def test_one_and_two_threads_give_the_same_bits(tmp_path):
    """The Gish level (serial: 2 blobs), and 36 sticky blobs raining onto a sticky floor and each other (the
    parallel build, from 32 blobs; the collider pulls split over threads, the blob pairs' in vertex order)."""
    if not lib.bc_has_openmp() or threads_module.available() < 2:
        pytest.skip("the core has one thread here")
    rain = parse_scene("""
[scene]
steps = 24
[[blob]]
name = "rain"
center = [-1.5, 0.25]
radius = 0.2
grid = [6, 6]
spacing = [0.45, 0.45]
adhesion = 40.0
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
adhesion = 20.0
""", "rain.toml")
    assert build(rain)[0].parallel
    for name, sc in (("level", parse_scene(level_text(), "gish_level.toml")), ("rain", rain)):
        assert simulate(sc, tmp_path / f"{name}1.h5", threads=1).status == "complete"
        assert simulate(sc, tmp_path / f"{name}2.h5", threads=2).status == "complete"
        report = compare_files(tmp_path / f"{name}1.h5", tmp_path / f"{name}2.h5")
        assert report.same, (name, report.text())
