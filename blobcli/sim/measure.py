"""Per-blob measurements taken at recorded frames, and the runaway check."""

import numpy as np

from ..jit import kernel
from .model import Model, State
from .ring import twice_ring_area

RUNAWAY = 1e6  # m: a coordinate beyond this (or non-finite) stops the run


@kernel
def _blob_measures(pos, vel, inv_mass, offsets, area, kinetic):
    for b in range(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        ke = 0.0
        for i in range(o, e):
            ke += (vel[i, 0] ** 2 + vel[i, 1] ** 2) / inv_mass[i]
        area[b] = 0.5 * twice_ring_area(pos, o, e)
        kinetic[b] = 0.5 * ke


def blob_measures(state: State, model: Model) -> tuple[np.ndarray, np.ndarray]:
    """(signed area (B,) m², kinetic energy (B,) J) of every blob."""
    area = np.empty(model.blob_count)
    kinetic = np.empty(model.blob_count)
    _blob_measures(state.pos, state.vel, model.inv_mass, model.offsets, area, kinetic)
    return area, kinetic


@kernel
def _first_runaway(pos, limit):
    for i in range(pos.shape[0]):
        for k in range(2):
            v = pos[i, k]
            if not (abs(v) <= limit):  # also catches NaN
                return i
    return -1


def first_runaway(state: State) -> int:
    """Index of the first vertex that is non-finite or beyond RUNAWAY, or -1."""
    return _first_runaway(state.pos, RUNAWAY)
