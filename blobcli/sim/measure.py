"""Per-blob measurements taken at recorded frames, and the runaway check."""

import numpy as np

from ..jit import kernel
from .model import Model, State
from .ring import next_in_ring, turn, twice_ring_area

RUNAWAY = 1e6  # m: a coordinate beyond this (or non-finite) stops the run


@kernel
def _blob_measures(pos, vel, inv_mass, offsets, area, kinetic):
    for b in range(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        ke = 0.0
        for i in range(o, e):
            ke += (vel[0, i] ** 2 + vel[1, i] ** 2) / inv_mass[i]
        area[b] = 0.5 * twice_ring_area(pos, o, e)
        kinetic[b] = 0.5 * ke


def blob_measures(state: State, model: Model, inv_mass: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(signed area (B,) m², kinetic energy (B,) J) of every blob; `inv_mass`: a schedule's, not the model's."""
    area = np.empty(model.blob_count)
    kinetic = np.empty(model.blob_count)
    _blob_measures(state.position, state.velocity, model.inv_mass if inv_mass is None else inv_mass, model.offsets,
                   area, kinetic)
    return area, kinetic


@kernel
def first_runaway(pos, limit):
    """Index of the first vertex of pos (2, N) that is non-finite or beyond `limit`, or -1."""
    bad = False
    for i in range(pos.shape[1]):  # a loop with no exit, so that it vectorizes: it runs every step
        bad |= not (abs(pos[0, i]) <= limit) or not (abs(pos[1, i]) <= limit)  # also catches NaN
    if bad:
        for i in range(pos.shape[1]):
            if not (abs(pos[0, i]) <= limit) or not (abs(pos[1, i]) <= limit):
                return i
    return -1


SELF_CROSSING_MAX_VERTICES = 4096  # larger rings are not checked for self-crossing (O(n²) per ring)


@kernel
def _shape_faults(pos, offsets, orient, faults):
    """faults[b] = 1 if blob b's signed area has lost its rest sign (inside out), 2 if its ring
    crosses itself (two non-adjacent edges properly cross), else 0."""
    for b in range(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        faults[b] = 0
        if twice_ring_area(pos, o, e) * orient[b] <= 0.0:
            faults[b] = 1
            continue
        if e - o > SELF_CROSSING_MAX_VERTICES:
            continue
        for i in range(o, e):
            i1 = next_in_ring(i, o, e)
            for j in range(i + 2, e):
                j1 = next_in_ring(j, o, e)
                if j1 == i:
                    continue
                if (turn(pos, i, i1, j) * turn(pos, i, i1, j1) < 0
                        and turn(pos, j, j1, i) * turn(pos, j, j1, i1) < 0):
                    faults[b] = 2
                    break
            if faults[b]:
                break


def shape_warning(state: State, model: Model) -> str:
    """One sentence on blobs that are inside out or self-intersecting now, or ""."""
    faults = np.zeros(model.blob_count, dtype=np.int64)
    _shape_faults(state.position, model.offsets, model.orient, faults)
    parts = []
    for code, what in ((1, "inside out"), (2, "self-intersecting")):
        blobs = np.flatnonzero(faults == code)
        if len(blobs):
            names = ", ".join(model.names[b] for b in blobs[:3]) + (", ..." if len(blobs) > 3 else "")
            parts.append(f"{len(blobs)} blob{'s' * (len(blobs) > 1)} {what} ({names})")
    return "; ".join(parts) + " at the end" if parts else ""
