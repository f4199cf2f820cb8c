"""The static colliders and the walls that move, compiled (blobcli/core/statics.c, walls.c), against their numba
twins (blobcli/sim/statics.py, walls.py): the same bits.

Each scene runs some numba steps, then, step after step, a substep's collider stages in the order the step calls
them (pipeline._advance): the walls placed at the substep's end, the prediction (numba's, on both), the colliders
and the loaded walls' share each iteration, the loaded walls' velocity, the velocity stages' impulses into the
records and into the loaded walls, and the step's account. After each stage every array of the state must match,
for the C stage run serially, in parallel on one thread and on two. Some blobs are put to sleep at every other
check (skipped by the colliders, woken by a moving wall). The flags a scene's own build binds (MOVING, LOADED)
are run both ways where a scene can have either."""

import numpy as np
import pytest
from core_twins import assert_same_bits, core, scene_state, twins, views

from blobcli import jit
from blobcli.sim import pipeline, statics, walls
from blobcli.sim.integrate import predict

VARIANTS = ((False, 1), (True, 1), (True, 2))  # the C stage: (parallel, threads)

# Fixed colliders of every kind, with fast blobs that reach them within a substep (the swept tests): a sloping floor, a
# segment, a circle (blobs outside it), a concave polygon (a reflex corner), a box that is a conveyor belt.
FIXED = """[scene]
substeps = 4
iterations = 2
sleep = false
[[blob]]
mass = 0.7
name = "floor"
center = [-2.6, 0.9]
radius = 0.3
vertices = 16
velocity = [0.0, -40.0]
friction = 0.6
[[blob]]
mass = 1.3
name = "segment"
center = [0.2, 1.2]
radius = 0.25
vertices = 16
velocity = [30.0, -2.0]
[[blob]]
mass = 0.9
name = "circle"
center = [-1.0, 2.0]
radius = 0.25
vertices = 16
velocity = [0.5, -35.0]
restitution = 0.5
[[blob]]
mass = 1.1
name = "corner"
center = [2.6, 2.3]
radius = 0.2
vertices = 16
velocity = [0.0, -30.0]
static_friction = 0.9
[[blob]]
mass = 0.6
name = "belt"
center = [-3.6, 0.97]
radius = 0.25
vertices = 16
friction = 0.9
[[static]]
kind = "plane"
point = [0.3, 0.0]
normal = [0.1, 1.0]
restitution = 0.3
[[static]]
kind = "segment"
a = [1.0, 0.05]
b = [1.0, 2.5]
[[static]]
kind = "circle"
center = [-1.0, 0.6]
radius = 0.35
[[static]]
kind = "polygon"
points = [[1.8, 0.3], [3.4, 0.3], [3.4, 1.6], [2.6, 0.8], [1.8, 1.6]]
friction = 0.2
[[static]]
kind = "box"
center = [-3.6, 0.6]
size = [1.4, 0.2]
angle = 8.0
friction = 0.9
surface_velocity = 1.5
"""

# A drum turning (a container circle that moves at an angular velocity, and a surface velocity), a circle that
# slides across it, and a segment turning about its pivot: moving colliders without loads.
DRUM = """[scene]
substeps = 4
iterations = 2
sleep = false
[[blob]]
mass = 0.8
name = "grain"
center = [-0.6, -0.7]
radius = 0.22
vertices = 16
grid = [3, 2]
spacing = [0.5, 0.5]
velocity = [3.0, -4.0]
friction = 0.8
[[static]]
kind = "circle"
center = [0.0, 0.0]
radius = 1.3
inside = true
friction = 0.8
surface_velocity = 1.3
angular_velocity = 1.0
[[static]]
kind = "circle"
center = [-0.2, 0.55]
radius = 0.2
velocity = [0.0, -1.5]
angular_velocity = -2.0
[[static]]
kind = "segment"
a = [0.2, 0.9]
b = [1.0, 0.1]
angular_velocity = 3.0
velocity = [-0.5, 0.0]
"""

# Colliders on paths of keyframes, turning as they go: a box pressing a blob onto a plane that sways, a polygon
# that sweeps across; a keyframe before the first is held, and the last after it.
PRESS = """[scene]
substeps = 4
iterations = 3
sleep = false
[[blob]]
mass = 1.7
name = "gish"
center = [0.0, 0.45]
radius = 0.4
vertices = 24
friction = 0.6
[[blob]]
mass = 0.75
name = "side"
center = [1.6, 0.3]
radius = 0.25
vertices = 16
[[static]]
kind = "plane"
point = [0.2, 0.0]
normal = [0.0, 1.0]
path = [[0.02, 0.0, 0.0, 0.0], [0.1, 0.0, 0.02, 3.0], [0.15, 0.0, -0.01, -2.0]]
[[static]]
kind = "box"
center = [0.0, 1.05]
size = [2.0, 0.2]
friction = 0.7
path = [[0.03, 0.0, 0.0, 0.0], [0.12, 0.1, -0.35, 6.0], [0.2, 0.1, -0.35, 6.0]]
[[static]]
kind = "polygon"
points = [[2.4, 0.1], [2.8, 0.1], [2.8, 0.9], [2.6, 0.5], [2.4, 0.9]]
path = [[0.0, 0.0, 0.0, 0.0], [0.25, -1.0, 0.0, 25.0]]
"""

# Loaded walls on blobs in a corner: a piston (a box), a loaded segment pushing sideways (a light one) and a loaded
# circle; a fixed floor and side wall (vertices in the corners pushed by two colliders).
PISTON = """[scene]
substeps = 4
iterations = 3
sleep = false
[[blob]]
mass = 1.2
name = "cell"
center = [-0.6, 0.26]
radius = 0.25
vertices = 16
grid = [3, 2]
spacing = [0.6, 0.52]
friction = 0.3
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "plane"
point = [0.86, 0.0]
normal = [-1.0, 0.0]
[[static]]
kind = "box"
center = [0.0, 1.15]
size = [1.7, 0.2]
load = 200.0
load_direction = [0.0, -1.0]
mass = 5.0
friction = 0.0
[[static]]
kind = "segment"
a = [-0.86, 0.02]
b = [-0.86, 0.6]
load = 3.0
load_direction = [1.0, 0.0]
mass = 0.2
[[static]]
kind = "circle"
center = [0.6, 1.12]
radius = 0.08
load = 30.0
load_direction = [0.0, -1.0]
mass = 1.0
"""



def poke_fixed(state, model):
    """Vertices no path of FIXED's reaches, put there after the prediction (as another stage might): one that began
    exactly on the segment's line, two that began inside the circle (one at its very centre), one that began inside
    the polygon below its reflex corner (nearest the corner)."""
    pos, prev, o = state.position, state.previous, model.offsets
    for i, start, end in [(o[1], (1.0, 1.0), (0.98, 1.0)), (o[2], (-1.0, 0.6), (-1.0, 0.6)),
                          (o[2] + 1, (-0.9, 0.6), (-0.9, 0.6)), (o[3], (2.6, 0.7), (2.6, 0.7))]:
        prev[:, i], pos[:, i] = start, end


def poke_piston(state, model):
    """Vertices pushed into PISTON's corners, below the floor and beyond the side wall or the loaded segment: two
    colliders push each."""
    o = model.offsets
    # the bottom right blob's vertex nearest the side wall, the bottom left one's nearest the segment
    for i, start, end in [(o[2], (0.84, 0.01), (0.9, -0.02)), (o[0] + 8, (-0.84, 0.1), (-0.9, -0.01))]:
        state.previous[:, i], state.position[:, i] = start, end


# (scene, numba steps first, checks, the flags (MOVING, LOADED) to run the colliders with, vertices put where no
# path reaches)
SCENES = {
    "fixed": (FIXED, 2, 8, [(True, True), (False, False)], poke_fixed),
    "fixed later": (FIXED, 40, 6, [(True, True), (False, False)], None),  # at rest: held, on the belt too
    "drum": (DRUM, 4, 6, [(True, True), (True, False)], None),
    "press": (PRESS, 2, 10, [(True, True), (True, False)], None),
    "piston": (PISTON, 4, 8, [(True, True)], poke_piston),
}


class Twin:
    """One C copy of the state, with its views, scratch and how its stages run (parallel, threads)."""

    def __init__(self, ffi, lib, model, state, settings, parallel, threads, moving, loaded):
        self.lib, self.state, self.threads = lib, state, threads
        self.v = views(ffi, model, state, settings, parallel)
        self.v.settings.moving, self.v.settings.loaded = moving, loaded
        self.w = ffi.gc(lib.bc_scratch_new(self.v.model), lib.bc_scratch_free)
        assert self.w != ffi.NULL
        self.v.context.w = self.w

    def run(self, name, *args):
        self.lib.bc_set_threads(self.threads)
        return getattr(self.lib, name)(self.v.context, *args)


def same(stage, ref, twin):
    try:
        assert_same_bits(ref, twin.state)
    except AssertionError as e:
        raise AssertionError(f"{stage} (parallel {bool(twin.v.settings.parallel)}, {twin.threads} threads): {e}")


def sleep_some(state, check):
    """Every other check, put every third blob to sleep (as if its island had come to rest)."""
    if check % 2 == 1:
        state.awake[check % 3::3] = 0


def substep(ref, cores, model, settings, collide, moving, loaded, h, poke):
    """One substep's collider stages, numba on `ref` and C on each of `cores`, compared after each."""
    m, s = model.arrays, ref

    def both(stage, numba_call, *args):
        numba_call()
        for twin in cores:
            twin.run(stage, *args)
            same(stage, ref, twin)

    t = float((s.steps_done[0] * settings.substeps) * h)
    if moving:
        both("bc_place_walls", lambda: walls.place_walls(t, h, m.walls, s.static_pose, m.statics, s.placed, s.position,
                                                         m.offsets, s.awake, s.still), t, h)
    for state in [s] + [twin.state for twin in cores]:  # the same prediction on every copy
        predict(state.position, state.previous, state.velocity, state.lam, state.contact_depth, m.offsets,
                state.awake, state.predicted, settings.gx, settings.gy, h)
        if poke is not None:
            poke(state, model)
    for _ in range(settings.iterations):
        both("bc_collide_statics", lambda: collide(s.position, s.previous, m.blob_of, s.awake, m.material, m.statics,
                                                   s.placed, s.contact_normal, s.contact_depth, s.contact_material,
                                                   s.touch, h), h)
        if loaded:
            both("bc_yield_loaded_walls", lambda: walls.yield_loaded_walls(s.position, m.inv_mass, m.walls,
                                                                           s.static_pose, m.statics, s.placed,
                                                                           s.touch))
    if loaded:
        both("bc_finish_loaded_walls", lambda: walls.finish_loaded_walls(m.walls, s.static_pose, h), h)
    both("bc_record_contact_impulses", lambda: walls.record_contact_impulses(
        s.position, s.previous, s.velocity, m.inv_mass, m.offsets, s.awake, s.contact_depth, m.walls, s.touch, h), h)
    if loaded:
        both("bc_react_loaded_walls", lambda: walls.react_loaded_walls(
            s.position, s.previous, s.velocity, m.inv_mass, m.offsets, s.awake, s.contact_normal, s.contact_depth,
            m.walls, s.static_pose, s.touch, h), h)
    both("bc_account_contacts", lambda: walls.account_contacts(s.position, m.inv_mass, m.walls, s.static_pose,
                                                               s.touch, s.static_impulse, h), h)


@pytest.mark.parametrize("name", SCENES)
def test_the_collider_stages_give_numbas_bits(name):
    toml, steps, checks, flags, poke = SCENES[name]
    ffi, lib = core()
    model, state, params, settings = scene_state(toml, steps)
    config = pipeline.shared_build(pipeline.configuration(model, params)).constants()
    h = settings.dt / settings.substeps
    contacts = 0
    for check in range(checks):
        for moving, loaded in flags:
            collide = jit.build(statics.collide_statics, False, dict(config, MOVING=moving, LOADED=loaded))
            ref, base = twins(state)
            sleep_some(ref, check)
            sleep_some(base, check)
            cores = [Twin(ffi, lib, model, copy, settings, parallel, threads, moving, loaded)
                     for (parallel, threads), copy in zip(VARIANTS, [base, *twins(base)])]
            substep(ref, cores, model, settings, collide, moving, loaded, h, poke)
            contacts += int(np.count_nonzero(ref.contact_depth))
        pipeline.advance(state, model, params, 1, step_settings=settings)
    assert contacts > 0  # the colliders pushed


@pytest.mark.parametrize("name", SCENES)
def test_placing_the_walls_at_the_start_and_whether_any_moves_give_numbas_bits(name):
    ffi, lib = core()
    model, state, params, settings = scene_state(SCENES[name][0], 1)
    ref, copy = twins(state)
    twin = Twin(ffi, lib, model, copy, settings, False, 1, True, True)
    m = model.arrays
    assert bool(twin.run("bc_any_moves")) == walls.any_moves(m.walls) == model.moving
    walls.place_initial(m.walls, ref.static_pose, m.statics, ref.placed)
    twin.run("bc_place_initial")
    same("bc_place_initial", ref, twin)
