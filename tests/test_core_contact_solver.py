"""The compiled contact solver (blobcli/core/contact_solver.c) against its numba twin, bit for bit:
collide.resolve_blob_contacts every iteration and collide.blob_contact_velocities after them, in piles with
strips (the parallel phases, far and crossing contacts), with and without friction, heavy blobs on light ones
(the mass scaling), sleeping blobs, a periodic box with its virial (sheared too), and the head-on pair.

Each round, numba steps the scene on (so the contacts, stick points and sleeping blobs are the ones a run
meets), then one substep is played on twins: numba's prediction, broad phase and narrow phase on both, the
resolve on each twin (numba on the reference, C on the others, serially, and in parallel on 2 threads and
on 1), the velocity stage after the iterations; every array must agree after every call."""

import dataclasses

import numpy as np
import pytest
from core_twins import assert_same_bits, core, fill_pairs, scene_state, views

from blobcli import build, build_params, parse_scene
from blobcli.jit import build as jit_build
from blobcli.sim import collide, integrate, pipeline
from blobcli.sim.jamming import copy_state

# 120 blobs (3 strips, contacts across their boundaries), spawned pressed into each other and onto the floor
PILE = """
[scene]
sleep = false
[[blob]]
name = "pile"
center = [-2.0, 0.19]
radius = 0.2
vertices = 16
mass = 0.5
grid = [12, 10]
spacing = [0.37, 0.37]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# 96 small blobs in two columns between walls without gravity, inflated into each other: 3 strips, the middle one empty, so
# every contact between the columns is a far one (strips 0 and 2); frictionless
FAR = """
[scene]
gravity = [0.0, 0.0]
[[blob]]
name = "column"
center = [0.0, 0.0]
radius = 0.1
vertices = 12
pressure = 1.3
friction = 0.0
grid = [2, 48]
spacing = [0.19, 0.19]
[[static]]
kind = "plane"
point = [-0.1, 0.0]
normal = [1.0, 0.0]
[[static]]
kind = "plane"
point = [0.29, 0.0]
normal = [-1.0, 0.0]
"""

# 72 blobs (2 strips) of two sizes and masses, the heavy ones (30×) on the light ones, pressed together
HEAVY_ON_LIGHT = """
[scene]
sleep = false
[[blob]]
name = "light"
center = [-1.65, 0.15]
radius = 0.15
vertices = 16
mass = 0.2
friction = 0.3
grid = [12, 3]
spacing = [0.29, 0.29]
[[blob]]
name = "heavy"
center = [-1.6, 0.98]
radius = 0.11
vertices = 20
mass = 6.0
friction = 0.3
grid = [14, 3]
spacing = [0.21, 0.21]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# 40 blobs of two sizes in a narrow bin (one strip: blobs in index order), with high friction
NARROW = """
[scene]
sleep = false
[[blob]]
name = "small"
center = [-0.36, 0.12]
radius = 0.12
vertices = 18
grid = [4, 5]
spacing = [0.235, 0.47]
friction = 0.8
static_friction = 1.0
[[blob]]
name = "big"
center = [-0.28, 0.4]
radius = 0.15
vertices = 28
grid = [3, 5]
spacing = [0.29, 0.47]
friction = 0.3
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "box"
center = [-0.6, 2.0]
size = [0.2, 4.0]
[[static]]
kind = "box"
center = [0.6, 2.0]
size = [0.2, 4.0]
"""

# a 4 × 4 lattice in a periodic box, each blob inflated into its neighbours (across the box's edges too), and a
# small blob running through it
PERIODIC = """
[scene]
gravity = [0.0, 0.0]
periodic = [1.6, 1.6]
[[blob]]
name = "cell"
center = [-0.6, -0.6]
radius = 0.19
vertices = 20
pressure = 1.2
grid = [4, 4]
spacing = [0.4, 0.4]
velocity = [0.4, -0.3]
friction = 0.4
[[blob]]
name = "odd"
center = [-0.4, -0.4]
radius = 0.06
vertices = 12
mass = 0.3
velocity = [-1.0, 0.5]
"""


def head_on(friction):
    """tests/test_collide.py's head-on pair: two 32-gons, mirror images, meeting at 6 m/s"""
    th = 2 * np.pi * np.arange(32) / 32
    a = np.stack([-1 + 0.4 * np.cos(th), 0.4 * np.sin(th)], axis=1)
    b = (a * [-1, 1])[::-1]

    def fmt(points):
        return "[" + ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in points) + "]"

    blob = f"pressure = 1.0\ncompliance = 2e-4\nfriction = {friction}\nstatic_friction = {friction}\n"
    return f"""
[scene]
gravity = [0.0, 0.0]
[[blob]]
points = {fmt(a)}
velocity = [3.0, 0.0]
{blob}
[[blob]]
points = {fmt(b)}
velocity = [-3.0, 0.0]
{blob}
"""


def sheared_state(toml, steps, shear):
    """scene_state, in a box sheared by γ (a schedule's shear, here fixed)"""
    scene = parse_scene(toml)
    model, state = build(scene)
    params = dataclasses.replace(build_params(scene), shear=shear)
    pipeline.advance(state, model, params, steps)
    return model, state, params, pipeline.settings(model, params)


def resolve_scratch(model):
    """pipeline._advance's resolve_scratch"""
    slots = collide.CONTACTS_PER_VERTEX * int(np.diff(model.offsets).max())
    n, blobs = int(model.offsets[-1]), len(model.offsets) - 1
    return (np.empty((collide.MAX_STRIPS, slots, 8)), np.empty((collide.MAX_STRIPS, slots), np.int64), np.zeros(n),
            np.empty((2, collide.CONTACTS_PER_VERTEX * n), np.int64), np.empty(blobs, np.int64))


def substep_on_twins(model, state, params, settings, ffi, lib, counts):
    """One substep's blob contacts, numba on a copy of `state` and C on three more (serial; parallel on 2
    threads; parallel on 1), the same bits after every call; counts the pushes, sleeping and far contacts seen."""
    m, c = model.arrays, settings
    config = pipeline.configuration(model, params)
    find = jit_build(collide.find_blob_pairs, False, pipeline.shared_build(config).constants())
    box = (c.box_x, c.box_y, c.box_tilt)
    h = c.dt / c.substeps
    g = float(np.hypot(c.gx, c.gy))
    ref, *cores = [copy_state(state) for _ in range(4)]
    modes = [(False, 2), (True, 2), (True, 1)]
    scratch = resolve_scratch(model)
    found = []
    for s in [ref, *cores]:
        integrate.predict(s.position, s.previous, s.velocity, s.lam, s.contact_depth, m.offsets, s.awake, s.predicted,
                          c.gx, c.gy, h)
        found.append(find(s.position, m.offsets, s.awake, s.center, s.radius, s.edges, s.blob_contact_depth, s.c_hit,
                          box))
    pairs, partners, strips, count = found[0]
    assert 0 < count <= collide.PAIRS_PER_BLOB * model.blob_count
    counts["strips"] = max(counts.get("strips", 0), len(strips[1]) - 1)
    counts["far"] = counts.get("far", 0) + int(strips[4])
    counts["crossing"] = counts.get("crossing", 0) + int(strips[3].max() > 0)
    all_views, scratches = [], []
    for s, (parallel, threads) in zip(cores, modes):
        v = views(ffi, model, s, settings, parallel)
        w = lib.bc_scratch_new(v.model)
        assert w != ffi.NULL
        v.context.w = w
        fill_pairs(ffi, w, pairs, partners, strips)
        all_views.append(v)
        scratches.append(w)
    try:
        for it in range(4):
            for s in [ref, *cores]:
                collide.keep_blob_contacts(s.position, s.velocity, m.inv_mass, m.offsets, m.blob_of, s.awake,
                                           m.orient, s.center, s.radius, s.edges, pairs, partners, it == 0, h, g,
                                           s.anchor, s.budget, s.moved, s.c_edge, s.stick_edge, s.stick_t, box)
            collide.resolve_blob_contacts(ref.position, ref.previous, m.inv_mass, m.offsets, m.blob_of, ref.awake,
                                          m.orient, m.material, ref.c_edge, ref.c_hit, ref.c_normal,
                                          ref.blob_contact_depth, ref.center, ref.radius, c.up_x, c.up_y, strips,
                                          it % 2 == 1, ref.stick_edge, ref.stick_t, box, ref.packing[0], h, scratch)
            for s, v, (parallel, threads) in zip(cores, all_views, modes):
                lib.bc_set_threads(threads)
                lib.bc_resolve_blob_contacts(v.context, it % 2 == 1, h)
                assert_same_bits(ref, s)
        counts["pushes"] = counts.get("pushes", 0) + int(ref.c_hit.sum())
        counts["asleep"] = counts.get("asleep", 0) + int((ref.awake == 0).sum())
        for s in [ref, *cores]:  # v = (x - x_prev) / h, as the velocity update leaves it
            s.velocity[:] = (s.position - s.previous) / h
        collide.blob_contact_velocities(ref.position, ref.velocity, m.inv_mass, m.offsets, m.blob_of, ref.awake,
                                        m.material, ref.c_edge, ref.c_hit, ref.c_normal, ref.blob_contact_depth, h,
                                        ref.center, box, ref.packing[0])
        for s, v, (parallel, threads) in zip(cores, all_views, modes):
            lib.bc_set_threads(threads)
            lib.bc_blob_contact_velocities(v.context, h)
            assert_same_bits(ref, s)
    finally:
        for w in scratches:
            lib.bc_scratch_free(w)


def fall_asleep(model, state, blobs):
    """Blobs frozen as sleep.update_sleep leaves them: asleep, without contacts of their own"""
    for b in blobs:
        state.awake[b] = 0
        state.c_edge[:, model.offsets[b]:model.offsets[b + 1]] = -1


def run_rounds(model, state, params, settings, rounds, steps_between):
    ffi, lib = core()
    counts = {}
    for n in range(rounds):
        substep_on_twins(model, state, params, settings, ffi, lib, counts)
        if n + 1 < rounds:
            pipeline.advance(state, model, params, steps_between)
    return counts


def test_a_pile_of_120_blobs_in_strips_gives_numbas_bits():
    model, state, params, settings = scene_state(PILE, 4)
    counts = run_rounds(model, state, params, settings, rounds=2, steps_between=3)
    assert counts["strips"] == 3 and counts["crossing"] and counts["pushes"] > 300


def test_contacts_across_strips_two_apart_give_numbas_bits():
    model, state, params, settings = scene_state(FAR, 2)
    counts = run_rounds(model, state, params, settings, rounds=2, steps_between=2)
    assert counts["strips"] == 3 and counts["far"] == 2 and counts["pushes"] > 50


def test_heavy_blobs_on_light_ones_some_asleep_give_numbas_bits():
    model, state, params, settings = scene_state(HEAVY_ON_LIGHT, 4)
    counts = run_rounds(model, state, params, settings, rounds=1, steps_between=0)
    fall_asleep(model, state, range(12))  # the bottom row of light blobs
    counts2 = run_rounds(model, state, params, settings, rounds=2, steps_between=2)
    assert counts["strips"] == 2 and counts["pushes"] > 40 and counts2["asleep"] > 0


def test_a_narrow_frictional_pile_of_two_sizes_gives_numbas_bits():
    model, state, params, settings = scene_state(NARROW, 6)
    counts = run_rounds(model, state, params, settings, rounds=2, steps_between=3)
    assert counts["strips"] == 1 and counts["pushes"] > 100


@pytest.mark.parametrize("shear", [0.0, 0.15])
def test_a_periodic_packing_and_its_virial_give_numbas_bits(shear):
    model, state, params, settings = sheared_state(PERIODIC, 6, shear)
    assert settings.box_x > 0.0 and len(state.packing[0])
    counts = run_rounds(model, state, params, settings, rounds=2, steps_between=4)
    assert counts["pushes"] > 20


@pytest.mark.parametrize("friction", [0.0, 0.5])
def test_the_head_on_pair_gives_numbas_bits(friction):
    model, state, params, settings = scene_state(head_on(friction), 12)
    counts = run_rounds(model, state, params, settings, rounds=4, steps_between=2)
    assert counts["pushes"] > 0
