"""The step of the simulation: a list of named stages, compiled whole.

Each stage is a kernel over flat arrays (model.State: structure of arrays). `_advance` calls
them in order, for as many steps as it is asked, in one compiled call: Python is entered only
between calls (to record a frame, update the progress bar, see a Ctrl-C), never per substep.
A stage a scene does not need (damping off, one blob, no statics) is
not run: StepSettings says which, decided from the model when the call is made.

The step is compiled twice from this one text (jit.stage_kernel): serial, and with every
stage's parallel build, which scenes of 32 blobs or more run. Both give the same bits.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numba
import numpy as np

from ..jit import build, inline_kernel, stage_kernel
from .area import GAS, KOT, METHODS, SPRINGS, XPBD, area_gas, area_kot, area_springs, area_xpbd
from .collide import (
    PAIRS_PER_BLOB,
    blob_contact_velocities,
    blob_restitution,
    carry_impacts,
    find_blob_pairs,
    keep_blob_contacts,
    keep_impacts,
    release_sticks,
    resolve_blob_contacts,
)
from .integrate import MIN_REST_SPEED, REST_SPEED_FACTOR, damp_deformation, predict, restitution, update_velocities
from .measure import RUNAWAY, first_runaway
from .model import Model, Params, SimulationError, State
from .perimeter import solve_perimeter
from .sleep import update_sleep
from .statics import collide_statics

STAGES = ("damping", "predict", "broad phase", "perimeter", "area", "blob detect", "blob resolve", "statics",
          "velocities", "restitution", "blob velocities", "blob restitution", "sleep")
(DAMPING, PREDICT, BROAD_PHASE, PERIMETER, AREA, BLOB_DETECT, BLOB_RESOLVE, STATICS, VELOCITIES, RESTITUTION,
 BLOB_VELOCITIES, BLOB_RESTITUTION, SLEEP) = range(len(STAGES))
DONE, RUNAWAY_VERTEX, TOO_MANY_PAIRS = range(3)  # why _advance returned


class StepSettings(NamedTuple):
    """Params and the model's flags, as the compiled step reads them."""
    dt: float  # s
    substeps: int
    iterations: int
    gx: float  # m/s²
    gy: float
    damping: float  # 1/s
    method: int  # index into area.METHODS
    up_x: float  # -g / |g| (0 without gravity): "above", for the stacking rule of sim/collide.py
    up_y: float
    rest_speed: float  # m/s: slower impacts never bounce (integrate.bounce)
    collides: bool  # blob–blob stages: more than one blob
    statics: bool  # static collider stage: any static collider
    sleep: bool  # islands at rest go to sleep (sim/sleep.py) ...
    sleep_speed: float  # m/s ... once every blob has gone slower than this, on average ...
    time_to_sleep: float  # s ... for this long


@stage_kernel
def _advance(steps, state, model, settings, clock):
    """Run `steps` steps. Returns (steps done, why it stopped, detail): DONE; RUNAWAY_VERTEX after a step
    that left vertex `detail` non-finite or beyond RUNAWAY (that step not counted); TOO_MANY_PAIRS, when
    `detail` blob pairs overlap (the state is then mid-step). With a clock (one slot per stage), each
    stage's wall time is added to its slot, in seconds."""
    s, m, c = state, model, settings
    h = c.dt / c.substeps
    damping = math.exp(-c.damping * h)
    blob_count = m.offsets.shape[0] - 1
    no_pairs = np.zeros((0, 2), np.int64)
    pairs, partners, strips = no_pairs, (np.zeros(blob_count + 1, np.int64), no_pairs[:, 0], no_pairs[:, 0]), \
        (np.zeros(blob_count, np.int64), np.zeros(2, np.int64), np.arange(blob_count), np.zeros(blob_count, np.bool_),
         False)
    pair_impact = np.zeros((0, 4))  # the impact records of this substep's pairs (integrate.bounce)
    awake_count = np.count_nonzero(s.awake)
    t = _lap(clock, -1, 0.0)
    g = math.sqrt(c.gx * c.gx + c.gy * c.gy)
    for n in range(steps):
        if awake_count == 0:  # everything asleep: nothing moves, and only a mover could wake it
            continue
        found = False  # blob contacts are found once per step (and again when a blob outgrows them)
        for sub in range(c.substeps):
            if c.damping > 0.0:
                # (v - v_rigid) *= exp(-damping h)
                damp_deformation(s.position, s.velocity, m.offsets, s.awake, damping)
                t = _lap(clock, DAMPING, t)
            # x_prev <- x, v += g h, x += v h (rigid rotation exact); multipliers and contacts start at 0
            predict(s.position, s.previous, s.velocity, s.lam, s.contact_depth, m.offsets, s.awake, s.predicted, c.gx,
                    c.gy, h)
            s.area_lam[:] = 0.0
            s.perimeter_lam[:] = 0.0
            s.spring_lam[:] = 0.0
            t = _lap(clock, PREDICT, t)
            if c.collides:  # uniform grid of blob centres
                pairs, partners, strips, count = find_blob_pairs(s.position, m.offsets, s.awake, s.center, s.radius,
                                                                 s.edges, s.blob_contact_depth, s.c_hit)
                if count > PAIRS_PER_BLOB * blob_count:
                    return n, TOO_MANY_PAIRS, count
                pair_impact = carry_impacts(pairs, blob_count, s.pair_key, s.pair_impact, s.pair_count)
                t = _lap(clock, BROAD_PHASE, t)
            for it in range(c.iterations):
                solve_perimeter(s.position, m.inv_mass, m.offsets, s.awake, m.rest_length, m.rest_perimeter,
                                m.compliance, s.lam, s.perimeter_lam, h)  # XPBD
                t = _lap(clock, PERIMETER, t)
                # the scene's area method (area.py); kot: exact, a h² + b h + c = 0
                if c.method == KOT:
                    area_kot(s.position, m.inv_mass, m.offsets, s.awake, m.target_area)
                elif c.method == XPBD:
                    area_xpbd(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.area_compliance, s.area_lam,
                              h)
                elif c.method == GAS:
                    area_gas(s.position, m.inv_mass, m.offsets, s.awake, m.target_area, m.gas_pressure,
                             h * h / c.iterations)
                elif c.method == SPRINGS:
                    area_springs(s.position, m.inv_mass, m.blob_of, s.awake, m.spring_pairs, m.spring_rest,
                                 m.spring_compliance, s.spring_lam, h)
                t = _lap(clock, AREA, t)
                if pairs.shape[0] > 0:  # a vertex inside another blob: pushed out, with friction
                    # contacts are found once per step, and again for blobs that went past their margin
                    keep_blob_contacts(s.position, s.velocity, m.inv_mass, m.offsets, m.blob_of, s.awake, m.orient,
                                       s.center, s.radius, s.edges, pairs, partners, not found,
                                       (c.substeps - sub) * h, g, s.anchor, s.budget, s.moved, s.c_edge,
                                       s.stick_edge, s.stick_t)
                    found = True
                    t = _lap(clock, BLOB_DETECT, t)
                    resolve_blob_contacts(s.position, s.previous, m.inv_mass, m.offsets, m.blob_of, s.awake,
                                          m.orient, m.material, s.c_edge, s.c_hit, s.blob_contact_depth, s.center,
                                          s.radius, c.up_x, c.up_y, strips, it % 2 == 1, s.stick_edge, s.stick_t)
                    t = _lap(clock, BLOB_RESOLVE, t)
                if c.statics:  # one kernel per collider kind
                    collide_statics(s.position, s.previous, m.blob_of, s.awake, m.material, m.planes, m.segments,
                                    m.circles, m.polygons, s.contact_normal, s.contact_depth, s.contact_material)
                    t = _lap(clock, STATICS, t)
            # v = (x - x_prev) / h (rotation read as an angle), kinetic friction at static contacts
            update_velocities(s.position, s.previous, m.offsets, s.awake, s.velocity, s.contact_normal,
                              s.contact_depth, s.contact_material, h)
            t = _lap(clock, VELOCITIES, t)
            if c.statics:  # leave statics at e × impact speed, never faster
                restitution(s.position, s.velocity, m.offsets, s.awake, s.predicted, s.contact_normal,
                            s.contact_depth, s.contact_material, s.impact, c.gx, c.gy, c.rest_speed)
                t = _lap(clock, RESTITUTION, t)
            if pairs.shape[0] > 0:  # blob contacts: no approach, Coulomb friction, at velocity level
                blob_contact_velocities(s.position, s.velocity, m.inv_mass, m.offsets, m.blob_of, s.awake, m.orient,
                                        m.material, s.c_edge, s.c_hit, s.blob_contact_depth, h)
                t = _lap(clock, BLOB_VELOCITIES, t)
            if c.collides:  # blob pairs leave each other at e × impact speed, never faster
                blob_restitution(s.position, s.velocity, m.offsets, m.inv_mass, m.blob_of, s.awake, m.material,
                                 s.c_edge, s.c_hit, pairs, partners, s.predicted, pair_impact, c.rest_speed)
                keep_impacts(pairs, blob_count, pair_impact, s.pair_key, s.pair_impact, s.pair_count)
                release_sticks(s.c_hit, s.stick_edge)  # static friction holds only contacts that keep pushing
                t = _lap(clock, BLOB_RESTITUTION, t)
        if c.sleep:  # islands of blobs at rest fall asleep, islands with a mover wake
            awake_count = update_sleep(s.position, s.previous, s.velocity, m.offsets, pairs, s.contact_depth,
                                       s.c_edge, s.awake, s.still, s.still_center, s.still_angle, c.sleep_speed,
                                       c.time_to_sleep, c.dt)
            t = _lap(clock, SLEEP, t)
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


def settings(model: Model, params: Params) -> StepSettings:
    """What the compiled step needs of params and the model."""
    g = math.hypot(params.gravity[0], params.gravity[1])
    up = -params.gravity / g if g > 0 else np.zeros(2)
    h = params.dt / params.substeps
    return StepSettings(dt=params.dt, substeps=params.substeps, iterations=params.iterations,
                        gx=float(params.gravity[0]), gy=float(params.gravity[1]), damping=params.damping,
                        method=METHODS.index(params.method), up_x=float(up[0]), up_y=float(up[1]),
                        rest_speed=max(REST_SPEED_FACTOR * g * h, MIN_REST_SPEED), collides=model.collides,
                        statics=bool(model.statics), sleep=params.sleep, sleep_speed=params.sleep_speed,
                        time_to_sleep=params.time_to_sleep)


NO_CLOCK = np.zeros(0)


def advance(state: State, model: Model, params: Params, steps: int, clock: dict | None = None,
            step_settings: StepSettings | None = None) -> int:
    """Advance the state by up to `steps` steps of params.dt (each in `substeps` substeps), in one
    compiled call. Returns the steps done: fewer than asked only when a step left a vertex non-finite
    or beyond RUNAWAY (measure.first_runaway finds it). Raises SimulationError when far more blob
    pairs overlap than memory can hold.

    With `clock` (a dict), each stage's wall time is added to clock[stage name], in seconds:
    `blobsim bench` profiles the real step this way. `step_settings` (from `settings`) saves
    rebuilding them on every call."""
    timer = np.zeros(len(STAGES)) if clock is not None else NO_CLOCK
    done, why, detail = build(_advance, model.parallel)(steps, state, model.arrays,
                                                        step_settings or settings(model, params), timer)
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
