"""The compiled core's broad phase and blob-contact bookkeeping (blobcli/core/broad_phase.c) and measurements
(measure.c) against their numba twins (sim/collide.py, sim/measure.py), bit for bit, serial and on threads."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from core_twins import assert_same_bits, core, scene_state, twins, views

from blobcli import build, build_params, parse_scene
from blobcli.jit import build as jit_build
from blobcli.sim import collide, measure, pipeline

SCENES = Path(__file__).resolve().parents[1] / "scenes"
PILE = (SCENES / "pile.toml").read_text()
PERIODIC = (SCENES / "periodic.toml").read_text()

# 128 blobs in two tall columns: 4 strips, the columns 3 strips apart (far pairs), falling over
COLUMNS = """[scene]
[[blob]]
name = "column"
center = [0.0, 0.3]
radius = 0.2
vertices = 16
grid = [2, 64]
spacing = [0.42, 0.42]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# 70 blobs (two strips), some far apart: the open world's grid coarsens its cells
SPREAD = """[scene]
gravity = [0.0, 0.0]
[[blob]]
name = "near"
center = [0.0, 0.0]
radius = 0.2
vertices = 12
grid = [11, 6]
spacing = [0.41, 0.43]
[[blob]]
name = "far"
center = [-400.0, 300.0]
radius = 0.25
vertices = 12
grid = [2, 2]
spacing = [600.0, 0.45]
"""

# 16 blobs spawned almost on top of each other: a blob with more pairs than FOUND_PER_BLOB (searched again) ...
CLUMP = """[scene]
gravity = [0.0, 0.0]
[[blob]]
name = "clump"
center = [0.0, 0.0]
radius = 0.2
vertices = 10
grid = [4, 4]
spacing = [0.06, 0.05]
"""
# ... and 144 of them: more pairs than PAIRS_PER_BLOB per blob, none listed
HEAP = CLUMP.replace("[4, 4]", "[12, 12]").replace("[0.06, 0.05]", "[0.01, 0.012]")

# 20 blobs resting on a floor, most asleep after 150 steps
ASLEEP = """[scene]
time_to_sleep = 0.1
[[blob]]
name = "row"
center = [-4.0, 0.2]
radius = 0.2
vertices = 12
grid = [20, 1]
spacing = [0.41, 0.0]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def _box(box, centers):
    """A periodic box of blobs of radius 0.1 m at these centres, moving"""
    blobs = "".join(f"[[blob]]\ncenter = [{x:.6f}, {y:.6f}]\nradius = 0.1\nvertices = 10\nvelocity = [0.3, -0.2]\n"
                    for x, y in centers)
    return f"[scene]\ngravity = [0.0, 0.0]\nperiodic = [{box[0]}, {box[1]}]\n" + blobs


def _chain(x0, y0, dx, dy, count):
    return [(x0 + k * dx, y0 + k * dy) for k in range(count)]


# more cells (32 × 32) than 4 B + 64: the sorted cells; chains along the four edges, paired across them (and,
# sheared by γ = 0.3, the top chain with the bottom one's image 2.4 m along)
DILUTE_BOX = _box((8.0, 8.0), _chain(-2.0, 3.9, 0.19, 0.0, 22) + _chain(-2.0, -3.9, 0.19, 0.0, 22)
                  + _chain(3.9, -1.0, 0.0, 0.19, 10) + _chain(-3.9, -1.0, 0.0, 0.19, 10))
# fewer than 3 cells along x (whole rows): two columns, paired across the sides and round the top and bottom
THIN_BOX = _box((0.6, 6.0), _chain(-0.2, -2.9, 0.0, 6.0 / 31, 31) + _chain(0.2, -2.9, 0.0, 6.0 / 31, 31))
# fewer than 3 along y: three rows, paired across the top and bottom and round the sides
FLAT_BOX = _box((6.0, 0.6), _chain(-2.9, -0.2, 6.0 / 31, 0.0, 31) + _chain(-2.9, 0.0, 6.0 / 31, 0.0, 31)
                + _chain(-2.9, 0.2, 6.0 / 31, 0.0, 31))

# 90 blobs on a lattice that fills a periodic box, pressed into each other, across the edges too
LATTICE = """[scene]
gravity = [0.0, 0.0]
periodic = [1.9, 1.71]
[[blob]]
name = "lattice"
center = [-0.855, -0.76]
radius = 0.1
vertices = 10
grid = [10, 9]
spacing = [0.19, 0.19]
velocity = [0.2, 0.1]
"""


def _state(toml, steps, shear=0.0):
    """(model, state, params, settings) after `steps` numba steps, in a box sheared by γ = shear"""
    if not shear:
        return scene_state(toml, steps)
    scene = parse_scene(toml)
    model, state = build(scene)
    params = dataclasses.replace(build_params(scene), shear=shear)
    if steps:
        pipeline.advance(state, model, params, steps)
    return model, state, params, pipeline.settings(model, params)


def _ints(ffi, pointer, count):
    return np.frombuffer(ffi.buffer(pointer, 8 * count), np.int64).copy()


def _floats(ffi, pointer, count):
    return np.frombuffer(ffi.buffer(pointer, 8 * count), np.float64).copy()


def _put(ffi, pointer, array):
    array = np.ascontiguousarray(array)
    ffi.memmove(pointer, ffi.from_buffer(array), array.nbytes)


def _same(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), what


RUNS = ((False, 1), (True, 2), (True, 1))  # (parallel, threads)


def _cells(state, box):
    """How many cells the periodic box's grid has (collide._find_pairs_periodic)"""
    cell = 2.0 * state.radius.max() * (1.0 + collide.BROAD_MARGIN)
    return max(1, int(box[0] / cell)) * max(1, int(box[1] / cell))


def _check_state(model, state, params, settings, ffi, lib, rng):
    """Every stage of broad_phase.c on twins of this state, each run serial, on 2 threads and on 1, against numba."""
    B = model.blob_count
    config = pipeline.configuration(model, params)
    find = jit_build(collide.find_blob_pairs, False, pipeline.shared_build(config).constants())
    box = (settings.box_x, settings.box_y, settings.box_tilt)
    periodic = settings.box_x > 0.0
    seen = {}
    for parallel, threads in RUNS:
        lib.bc_set_threads(threads)
        ref, cor = twins(state)
        pairs, (start, partner, pair_of), (strip_of, strip_start, strip_blobs, crossing, far), count = find(
            ref.position, model.offsets, ref.awake, ref.center, ref.radius, ref.edges, ref.blob_contact_depth,
            ref.c_hit, box)
        v = views(ffi, model, cor, settings, parallel)
        w = lib.bc_scratch_new(v.model)
        assert w != ffi.NULL
        v.context.w = w
        try:
            # the broad phase: the state's bounds, the pairs, partners and strips
            assert lib.bc_find_blob_pairs(v.context) == count
            assert_same_bits(ref, cor)
            P = len(pairs)
            assert w.pair_count == P and (P == count or P == 0)
            _same(_ints(ffi, w.pairs, 2 * P).reshape(-1, 2), pairs, "pairs")
            _same(_ints(ffi, w.partner_start, B + 1), start, "partner_start")
            _same(_ints(ffi, w.partner, 2 * P), partner, "partner")
            _same(_ints(ffi, w.partner_pair, 2 * P), pair_of, "partner_pair")
            assert w.strip_count == len(strip_start) - 1
            _same(_ints(ffi, w.strip_of, B), strip_of, "strip_of")
            _same(_ints(ffi, w.strip_start, len(strip_start)), strip_start, "strip_start")
            _same(_ints(ffi, w.strip_blobs, B), strip_blobs, "strip_blobs")
            _same(_ints(ffi, w.crossing, B), crossing, "crossing")
            assert w.far == int(far)
            seen.update(pairs=P, count=count, far=bool(far), kept=int(state.pair_count[0]), strips=len(strip_start) - 1,
                        cells=_cells(ref, box) if periodic else 0)
            if P < count:
                continue
            # the impact records carried to this substep's pairs
            impact = collide.carry_impacts(pairs, B, ref.pair_key, ref.pair_impact, ref.pair_count)
            lib.bc_carry_impacts(v.context)
            _same(_floats(ffi, w.pair_impact, 4 * P).reshape(-1, 4), impact, "pair_impact (carry_impacts)")
            # kept again: the records as carried, then records of which about half have had an impact
            for records in (impact, np.where(rng.random((P, 1)) < 0.5, rng.random((P, 4)), -rng.random((P, 4)))):
                _put(ffi, w.pair_impact, records)
                collide.keep_impacts(pairs, B, records, ref.pair_key, ref.pair_impact, ref.pair_count)
                lib.bc_keep_impacts(v.context)
                assert_same_bits(ref, cor)
                impact = collide.carry_impacts(pairs, B, ref.pair_key, ref.pair_impact, ref.pair_count)
                lib.bc_carry_impacts(v.context)
                _same(_floats(ffi, w.pair_impact, 4 * P).reshape(-1, 4), impact, "pair_impact (carried after kept)")
            # the stick points of contacts that did not push let go (c_hit and stick_edge at random)
            hit = (rng.random(state.c_hit.shape) < 0.5).astype(np.uint8)
            sticks = rng.integers(-1, model.vertex_count, state.stick_edge.shape)
            for s in (ref, cor):
                s.c_hit[:], s.stick_edge[:] = hit, sticks
            collide.release_sticks(ref.c_hit, ref.stick_edge)
            lib.bc_release_sticks(v.context)
            assert_same_bits(ref, cor)
            # the pairs touching at the step's end, from the contacts the step left
            if periodic:
                for s in (ref, cor):
                    s.c_hit[:], s.c_edge[:] = state.c_hit, state.c_edge
                collide.keep_touching(model.offsets, model.blob_of, ref.awake, ref.c_edge, ref.c_hit, pairs,
                                      (start, partner, pair_of), ref.packing[1], ref.packing[2])
                lib.bc_keep_touching(v.context)
                assert_same_bits(ref, cor)
                seen["touching"] = int(ref.packing[2][0])
        finally:
            lib.bc_scratch_free(w)
            lib.bc_set_threads(1)
    return seen


def _run(toml, steps, rounds, shear=0.0, seed=0):
    """The stages' twins on a scene's state after `steps` numba steps, then after each of `rounds` more steps"""
    ffi, lib = core()
    model, state, params, settings = _state(toml, steps, shear)
    rng = np.random.default_rng(seed)
    seen = []
    for r in range(rounds + 1):
        if r:
            pipeline.advance(state, model, params, 1)
        seen.append(_check_state(model, state, params, settings, ffi, lib, rng))
    return model, state, seen


def test_a_pile_of_120_blobs_in_three_strips_lists_the_same_pairs_and_records():
    model, state, seen = _run(PILE, 30, 2)
    assert all(s["strips"] == 3 and s["pairs"] > 100 for s in seen)
    assert any(s["kept"] > 0 for s in seen)  # impact records carried from the steps before


def test_two_columns_of_128_blobs_have_pairs_across_strips_two_or_more_apart():
    _, _, seen = _run(COLUMNS, 2, 1)
    assert all(s["strips"] == 4 and s["far"] for s in seen)


def test_blobs_far_apart_coarsen_the_open_worlds_cells_and_sleeping_blobs_are_paired():
    _, _, seen = _run(SPREAD, 0, 1)
    assert all(s["pairs"] > 50 and s["strips"] == 2 for s in seen)
    model, state, seen = _run(ASLEEP, 150, 1)
    assert 0 < state.awake.sum() < model.blob_count and all(s["pairs"] >= 15 for s in seen)


def test_a_blob_with_more_pairs_than_it_keeps_while_counting_is_searched_again():
    _, _, seen = _run(CLUMP, 0, 0)
    assert seen[0]["pairs"] == 120  # every pair of the 16: blob 0 has 15


def test_more_pairs_than_the_capacity_lists_none_and_counts_them():
    model, _, seen = _run(HEAP, 0, 0)
    assert seen[0]["pairs"] == 0 and seen[0]["count"] > collide.PAIRS_PER_BLOB * model.blob_count


@pytest.mark.parametrize("shear", [0.0, 0.25, -0.4])
def test_a_periodic_packing_pairs_across_the_edges_of_a_plain_or_sheared_box(shear):
    _, _, seen = _run(LATTICE, 3, 1, shear)
    assert all(s["pairs"] >= 180 and s["touching"] > 50 and s["cells"] <= 4 * 90 + 64 for s in seen)


def test_the_periodic_scene_lists_the_same_pairs():
    _, _, seen = _run(PERIODIC, 20, 0)
    assert seen[0]["pairs"] > 30


@pytest.mark.parametrize("toml", [DILUTE_BOX, THIN_BOX, FLAT_BOX], ids=["dilute", "thin", "flat"])
@pytest.mark.parametrize("shear", [0.0, 0.3])
def test_boxes_of_many_cells_or_fewer_than_three_a_side_list_the_same_pairs(toml, shear):
    model, _, seen = _run(toml, 3, 1, shear)
    assert all(s["cells"] > 4 * model.blob_count + 64 for s in seen) == (toml == DILUTE_BOX)
    assert all(s["pairs"] >= model.blob_count for s in seen) and any(s["touching"] > 0 for s in seen)


def test_the_runaway_check_and_the_measurements_are_numbas():
    ffi, lib = core()
    model, state, params, settings = scene_state(ASLEEP, 2)
    pos, vel, offsets = state.position.copy(), state.velocity.copy(), model.offsets
    n, B = model.vertex_count, model.blob_count
    v = views(ffi, model, state, settings)
    faults = ({}, {(1, 17): np.nan}, {(0, 5): 2e6}, {(1, 205): -np.inf}, {(0, 40): 1e6}, {(1, 90): 6.0, (0, 70): 5.5})
    for bad in faults:
        state.position[:] = pos
        for (row, i), value in bad.items():
            state.position[row, i] = value
        runaway = measure.first_runaway(state.position, measure.RUNAWAY)
        assert lib.bc_first_runaway(v.context, measure.RUNAWAY) == runaway
        assert lib.bc_first_runaway_in(ffi.cast("double *", state.position.ctypes.data), n, 5.0) == \
            measure.first_runaway(state.position, 5.0)
    # a blob turned inside out (its ring reversed), one crossing itself (two vertices swapped), the rest sound
    o = offsets
    pos[:, o[3]:o[4]] = pos[:, o[3]:o[4]][:, ::-1]
    pos[:, [o[7] + 2, o[7] + 7]] = pos[:, [o[7] + 7, o[7] + 2]]
    p = lambda a, t="double *": ffi.cast(t, a.ctypes.data)  # noqa: E731
    area, kinetic, faults = np.empty(B), np.empty(B), np.empty(B, np.int64)
    measure._blob_measures(pos, vel, model.inv_mass, offsets, area, kinetic)
    c_area, c_kinetic, c_faults = np.empty(B), np.empty(B), np.full(B, 9, np.int64)
    lib.bc_blob_measures(p(pos), p(vel), n, p(model.inv_mass), p(offsets, "int64_t *"), B, p(c_area), p(c_kinetic))
    _same(c_area, area, "area")
    _same(c_kinetic, kinetic, "kinetic")
    measure._shape_faults(pos, offsets, model.orient, faults)
    lib.bc_shape_faults(p(pos), n, p(offsets, "int64_t *"), B, p(model.orient), p(c_faults, "int64_t *"))
    _same(c_faults, faults, "faults")
    assert faults[3] == 1 and faults[7] == 2 and (np.delete(faults, [3, 7]) == 0).all()
