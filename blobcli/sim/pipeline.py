"""The step of the simulation, as Python calls it: the compiled core's driver (blobcli/core/step.c).

The step is a list of named stages (step.c reads top to bottom: predict, then per iteration the perimeter,
the self-contacts, the area, the adhesion (the last iteration, where something is sticky), the blob contacts and
the colliders, then the velocities and the bounces),
each a C function over flat arrays (model.State: structure of arrays). `advance` fills the C views over a
run's arrays once (blobcli.core.Views) and runs as many steps as it is asked in one call: Python is entered
only between calls (to record a frame, update the progress bar, see a Ctrl-C), never per substep. One
library serves every scene: what a scene uses (its area method, blob contacts, its colliders, moving or
loaded walls, sleeping, a periodic box, threads or not) is read at run time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..colliders import SOLVERS
from ..scene.schema import MAX_STEP_WORK, METHODS
from .measure import RUNAWAY
from .model import LOADED, PAIRS_PER_BLOB, Model, Params, SimulationError, State

STAGES = ("walls", "damping", "predict", "broad phase", "perimeter", "area", "blob detect", "blob resolve",
          "self contact", "statics", "velocities", "restitution", "blob velocities", "blob restitution", "sleep",
          "adhesion")


class Configuration(NamedTuple):
    """What a scene uses: the stages the step runs for it (step.c reads these at run time)."""
    method: int  # index into area.METHODS
    collides: bool  # blob–blob stages: more than one blob
    statics: bool  # static collider stage: any static collider (which kinds: statics' rows, per kind)
    planes: bool
    segments: bool
    circles: bool
    polygons: bool
    sleep: bool  # islands at rest go to sleep (blobcli/core/sleep.c)
    moving: bool  # a collider moves (blobcli/core/walls.c) ...
    loaded: bool  # ... or is a loaded wall
    periodic: bool  # a periodic box: the broad phase wraps; contacts see nearest images


class StepSettings(NamedTuple):
    """Params and the model's numbers, as the compiled step reads them (bcSettings)."""
    dt: float  # s
    substeps: int  # the least a step takes ...
    most_substeps: int  # ... and the most (blobcli/core/integrate.c: bc_substeps_for)
    iterations: int
    gx: float  # m/s²
    gy: float
    damping: float  # 1/s
    drag: float  # 1/s
    up_x: float  # -g / |g| (0 without gravity): "above", for the stacking rule of the contact solver
    up_y: float
    sleep_speed: float  # m/s: islands at rest go to sleep once every blob has gone slower than this, on average ...
    time_to_sleep: float  # s ... for this long
    box_x: float  # m: the periodic box's sides; 0: an open world
    box_y: float
    box_tilt: float  # m: γ L_y, how far the image above is shifted along x (Lees–Edwards shear γ)
    config: Configuration


def configuration(model: Model, params: Params) -> Configuration:
    """What the scene uses."""
    kinds = {s.kind for s in model.statics}
    return Configuration(method=METHODS.index(params.method), collides=model.collides, statics=bool(kinds),
                         planes="plane" in kinds, segments="segment" in kinds, circles="circle" in kinds,
                         polygons="polygon" in kinds, sleep=params.sleep, moving=model.moving, loaded=model.loaded,
                         periodic=params.box[0] > 0.0 and model.collides)


def settings(model: Model, params: Params) -> StepSettings:
    """What the compiled step needs of params and the model."""
    g = math.hypot(params.gravity[0], params.gravity[1])
    up = -params.gravity / g if g > 0 else np.zeros(2)
    # the most: the scene's max_substeps, within the step's work bound (never fewer than `substeps`)
    vertices = int(model.offsets[-1])
    most = max(params.substeps, min(params.max_substeps, MAX_STEP_WORK // max(params.iterations * vertices, 1)))
    return StepSettings(dt=params.dt, substeps=params.substeps, most_substeps=most, iterations=params.iterations,
                        gx=float(params.gravity[0]), gy=float(params.gravity[1]), damping=params.damping,
                        drag=params.drag,
                        up_x=float(up[0]), up_y=float(up[1]),
                        sleep_speed=params.sleep_speed,
                        time_to_sleep=params.time_to_sleep if params.sleep else math.inf,
                        box_x=float(params.box[0]), box_y=float(params.box[1]),
                        box_tilt=float(params.shear * params.box[1]), config=configuration(model, params))


def describe(model: Model, step_settings: StepSettings) -> str:
    """What the step runs for this scene, in words: 'kot, blob contacts, plane and polygon colliders, sleeping;
    parallel'."""
    c = step_settings.config
    kinds = [kind for kind, present in zip(SOLVERS, (c.planes, c.segments, c.circles, c.polygons)) if present]
    parts = [METHODS[c.method]] + (["blob contacts"] if c.collides else []) \
        + ([" and ".join(kinds) + " colliders"] if kinds else []) + (["loaded walls"] if c.loaded else
                                                                     ["moving walls"] if c.moving else []) \
        + (["sleeping"] if c.sleep else []) + (["periodic box"] if c.periodic else [])
    return ", ".join(parts) + ("; parallel" if model.parallel else "; serial")


class _LastCall:
    """The C views over the arrays of the last call, with the step's scratch, kept while the same state,
    arrays and settings are stepped again (a run calls `advance` once per recorded frame)."""
    key = None
    views = None


def _views(state: State, arrays, step_settings: StepSettings, parallel: bool):
    from ..core import Views, load

    key = (id(state), id(state.position), id(arrays), step_settings, parallel)
    views = _LastCall.views
    if _LastCall.key != key:  # (the views hold the arrays, so no other array takes their ids while kept)
        ffi, lib = load()
        views = Views(ffi, arrays, state, step_settings, parallel)
        scratch = lib.bc_scratch_new(views.model)
        if scratch == ffi.NULL:
            raise MemoryError("the step's scratch could not be allocated")
        views.scratch = ffi.gc(scratch, lib.bc_scratch_free)  # freed with the views, never under a running step
        views.context.w = views.scratch
        _LastCall.key, _LastCall.views = key, views
    return views


def advance(state: State, model: Model, params: Params, steps: int, clock: dict | None = None,
            step_settings: StepSettings | None = None, arrays=None) -> int:
    """Advance the state by up to `steps` steps of params.dt (each in `substeps` substeps or more, up to
    `max_substeps`: blobcli/core/integrate.c), in one call of the compiled step. Returns the steps done:
    fewer than asked only when a step left a vertex (or a collider's pose) non-finite or beyond RUNAWAY. Raises
    SimulationError when far more blob pairs overlap than the step holds, or when a step left a blob inside out or
    crushed beside a moving collider (core/walls.c: bc_first_broken_blob).

    With `clock` (a dict), each stage's wall time is added to clock[stage name], in seconds:
    `blobsim bench` profiles the real step this way. `step_settings` (from `settings`) saves
    rebuilding them on every call; `arrays` (a schedule's: sim/schedule.py) replace model.arrays."""
    from ..core import load

    ffi, lib = load()
    step_settings = step_settings or settings(model, params)
    views = _views(state, model.arrays if arrays is None else arrays, step_settings, model.parallel)
    timer = np.zeros(lib.BC_STAGE_COUNT) if clock is not None else None  # the clock's slots, STAGES in order
    stop = lib.bc_advance(views.context, steps, RUNAWAY,
                          ffi.NULL if timer is None else ffi.cast("double *", timer.ctypes.data))
    if timer is not None:
        for name, seconds in zip(STAGES, timer):
            clock[name] = clock.get(name, 0.0) + float(seconds)
    if stop.why == lib.BC_TOO_MANY_PAIRS:
        most = PAIRS_PER_BLOB * model.blob_count
        raise SimulationError(f"{stop.detail:,} blob pairs overlap (at most {most:,}, {PAIRS_PER_BLOB} per blob): "
                              "are blobs spawned on top of each other?", steps_done=stop.steps)
    if stop.why == lib.BC_NO_MEMORY:
        raise MemoryError("the step's scratch could not be allocated")
    if stop.why in (lib.BC_BROKEN_BLOB, lib.BC_PASSED_BLOB):
        blob, wall = divmod(stop.detail, len(model.walls.motion))
        raise SimulationError(broken_blob(state, model, blob, wall, stop.why == lib.BC_PASSED_BLOB, arrays),
                              steps_done=stop.steps)
    return stop.steps


def broken_blob(state: State, model: Model, blob: int, wall: int, passed: bool = False, arrays=None) -> str:
    """What the step says of blob `blob`, which loaded wall `wall` passed through (`passed`), or which it left
    inside out or crushed beside moving collider `wall` (core/walls.c: bc_find_passed_blob, bc_first_broken_blob);
    `arrays`: a schedule's, whose target areas the blob was held to."""
    from .measure import blob_measures

    area, _ = blob_measures(state, model)
    ratio = area[blob] / (model.target_area if arrays is None else arrays.target_area)[blob]
    what = "inside out" if not ratio > 0.0 else f"at {ratio:.0%} of its area"
    if model.walls.motion[wall] == LOADED:
        kind, why = "loaded", ("the blobs it presses cannot carry its load at the substeps a step may take: lower "
                               "the load, or let a step take more ([scene] max_substeps), or stiffen the blobs")
    else:
        kind, why = "moving", "a kinematic collider moves as it is told, however hard the blobs push back"
    if passed:
        return f"static[{wall}], a loaded collider, passed into or through blob {blob} ({model.names[blob]}): {why}"
    return f"blob {blob} ({model.names[blob]}) is {what} beside static[{wall}], a {kind} collider: {why}"


def step(state: State, model: Model, params: Params, clock: dict | None = None) -> None:
    """Advance the state by one step (see `advance`)."""
    advance(state, model, params, 1, clock)
