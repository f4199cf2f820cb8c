"""Per-blob measurements taken at recorded frames, and the runaway check (blobcli/core/measure.c)."""

import numpy as np

from .model import Model, State

RUNAWAY = 1e6  # m: a coordinate beyond this (or non-finite) stops the run


def _pointer(ffi, array: np.ndarray, kind: str):
    return ffi.cast(kind, array.ctypes.data)


def blob_measures(state: State, model: Model, inv_mass: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(signed area (B,) m², kinetic energy (B,) J) of every blob; `inv_mass`: a schedule's, not the model's."""
    from ..core import load

    ffi, lib = load()
    inv_mass = np.ascontiguousarray(model.inv_mass if inv_mass is None else inv_mass, dtype=np.float64)
    position, velocity = np.ascontiguousarray(state.position), np.ascontiguousarray(state.velocity)
    area, kinetic = np.empty(model.blob_count), np.empty(model.blob_count)
    lib.bc_blob_measures(_pointer(ffi, position, "double *"), _pointer(ffi, velocity, "double *"), position.shape[1],
                         _pointer(ffi, inv_mass, "double *"), _pointer(ffi, model.offsets, "int64_t *"),
                         model.blob_count, _pointer(ffi, area, "double *"), _pointer(ffi, kinetic, "double *"))
    return area, kinetic


def first_runaway(position: np.ndarray, limit: float = RUNAWAY) -> int:
    """Index of the first vertex of position (2, N) that is non-finite or beyond `limit` (m), or -1."""
    from ..core import load

    ffi, lib = load()
    position = np.ascontiguousarray(position, dtype=np.float64)
    return int(lib.bc_first_runaway_in(_pointer(ffi, position, "double *"), position.shape[1], limit))


def first_runaway_wall(static_pose: np.ndarray, limit: float = RUNAWAY) -> int:
    """Index of the first collider whose pose row (S, WALL_POSE_COLUMNS) holds a non-finite value or a
    displacement beyond `limit` (m), or -1."""
    from ..core import load

    ffi, lib = load()
    pose = np.ascontiguousarray(static_pose, dtype=np.float64)
    return int(lib.bc_first_runaway_wall(_pointer(ffi, pose, "double *"), pose.shape[0], limit))


def shape_warning(state: State, model: Model) -> str:
    """One sentence on blobs that are inside out or self-intersecting now (rings of up to
    BC_SELF_CROSSING_MAX_VERTICES vertices are checked for crossings), or ""."""
    from ..core import load

    ffi, lib = load()
    position = np.ascontiguousarray(state.position)
    orient = np.ascontiguousarray(model.orient, dtype=np.float64)
    faults = np.zeros(model.blob_count, dtype=np.int64)
    lib.bc_shape_faults(_pointer(ffi, position, "double *"), position.shape[1],
                        _pointer(ffi, model.offsets, "int64_t *"), model.blob_count,
                        _pointer(ffi, orient, "double *"), _pointer(ffi, faults, "int64_t *"))
    parts = []
    for code, what in ((1, "inside out"), (2, "self-intersecting")):
        blobs = np.flatnonzero(faults == code)
        if len(blobs):
            names = ", ".join(model.names[b] for b in blobs[:3]) + (", ..." if len(blobs) > 3 else "")
            parts.append(f"{len(blobs)} blob{'s' * (len(blobs) > 1)} {what} ({names})")
    return "; ".join(parts) + " at the end" if parts else ""
