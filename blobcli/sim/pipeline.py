"""One step of the simulation, as a list of named stages.

Each stage is a plain function (state, model, params, h) over flat arrays, with its
per-vertex work in a numba kernel. Stages never call each other; only `step` does, and
a stage a scene does not need (damping off, no statics, one blob) is not run at all.
"""

from __future__ import annotations

import time
from typing import Callable

from .area import AREA_METHODS
from .collide import detect_blob_contacts, find_blob_pairs, resolve_blob_contacts
from .integrate import damp_relative, predict, restitution, update_velocities
from .model import Model, Params, State
from .perimeter import solve_perimeter
from .statics import collide_statics

Stage = Callable[[State, Model, Params, float], None]  # every stage: (state, model, params, h) -> None

STAGES = ("damping", "predict", "broad phase", "perimeter", "area", "blob detect", "blob resolve", "statics",
          "velocities", "restitution")


def step(state: State, model: Model, params: Params, clock: dict | None = None) -> None:
    """Advance the state by params.dt, in `substeps` substeps of h = dt / substeps.

    With `clock` (a dict), each stage's wall time is added to clock[stage name], in seconds:
    `blobsim bench` profiles the real step this way."""
    run = _run if clock is None else _timed(clock)
    h = params.dt / params.substeps
    solve_area = AREA_METHODS[params.method]
    for _ in range(params.substeps):
        if params.damping > 0.0:
            run("damping", damp_relative, state, model, params, h)      # (v - v_cm) *= exp(-damping h)
        run("predict", predict, state, model, params, h)                # x_prev <- x, v += g h, x += v h
        if model.collides:
            run("broad phase", find_blob_pairs, state, model, params, h)  # uniform grid of blob centres
        for _ in range(params.iterations):
            run("perimeter", solve_perimeter, state, model, params, h)  # XPBD edge lengths
            run("area", solve_area, state, model, params, h)            # kot: exact, a h² + b h + c = 0
            if model.collides:
                run("blob detect", detect_blob_contacts, state, model, params, h)    # vertex in another blob
                run("blob resolve", resolve_blob_contacts, state, model, params, h)  # push out, friction
            if model.statics:
                run("statics", collide_statics, state, model, params, h)  # one kernel per collider kind
        run("velocities", update_velocities, state, model, params, h)   # v = (x - x_prev) / h, friction
        if model.bounces:
            run("restitution", restitution, state, model, params, h)    # leave statics at e × approach speed


def _run(name: str, stage: Stage, *args) -> None:
    stage(*args)


def _timed(clock: dict):
    def run(name, stage, *args):
        t0 = time.perf_counter()
        stage(*args)
        clock[name] = clock.get(name, 0.0) + time.perf_counter() - t0
    return run
