"""The step of the simulation: a list of named stages, compiled whole.

Each stage is a kernel over flat arrays (model.State: structure of arrays). `_advance` calls
them in order, for as many steps as it is asked, in one compiled call: Python is entered only
between calls (to record a frame, update the progress bar, see a Ctrl-C), never per substep.
A stage a scene does not need (one blob, no statics, another area method, sleeping off) is not
run, and not compiled: the step is compiled from this one text once per configuration (what the
scene uses: `Configuration`), each the first time a scene needs it, then loaded from numba's disk
cache (jit.build). Each configuration has a serial build and a parallel one (every stage's parallel
build), which scenes of 32 blobs or more run. All give the same bits.
"""

from __future__ import annotations

import math
import os
import time
from typing import NamedTuple

import numba
import numpy as np

from ..colliders import SOLVERS
from ..jit import build, in_disk_cache, inline_kernel, stage_kernel
from ..scene.schema import MAX_STEP_WORK
from .area import GAS, KOT, METHODS, SPRINGS, XPBD, area_gas, area_kot, area_springs, area_xpbd
from .collide import (
    CONTACTS_PER_VERTEX,
    MAX_STRIPS,
    PAIRS_PER_BLOB,
    blob_contact_velocities,
    blob_restitution,
    carry_impacts,
    find_blob_pairs,
    keep_blob_contacts,
    keep_impacts,
    keep_touching,
    release_sticks,
    resolve_blob_contacts,
)
from .integrate import (
    MIN_REST_SPEED,
    REST_SPEED_FACTOR,
    damp_deformation,
    drag_motion,
    predict,
    restitution,
    stop_impact_velocities,
    stop_impacts,
    substeps_for,
    update_velocities,
)
from .measure import RUNAWAY, first_runaway
from .model import Model, Params, SimulationError, State
from .perimeter import solve_perimeter
from .ring import most_vertices
from .self_contact import find_self_contacts, keep_rings_simple, pairs_found, resolve_self_contacts
from .sleep import awake_count, update_sleep
from .statics import collide_statics
from .walls import (
    account_contacts,
    any_moves,
    finish_loaded_walls,
    place_walls,
    react_loaded_walls,
    record_contact_impulses,
    yield_loaded_walls,
)

STAGES = ("walls", "damping", "predict", "broad phase", "perimeter", "area", "blob detect", "blob resolve",
          "self contact", "statics", "velocities", "restitution", "blob velocities", "blob restitution", "sleep")
# the stage clock's slots, and none: numpy integers, which numba types as int64, so that _lap is compiled
# once (a Python int is a literal to numba, and each slot compiled a _lap of its own)
(LAP_WALLS, LAP_DAMPING, LAP_PREDICT, LAP_BROAD_PHASE, LAP_PERIMETER, LAP_AREA, LAP_BLOB_DETECT, LAP_BLOB_RESOLVE,
 LAP_SELF_CONTACT, LAP_STATICS, LAP_VELOCITIES, LAP_RESTITUTION, LAP_BLOB_VELOCITIES, LAP_BLOB_RESTITUTION, LAP_SLEEP) \
    = map(np.int64, range(len(STAGES)))
NO_LAP = np.int64(-1)
DONE, RUNAWAY_VERTEX, TOO_MANY_PAIRS = range(3)  # why _advance returned


class Configuration(NamedTuple):
    """What a scene uses, bound as constants into the step's build for it (jit.build): the step reads
    each field as the global of its name in capitals (METHOD, COLLIDES, ...), below."""
    method: int  # index into area.METHODS
    collides: bool  # blob–blob stages: more than one blob
    statics: bool  # static collider stage: any static collider (which kinds: statics.PLANES, ...)
    planes: bool
    segments: bool
    circles: bool
    polygons: bool
    sleep: bool  # islands at rest go to sleep (sim/sleep.py)
    moving: bool  # a collider moves (sim/walls.py) ...
    loaded: bool  # ... or is a loaded wall
    periodic: bool  # a periodic box (sim/collide.py: the broad phase wraps; contacts see nearest images)

    def constants(self) -> dict:
        return {name.upper(): value for name, value in self._asdict().items()}


# The configuration names the step reads. These module values (every stage, area method kot) are never
# run: `advance` runs the build for the scene's Configuration.
METHOD, COLLIDES, STATICS, SLEEP, MOVING, LOADED, PERIODIC = KOT, True, True, True, True, True, True


class StepSettings(NamedTuple):
    """Params and the model's numbers, as the compiled step reads them; `config`, what the scene
    uses, decides which build of the step runs."""
    dt: float  # s
    substeps: int  # the least a step takes ...
    most_substeps: int  # ... and the most (integrate.substeps_for)
    iterations: int
    gx: float  # m/s²
    gy: float
    damping: float  # 1/s
    drag: float  # 1/s
    up_x: float  # -g / |g| (0 without gravity): "above", for the stacking rule of sim/collide.py
    up_y: float
    sleep_speed: float  # m/s: islands at rest go to sleep once every blob has gone slower than this, on average ...
    time_to_sleep: float  # s ... for this long (∞ with sleeping off: the shared build runs the sleep stage)
    box_x: float  # m: the periodic box's sides; 0: an open world
    box_y: float
    box_tilt: float  # m: γ L_y, how far the image above is shifted along x (Lees–Edwards shear γ)
    config: Configuration


@stage_kernel
def _advance(steps, state, model, settings, clock):
    """Run `steps` steps. Returns (steps done, why it stopped, detail): DONE; RUNAWAY_VERTEX after a step
    that left vertex `detail` non-finite or beyond RUNAWAY (that step not counted); TOO_MANY_PAIRS, when
    `detail` blob pairs overlap (the state is then mid-step). With a clock (one slot per stage), each
    stage's wall time is added to its slot, in seconds."""
    s, m, c = state, model, settings
    blob_count = m.offsets.shape[0] - 1
    no_pairs = np.zeros((0, 2), np.int64)
    pairs, partners, strips = no_pairs, (np.zeros(blob_count + 1, np.int64), no_pairs[:, 0], no_pairs[:, 0]), \
        (np.zeros(blob_count, np.int64), np.zeros(2, np.int64), np.arange(blob_count), np.zeros(blob_count, np.int64),
         False)
    pair_impact = np.zeros((0, 4))  # the impact records of this substep's pairs (integrate.bounce)
    slots = CONTACTS_PER_VERTEX * most_vertices(m.offsets)
    vertices = m.inv_mass.shape[0]
    resolve_scratch = (np.empty((MAX_STRIPS, slots, 8)), np.empty((MAX_STRIPS, slots), np.int64), np.zeros(vertices),
                       np.empty((2, CONTACTS_PER_VERTEX * vertices), np.int64),
                       np.empty(blob_count, np.int64))  # the blob contacts' pushes and rows (collide._resolve)
    awake_blobs = awake_count(s.awake)
    t = _lap(clock, NO_LAP, 0.0)
    g = math.sqrt(c.gx * c.gx + c.gy * c.gy)
    box = (c.box_x, c.box_y, c.box_tilt)  # the periodic box; (0, 0, 0): an open world
    self_pairs, self_values, self_count, self_near, self_chunks, zoned = s.self_contact
    # False and True as values known only when run: numba compiles a stage once per literal argument, and
    # these let one build of the self-contact resolve serve both its calls
    free, hold = blob_count < 0, blob_count >= 0
    movers = MOVING and any_moves(m.walls)  # (MOVING: the build runs moving colliders; the shared one for any scene)
    for n in range(steps):
        if awake_blobs == 0 and not movers:  # everything asleep: nothing moves, and only a mover could wake it
            s.steps_done[0] += 1
            continue
        found = False  # blob contacts are found once per step (and again when a blob outgrows them)
        # the scene's substeps, or more where a blob would move or sag too far in one
        substeps = substeps_for(s.position, s.velocity, m.offsets, s.awake, m.rest_perimeter, c.dt, g, c.up_x, c.up_y,
                                c.substeps, c.most_substeps)
        h = c.dt / substeps
        damping = math.exp(-c.damping * h)
        rest_speed = max(REST_SPEED_FACTOR * g * h, MIN_REST_SPEED)  # m/s: slower impacts never bounce (bounce)
        s.substeps_taken[0] = max(s.substeps_taken[0], substeps)
        s.substeps_taken[1] += substeps > c.substeps
        if PERIODIC and c.box_x > 0.0:  # the step's contact impulses, for the stress (sim/packing.py)
            s.packing[0][:] = 0.0
        for sub in range(substeps):
            if MOVING:  # colliders to where they are at the substep's end; those near sleeping blobs wake them
                place_walls((s.steps_done[0] * substeps + sub) * h, h, m.walls, s.static_pose, m.statics, s.placed,
                            s.position, m.offsets, s.awake, s.still)
                t = _lap(clock, LAP_WALLS, t)
            if c.damping > 0.0:
                # (v - v_rigid) *= exp(-damping h)
                damp_deformation(s.position, s.velocity, m.offsets, s.awake, damping)
                t = _lap(clock, LAP_DAMPING, t)
            if c.drag > 0.0:  # v *= exp(-drag h): all motion, toward rest
                drag_motion(s.velocity, m.offsets, s.awake, math.exp(-c.drag * h))
                t = _lap(clock, LAP_DAMPING, t)
            # x_prev <- x, v += g h, x += v h (rigid rotation exact); multipliers and contacts start at 0
            predict(s.position, s.previous, s.velocity, s.lam, s.contact_depth, m.offsets, s.awake, s.predicted, c.gx,
                    c.gy, h)
            s.area_lam[:] = 0.0
            s.perimeter_lam[:] = 0.0
            s.spring_lam[:] = 0.0
            t = _lap(clock, LAP_PREDICT, t)
            # pairs of a vertex and an edge of its own ring that may meet this substep (sim/self_contact.py)
            find_self_contacts(s.previous, s.position, m.offsets, s.awake, m.orient, m.rest_perimeter, self_pairs,
                               self_values, self_count, self_near, self_chunks)
            self_found = pairs_found(self_count)
            t = _lap(clock, LAP_SELF_CONTACT, t)
            if COLLIDES:  # uniform grid of blob centres
                pairs, partners, strips, count = find_blob_pairs(s.position, m.offsets, s.awake, s.center, s.radius,
                                                                 s.edges, s.blob_contact_depth, s.c_hit, box)
                if count > PAIRS_PER_BLOB * blob_count:
                    return n, TOO_MANY_PAIRS, count
                pair_impact = carry_impacts(pairs, blob_count, s.pair_key, s.pair_impact, s.pair_count)
                t = _lap(clock, LAP_BROAD_PHASE, t)
            for it in range(c.iterations):
                solve_perimeter(s.position, m.inv_mass, m.offsets, s.awake, m.rest_length, m.rest_perimeter,
                                m.compliance, s.lam, s.perimeter_lam, h)  # XPBD
                t = _lap(clock, LAP_PERIMETER, t)
                # a ring's vertices kept off its own edges, so that folds and pinches do not cross (before the
                # area, which stays exact where nothing comes after it)
                if self_found > 0:
                    resolve_self_contacts(s.position, s.previous, m.inv_mass, s.contact_depth, s.contact_normal,
                                          free, m.offsets, s.awake, m.orient, m.material, self_pairs, self_values,
                                          self_count, it % 2 == 1)
                    t = _lap(clock, LAP_SELF_CONTACT, t)
                # the scene's area method (area.py); kot: exact, a h² + b h + c = 0
                if METHOD == KOT:
                    area_kot(s.position, m.inv_mass, m.offsets, s.awake, m.target_area)
                elif METHOD == XPBD:
                    area_xpbd(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.area_compliance, s.area_lam,
                              h)
                elif METHOD == GAS:
                    area_gas(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.gas_pressure,
                             h * h / c.iterations)
                elif METHOD == SPRINGS:
                    area_springs(s.position, m.inv_mass, m.blob_of, s.awake, m.spring_pairs, m.spring_rest,
                                 m.spring_compliance, s.spring_lam, h)
                t = _lap(clock, LAP_AREA, t)
                if COLLIDES and pairs.shape[0] > 0:  # a vertex inside another blob: pushed out, with friction
                    # contacts are found once per step, and again for blobs that went past their margin
                    keep_blob_contacts(s.position, s.velocity, m.inv_mass, m.offsets, m.blob_of, s.awake, m.orient,
                                       s.center, s.radius, s.edges, pairs, partners, not found,
                                       (substeps - sub) * h, g, s.anchor, s.budget, s.moved, s.c_edge,
                                       s.stick_edge, s.stick_t, box)
                    found = True
                    t = _lap(clock, LAP_BLOB_DETECT, t)
                    resolve_blob_contacts(s.position, s.previous, m.inv_mass, m.offsets, m.blob_of, s.awake,
                                          m.orient, m.material, s.c_edge, s.c_hit, s.c_normal, s.blob_contact_depth,
                                          s.center, s.radius, c.up_x, c.up_y, strips, it % 2 == 1, s.stick_edge,
                                          s.stick_t, box, s.packing[0], h, resolve_scratch)
                    t = _lap(clock, LAP_BLOB_RESOLVE, t)
                if STATICS:  # one kernel per collider kind present
                    collide_statics(s.position, s.previous, m.blob_of, s.awake, m.material, m.statics, s.placed,
                                    s.contact_normal, s.contact_depth, s.contact_material, s.touch, h)
                    if LOADED:  # each loaded wall takes its share of its pushes (momentum kept)
                        yield_loaded_walls(s.position, m.inv_mass, m.walls, s.static_pose, m.statics, s.placed, s.touch)
                    if it == 0:  # a fast impact stops the whole blob, so that its ring does not fold across itself
                        stop_impacts(s.position, m.offsets, s.awake, m.rest_perimeter, s.contact_normal,
                                     s.contact_depth)
                    t = _lap(clock, LAP_STATICS, t)
                    # again after the statics, holding the vertices they pushed (the statics keep the last word)
                    if self_found > 0:
                        resolve_self_contacts(s.position, s.previous, m.inv_mass, s.contact_depth, s.contact_normal,
                                              hold, m.offsets, s.awake, m.orient, m.material, self_pairs, self_values,
                                              self_count, it % 2 == 1)
                        t = _lap(clock, LAP_SELF_CONTACT, t)
            # where the constraints left two edges of a ring crossed, their ends move rigidly for the substep
            zoned_before = zoned.sum()
            keep_rings_simple(s.position, s.previous, s.velocity, h, s.contact_depth, s.contact_material, m.inv_mass,
                              m.offsets, s.awake, m.rest_perimeter, m.target_area, METHOD == KOT, zoned, self_near,
                              self_chunks)
            t = _lap(clock, LAP_SELF_CONTACT, t)
            if STATICS and (self_found > 0 or zoned.sum() > zoned_before):
                # the statics have the last word: a vertex that the self-contacts or a zone moved into a collider
                # is put back now; left there, the next substep would take the far side of a segment (or of a
                # moving wall's line) for the side it belongs to, and keep it there
                collide_statics(s.position, s.previous, m.blob_of, s.awake, m.material, m.statics, s.placed,
                                s.contact_normal, s.contact_depth, s.contact_material, s.touch, h)
                if LOADED:
                    yield_loaded_walls(s.position, m.inv_mass, m.walls, s.static_pose, m.statics, s.placed, s.touch)
                t = _lap(clock, LAP_STATICS, t)
            if LOADED:
                finish_loaded_walls(m.walls, s.static_pose, h)
                t = _lap(clock, LAP_STATICS, t)
            # v = (x - x_prev) / h (rotation read as an angle), kinetic friction at static contacts
            update_velocities(s.position, s.previous, m.offsets, s.awake, s.velocity, s.contact_normal,
                              s.contact_depth, s.contact_material, h)
            if STATICS:
                stop_impact_velocities(s.velocity, m.offsets, s.awake, m.rest_perimeter, s.contact_normal,
                                       s.contact_depth)
            t = _lap(clock, LAP_VELOCITIES, t)
            if STATICS:  # leave statics at e × impact speed, never faster
                restitution(s.position, s.velocity, m.offsets, s.awake, s.predicted, s.contact_normal,
                            s.contact_depth, s.contact_material, s.impact, c.gx, c.gy, rest_speed)
                t = _lap(clock, LAP_RESTITUTION, t)
            if STATICS:  # the velocity stages' impulses into the colliders' records ...
                record_contact_impulses(s.position, s.previous, s.velocity, m.inv_mass, m.offsets, s.awake,
                                        s.contact_depth, m.walls, s.touch, h)
                if LOADED:  # ... and a loaded wall takes its share of them (momentum kept)
                    react_loaded_walls(s.position, s.previous, s.velocity, m.inv_mass, m.offsets, s.awake,
                                       s.contact_normal, s.contact_depth, m.walls, s.static_pose, s.touch, h)
                t = _lap(clock, LAP_STATICS, t)
            if COLLIDES and pairs.shape[0] > 0:  # blob contacts: no approach, Coulomb friction, at velocity level
                blob_contact_velocities(s.position, s.velocity, m.inv_mass, m.offsets, m.blob_of, s.awake, m.material,
                                        s.c_edge, s.c_hit, s.c_normal, s.blob_contact_depth, h, s.center, box,
                                        s.packing[0])
                t = _lap(clock, LAP_BLOB_VELOCITIES, t)
            if COLLIDES:  # blob pairs leave each other at e × impact speed, never faster
                blob_restitution(s.position, s.velocity, m.offsets, m.inv_mass, m.blob_of, s.awake, m.material,
                                 s.c_edge, s.c_hit, pairs, partners, s.predicted, pair_impact, rest_speed, box,
                                 s.packing[0])
                keep_impacts(pairs, blob_count, pair_impact, s.pair_key, s.pair_impact, s.pair_count)
                release_sticks(s.c_hit, s.stick_edge)  # static friction holds only contacts that keep pushing
                t = _lap(clock, LAP_BLOB_RESTITUTION, t)
        if PERIODIC and c.box_x > 0.0:  # the pairs in contact at the step's end, for the contact numbers (packing.py)
            keep_touching(m.offsets, m.blob_of, s.awake, s.c_edge, s.c_hit, pairs, partners, s.packing[1],
                          s.packing[2])
        if SLEEP:  # islands of blobs at rest fall asleep, islands with a mover wake
            awake_blobs = update_sleep(s.position, s.previous, s.velocity, m.offsets, pairs, s.contact_depth,
                                       s.contact_material, s.c_edge, s.awake, s.still, s.still_center,
                                       s.still_angle, c.sleep_speed, c.time_to_sleep, c.dt)
            t = _lap(clock, LAP_SLEEP, t)
        if STATICS:  # the step's pushes as impulses on the colliders
            account_contacts(s.position, m.inv_mass, m.walls, s.static_pose, s.touch, s.static_impulse, h)
            t = _lap(clock, LAP_STATICS, t)
        s.steps_done[0] += 1
        bad = first_runaway(s.position, RUNAWAY)
        if bad >= 0:
            return n, RUNAWAY_VERTEX, bad
    return steps, DONE, 0


@inline_kernel
def _lap(clock, stage, t):
    """With a clock (non-empty), add the time since t to clock[stage] and return the time now."""
    if clock.shape[0] == 0:
        return t
    now = _now()
    if stage >= 0:
        clock[stage] += now - t
    return now


@numba.njit(cache=True)  # not nogil: an object-mode block takes the GIL
def _now():
    with numba.objmode(now="float64"):
        now = time.perf_counter()
    return now


SHARED_BUILD = "BLOBSIM_SHARED_BUILD"  # environment: "1", one build of the step for scenes of many kinds
_SHARED_BUILD_OLD_NAME = "BLOBSIM_EVERY_COLLIDER_KIND"  # its name before 2026-11-26, when it widened colliders only


def configuration(model: Model, params: Params) -> Configuration:
    """What the scene uses: which build of the step runs it. With BLOBSIM_SHARED_BUILD=1 in the
    environment, the shared build instead (`shared_build`)."""
    kinds = {s.kind for s in model.statics}
    config = Configuration(method=METHODS.index(params.method), collides=model.collides, statics=bool(kinds),
                           planes="plane" in kinds, segments="segment" in kinds, circles="circle" in kinds,
                           polygons="polygon" in kinds, sleep=params.sleep, moving=model.moving, loaded=model.loaded,
                           periodic=params.box[0] > 0.0 and model.collides)
    shared = "1" in (os.environ.get(SHARED_BUILD), os.environ.get(_SHARED_BUILD_OLD_NAME))
    return shared_build(config) if shared else config


def shared_build(config: Configuration) -> Configuration:
    """The build that serves every scene of the same area method, whatever else it uses: every collider kind,
    moving and loaded walls, blob contacts, sleeping, a periodic box. A stage a scene has nothing for runs over
    no rows (no colliders of a kind, no moving or loaded wall, no blob pair with one blob), sleeping is off at
    run time (`settings`: nobody is ever still for time_to_sleep = ∞), and the periodic box's stages run only
    where there is a box (box_x > 0), so the bits are the scene's own build's (tests/test_builds.py). Each
    configuration would otherwise compile a build of its own (each links and optimizes the whole step again:
    6-12 s on the 2-core machine; kot's periodic one, 27 s after kot's): for a test suite, or a sweep over scenes of
    different kinds."""
    return config._replace(collides=True, statics=True, planes=True, segments=True, circles=True, polygons=True,
                           sleep=True, moving=True, loaded=True, periodic=True)


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


NO_CLOCK = np.zeros(0)


def step_build(model: Model, step_settings: StepSettings):
    """The build of the step that runs this scene: for its configuration, serial or parallel."""
    return build(_advance, model.parallel, step_settings.config.constants())


def describe(model: Model, step_settings: StepSettings) -> str:
    """The build of the step in words: 'kot, blob contacts, plane and polygon colliders, sleeping; parallel'."""
    c = step_settings.config
    kinds = [kind for kind, present in zip(SOLVERS, (c.planes, c.segments, c.circles, c.polygons)) if present]
    parts = [METHODS[c.method]] + (["blob contacts"] if c.collides else []) \
        + ([" and ".join(kinds) + " colliders"] if kinds else []) + (["loaded walls"] if c.loaded else
                                                                     ["moving walls"] if c.moving else []) \
        + (["sleeping"] if c.sleep else []) + (["periodic box"] if c.periodic else [])
    return ", ".join(parts) + ("; parallel" if model.parallel else "; serial")


def compile_step(state: State, model: Model, step_settings: StepSettings, announce=None) -> None:
    """Compile the step that runs this scene, or load it from numba's disk cache, before its first step
    (a call of no steps: the state is not touched). When the build is not in the cache, it is compiled
    here (tens of seconds): `announce(description)`, a context manager, is entered around it."""
    kernel = step_build(model, step_settings)
    args = (0, state, model.arrays, step_settings, NO_CLOCK)
    if announce is not None and in_disk_cache(kernel, args) is False:
        with announce(describe(model, step_settings)):
            kernel(*args)
    else:
        kernel(*args)


CORE_STEP = "BLOBSIM_STEP"  # environment: "numba", numba's step instead of the compiled core's (blobcli/core)


def core_step_chosen() -> bool:
    """Whether `advance` runs the compiled core's step (unless BLOBSIM_STEP=numba)."""
    return os.environ.get(CORE_STEP, "c") != "numba"


class _CoreCall:
    """The compiled core's views over the arrays of the last call, kept while the same state, arrays and
    settings are stepped again (a run calls `advance` once per recorded frame)."""
    key = None
    views = None
    scratch = None


def _core_views(state: State, arrays, step_settings: StepSettings, parallel: bool):
    from ..core import Views, load

    key = (id(state), id(state.position), id(arrays), step_settings, parallel)
    if _CoreCall.key != key:
        ffi, lib = load()
        _CoreCall.views = None
        _CoreCall.views = Views(ffi, arrays, state, step_settings, parallel)
        _CoreCall.scratch = ffi.gc(lib.bc_scratch_new(_CoreCall.views.model), lib.bc_scratch_free)
        _CoreCall.views.context.w = _CoreCall.scratch
        _CoreCall.key = key
    return _CoreCall.views


def _advance_core(state: State, arrays, step_settings: StepSettings, parallel: bool, steps: int, timer):
    """The compiled core's step (blobcli/core/step.c): (steps done, why, detail), as `_advance`."""
    from ..core import load

    ffi, lib = load()
    views = _core_views(state, arrays, step_settings, parallel)
    clock = ffi.cast("double *", timer.ctypes.data) if len(timer) else ffi.NULL
    stop = lib.bc_advance(views.context, steps, RUNAWAY, clock)
    if stop.why == lib.BC_NO_MEMORY:
        raise MemoryError("the step's scratch could not be allocated")
    return stop.steps, stop.why, stop.detail


def advance(state: State, model: Model, params: Params, steps: int, clock: dict | None = None,
            step_settings: StepSettings | None = None, arrays=None) -> int:
    """Advance the state by up to `steps` steps of params.dt (each in `substeps` substeps or more, up to
    `max_substeps`: integrate.substeps_for), in one compiled call. Returns the steps done: fewer than
    asked only when a step left a vertex non-finite or beyond RUNAWAY (measure.first_runaway finds it).
    Raises SimulationError when far more blob pairs overlap than memory can hold.

    With `clock` (a dict), each stage's wall time is added to clock[stage name], in seconds:
    `blobsim bench` profiles the real step this way. `step_settings` (from `settings`) saves
    rebuilding them on every call; `arrays` (a schedule's: sim/schedule.py) replace model.arrays."""
    timer = np.zeros(len(STAGES)) if clock is not None else NO_CLOCK
    step_settings = step_settings or settings(model, params)
    arrays = model.arrays if arrays is None else arrays
    if core_step_chosen():
        done, why, detail = _advance_core(state, arrays, step_settings, model.parallel, steps, timer)
    else:
        done, why, detail = step_build(model, step_settings)(steps, state, arrays, step_settings, timer)
    if clock is not None:
        for name, seconds in zip(STAGES, timer):
            clock[name] = clock.get(name, 0.0) + float(seconds)
    if why == TOO_MANY_PAIRS:
        most = PAIRS_PER_BLOB * model.blob_count
        raise SimulationError(f"{detail:,} blob pairs overlap (at most {most:,}, {PAIRS_PER_BLOB} per blob): "
                              "are blobs spawned on top of each other?", steps_done=done)
    return done


def step(state: State, model: Model, params: Params, clock: dict | None = None) -> None:
    """Advance the state by one step (see `advance`)."""
    advance(state, model, params, 1, clock)
