"""A periodic box: contacts across its edges are the contacts in its middle, blobs cross it whole, the
file says so the H5MD way, and an open world keeps its bits."""

import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import blobsim

from blobcli import build, build_params, parse_scene
from blobcli.geometry import ring_next
from blobcli.scene.schema import SceneError
from blobcli.sim.measure import blob_measures
from blobcli.sim.pipeline import advance
from blobcli.tools.compare import compare_files

SCENES = Path(__file__).resolve().parent.parent / "scenes"
PAIR = """[scene]
gravity = [0.0, 0.0]
{box}
[[blob]]
center = [{xa}, 0.05]
radius = 0.4
velocity = [2.0, 0.0]
angular_velocity = 1.0
[[blob]]
center = [{xb}, -0.05]
radius = 0.3
mass = 0.6
velocity = [-2.0, 0.5]
"""


def run(text, steps):
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    advance(state, model, params, steps)
    return model, state


def momentum(model, state):
    return (state.vel / model.inv_mass[:, None]).sum(axis=0)


def test_a_periodic_box_with_no_contact_across_its_edges_gives_the_open_worlds_bits():
    _, open_world = run(PAIR.format(box="", xa=-0.6, xb=0.6), 60)
    _, boxed = run(PAIR.format(box="periodic = [4.0, 3.0]", xa=-0.6, xb=0.6), 60)
    assert np.array_equal(open_world.pos, boxed.pos) and np.array_equal(open_world.vel, boxed.vel)


def test_a_pair_colliding_across_an_edge_moves_as_the_same_pair_in_the_middle():
    """The pair straddles x = ±2 (one blob at 1.4, the other at 2.6 ≡ -1.4): the nearest images meet."""
    model, middle = run(PAIR.format(box="", xa=-0.6, xb=0.6), 60)
    _, edge = run(PAIR.format(box="periodic = [4.0, 3.0]", xa=1.4, xb=-1.4), 60)
    o = model.offsets
    assert middle.blob_contact_depth.max() >= 0.0 and np.abs(middle.vel[o[1]:, 0].mean() + 2.0) > 0.5  # they met
    for b in range(2):
        seen = edge.pos[o[b]:o[b + 1]] - [2.0, 0.0]
        seen[:, 0] -= 4.0 * np.round((seen[:, 0].mean() - middle.pos[o[b]:o[b + 1], 0].mean()) / 4.0)
        assert np.abs(seen - middle.pos[o[b]:o[b + 1]]).max() < 1e-10  # round-off of the shifted coordinates
    assert np.abs(momentum(model, edge) - momentum(model, middle)).max() < 1e-10


def test_a_blob_crossing_the_box_keeps_its_area_perimeter_and_momentum():
    text = PAIR.format(box="periodic = [3.0, 2.5]", xa=0.9, xb=-0.2).replace(
        "velocity = [-2.0, 0.5]", "velocity = [0.0, 0.0]").replace("[-0.2, -0.05]", "[-0.2, -0.9]")
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    def perimeters():
        ring = state.pos[ring_next(model.offsets)] - state.pos
        return np.add.reduceat(np.hypot(ring[:, 0], ring[:, 1]), model.offsets[:-1])
    p0, a0, l0 = momentum(model, state), blob_measures(state, model)[0], perimeters()
    for _ in range(60):  # 1 s: the first blob crosses x = 1.5 (and passes the second, 0.95 m below it)
        advance(state, model, params, 1)
        assert np.allclose(blob_measures(state, model)[0], a0, rtol=1e-12, atol=0)
        assert np.allclose(perimeters(), l0, rtol=1e-3, atol=0)
    assert np.abs(momentum(model, state) - p0).max() < 1e-12
    assert state.pos[:model.offsets[1], 0].min() > 1.5  # it crossed (the state keeps it continuous)
    assert state.blob_contact_depth.max() == 0.0


def test_the_file_has_the_box_the_image_and_each_blob_whole_inside(tmp_path):
    text = PAIR.format(box="periodic = [3.0, 2.5]", xa=0.9, xb=-0.5)
    (tmp_path / "cross.toml").write_text(text)
    out = tmp_path / "cross.h5"
    r = blobsim("run", tmp_path / "cross.toml", "-o", out, "--steps", "90", "-q")
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as f:
        box = f["particles/blobs/box"]
        assert list(box.attrs["boundary"]) == [b"periodic", b"periodic"] and box.attrs["dimension"] == 2
        edges = box["edges"][...]
        assert edges.tolist() == [3.0, 2.5] and f.attrs["blobsim_format"] == 10
        pos, image = f["particles/blobs/position/value"][...], f["particles/blobs/image/value"][...]
        offsets = f["parameters/blob_offsets"][...]
    centres = np.stack([pos[:, o:e].mean(axis=1) for o, e in zip(offsets[:-1], offsets[1:])], axis=1)
    assert np.all(np.abs(centres) <= edges / 2)  # every blob's centre in the box ...
    assert image[:, :offsets[1], 0].max() == 1  # ... the first one after crossing x = 1.5
    for o, e in zip(offsets[:-1], offsets[1:]):  # ... each blob whole (one image for all its vertices)
        assert np.all(image[:, o:e] == image[:, o:o + 1])
    unwrapped = pos + image * edges
    assert np.abs(np.diff(unwrapped, axis=0)).max() < 0.05  # continuous: no jump by a box side


def test_a_box_too_small_for_its_blobs_is_bad_input():
    with pytest.raises(SceneError) as e:
        parse_scene("[scene]\nperiodic = [1.0, 3.0]\n[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.3\n", "s.toml")
    assert e.value.problems == ["s.toml:2: scene.periodic: each side must be at least 5 × the largest blob's radius "
                                "(1.5 m) (got [1.0, 3.0])"]


@pytest.mark.parametrize("damage, says", [
    ("missing", "particles/blobs/box/edges is missing"),
    ("nan", "particles/blobs/box/edges holds a value that is not a finite number"),
    ("zero", "particles/blobs/box/edges holds a side of the box that is not > 0"),
    ("negative", "particles/blobs/box/edges holds a side of the box that is not > 0"),
    ("scheduled nan", "particles/blobs/box/edges holds a value that is not a finite number"),
    ("scheduled zero", "particles/blobs/box/edges holds a side of the box that is not > 0"),
])
def test_every_reader_refuses_a_box_whose_edges_are_missing_not_finite_or_not_positive(tmp_path, damage, says):
    """A format-8/9 file with a damaged periodic box is bad input, one line and exit 2, for render and replay as
    for export and compare (they said "internal error")."""
    text = PAIR.format(box="periodic = [3.0, 2.5]", xa=0.9, xb=-0.5)
    if damage.startswith("scheduled"):  # the box a time series
        text += '[[schedule]]\nkey = "scene.periodic"\nat = [[0.0, 3.0, 2.5], [1.0, 3.2, 2.6]]\n'
    (tmp_path / "s.toml").write_text(text)
    traj = tmp_path / "t.h5"
    assert blobsim("run", tmp_path / "s.toml", "-o", traj, "--steps", "6", "-q").returncode == 0
    with h5py.File(traj, "r+") as f:
        edges = f["particles/blobs/box/edges"]
        values = edges["value"] if isinstance(edges, h5py.Group) else edges
        if damage == "missing":
            del f["particles/blobs/box/edges"]
        else:
            e = values[...]
            e[..., 0] = {"nan": np.nan, "zero": 0.0, "negative": -3.0}[damage.split()[-1]]
            values[...] = e
    for args in (("render", traj, "-o", tmp_path / "t.png"), ("replay", traj, "-o", tmp_path / "t.rrd"),
                 ("export", traj, "--format", "xyz", "-o", tmp_path / "t.xyz"), ("compare", traj, traj)):
        r = blobsim(*args)
        assert r.returncode == 2 and says in r.stderr and len(r.stderr.splitlines()) == 1, (args, r.stderr)
    assert not any((tmp_path / f"t.{ext}").exists() for ext in ("png", "rrd", "xyz"))


def test_shear_keyframes_are_bounded():
    """A shear strain of ±1e20 or 1e300 crashed the step; |γ| is at most MAX_SHEAR (1,000), stated in the key's
    doc, and that much runs."""
    from blobcli.scene.schema import MAX_SHEAR
    text = PAIR.format(box="periodic = [4.0, 3.0]", xa=0.9, xb=-0.9) + \
        '[[schedule]]\nkey = "scene.shear"\nat = [[0.0, 0.0], [1.0, {gamma}]]\n'
    for gamma in (1e20, -1e20, 1e300, 1001.0):
        with pytest.raises(SceneError) as e:
            parse_scene(text.format(gamma=gamma), "s.toml")
        assert e.value.problems == [f"s.toml:16: schedule[0].at[1]: shear strain γ must be within ±1,000 (the "
                                    f"images' shift γ L_y stays a number the step can wrap) (got {gamma!r})"]
    model, state = run(text.format(gamma=MAX_SHEAR), 10)  # γ = 167 at the tenth step
    assert np.isfinite(state.pos).all()


def test_a_box_of_more_broad_phase_cells_than_the_bound_is_refused():
    """periodic = [1e4, 1e4] with two blobs passed check and then took gigabytes; the box is now at most
    MAX_BOX_CELLS cells of the broad phase's grid (2.5 × the largest radius wide), as its key's doc says, in the
    scene, in a periodic schedule's keyframes and with a scale schedule's smallest blobs."""
    from blobcli.scene.schema import MAX_BOX_CELLS
    two = PAIR.format(box="periodic = [{side}, {side}]", xa=0.9, xb=-0.9)
    with pytest.raises(SceneError) as e:
        parse_scene(two.format(side=1e4), "s.toml")
    assert len(e.value.problems) == 1 and e.value.problems[0].startswith("s.toml:3: scene.periodic: the box is ")
    assert f"at most {MAX_BOX_CELLS:,} cells" in e.value.problems[0]
    parse_scene(two.format(side=1000.0), "s.toml")  # 1,000 × 1,000 cells of 1 m
    grown = two.format(side=1000.0) + '[[schedule]]\nkey = "scene.periodic"\nat = [[0.0, 1000.0, 1000.0], ' \
                                      '[1.0, 5000.0, 5000.0]]\n'
    with pytest.raises(SceneError) as e:
        parse_scene(grown, "s.toml")
    assert e.value.problems[0].startswith("s.toml:16: schedule[0].at[1]: the box is ")
    shrunk = two.format(side=1000.0).replace("radius = 0.4", 'name = "a"\nradius = 0.4').replace(
        "radius = 0.3", 'name = "b"\nradius = 0.3') + '[[schedule]]\nkey = "blob.*.scale"\nat = [[0.0, 1.0], [1.0, 0.1]]\n'
    with pytest.raises(SceneError) as e:
        parse_scene(shrunk, "s.toml")
    assert e.value.problems[0].startswith("s.toml:3: scene.periodic: the box is ")


def test_random_copies_fill_the_periodic_box_across_its_edges_without_overlap():
    sc = parse_scene("[scene]\nperiodic = [2.0, 2.0]\nseed = 4\n[[blob]]\nradius = 0.15\nvertices = 12\ncount = 30\n")
    model, state = build(sc)
    c = np.array([state.pos[o:e].mean(axis=0) for o, e in zip(model.offsets[:-1], model.offsets[1:])])
    d = c[:, None] - c[None]
    d -= 2.0 * np.round(d / 2.0)
    gaps = np.hypot(d[..., 0], d[..., 1]) - 0.3
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= -1e-12 and np.all(np.abs(c) <= 1.0)


@pytest.mark.slow
def test_the_periodic_scene_gives_the_same_bits_for_any_thread_count_and_when_resumed(tmp_path):
    """scenes/periodic.toml (80 blobs: the parallel build) on 1 and 2 threads, and stopped and resumed."""
    runs = []
    for threads in ("1", "2"):
        out = tmp_path / f"run{threads}.h5"
        env = {**os.environ, "OMP_NUM_THREADS": threads}
        r = blobsim("run", SCENES / "periodic.toml", "-o", out, "--steps", "240", "-q", env=env)
        assert r.returncode == 0, r.stderr
        runs.append(out)
    report = compare_files(*runs)
    assert report.same, report.text()
    first = tmp_path / "first.h5"
    assert blobsim("run", SCENES / "periodic.toml", "-o", first, "--steps", "131", "-q").returncode == 0
    r = blobsim("run", SCENES / "periodic.toml", "-q", "--steps", "240", "--resume", first)
    assert r.returncode == 0, r.stderr
    report = compare_files(runs[0], first)
    assert report.same and report.frames == 241, report.text()


def test_rattlers_are_removed_repeatedly():
    from blobcli.sim.packing import contact_counts, mean_contacts, rattlers
    # a triangle 0-1-2 braced by 3 (touching all three), and a chain 3-4-5: 5 has one contact, then 4 has one left
    touching = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3], [3, 4], [4, 5]])
    assert contact_counts(touching, 6).tolist() == [3, 3, 3, 4, 2, 1]
    assert rattlers(touching, 6).tolist() == [False, False, False, False, True, True]
    z, z_kept = mean_contacts(touching, rattlers(touching, 6))
    assert z == 2 * 8 / 6 and z_kept == 2 * 6 / 4


def test_a_head_on_collision_across_the_edge_records_its_impulse_as_stress(tmp_path):
    """Two blobs (e = 0) meet across x = ±2 at 2 m/s each and stop. The contact stress integrates, step by step,
    to the branch vector times the impulse: Σ σ_xx A dt = Σ_steps (c_b - c_a)_x Δp_a,x (measured: to 0.04%),
    negative (compression); after they stop, pressed together, their force and stress are zero. The file's net
    contact forces are equal and opposite (the pair's), carried while they collide and gone at rest."""
    from blobcli import simulate
    text = PAIR.format(box="periodic = [4.0, 3.0]", xa=1.4, xb=-1.4).replace("angular_velocity = 1.0\n", "").replace(
        "radius = 0.3\nmass = 0.6\nvelocity = [-2.0, 0.5]", "radius = 0.3\nvelocity = [-2.0, 0.0]").replace(
        "center = [1.4, 0.05]", "center = [1.4, 0.0]").replace("center = [-1.4, -0.05]", "center = [-1.4, 0.0]")
    model, state = build(parse_scene(text))
    params = build_params(parse_scene(text))
    o, box = model.offsets, np.array([4.0, 3.0])

    def branch():
        d = state.pos[o[1]:].mean(axis=0) - state.pos[:o[1]].mean(axis=0)
        return d - box * np.round(d / box)
    expected = 0.0
    for _ in range(45):
        before, p_a = branch(), momentum_of(model, state, 0)
        advance(state, model, params, 1)
        expected += 0.5 * (before[0] + branch()[0]) * (momentum_of(model, state, 0) - p_a)[0]
    out = tmp_path / "hit.h5"
    simulate(parse_scene(text.replace("[scene]\n", "[scene]\nsteps = 45\n"), "hit.toml"), out)
    with h5py.File(out) as f:
        stress = f["observables/stress/value"][...]
        pressure = f["observables/pressure/value"][...]
        contacts = f["observables/contacts/value"][...]
        fraction = f["observables/packing_fraction/value"][...]
        net = f["observables/net_force/value"][...]
        bearing = f["observables/bearing_contacts/value"][...]
    integral = stress[:, 0, 0].sum() * params.dt * 12.0
    assert expected < -0.9 and integral == pytest.approx(expected, rel=0.02)
    assert np.abs(stress[:, 1, 1]).sum() < 0.05 * np.abs(stress[:, 0, 0]).sum()  # along the line of centres
    assert pressure.max() > 0 and np.allclose(pressure, -0.5 * (stress[:, 0, 0] + stress[:, 1, 1]))
    assert abs(pressure[-1]) < 0.02 * pressure.max()  # at rest, pressed together: no force left
    assert contacts.max() == 1 and contacts[0].sum() == 0  # they touch each other (once), not before
    assert np.array_equal(net[:, 0], -net[:, 1]) and np.all(bearing <= contacts)
    hit = np.abs(net[:, 0, 0]).argmax()
    assert bearing[hit].tolist() == [1, 1] and np.abs(net[-1]).max() < 0.02 * np.abs(net[hit, 0, 0])
    polygon = 16 * np.sin(2 * np.pi / 32)  # a 32-gon's area over r²
    assert fraction[0] == pytest.approx(polygon * (0.16 + 0.09) / 12.0, rel=1e-12)
    assert np.allclose(fraction, fraction[0], rtol=1e-3)  # (pressed, the blobs lose a little area)


def test_the_packing_records_are_the_last_steps_of_a_call_however_many_steps_it_runs():
    """Only a call's last step keeps the packing records (core/step.c): the pair of the test above, mid-collision
    after 10 steps, records the same bits whether the 10 steps ran in one call or in 9 and 1: neither nothing
    (records skipped) nor the sum over the call's steps."""
    from blobcli.sim.jamming import copy_state
    text = PAIR.format(box="periodic = [4.0, 3.0]", xa=1.4, xb=-1.4)
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    split = copy_state(state)
    advance(state, model, params, 10)
    advance(split, model, params, 9)
    advance(split, model, params, 1)
    assert np.array_equal(state.pos, split.pos)
    virial, touching, force, count = state.packing
    assert count[0] == 1 and np.abs(virial).max() > 0.0
    for ours, theirs in zip(state.packing, split.packing):
        assert np.array_equal(ours, theirs)


def momentum_of(model, state, b):
    o, e = model.offsets[b], model.offsets[b + 1]
    return (state.vel[o:e] / model.inv_mass[o:e, None]).sum(axis=0)


def test_drag_slows_all_motion_as_exp_minus_drag_t_and_turns_sleeping_off():
    # (a floor far below, out of reach: the step built for it is the one the suite's floor tests compile)
    text = ("[scene]\ngravity = [0.0, 0.0]\ndrag = 2.0\n[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.3\n"
            "velocity = [1.0, 0.5]\nangular_velocity = 3.0\n"
            '[[static]]\nkind = "plane"\npoint = [0.0, -100.0]\nnormal = [0.0, 1.0]\n')
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    assert not params.sleep  # a packing relaxing under drag must not be frozen on its way to rest
    advance(state, model, params, 60)  # 1 s
    v = state.vel.mean(axis=0)
    assert v == pytest.approx(np.array([1.0, 0.5]) * np.exp(-2.0), rel=1e-9)
    r = state.pos - state.pos.mean(axis=0)
    spin = (r[:, 0] * state.vel[:, 1] - r[:, 1] * state.vel[:, 0]).sum() / (r ** 2).sum()
    assert spin == pytest.approx(3.0 * np.exp(-2.0), rel=1e-3)  # spinning is slowed too (not by damping alone)


SQUEEZE = """[scene]
gravity = [0.0, 0.0]
periodic = [3.0, 3.0]
seed = 2
{scene}
[[blob]]
radius = 0.2
vertices = 16
count = 24
friction = 0.0
[[schedule]]
key = "scene.periodic"
at = [[0.0, 3.0, 3.0], [1.0, {lx}, {ly}]]
"""
SHRINK = SQUEEZE.format(scene="steps = 90", lx=1.9, ly=1.95)


def test_a_scheduled_box_shrinks_and_carries_the_blobs_with_it(tmp_path):
    """The box goes from 3 × 3 to 1.9 × 1.95 m in 1 s: each frame's edges are recorded, every blob's centre stays
    in the box, the packing fraction follows 1 / (L_x L_y), and the blobs end pressed together (pressure > 0)."""
    from blobcli import simulate
    out = tmp_path / "shrink.h5"
    result = simulate(parse_scene(SHRINK, "shrink.toml"), out)
    assert result.status == "complete"
    with h5py.File(out) as f:
        edges = f["particles/blobs/box/edges/value"][...]
        time = f["particles/blobs/box/edges/time"][...]
        pos = f["particles/blobs/position/value"][...]
        offsets = f["parameters/blob_offsets"][...]
        fraction = f["observables/packing_fraction/value"][...]
        pressure = f["observables/pressure/value"][...]
    # frame k holds the box of the step that made it, set at its start: t = (k - 1) dt
    expected = np.stack([np.interp(time - 1 / 60, [0, 1], [3.0, 1.9]), np.interp(time - 1 / 60, [0, 1], [3.0, 1.95])], 1)
    assert np.allclose(edges[1:], expected[1:]) and np.allclose(edges[0], [3.0, 3.0])
    centres = np.stack([pos[:, o:e].mean(axis=1) for o, e in zip(offsets[:-1], offsets[1:])], axis=1)
    assert np.all(np.abs(centres) <= edges[:, None, :] / 2 + 1e-12)
    area = fraction * edges[:, 0] * edges[:, 1]
    assert np.allclose(area[1:], area[1], rtol=2e-3)  # the blobs' area: what the box loses, φ gains
    assert fraction[-1] > 0.75 and pressure[-10:].mean() > 0


def test_a_box_schedule_needs_a_periodic_box():
    with pytest.raises(SceneError) as e:
        parse_scene(SHRINK.replace("periodic = [3.0, 3.0]\n", "").replace("count = 24\n", "count = 24\n"
                                                                          "region = [-1.5, -1.5, 1.5, 1.5]\n"), "s.toml")
    assert e.value.problems == ["s.toml:12: schedule[0].key: only in a periodic box ([scene] periodic) "
                                "(got 'scene.periodic')"]


def test_a_run_stopped_while_the_box_shrinks_resumes_bit_identically(tmp_path):
    from blobcli import simulate
    from blobcli.scene.schema import with_overrides
    scene = parse_scene(SHRINK, "shrink.toml")
    whole, first = tmp_path / "whole.h5", tmp_path / "first.h5"
    simulate(scene, whole)
    simulate(with_overrides(scene, steps=47), first)
    resumed = simulate(scene, tmp_path / "resumed.h5", resume=first)
    assert resumed.status == "complete"
    report = compare_files(whole, tmp_path / "resumed.h5")
    assert report.same and report.frames == 91, report.text()
    with h5py.File(whole) as a, h5py.File(tmp_path / "resumed.h5") as b:
        for name in ("particles/blobs/box/edges/value", "observables/pressure/value", "observables/contacts/value"):
            assert np.array_equal(a[name][...], b[name][...]), name
        assert np.array_equal(a["restart/position"][...], b["restart/position"][...])


def test_across_a_sheared_boxs_top_edge_blobs_meet_the_image_shifted_by_gamma_ly():
    """Lees–Edwards: with γ = 0.25 in a 4 × 3 box the row of images above is shifted by 0.75 m. A pair meeting
    across y = ±1.5 moves as the same pair in an open world, placed as the images are (to 1e-10 m)."""
    from blobcli.sim.schedule import Schedules
    text = PAIR.format(box="periodic = [4.0, 3.0]", xa=0.3, xb=0.3).replace("angular_velocity = 1.0\n", "").replace(
        "center = [0.3, 0.05]", "center = [0.3, 1.0]").replace("velocity = [2.0, 0.0]", "velocity = [0.0, 2.0]").replace(
        "center = [0.3, -0.05]", "center = [0.3, -1.0]").replace("velocity = [-2.0, 0.5]", "velocity = [0.0, -2.0]")
    sheared = parse_scene(text + '[[schedule]]\nkey = "scene.shear"\nat = [[0.0, 0.25]]\n')
    model, state = build(sheared)
    params = build_params(sheared)
    schedules = Schedules(sheared, model, params)
    for step in range(40):
        step_settings = schedules.apply(step, None, state)
        advance(state, model, params, 1, step_settings=step_settings, arrays=schedules.arrays)
    # the open world: a as the shear left it (x + γ y), b as its image above (x + γ y + γ L_y, y + L_y)
    reference = PAIR.format(box="", xa=0.55, xb=0.8).replace("angular_velocity = 1.0\n", "").replace(
        "center = [0.55, 0.05]", "center = [0.55, 1.0]").replace("velocity = [2.0, 0.0]", "velocity = [0.0, 2.0]").replace(
        "center = [0.8, -0.05]", "center = [0.8, 2.0]").replace("velocity = [-2.0, 0.5]", "velocity = [0.0, -2.0]")
    model_ref, ref = run(reference, 40)
    o = model.offsets
    assert ref.blob_contact_depth.max() >= 0.0 and np.abs(ref.vel[o[1]:, 1].mean() + 2.0) > 0.5  # they met
    assert np.abs(state.pos[:o[1]] - ref.pos[:o[1]]).max() < 1e-10
    assert np.abs(state.pos[o[1]:] + [0.75, 3.0] - ref.pos[o[1]:]).max() < 1e-10


@pytest.mark.slow
def test_a_jammed_packing_resists_shear_and_an_unjammed_one_does_not(tmp_path):
    """24 blobs squeezed to φ = 0.86 (drag 5/s), held 3 s, then sheared to γ = 0.03 in 3 s: the shear stress
    σ_xy rises over the first 0.01 of strain (measured 0.088 → 0.170 N/m; run on to γ = 0.03 it yields, 0.108);
    at φ = 0.43 it stays below 1e-3 of the jammed packing's pressure (0.83 N/m)."""
    from blobcli import simulate
    text = SQUEEZE.format(scene="drag = 5.0\nduration = 5.0", lx="{L}", ly="{L}") + (
        '[[schedule]]\nkey = "scene.shear"\nat = [[4.0, 0.0], [7.0, 0.03]]\n')
    found = {}
    for name, side in (("jammed", 1.85), ("loose", 2.6)):
        out = tmp_path / f"{name}.h5"
        simulate(parse_scene(text.format(L=side), f"{name}.toml"), out)
        with h5py.File(out) as f:
            found[name] = (f["observables/stress/value"][...], f["observables/pressure/value"][...])
    stress, pressure = found["jammed"]
    at = {0.0: 239, 0.01: 300}  # frames: γ = 0 (t = 3.98 s), γ = 0.01 (t = 5 s)
    assert pressure[at[0.0]] > 0.3
    assert stress[at[0.01], 0, 1] - stress[at[0.0], 0, 1] > 0.1 * stress[at[0.01], 0, 1] > 0
    loose, _ = found["loose"]
    assert np.abs(loose[at[0.0]:, 0, 1]).max() < 1e-3 * pressure[at[0.0]]
