"""Twin tests of the compiled core's integration, restitution and sleep stages (blobcli/core/integrate.c,
restitution.c, sleep.c) against their numba kernels (sim/integrate.py, sim/sleep.py, collide.blob_restitution).

The step's own driver (pipeline._advance) runs as plain Python here, calling numba's stage builds for the
scene's (shared) configuration, so that every stage meets the inputs the real step gives it mid-substep (fresh
contacts, a bounce about to happen, blobs falling asleep). Each call of a stage under test is a twin test: the
state is copied, numba's kernel runs on the step's own state and the C stage on the copies (serial, and parallel
on 1 and 2 threads), and every array must agree bit for bit (the returned counts and the pairs' impact records
too). Stages that read MOVING are also checked with it off (numba's build without it, the C with moving = 0).
"""

from __future__ import annotations

import math
import types

import numba
import numpy as np
import pytest
from core_twins import assert_same_bits, core, scene_state, views

from blobcli import jit
from blobcli.sim import collide, integrate, pipeline, sleep
from blobcli.sim.jamming import copy_state

# (C stage parallel, threads): every stage call is checked in each
MODES = ((False, 1), (True, 2), (True, 1))

# Scenes that reach every branch: statics of each kind with restitution (bounces, first and later), a conveyor
# and a moving wall (MOVING's terms), blob–blob bounces, damping, sleeping islands that sleep and wake.
STATICS = """
[scene]
sleep_speed = 0.1
time_to_sleep = 0.1

[[blob]]
name = "on_plane"
center = [-3.0, 0.6]
radius = 0.3
vertices = 16
restitution = 0.8
velocity = [0.0, -3.0]

[[blob]]
name = "on_segment"
center = [-1.5, 1.2]
radius = 0.25
vertices = 12
restitution = 0.6
angular_velocity = 4.0

[[blob]]
name = "on_circle"
center = [0.0, 2.1]
radius = 0.25
vertices = 14
restitution = 1.0

[[blob]]
name = "on_polygon"
center = [1.6, 1.4]
radius = 0.25
vertices = 12
restitution = 0.5

[[blob]]
name = "on_belt"
center = [3.5, 0.9]
radius = 0.25
vertices = 12
restitution = 0.3

[[blob]]
name = "on_lift"
center = [5.5, 0.7]
radius = 0.25
vertices = 12

[[blob]]
name = "left"
center = [-1.5, 4.0]
radius = 0.3
vertices = 16
restitution = 0.9
velocity = [3.0, 0.0]

[[blob]]
name = "right"
center = [0.5, 4.1]
radius = 0.3
vertices = 16
restitution = 0.9
velocity = [-3.0, 0.0]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
restitution = 0.5

[[static]]
kind = "segment"
a = [-2.0, 0.6]
b = [-1.0, 0.5]
restitution = 0.7

[[static]]
kind = "circle"
center = [0.0, 1.0]
radius = 0.5
restitution = 0.9

[[static]]
kind = "polygon"
points = [[1.2, 0.5], [2.0, 0.5], [1.6, 0.9]]
restitution = 0.4

[[static]]
kind = "box"
center = [3.5, 0.4]
size = [1.5, 0.2]
surface_velocity = 1.0
restitution = 0.2

[[static]]
kind = "box"
center = [5.5, 0.3]
size = [1.0, 0.1]
velocity = [0.2, 0.4]
"""

# A fast fall that takes more substeps (and stops the whole blob at its impact), over a stack of three
FAST = """
[scene]
damping = 0.0

[[blob]]
name = "fast"
center = [-1.5, 2.0]
radius = 0.3
vertices = 20
velocity = [0.0, -30.0]
restitution = 0.7

[[blob]]
name = "faster"
center = [-3.0, 3.5]
radius = 0.3
vertices = 20
velocity = [0.0, -80.0]
restitution = 0.2

[[blob]]
name = "stack"
center = [1.0, 0.41]
radius = 0.4
grid = [1, 3]
spacing = [0.0, 0.82]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
restitution = 0.3

[[static]]
kind = "box"
center = [0.45, 2.0]
size = [0.1, 5.0]

[[static]]
kind = "box"
center = [1.55, 2.0]
size = [0.1, 5.0]
"""

# 40 blobs (the parallel stages) rain into a box, bouncing, and fall asleep as islands
PILE = """
[scene]
sleep_speed = 0.1
time_to_sleep = 0.1

[[blob]]
name = "pile"
center = [-1.2, 0.6]
radius = 0.15
vertices = 12
restitution = 0.6
grid = [8, 5]
spacing = [0.34, 0.34]

[[blob]]
name = "launched"  # up and back, onto the pile asleep: it wakes
center = [0.0, 3.0]
radius = 0.15
vertices = 12
velocity = [0.0, 20.0]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
restitution = 0.4

[[static]]
kind = "box"
center = [-1.6, 2.0]
size = [0.2, 4.0]

[[static]]
kind = "box"
center = [1.5, 2.0]
size = [0.2, 4.0]
"""

# One blob (no stack to measure) comes to rest on the floor and sleeps
ALONE = """
[scene]
sleep_speed = 0.1
time_to_sleep = 0.1

[[blob]]
name = "alone"
center = [0.0, 0.35]
radius = 0.3
vertices = 16

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

# No gravity, a periodic box: blobs of two tables fly at each other and bounce (the virial), under drag
PERIODIC = """
[scene]
gravity = [0.0, 0.0]
periodic = [3.0, 3.0]
drag = 0.5
seed = 2

[[blob]]
name = "east"
radius = 0.14
vertices = 12
count = 18
velocity = [2.0, 0.3]
restitution = 1.0

[[blob]]
name = "west"
radius = 0.12
vertices = 12
count = 18
velocity = [-2.0, -0.5]
restitution = 0.8
"""

# (toml, phases: (numba steps, twin-tested steps), ..., what sleep does in them: blobs fall asleep, are woken).
# The phases are where the events are: the statics' blobs left and right meet in step 14 and its first blob
# sleeps in step 182; the fast blobs hit the floor in steps 3 and 4; the pile sleeps in step 219 and is woken
# in step 250; the blob alone sleeps in step 26.
SCENES = {
    "statics": (STATICS, ((10, 5), (166, 2)), {"asleep"}),
    "fast": (FAST, ((2, 3),), set()),
    "pile": (PILE, ((10, 1), (207, 2), (29, 2)), {"asleep", "woken"}),
    "alone": (ALONE, ((24, 3),), {"asleep"}),
    "periodic": (PERIODIC, ((5, 1), (30, 2)), set()),
}


def _put(ffi, dest, array) -> None:
    array = np.ascontiguousarray(array)
    ffi.memmove(dest, ffi.from_buffer(array), array.nbytes)


class Twins:
    """The hooks that run each stage under test on the step's state (numba) and on copies of it (C)."""

    def __init__(self, ffi, lib, model, state, settings):
        self.ffi, self.lib, self.model, self.state, self.settings = ffi, lib, model, state, settings
        self.constants = pipeline.shared_build(settings.config).constants()
        self.still = dict(self.constants, MOVING=False)  # the builds of a scene without moving colliders
        self.scratch = lib.bc_scratch_new(views(ffi, model, state, settings).model)
        self.calls: dict[str, int] = {}
        self.events: set[str] = set()  # what update_sleep did: blobs fell "asleep", were "woken"
        self.h = None

    def close(self) -> None:
        self.lib.bc_scratch_free(self.scratch)

    def numba(self, kernel, constants=None):
        return jit.build(kernel, False, self.constants if constants is None else constants)

    def check(self, name, reference, c_stage, pairs=None, partners=None, pair_impact=None, moving=True):
        """Copies of the state for the C runs; the reference on the state itself; then every copy against it."""
        copies = [copy_state(self.state) for _ in MODES]
        records = None if pair_impact is None else pair_impact.copy()
        expected = reference()
        for (parallel, threads), twin in zip(MODES, copies):
            self.lib.bc_set_threads(threads)
            v = views(self.ffi, self.model, twin, self.settings, parallel)
            v.settings.moving = moving and self.settings.config.moving
            w = v.context.w = self.scratch
            if pairs is not None:
                w.pair_count = len(pairs)
                _put(self.ffi, w.pairs, pairs.astype(np.int64))
            if partners is not None:
                for dest, array in zip((w.partner_start, w.partner, w.partner_pair), partners):
                    _put(self.ffi, dest, array)
            if records is not None:
                _put(self.ffi, w.pair_impact, records)
            got = c_stage(v)
            where = f"{name} (parallel {parallel}, {threads} threads)"
            try:
                assert_same_bits(self.state, twin)
            except AssertionError as e:
                raise AssertionError(f"{where}: {e}") from None
            if expected is not None:
                assert got == expected, f"{where}: {got} != {expected}"
            if pair_impact is not None:
                kept = np.frombuffer(self.ffi.buffer(w.pair_impact, pair_impact.nbytes), np.float64)
                assert kept.tobytes() == pair_impact.tobytes(), f"{where}: pair_impact differs"
        self.calls[name] = self.calls.get(name, 0) + 1
        return expected

    def check_still(self, name, kernel, args, c_stage):
        """A stage that reads MOVING, with it off, on copies (the step goes on with the scene's own build)."""
        saved = self.state
        try:
            self.state = copy_state(saved)
            swap = {id(a): b for a, b in zip(_leaves(saved), _leaves(self.state))}
            moved_args = [swap.get(id(a), a) for a in args]
            self.check(name + " (MOVING off)", lambda: self.numba(kernel, self.still)(*moved_args), c_stage,
                       moving=False)
        finally:
            self.state = saved

    # the hooks, with _advance's arguments
    def substeps_for(self, *a):
        return self.check("substeps_for", lambda: integrate.substeps_for(*a), lambda v: self.lib.bc_substeps_for(
            v.context, a[6]))

    def damp_deformation(self, *a):
        self.check("damp_deformation", lambda: integrate.damp_deformation(*a),
                   lambda v: self.lib.bc_damp_deformation(v.context, a[4]))

    def drag_motion(self, *a):
        self.check("drag_motion", lambda: integrate.drag_motion(*a), lambda v: self.lib.bc_drag_motion(v.context, a[3]))

    def predict(self, *a):
        self.h = a[10]
        self.check("predict", lambda: integrate.predict(*a), lambda v: self.lib.bc_predict(v.context, a[10]))

    def stop_impacts(self, *a):
        self.check("stop_impacts", lambda: integrate.stop_impacts(*a), lambda v: self.lib.bc_stop_impacts(v.context))

    def stop_impact_velocities(self, *a):
        self.check("stop_impact_velocities", lambda: integrate.stop_impact_velocities(*a),
                   lambda v: self.lib.bc_stop_impact_velocities(v.context))

    def update_velocities(self, *a):
        def c_stage(v):
            self.lib.bc_update_velocities(v.context, a[8])
        self.check_still("update_velocities", integrate.update_velocities, a, c_stage)
        self.check("update_velocities", lambda: self.numba(integrate.update_velocities)(*a), c_stage)

    def restitution(self, *a):
        g = math.sqrt(self.settings.gx ** 2 + self.settings.gy ** 2)
        assert self.lib.bc_rest_speed(g, self.h) == a[11]

        def c_stage(v):
            self.lib.bc_restitution(v.context, a[11])
        self.check_still("restitution", integrate.restitution, a, c_stage)
        self.check("restitution", lambda: self.numba(integrate.restitution)(*a), c_stage)

    def blob_restitution(self, *a):
        pairs, partners, pair_impact = a[9], a[10], a[12]
        self.check("blob_restitution", lambda: self.numba(collide.blob_restitution)(*a),
                   lambda v: self.lib.bc_blob_restitution(v.context, a[13]), pairs, partners, pair_impact)

    def update_sleep(self, *a):
        awake = self.state.awake.copy()
        count = self.check("update_sleep", lambda: sleep.update_sleep(*a), lambda v: self.lib.bc_update_sleep(
            v.context), pairs=a[4])
        if np.any(awake > self.state.awake):
            self.events.add("asleep")
        if np.any(awake < self.state.awake):
            self.events.add("woken")
        return count

    def awake_count(self, *a):
        return self.check("awake_count", lambda: sleep.awake_count(*a), lambda v: self.lib.bc_awake_count(v.context))


def _leaves(state):
    for x in state:
        if isinstance(x, tuple):
            yield from _leaves(x)
        else:
            yield x


HOOKED = ("substeps_for", "damp_deformation", "drag_motion", "predict", "stop_impacts", "stop_impact_velocities",
          "update_velocities", "restitution", "blob_restitution", "update_sleep", "awake_count")


def twin_steps(twins: Twins, steps: int) -> None:
    """pipeline._advance run as Python over `steps` steps: numba's stage builds for the scene's (shared)
    configuration, the stages under test through the twins' hooks."""
    fn = jit._STAGES[id(pipeline._advance)][1]
    scope = dict(fn.__globals__)
    scope.update(twins.constants)
    for name in fn.__code__.co_names:
        kernel = scope.get(name)
        if name in HOOKED:
            scope[name] = getattr(twins, name)
        elif isinstance(kernel, numba.core.registry.CPUDispatcher):
            if id(kernel) in jit._STAGES:
                scope[name] = twins.numba(kernel)
            elif kernel.targetoptions.get("no_cpython_wrapper"):
                scope[name] = kernel.py_func  # (an inlined helper has no Python entry)
    scope["_lap"] = lambda clock, stage, t: t
    advance = types.FunctionType(fn.__code__, scope, fn.__name__)
    done, why, _ = advance(steps, twins.state, twins.model.arrays, twins.settings, pipeline.NO_CLOCK)
    assert (done, why) == (steps, pipeline.DONE)


@pytest.mark.parametrize("scene", SCENES)
def test_stages_twin(scene):
    ffi, lib = core()
    toml, phases, events = SCENES[scene]
    model, state, params, settings = scene_state(toml, 0)
    twins = Twins(ffi, lib, model, state, settings)
    try:
        for numba_steps, twin_tested in phases:
            pipeline.advance(state, model, params, numba_steps)
            twin_steps(twins, twin_tested)
        every = {"substeps_for", "predict", "stop_impacts", "update_velocities", "stop_impact_velocities",
                 "restitution", "update_sleep", "awake_count"} | ({"blob_restitution"} if model.collides else set())
        assert every <= set(twins.calls)
        assert events <= twins.events
    finally:
        lib.bc_set_threads(1)
        twins.close()
    if scene == "periodic":
        assert "drag_motion" in twins.calls
    else:
        assert ("damp_deformation" in twins.calls) == (params.damping > 0.0)


# Five blobs stacked in a shaft (scenes/stack.toml)
STACK = """
[[blob]]
name = "stack"
center = [0.0, 0.45]
radius = 0.4
grid = [1, 5]
spacing = [0.0, 0.82]

[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]

[[static]]
kind = "box"
center = [-0.55, 2.0]
size = [0.1, 5.0]

[[static]]
kind = "box"
center = [0.55, 2.0]
size = [0.1, 5.0]
"""


def test_substeps_for_stacks():
    """substeps_for where a stack's sag decides the substeps (rows_stacked): with one substep the least and no
    most, and g and dt where dt √(n g / (SAG L)) outgrows the stride term and tells n = 3, 4, 5 ... apart."""
    ffi, lib = core()
    for toml, steps in ((STACK, 40), (PILE, 60), (PILE, 230)):
        model, state, params, settings = scene_state(toml, steps)
        a = model.arrays
        assert integrate.rows_stacked(state.position, a.offsets, a.rest_perimeter, settings.up_x, settings.up_y) >= 3
        v = views(ffi, model, state, settings)
        w = v.context.w = lib.bc_scratch_new(v.model)
        try:
            for dt, g in ((1e-3, 1e4), (1e-3, 1e5), (1e-3, 1e6), (1e-2, 1e4), (1 / 60, 9.81)):
                v.settings.dt, v.settings.substeps, v.settings.most_substeps = dt, 1, 10 ** 9
                expected = integrate.substeps_for(state.position, state.velocity, a.offsets, state.awake,
                                                  a.rest_perimeter, dt, g, settings.up_x, settings.up_y, 1, 10 ** 9)
                assert lib.bc_substeps_for(v.context, g) == expected, (steps, dt, g)
        finally:
            lib.bc_scratch_free(w)


class LostEdges(Twins):
    """A contact that pushed in an earlier iteration keeps its c_hit when the narrow phase, finding its blob's
    contacts again, finds no edge for it (c_edge -1): blob_restitution reads that, as numba does, as
    blob_of[-1], the last vertex's blob. Here the contacts that pushed on the last blob lose their edge so, and
    its own contacts did not push: its pairs touch through the lost edges alone."""

    lost = 0

    def blob_restitution(self, *a):
        c_edge, c_hit = a[7], a[8]
        blob_of = self.model.arrays.blob_of
        last = blob_of[-1]
        c_hit[:, blob_of == last] = 0
        hit = (c_hit != 0) & (blob_of[c_edge] == last)
        c_edge[hit] = -1
        self.lost += int(hit.sum())
        super().blob_restitution(*a)


def test_blob_restitution_lost_edges():
    ffi, lib = core()
    model, state, params, settings = scene_state(PERIODIC, 19)  # the last blob meets others in steps 20-23
    twins = LostEdges(ffi, lib, model, state, settings)
    try:
        twin_steps(twins, 2)
    finally:
        lib.bc_set_threads(1)
        twins.close()
    assert twins.lost > 0 and twins.calls["blob_restitution"] > 0


@pytest.mark.parametrize("scene", ["statics", "pile"])
def test_begin_still(scene):
    """begin_still on a state just built (as model.build calls it) and on one that has moved."""
    ffi, lib = core()
    model, state, params, settings = scene_state(SCENES[scene][0], 0)
    for steps in (0, 20):
        pipeline.advance(state, model, params, steps)
        reference, twin = copy_state(state), copy_state(state)
        reference.still[:] = twin.still[:] = 1.0
        sleep.begin_still(reference.position, model.arrays.offsets, reference.still, reference.still_center,
                          reference.still_angle)
        v = views(ffi, model, twin)  # (kept: the context points into its structs)
        lib.bc_begin_still(v.context)
        assert_same_bits(reference, twin)
