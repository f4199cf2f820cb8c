"""The narrow phase in C (blobcli/core/narrow_phase.c: bc_keep_blob_contacts) against numba's
collide.keep_blob_contacts, bit for bit, on scenes that reach each of its branches: piles (contacts found
at the step's start and again for blobs that outgrow their budgets), periodic boxes (plain and sheared:
partners met as their nearest images), deep overlaps (pairs split, in an open world and across a box's
edge), sleeping blobs beside awake ones, and fast blobs.

Each scene is run some numba steps first; then, for a few steps, the numba broad phase lists the pairs
of every substep, and every iteration the numba narrow phase runs on one copy of the state and the C one
on three others (serial; parallel on 2 threads; parallel on 1), which must all agree bit for bit. Between
iterations every copy moves the same way (x += v h, plus the same small noise), as the other stages
would move it, so that blobs outgrow their budgets and have their contacts found again.
"""

import dataclasses
import math

import numpy as np
import pytest
from core_twins import assert_same_bits, core, fill_pairs, scene_state, views

from blobcli import jit
from blobcli.sim import collide, pipeline
from blobcli.sim.jamming import copy_state

PILE = """
[scene]
time_to_sleep = 0.5

[[blob]]
name = "pile"
center = [-2.2, 1.0]
radius = 0.2
vertices = 24
mass = 0.5
grid = [GRID]
spacing = [0.4, 0.45]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]

[[static]]
kind = "box"
center = [-2.6, 3.5]
size = [0.2, 7.0]

[[static]]
kind = "box"
center = [2.6, 3.5]
size = [0.2, 7.0]
"""

PERIODIC = """
[scene]
gravity = [0.0, 0.0]
periodic = [3.0, 3.0]
seed = 1

[[blob]]
name = "small"
radius = 0.1
vertices = 24
count = 40
friction = 0.0
velocity = [0.3, -0.2]

[[blob]]
name = "large"
radius = 0.14
vertices = 24
count = 40
velocity = [-0.3, 0.1]
"""

# two blobs spawned overlapping, and a heavy blob driven into a light one on the floor
DEEP = """
[scene]
substeps = 2
max_substeps = 2

[[blob]]
center = [-1.0, 1.0]
radius = 0.3
vertices = 20

[[blob]]
center = [-0.9, 1.05]
radius = 0.25
vertices = 16
velocity = [-3.0, 0.0]

[[blob]]
name = "light"
center = [1.0, 0.21]
radius = 0.2
vertices = 24
mass = 0.05

[[blob]]
name = "heavy"
center = [1.02, 0.75]
radius = 0.25
vertices = 12
mass = 40.0
velocity = [0.0, -30.0]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# overlapping across the box's edges: the split meets b as its image nearest a
DEEP_PERIODIC = """
[scene]
gravity = [0.0, 0.0]
periodic = [2.0, 2.0]

[[blob]]
center = [0.93, 0.2]
radius = 0.2
vertices = 16

[[blob]]
center = [-0.95, 0.25]
radius = 0.18
vertices = 20

[[blob]]
center = [0.0, 0.92]
radius = 0.2
vertices = 16

[[blob]]
center = [0.05, -0.93]
radius = 0.2
vertices = 16
velocity = [0.0, -1.0]
"""

# a row of blobs apart on the floor that falls asleep, and a blob that falls onto it (awake beside asleep)
SLEEPING = """
[scene]
time_to_sleep = 0.1

[[blob]]
name = "row"
center = [-0.5, 0.2]
radius = 0.2
vertices = 16
grid = [3, 1]
spacing = [0.5, 0.5]

[[blob]]
name = "late"
center = [0.1, 6.0]
radius = 0.2
vertices = 16

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# fast blobs meeting head on, and one at a slant (budgets renewed from their speed)
FAST = """
[scene]
gravity = [0.0, 0.0]
substeps = 2
max_substeps = 2
iterations = 4

[[blob]]
center = [-0.6, 0.0]
radius = 0.2
vertices = 24
velocity = [12.0, 0.0]

[[blob]]
center = [0.6, 0.02]
radius = 0.2
vertices = 24
velocity = [-12.0, 0.0]

[[blob]]
center = [0.0, 0.8]
radius = 0.15
vertices = 12
velocity = [1.0, -15.0]
mass = 3.0
"""

# name: (scene, numba steps first, shear γ, steps compared, noise (m), the branches it must reach)
SCENES = {
    "pile 120": (PILE.replace("GRID", "12, 10"), 60, 0.0, 1, 1e-3, {"renewed"}),
    "pile 60": (PILE.replace("GRID", "10, 6"), 40, 0.0, 1, 1e-3, {"renewed"}),
    "periodic": (PERIODIC, 15, 0.0, 1, 1e-3, {"renewed", "image"}),
    "periodic sheared": (PERIODIC, 15, 0.3, 1, 1e-3, {"renewed", "image"}),
    "deep": (DEEP, 0, 0.0, 3, 0.0, {"split", "renewed"}),
    "deep periodic": (DEEP_PERIODIC, 0, 0.0, 2, 0.0, {"split", "image"}),
    "sleeping": (SLEEPING, 61, 0.0, 3, 1e-3, {"asleep", "renewed"}),
    "fast": (FAST, 2, 0.0, 2, 0.0, {"renewed"}),
}

LANES = ((False, 1), (True, 2), (True, 1))  # the C stage's runs: (parallel, threads)


def _numba_step_state(toml, steps, shear):
    model, state, params, settings = scene_state(toml)
    if shear:
        params = dataclasses.replace(params, shear=shear)
        settings = pipeline.settings(model, params)
    if steps:
        pipeline.advance(state, model, params, steps)
    return model, state, params, settings


@pytest.mark.parametrize("name", SCENES)
def test_keep_blob_contacts_gives_numbas_bits(name):
    toml, steps, shear, compared, noise, branches = SCENES[name]
    ffi, lib = core()
    model, state, params, settings = _numba_step_state(toml, steps, shear)
    a = model.arrays
    config = pipeline.shared_build(pipeline.configuration(model, params)).constants()
    find_blob_pairs = jit.build(collide.find_blob_pairs, False, config)
    box = (settings.box_x, settings.box_y, settings.box_tilt)
    g = math.hypot(settings.gx, settings.gy)
    rng = np.random.default_rng(7)
    threads = lib.bc_threads()
    reached = set()
    try:
        for _ in range(compared):
            ref = copy_state(state)
            lanes = []
            for parallel, lane_threads in LANES:
                twin = copy_state(state)
                v = views(ffi, model, twin, settings, parallel)
                w = ffi.gc(lib.bc_scratch_new(v.model), lib.bc_scratch_free)
                v.context.w = w
                lanes.append((twin, v, w, lane_threads))
            copies = [ref] + [lane[0] for lane in lanes]
            substeps = settings.substeps
            h = settings.dt / substeps
            first = True
            for sub in range(substeps):
                # the broad phase on every copy (it writes their centres, radii and edge tables): the reference's pairs
                pairs, partners, strips, count = [find_blob_pairs(s.position, a.offsets, s.awake, s.center, s.radius,
                                                                  s.edges, s.blob_contact_depth, s.c_hit, box)
                                                  for s in copies][0]
                assert count == len(pairs)
                if count == 0:  # (the step runs no narrow phase then)
                    continue
                for twin, v, w, _ in lanes:
                    fill_pairs(ffi, w, pairs, partners, strips)
                    assert_same_bits(ref, twin)
                if not ref.awake.all():
                    reached.add("asleep")
                d = ref.center[pairs[:, 1]] - ref.center[pairs[:, 0]]
                if box[0] > 0.0 and np.any((np.abs(d[:, 0]) > 0.5 * box[0]) | (np.abs(d[:, 1]) > 0.5 * box[1])):
                    reached.add("image")  # a pair that meets across the box's edge
                for it in range(settings.iterations):
                    before = copy_state(ref)
                    collide.keep_blob_contacts(ref.position, ref.velocity, a.inv_mass, a.offsets, a.blob_of,
                                               ref.awake, a.orient, ref.center, ref.radius, ref.edges, pairs,
                                               partners, first, (substeps - sub) * h, g, ref.anchor, ref.budget,
                                               ref.moved, ref.c_edge, ref.stick_edge, ref.stick_t, box)
                    for twin, v, w, lane_threads in lanes:
                        lib.bc_set_threads(lane_threads)
                        lib.bc_keep_blob_contacts(v.context, first, (substeps - sub) * h, g)
                        assert_same_bits(ref, twin)
                    if not np.array_equal(before.position, ref.position):
                        reached.add("split")  # (only the deep overlaps' split moves vertices here)
                    if not first and not np.array_equal(before.anchor, ref.anchor):
                        reached.add("renewed")  # contacts found again for a blob that outgrew its budget
                    first = False
                    # the other stages' motion, the same for every copy
                    shake = rng.normal(0.0, noise, ref.position.shape) if noise else 0.0
                    for s in copies:
                        s.position[...] += (s.velocity * h + shake) * s.awake[a.blob_of]
            pipeline.advance(state, model, params, 1)
    finally:
        lib.bc_set_threads(threads)
    assert branches <= reached, f"{name} did not reach {branches - reached}"
