"""One step of the simulation, as a list of named stages.

Each stage is a plain function (state, model, params, ...) over flat arrays, with its
per-vertex work in a numba kernel. Stages never call each other; only `step` does, and
a stage a scene does not need (damping off, no statics) is not run at all.
"""

from .area import AREA_METHODS
from .collide import collide_blobs, find_blob_pairs
from .integrate import damp_relative, predict, restitution, update_velocities
from .model import Model, Params, State
from .perimeter import solve_perimeter
from .statics import collide_static


def step(state: State, model: Model, params: Params) -> None:
    """Advance the state by params.dt, in `substeps` substeps of h = dt / substeps."""
    h = params.dt / params.substeps
    solve_area = AREA_METHODS[params.method]
    for _ in range(params.substeps):
        if params.damping > 0.0:
            damp_relative(state, model, params, h)           # (v - v_cm) *= exp(-damping h)
        predict(state, model, params, h)                     # x_prev <- x, v += g h, x += v h
        if model.collides:
            find_blob_pairs(state, model, params)            # broad phase: uniform grid
        for _ in range(params.iterations):
            solve_perimeter(state, model, params, h)         # XPBD edge lengths
            solve_area(state, model, params, h)              # params.method; kot: exact, a h² + b h + c = 0
            if model.collides:
                collide_blobs(state, model, params)          # vertex out of the other blob, friction
            for statics in model.statics:                    # one pass per collider kind present
                collide_static(state, model, statics)
        update_velocities(state, model, params, h)           # v = (x - x_prev) / h, friction
        if model.bounces:
            restitution(state, model, params, h)             # blobs leave statics at e × approach speed
