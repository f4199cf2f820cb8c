"""Reading a trajectory: open it checked against LAYOUT (a file that would crash or hang the HDF5 library
is probed in a child first), and read it back whole or its stored scene; every failure is one
TrajectoryError line.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from .layout import (
    AREA,
    AWAKE,
    EDGES,
    IMAGE,
    KINETIC,
    PARAMETERS,
    POSITION,
    READS_FORMATS,
    RESTART,
    RESTART_FIELDS,
    SINCE_FORMAT,
    STATICS,
    TrajectoryError,
    restart_shape,
    text,
)


def _shape_problem(f, name, shape, kinds="f") -> str | None:
    """Why dataset `name` is missing or not of `shape` (None entries: any length) and kind."""
    obj = f.get(name)
    if not isinstance(obj, h5py.Dataset):
        return f"{name} is missing"
    if len(obj.shape) != len(shape) or any(s is not None and s != o for s, o in zip(shape, obj.shape)):
        return f"{name} has shape {obj.shape}, expected {tuple('*' if s is None else s for s in shape)}"
    if obj.dtype.kind not in kinds:
        return f"{name} has type {obj.dtype}"
    return None


def trajectory_problems(f, need_restart: bool = False) -> list[str]:
    """Every way the open file `f` departs from LAYOUT that a reader would trip on."""
    attrs = f.attrs
    if "blobsim_format" not in attrs or "complete" not in attrs:
        return ["root attributes blobsim_format and complete are missing"]
    try:
        version = int(np.asarray(attrs["blobsim_format"]).flat[0])
    except (TypeError, ValueError):
        version = None
    if version not in READS_FORMATS:
        return [f"blobsim format {attrs['blobsim_format']} (this blobsim reads formats "
                f"{', '.join(map(str, READS_FORMATS))})"]
    p = PARAMETERS
    first = [_shape_problem(f, f"{p}/blob_offsets", (None,), "iu"),
             _shape_problem(f, f"{POSITION}/value", (None, None, 2))]
    if any(first):
        return [x for x in first if x]
    offsets = f[f"{p}/blob_offsets"][...]
    frames, n = f[f"{POSITION}/value"].shape[:2]
    b = len(offsets) - 1
    problems = []
    if b < 1 or offsets[0] != 0 or offsets[-1] != n or np.any(np.diff(offsets) < 3):
        problems.append(f"{p}/blob_offsets do not split the {n} vertices into rings of 3 or more")
    for name, shape, kinds in ((f"{POSITION}/step", (frames,), "iu"), (f"{POSITION}/time", (frames,), "f"),
                               (f"{AREA}/value", (frames, b), "f"), (f"{AREA}/step", (frames,), "iu"),
                               (f"{KINETIC}/value", (frames, b), "f"), (f"{KINETIC}/step", (frames,), "iu"),
                               (f"{p}/blob_names", (b,), "OSU"), (f"{p}/target_area", (b,), "f"),
                               (f"{p}/mass", (b,), "f"), (f"{p}/scene", (), "OSU")):
        problems.append(_shape_problem(f, name, shape, kinds))
    if version >= 4:
        problems += [_shape_problem(f, f"{AWAKE}/value", (frames, b), "u"),
                     _shape_problem(f, f"{AWAKE}/step", (frames,), "iu")]
    if frames == 0:
        problems.append("it holds no frames")
    for key in ("dt", "substeps", "iterations", "method", "every", "steps"):
        if key not in f[p].attrs:
            problems.append(f"{p} attribute {key} is missing")
    if "dt" in f[p].attrs and not (np.isfinite(f[p].attrs["dt"]) and f[p].attrs["dt"] > 0):
        problems.append(f"{p} attribute dt is not a positive number")
    if version >= 8 and (IMAGE in f or EDGES in f):  # a periodic box
        problems += _box_problems(f, frames, n)
    if version >= 7 and STATICS in f:
        problems += _statics_problems(f, frames)
    if need_restart and version < 6:
        problems.append(f"blobsim format {version} keeps an older restart state (resuming needs format 6): "
                        "run it again")
    elif need_restart or RESTART in f and version >= 6:
        pairs = f[f"{RESTART}/pair_key"].shape[0] if f"{RESTART}/pair_key" in f else 0
        statics = f[f"{RESTART}/static_pose"].shape[0] if f"{RESTART}/static_pose" in f else 0
        problems += [_shape_problem(f, f"{RESTART}/{name}", restart_shape(rows, columns, n, b, statics), kinds)
                     for name, rows, columns, kinds in RESTART_FIELDS if version >= SINCE_FORMAT.get(name, 6)]
        problems += [_shape_problem(f, f"{RESTART}/pair_key", (pairs,), "iu"),
                     _shape_problem(f, f"{RESTART}/pair_impact", (pairs, 4))]
        if RESTART in f and "step" not in f[RESTART].attrs:
            problems.append(f"{RESTART} attribute step is missing")
    return [x for x in problems if x]


BOX_BLOCK = 1 << 16  # frames of a box's edges checked at a time


def _box_problems(f, frames: int, n: int) -> list[str]:
    """Why a periodic box's record would trip a reader: its images or edges missing or of another shape, or an
    edge that is not a finite number, or a side (L_x, L_y) that is not > 0."""
    image = [_shape_problem(f, f"{IMAGE}/{name}", shape, kinds) for name, shape, kinds in
             (("value", (frames, n, 2), "i"), ("step", (frames,), "iu"))]
    if any(image):
        return [x for x in image if x]
    edges = f.get(EDGES)
    if isinstance(edges, h5py.Group):  # a box that changes: sides [frames, 2], or box vectors [frames, 2, 2]
        shape = (frames, 2, 2) if len(getattr(edges.get("value"), "shape", ())) == 3 else (frames, 2)
        problem = _shape_problem(f, f"{EDGES}/value", shape) or _shape_problem(f, f"{EDGES}/step", (frames,), "iu")
        values = edges.get("value")
    else:
        problem = _shape_problem(f, EDGES, (2,))
        values = edges
    if problem:
        return [problem]
    blocks = [values[...][None]] if values.ndim == 1 else \
        (values[k:k + BOX_BLOCK] for k in range(0, values.shape[0], BOX_BLOCK))
    for e in blocks:
        if not np.isfinite(e).all():
            return [f"{EDGES} holds a value that is not a finite number"]
        sides = e if e.ndim == 2 else np.stack([e[:, 0, 0], e[:, 1, 1]], axis=1)  # L_x, L_y
        if not (sides > 0.0).all():
            return [f"{EDGES} holds a side of the box that is not > 0 ({float(sides.min())!r} m)"]
    return []


def _statics_problems(f, frames: int) -> list[str]:
    """Why the colliders' record (format 7 on) would trip a reader: a series missing or not one row per frame
    and one per collider."""
    position = _shape_problem(f, f"{STATICS}/position/value", (frames, None, 2))
    if position:
        return [position]
    count = f[f"{STATICS}/position/value"].shape[1]
    return [x for x in (_shape_problem(f, f"{STATICS}/{name}/value", (frames, count, *tail))
                        for name, tail in (("angle", ()), ("force", (2,)), ("torque", ()))) if x]


@contextmanager
def reading(path):
    """Turn a failure while reading a trajectory's data (a damaged block passes the layout
    check and fails only when read) into TrajectoryError."""
    try:
        yield
    except TrajectoryError:
        raise
    except (OSError, RuntimeError, ValueError, KeyError, TypeError, IndexError, UnicodeDecodeError) as e:
        raise TrajectoryError(f"{path}: damaged, cannot be read ({str(e).splitlines()[0]})") from None


PROBE_BYTES = 1 << 20  # the probe reads datasets up to this size whole, larger ones at both ends
PROBE_SECONDS = 10.0  # and gives up on (and refuses) a file whose metadata it cannot read in this time
_probed: dict = {}  # (device, inode, size, mtime) -> crashed: a file is probed once per process


def _probe_crashes(path) -> bool:
    """Whether reading the file's metadata crashes or hangs the process. The HDF5 library can
    segfault on a byte-flipped file (seen reading an attribute), or loop without end, which no
    Python handler can catch; so a forked child reads every attribute and the ends of every
    dataset first, and only a file it survives within PROBE_SECONDS is opened here."""
    if not hasattr(os, "fork"):
        return False
    st = os.stat(path)
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    if key not in _probed:
        _probed[key] = _probe_in_child(path)
    return _probed[key]


def _probe_in_child(path) -> bool:
    pid = os.fork()
    if pid == 0:  # the child: read, then leave without running any cleanup of the parent's
        code = 0
        try:
            with h5py.File(path, "r") as f:
                def visit(name, obj):
                    dict(obj.attrs)
                    if isinstance(obj, h5py.Dataset) and obj.shape is not None:
                        if obj.size * obj.dtype.itemsize <= PROBE_BYTES or not obj.shape:
                            obj[()]
                        else:
                            obj[:1], obj[-1:]
                dict(f.attrs)
                f.visititems(visit)
        except BaseException:  # noqa: BLE001 - an exception is the parent's to report, not a crash
            code = 0
        os._exit(code)
    deadline = time.monotonic() + PROBE_SECONDS
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.WIFSIGNALED(status)
        if time.monotonic() > deadline:  # a damaged file can also send HDF5 into an endless loop
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            return True
        time.sleep(0.002)


def open_trajectory(path, need_restart: bool = False) -> h5py.File:
    """Open a trajectory for reading, checked against LAYOUT; raise TrajectoryError (one line)."""
    if Path(path).is_file() and _probe_crashes(path):
        raise TrajectoryError(f"{path}: damaged: the HDF5 library crashes or hangs reading it")
    try:
        f = h5py.File(path, "r")
    except FileNotFoundError:
        raise TrajectoryError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise TrajectoryError(f"{path}: is a directory, not a trajectory file") from None
    except OSError as e:
        raise TrajectoryError(f"{path}: not a readable HDF5 file ({str(e).split(';')[0]})") from None
    try:
        problems = trajectory_problems(f, need_restart)
    except Exception as e:  # noqa: BLE001 - a byte-flipped file can fail in HDF5 itself
        problems = [f"unreadable ({type(e).__name__}: {e})"]
    if problems:
        f.close()
        raise TrajectoryError(f"{path}: not a usable blobsim trajectory: {'; '.join(problems[:3])}")
    return f


def stored_scene(f, path):
    """The validated scene stored in an open trajectory file; TrajectoryError if it is not valid."""
    from ...scene.schema import SceneError, parse_scene
    source = text(f[PARAMETERS].attrs.get("source", "")) or str(path)  # so the name is the scene's own
    try:
        scene = parse_scene(text(f[PARAMETERS]["scene"][()]), source)
        recorded = f[f"{STATICS}/position/value"].shape[1] if STATICS in f else len(scene.statics)
        if recorded != len(scene.statics):  # (each series' shape: trajectory_problems)
            raise TrajectoryError(f"{path}: not a usable blobsim trajectory: {STATICS} records {recorded} colliders, "
                                  f"its scene has {len(scene.statics)}")
        return scene
    except SceneError as e:
        raise TrajectoryError(f"{path}: its stored scene is not valid: {e.problems[0]}") from None
    except UnicodeDecodeError:
        raise TrajectoryError(f"{path}: its stored scene is not UTF-8 text") from None


@dataclass
class Trajectory:
    """A trajectory file read back whole (for tests, compare and replay)."""
    position: np.ndarray  # (frames, N, 2)
    step: np.ndarray  # (frames,)
    time: np.ndarray  # (frames,)
    offsets: np.ndarray  # (B + 1,)
    names: list
    area: np.ndarray  # (frames, B)
    kinetic_energy: np.ndarray  # (frames, B)
    awake: np.ndarray  # (frames, B) uint8: 1 awake, 0 asleep (all 1 in formats 1-3, which had no sleeping)
    target_area: np.ndarray  # (B,)
    mass: np.ndarray  # (B,) kg
    complete: bool
    attrs: dict  # /parameters attrs
    scene: str
    statics: dict  # /observables/statics: "position" (frames, S, 2), "angle", "force", "torque"; empty without


def read_trajectory(path: str | Path) -> Trajectory:
    """Read a whole trajectory file; raise TrajectoryError if it is not one."""
    with open_trajectory(path) as f, reading(path):
        pos = f[POSITION]
        p = f[PARAMETERS]
        return Trajectory(position=pos["value"][...], step=pos["step"][...], time=pos["time"][...],
                          offsets=p["blob_offsets"][...], names=[text(s) for s in p["blob_names"][...]],
                          area=f[AREA]["value"][...], kinetic_energy=f[KINETIC]["value"][...],
                          awake=f[AWAKE]["value"][...] if AWAKE in f else np.ones(f[AREA]["value"].shape, np.uint8),
                          target_area=p["target_area"][...], mass=p["mass"][...], complete=bool(f.attrs["complete"]),
                          attrs=dict(p.attrs), scene=text(p["scene"][()]),
                          statics={name: g["value"][...] for name, g in f[STATICS].items()} if STATICS in f else {})
