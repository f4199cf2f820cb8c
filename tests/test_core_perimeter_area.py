"""The perimeter and area stages, compiled (blobcli/core/perimeter.c, area.c), against their numba twins
(blobcli/sim/perimeter.py, area.py): the same bits.

Each scene runs some numba steps (its own area method), then, step after step, every stage (the perimeter and
all four area methods, whatever the scene's method: each reads only its own arrays) runs three times in a row on
twin copies of the state, and every array of the state must match after each call, for the C stage run serially,
in parallel on one thread and on two. Each step's state is also changed on both twins, in turn: some blobs put to
sleep (skipped), one ring stretched by half (the total length's trust region), one mirrored (turned inside out:
kot's unreachable area, gas's skipped blob), one collapsed to a point (zero-length edges, zero gradients, q = 0).
"""

import numpy as np
import pytest
from core_twins import assert_same_bits, core, scene_state, views

from blobcli.sim import area, perimeter, pipeline
from blobcli.sim.jamming import copy_state

VARIANTS = ((False, 1), (True, 1), (True, 2))  # the C stage: (parallel, threads)
REPEATS = 3  # calls of a stage in a row on the same twins
STEPS = 3  # states per scene, a numba step apart

# Rings of many vertex counts (3 to 128), both windings (a clockwise polygon: negative target area), an
# over-pressured blob, an inextensible hard one (compliance 0, area_compliance 0: the collapsed ring's zero
# weights), and soft ones, dropped onto a floor and each other.
BLOBS = """
[[blob]]
name = "triangle"
center = [-2.0, 0.6]
radius = 0.3
vertices = 3
[[blob]]
name = "pentagon"
center = [-1.2, 0.5]
radius = 0.3
vertices = 5
pressure = 2.0
area_compliance = 0.001
gas_pressure = 40.0
[[blob]]
name = "hard"
center = [-0.4, 0.8]
radius = 0.35
vertices = 12
compliance = 0.0
[[blob]]
name = "soft"
center = [0.5, 0.6]
radius = 0.4
vertices = 33
compliance = 0.002
area_compliance = 0.0001
spring_stiffness = 300.0
velocity = [0.0, -3.0]
[[blob]]
name = "long"
center = [1.7, 0.9]
radius = 0.6
vertices = 128
pressure = 1.3
[[blob]]
name = "clockwise"
points = [[2.6, 0.2], [2.5, 0.9], [3.1, 1.0], [3.3, 0.4], [2.9, 0.1]]
pressure = 0.8
[[blob]]
name = "fast"
center = [0.0, 2.2]
radius = 0.3
vertices = 7
velocity = [0.5, -8.0]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def _scene(method: str) -> str:
    return f'[scene]\nmethod = "{method}"\nsubsteps = 4\niterations = 2\n' + BLOBS


# >= 32 blobs (model.PARALLEL_BLOBS): the parallel builds, each blob a parallel item
PILE = """[scene]
substeps = 4
iterations = 2
[[blob]]
name = "pile"
center = [-1.6, 0.3]
radius = 0.18
vertices = 11
grid = [8, 5]
spacing = [0.4, 0.38]
[[blob]]
name = "big"
center = [0.0, 2.4]
radius = 0.4
vertices = 40
velocity = [0.0, -6.0]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""

SCENES = {"kot": (_scene("kot"), 12), "xpbd": (_scene("xpbd"), 12), "gas": (_scene("gas"), 12),
          "springs": (_scene("springs"), 12), "pile": (PILE, 15)}


def _stages(h: float, iterations: int):
    """(name, numba call on a state, C call on a context) of each stage, with the step's arguments."""
    return (
        ("perimeter",
         lambda m, s: perimeter.solve_perimeter(s.position, m.inv_mass, m.offsets, s.awake, m.rest_length,
                                                m.rest_perimeter, m.compliance, s.lam, s.perimeter_lam, h),
         lambda lib, v: lib.bc_solve_perimeter(v.context, h)),
        ("kot",
         lambda m, s: area.area_kot(s.position, m.inv_mass, m.offsets, s.awake, m.target_area),
         lambda lib, v: lib.bc_area_kot(v.context)),
        ("xpbd",
         lambda m, s: area.area_xpbd(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.area_compliance,
                                     s.area_lam, h),
         lambda lib, v: lib.bc_area_xpbd(v.context, h)),
        ("gas",
         lambda m, s: area.area_gas(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.gas_pressure,
                                    h * h / iterations),
         lambda lib, v: lib.bc_area_gas(v.context, h * h / iterations)),
        ("springs",
         lambda m, s: area.area_springs(s.position, m.inv_mass, m.blob_of, s.awake, m.spring_pairs, m.spring_rest,
                                        m.spring_compliance, s.spring_lam, h),
         lambda lib, v: lib.bc_area_springs(v.context, h)),
    )


def _ring(model, b):
    o, e = model.offsets[b], model.offsets[b + 1]
    return slice(o, e)


def _changed(state, model, step: int):
    """A copy of the state, changed in turn (see the module docstring) so that every branch is met."""
    state = copy_state(state)
    blobs = len(model.offsets) - 1
    p = state.position
    if step % 3 == 1:
        state.awake[::3] = 0
    big = int(np.argmax(np.diff(model.offsets)))  # the longest ring: stretched by half about its centre
    r = _ring(model, big)
    for row in (0, 1):
        p[row, r] = p[row, r].mean() + 1.5 * (p[row, r] - p[row, r].mean())
    r = _ring(model, (big + 1) % blobs)  # the next one mirrored: the same ring, inside out
    p[0, r] = 2.0 * p[0, r].mean() - p[0, r]
    if step % 3 == 2:
        hard = int(np.argmin(model.compliance))  # an inextensible ring, collapsed onto its first vertex
        r = _ring(model, hard)
        p[:, r] = p[:, r.start:r.start + 1]
    return state


def _check(ffi, lib, model, settings, state, call_numba, call_core):
    """The stage REPEATS times on twins of `state`, numba's against each C variant's: the same bits each time."""
    reference = copy_state(state)
    copies = [copy_state(state) for _ in VARIANTS]
    contexts = []
    for copy, (parallel, _) in zip(copies, VARIANTS):
        v = views(ffi, model, copy, settings, parallel)
        w = lib.bc_scratch_new(v.model)
        assert w != ffi.NULL
        v.context.w = w
        contexts.append((v, w))
    try:
        for _ in range(REPEATS):
            call_numba(model.arrays, reference)
            for copy, (v, _), (_, threads) in zip(copies, contexts, VARIANTS):
                lib.bc_set_threads(threads)
                call_core(lib, v)
                assert_same_bits(reference, copy)
    finally:
        for _, w in contexts:
            lib.bc_scratch_free(w)
        lib.bc_set_threads(1)


@pytest.mark.parametrize("name", SCENES)
def test_perimeter_and_area_twins(name):
    ffi, lib = core()
    toml, steps = SCENES[name]
    model, state, params, settings = scene_state(toml, steps)
    if name == "pile":
        assert len(model.offsets) - 1 >= 32
    if name == "springs":
        assert len(model.arrays.spring_rest) > 0
    h = settings.dt / settings.substeps
    for step in range(STEPS):
        changed = _changed(state, model, step)
        for stage, call_numba, call_core in _stages(h, settings.iterations):
            try:
                _check(ffi, lib, model, settings, changed, call_numba, call_core)
            except AssertionError as e:
                raise AssertionError(f"{name}, step {step}, {stage}: {e}") from e
        pipeline.advance(state, model, params, 1)
