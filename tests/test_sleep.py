"""Sleeping islands (blobcli/core/sleep.c): piles at rest sleep, frozen exactly, and wake when a mover comes."""

import h5py
import numpy as np
import pytest
from conftest import (
    BLOB_PENETRATION,
    IMPACT_SETTLED,
    LAYOUT_REST_CENTRE,
    LAYOUT_REST_VERTEX,
    PILE_ASLEEP,
    PILE_REST_CENTRE,
    PILE_REST_VERTEX,
    Stage,
    blobsim,
    deepest_overlap,
    scene,
)

from blobcli import build, build_params
from blobcli.sim.pipeline import advance
from blobcli.tools.compare import compare_files

PILE = """
[scene]
sleep = {sleep}
[[blob]]
name = "pile"
center = [-0.6, 0.25]
radius = 0.2
vertices = 16
grid = [4, 3]
spacing = [0.4, 0.45]
{extra}
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "box"
center = [-1.0, 2.0]
size = [0.2, 4.0]
[[static]]
kind = "box"
center = [1.0, 2.0]
size = [0.2, 4.0]
"""
LATE_BLOB = """
[[blob]]
name = "late"
center = [7.5, 4.4]
radius = 0.2
vertices = 16
velocity = [-1.0, 0.0]
[[static]]
kind = "box"
center = [4.3, 4.1]
size = [7.4, 0.2]
friction = 0.0
static_friction = 0.0
"""  # slides along a frictionless ledge above the pile's right wall at 1 m/s, leaves it at x = 0.6 about 6.9 s
#     after the start and lands on the pile (asleep from about 5.5 s) at some 8 m/s, about 7.5 s after the start;
#     the heap is asleep again by about 14 s.
#     (Dropped from 247 m to arrive as late, it hit at 70 m/s and crushed the top blob of its column: where it
#     ended, on the column or wedged into a gap, turned on millimetres.)


def run(text, seconds):
    s = scene(text)
    model, state = build(s)
    params = build_params(s)
    advance(state, model, params, int(round(seconds / params.dt)))
    return model, state, params


def centre_speeds(model, state):
    return np.hypot(*(np.add.reduceat(state.vel, model.offsets[:-1]) / np.diff(model.offsets)[:, None]).T)


def test_a_pile_at_rest_falls_asleep_frozen_exactly():
    model, state, params = run(PILE.format(sleep="true", extra=""), 6.0)
    assert state.awake.sum() <= (1 - PILE_ASLEEP) * model.blob_count, state.awake
    asleep = state.awake == 0
    frozen = state.pos.copy()
    advance(state, model, params, 60)
    sleeping_vertices = asleep[model.blob_of]
    assert np.array_equal(state.pos[sleeping_vertices], frozen[sleeping_vertices])  # bit for bit
    assert not state.vel[sleeping_vertices].any()


def test_without_sleeping_the_same_pile_is_still():
    model, state, _ = run(PILE.format(sleep="false", extra=""), 6.0)
    assert state.awake.all()
    assert centre_speeds(model, state).max() < PILE_REST_CENTRE
    assert np.hypot(*state.vel.T).max() < PILE_REST_VERTEX


@pytest.mark.slow
def test_a_pile_of_60_is_at_rest_14_s_after_the_drop_without_sleeping():
    """Issue 12's target on the pile of `python -m blobcli.tools.piles` (60 blobs of 32 vertices dropped
    into a box), over the whole second 13-14, not one frame: measured 0.05 / 3.2 mm/s. Without stick
    points (static friction held only within a substep) a vertex reached 35.9 mm/s in that second."""
    from blobcli.tools.bench import scene_text
    model, state, params = run(scene_text(60, "piled"), 13.0)
    for _ in range(60):
        advance(state, model, params, 1)
        assert centre_speeds(model, state).max() < PILE_REST_CENTRE
        assert np.hypot(*state.vel.T).max() < PILE_REST_VERTEX


@pytest.mark.slow
@pytest.mark.parametrize("layout", ["offset-91", "tilted-48", "tilted-60", "plane-300"])
def test_piles_unlike_the_benchs_own_come_to_rest(layout):
    """Piles of tools/piles.LAYOUTS (segment and plane floors, a floor tilted 4°, 24-48 vertices, 48-300 blobs),
    sleeping off, over the last second before their time (about 12 s after their last blob landed). Contacts
    that bounded each iteration's friction correction by μ_s D instead of the substep's sum slid and crept:
    offset-91 moved at 4.6 / 10.9 mm/s in second 15-16."""
    from blobcli.tools.piles import LAYOUTS, fastest
    text, seconds = LAYOUTS[layout]
    model, state, params = run(text(), seconds - 1.0)
    centre, vertex, _ = fastest(state, model, params, int(round(1.0 / params.dt)))
    assert centre < LAYOUT_REST_CENTRE and vertex < LAYOUT_REST_VERTEX, (centre, vertex)


@pytest.mark.slow
@pytest.mark.parametrize("layout, seconds", [("tilted-60", 14.0), ("plane-300", 14.0)])
def test_piles_unlike_the_benchs_own_fall_asleep(layout, seconds):
    """With sleeping on, a 60-blob pile on a tilted floor is asleep at 14 s, and a 300-blob pile (its last blob
    lands at about 3 s) 10 s after it."""
    from blobcli.scene.schema import parse_scene
    from blobcli.tools.piles import LAYOUTS, sleep_setting
    s = sleep_setting(parse_scene(LAYOUTS[layout][0](), layout), True)
    model, state = build(s)
    params = build_params(s)
    advance(state, model, params, int(round(seconds / params.dt)))
    assert state.awake.sum() <= (1 - PILE_ASLEEP) * model.blob_count


def test_piles_perturb_moves_each_blob_rigidly_within_eps_by_its_seed():
    """`tools/piles --perturb EPS --seed S`: each blob moved as a whole by up to EPS per axis before the drop, the same
    offsets for the same seed, others for another (the rest of a pile from a grid start is a property of that start
    only: its columns are mirror images of each other)."""
    from blobcli.scene.schema import parse_scene
    from blobcli.tools.piles import LAYOUTS, _run
    scene = parse_scene(LAYOUTS["tilted-48"][0](), "tilted-48")
    model, start, _, _ = _run(scene, 0.0)
    offsets = {}
    for seed in (1, 1, 2):
        _, state, _, _ = _run(scene, 0.0, perturb=0.01, seed=seed)
        moved = state.pos - start.pos
        per_blob = np.array([moved[o] for o in model.offsets[:-1]])
        assert np.all(np.abs(per_blob) <= 0.01) and np.abs(per_blob).max() > 0.005
        assert np.allclose(moved, np.repeat(per_blob, np.diff(model.offsets), axis=0), rtol=0, atol=1e-12)  # rigidly
        offsets.setdefault(seed, per_blob)
        assert np.array_equal(per_blob, offsets[seed])
    assert not np.array_equal(offsets[1], offsets[2])


def test_the_smallest_scenes_that_do_not_rest_run():
    """`tools/piles --smallest`: one blob nudged on a floor, three in a wedge, at a fixed substep count (docs/physics.md,
    Known limits, measures them for 20 s)."""
    from blobcli.tools.piles import SMALLEST, smallest
    for name in SMALLEST:
        rows = smallest(name, 4, seconds=2)
        assert [second for second, *_ in rows] == [1] and np.isfinite(rows[0][1:]).all()


def test_a_blob_landing_on_a_sleeping_pile_wakes_it():
    text = PILE.format(sleep="true", extra=LATE_BLOB)
    s = scene(text)
    model, state = build(s)
    params = build_params(s)
    late = model.names.index("late")
    awake_before_landing = woken = None
    for second in range(1, 17):
        advance(state, model, params, 60)
        if second == 6:  # the pile has slept; the late blob is still on its ledge
            awake_before_landing = state.awake.copy()
        if second == 8:  # it has landed: its island is awake
            woken = state.awake.copy()
    assert awake_before_landing[late] and awake_before_landing.sum() == 1
    assert woken.sum() > 1
    top_row = max(state.pos[model.offsets[b]:model.offsets[b + 1], 1].mean() for b in range(late))
    assert state.pos[model.offsets[late]:model.offsets[late + 1], 1].mean() > top_row  # on the pile ...
    assert deepest_overlap(state, model) < BLOB_PENETRATION  # ... not in a blob
    assert state.awake.sum() == 0  # and the whole heap sleeps again


def test_how_the_steps_are_split_into_calls_does_not_change_a_bit():
    """blobsim run grows its compiled calls to a wall time: a blob landing on a sleeping pile must come
    out the same whether the steps ran in one call or one by one."""
    s = scene(PILE.format(sleep="true", extra=LATE_BLOB))
    runs = []
    for calls in (1, 540):
        model, state = build(s)
        params = build_params(s)
        for _ in range(calls):
            advance(state, model, params, 540 // calls)
        runs.append(state.pos.copy())
    assert np.array_equal(*runs)


def test_a_spinning_blob_does_not_sleep():
    model, state, _ = run("""
[scene]
gravity = [0.0, 0.0]
damping = 0.0
[[blob]]
center = [0.0, 0.0]
radius = 0.3
angular_velocity = 0.1
""", 3.0)  # the centre stays put, but the rim moves at 30 mm/s
    assert state.awake.all()


def sleep_rule(n, r, xs, pairs, sleep_speed, time_to_sleep, dt):
    """Blobs of n vertices and radius r centred at (x, 0) for x in xs, with bc_update_sleep (core/sleep.c) on them
    over these pairs of the broad phase (the scratch's pairs and pair_count): the state, and a call of one step's
    sleep bookkeeping on the state's positions and velocities (no contacts: contact depth 0, no contact edges;
    the previous positions the current ones)."""
    model, state = build(scene("".join(f"[[blob]]\ncenter = [{x}, 0.0]\nradius = {r}\nvertices = {n}\n"
                                       for x in xs)))
    stage = Stage(model, state, scratch=True)
    c = stage.views.settings
    c.sleep_speed, c.time_to_sleep, c.dt = sleep_speed, time_to_sleep, dt
    for k, (a, b) in enumerate(pairs):
        stage.scratch.pairs[2 * k], stage.scratch.pairs[2 * k + 1] = a, b
    stage.scratch.pair_count = len(pairs)

    def update_sleep():
        state.previous[...] = state.position
        state.contact_depth[...], state.contact_material[...], state.c_edge[...] = 0.0, 0.0, -1
        return stage.call("update_sleep")

    return state, update_sleep


def test_a_blob_is_still_while_it_goes_nowhere_on_average():
    """The rule of core/sleep.c (bc_update_sleep) on its own (each blob its own island): a blob that rocks in place
    at 4× sleep_speed (the bottom row of a large pile does) sleeps after time_to_sleep, one that creeps at 0.8×
    sleep_speed sleeps too, and one that creeps at 1.2× never does. Tested on the speed at each step,
    the rocking blob never slept."""
    n, r, dt, sleep_speed, time_to_sleep = 16, 0.2, 1.0 / 60.0, 0.005, 1.0
    theta = 2 * np.pi * np.arange(n) / n
    ring = r * np.stack([np.cos(theta), np.sin(theta)])
    state, update_sleep = sleep_rule(n, r, (0.0, 1.0, 2.0), [], sleep_speed, time_to_sleep, dt)
    pos, vel, awake = state.position, state.velocity, state.awake
    pos[...] = np.concatenate([ring + [[x], [0.0]] for x in (0.0, 1.0, 2.0)], axis=1)
    awake[...], state.still[...] = 1, 0.0
    state.still_center[...], state.still_angle[...] = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 0.0
    spin = 4 * sleep_speed / r  # rad/s: the rim at 4 × sleep_speed
    asleep_at = [None] * 3
    for k in range(int(3 * time_to_sleep / dt)):
        vel[...] = 0.0
        w = spin if k % 2 == 0 else -spin  # rocking: a step one way, a step back
        vel[0, :n], vel[1, :n] = -w * ring[1], w * ring[0]
        vel[0, n:2 * n] = 0.8 * sleep_speed
        vel[0, 2 * n:] = 1.2 * sleep_speed
        pos += vel * dt * awake.repeat(n)
        update_sleep()
        for b in range(3):
            if asleep_at[b] is None and not awake[b]:
                asleep_at[b] = (k + 1) * dt
    assert asleep_at[0] == pytest.approx(time_to_sleep, abs=2 * dt)
    assert asleep_at[1] == pytest.approx(time_to_sleep, abs=2 * dt)
    assert asleep_at[2] is None


def test_an_island_of_blobs_creeping_slower_than_sleep_speed_sleeps():
    """Two blobs of one island creep at 0.8 × sleep_speed, the second's still time begun 2.5 mm behind it:
    measured from where their still times began, each would pass d = 5 mm every 1.25 s, out of step, and
    never both have time_to_sleep at once (the island never slept). Each window measured from where the
    last one ended, both are still: the island sleeps once the second has had time_to_sleep, at 1.625 s."""
    n, r, dt, sleep_speed, time_to_sleep = 16, 0.2, 1.0 / 60.0, 0.005, 1.0
    theta = 2 * np.pi * np.arange(n) / n
    ring = r * np.stack([np.cos(theta), np.sin(theta)])
    state, update_sleep = sleep_rule(n, r, (0.0, 0.41), [(0, 1)], sleep_speed, time_to_sleep, dt)
    pos, awake = state.position, state.awake
    pos[...] = np.concatenate([ring + [[x], [0.0]] for x in (0.0, 0.41)], axis=1)
    awake[...], state.still[...] = 1, 0.0
    state.still_center[...], state.still_angle[...] = [[0.0, 0.0], [0.41 - 0.0025, 0.0]], 0.0
    vel = np.zeros((2, 2 * n))
    vel[0] = 0.8 * sleep_speed
    for k in range(int(6 * time_to_sleep / dt)):
        pos += vel * dt * awake.repeat(n)
        state.velocity[...] = vel
        update_sleep()
        if not awake.any():
            break
    assert not awake.any() and (k + 1) * dt == pytest.approx(1.625, abs=2 * dt)


def test_the_file_records_who_is_awake_and_resumes_the_sleep_state(tmp_path):
    path = tmp_path / "pile.toml"
    path.write_text(PILE.format(sleep="true", extra=""))
    fresh, resumed = tmp_path / "fresh.h5", tmp_path / "resumed.h5"
    assert blobsim("run", path, "-o", fresh, "--steps", "420", "-q").returncode == 0
    with h5py.File(fresh) as f:
        awake = f["observables/awake/value"][...]
        assert awake.dtype == np.uint8 and awake.shape == (421, 12)
        assert awake[0].all() and not awake[-1].any()
        assert np.array_equal(f["restart/awake"][...], awake[-1])
    # stopped at 5 s, before the pile sleeps, and resumed: the still timers carry over, bit for bit
    assert blobsim("run", path, "-o", resumed, "--steps", "300", "-q").returncode == 0
    assert blobsim("run", path, "--resume", resumed, "--steps", "420", "-q").returncode == 0
    assert compare_files(fresh, resumed).same
    with h5py.File(resumed) as f:
        assert np.array_equal(f["observables/awake/value"][...], awake)


@pytest.mark.parametrize("key, value, message", [("sleep", '"yes"', "must be true or false"),
                                                 ("sleep_speed", "0.0", "must be >= 1e-09"),
                                                 ("time_to_sleep", "-1.0", "must be >= 0.1")])
def test_bad_sleep_settings_are_refused(tmp_path, key, value, message):
    path = tmp_path / "bad.toml"
    path.write_text(f"[scene]\n{key} = {value}\n[[blob]]\ncenter = [0.0, 1.0]\nradius = 0.3\n")
    r = blobsim("run", path, "-o", tmp_path / "x.h5")
    assert r.returncode == 2 and f"bad.toml:2: scene.{key}: {message}" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "x.h5").exists()


@pytest.mark.slow
def test_a_blob_dropped_onto_a_resting_pile_leaves_the_far_blobs_at_rest_within_two_seconds():
    """`python -m blobcli.tools.piles --impact`: the 60-blob pile at rest, a blob dropped onto its end from about
    3 m. The impact shoves the far blobs (it reached them: the dropped blob fell onto the pile), and two seconds
    later they are at rest again."""
    from blobcli.tools.piles import impact
    rows = impact(60)
    assert len(rows) == 9 and rows[-1][0] == pytest.approx(2.0)
    assert max(centre for _, centre, _ in rows) > 0.05
    assert rows[-1][1] < IMPACT_SETTLED, f"{1e3 * rows[-1][1]:.2f} mm/s two seconds after the impact"
