"""Trajectory files: H5MD 1.1, blobsim format FORMAT_VERSION (a contract: docs/output-format.md).

The layout, `LAYOUT` below, is the one copy of the schema: docs/output-format.md shows it
verbatim (a test keeps the two equal) and `trajectory_problems` checks every file read
against it, so a crafted or damaged file is refused with one line instead of a traceback.

Writing: frames are buffered and written in blocks of about 4 MiB (and at least every
FLUSH_SECONDS) into `<path>.partial`, created exclusively (blobcli.io.outputs); only `close`
marks the file, `complete = true` only for a run that finished, and renames it to `<path>`.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from ..geometry import ring_next
from ..sim import packing
from .outputs import create_partial, publish

FORMAT_VERSION = 9
# Format 1 lacks /connectivity, particles/blobs/mass and the units module; formats 1 and 2 store impact_speed
# in /restart; formats 1-3 have no sleeping (no /observables/awake: every blob was awake); formats 1-5 are not
# resumable by this blobsim (their /restart lacks the stick points (1-4) or where each blob's rest began (5));
# formats 1-6 have no moving colliders (no /observables/statics, no /restart/static_pose: every collider at rest);
# formats 1-7 have no periodic box (their box's boundary is "none").
READS_FORMATS = (1, 2, 3, 4, 5, 6, 7, 8, 9)
LAYOUT = """\
/                            attrs: complete (bool), blobsim_format = 9, stopped (str: why a run ended early),
                                    warnings (str: problems seen in the final state; may be absent)
/h5md                        attrs: version = [1, 1]
    author                   attrs: name (fixed-length ASCII)
    creator                  attrs: name = "blobsim", version (fixed-length ASCII)
    modules/units            attrs: version = [1, 0], system = "SI"
/particles/blobs
    box                      attrs: dimension = 2, boundary = ["none", "none"], or in a periodic box
                             ["periodic", "periodic"] with
      edges                  float64 [2]  unit "m": the box's sides L_x, L_y; the box is [-L/2, L/2) (format 8);
                             a box that changes (a scene.periodic schedule, or `blobsim jam`'s
                             compression): {value [frames, 2], step, time};
                             a sheared box (scene.shear): {value [frames, 2, 2], step, time}, its rows the
                             box vectors e_1 = (L_x, 0), e_2 = (γ L_y, L_y) (Lees–Edwards)
    position/value           float64 [frames, vertices, 2]  unit "m"; in a periodic box each blob is whole, moved
                             by whole box sides so that its centre (vertex average) lies in the box
    position/step            int64   [frames]
    position/time            float64 [frames]  unit "s" (= step × dt)
    image/{value,step,time}  value int32 [frames, vertices, 2] (periodic box only): the box vectors each vertex
                             was moved by, so that position + image × edges (n_x e_1 + n_y e_2 when sheared) is
                             the unwrapped trajectory, continuous but for the box's own remaps
    mass                     float64 [vertices]  unit "kg" (each vertex's share of its blob)
/connectivity
    edges                    int64 [vertices, 2]: vertex index pairs, each ring's closed polyline
      attrs: particles_group = reference to /particles/blobs
/observables
    area/{value,step,time}            value float64 [frames, blobs]  unit "m+2" (positive)
    kinetic_energy/{value,step,time}  value float64 [frames, blobs]  unit "J"
    awake/{value,step,time}           value uint8 [frames, blobs]: 1 awake, 0 asleep (frozen, not simulated)
    statics/                          (scenes with colliders; one row per [[static]] table, in scene order)
      position/{value,step,time}      value float64 [frames, statics, 2]  unit "m": its pivot, where it is now
      angle/{value,step,time}         value float64 [frames, statics]  unit "deg": its turn since t = 0
      force/{value,step,time}         value float64 [frames, statics, 2]  unit "N": the force the blobs exert
                                      on it, their contact impulses over the frame's step / dt (0 at frame 0):
                                      the pushes and the velocity stages' impulses (since 2026-11-26; before,
                                      the pushes alone, too much while a blob settled after an impact)
      torque/{value,step,time}        value float64 [frames, statics]  unit "N m": their moment about its pivot
    (in a periodic box only, format 8: what the packing measures, sim/packing.py; 0 at frame 0)
    packing_fraction/{value,step,time}  value float64 [frames]: the blobs' area over the box's
    contacts/{value,step,time}        value int32 [frames, blobs]: the blobs each touches (contacts that pushed in
                                      the frame's step's last substep)
    rattler/{value,step,time}         value uint8 [frames, blobs]: 1 for a rattler (fewer than 3 contacts, 2 when
                                      the blobs have friction; removed repeatedly)
    pressure/{value,step,time}        value float64 [frames]  unit "N m-1": -tr(stress) / 2, > 0 compressed
    stress/{value,step,time}          value float64 [frames, 2, 2]  unit "N m-1": the contact (virial) stress
                                      (1/A) Σ (x - c) ⊗ f over the frame's step, Cauchy: negative compressed
/parameters
    blob_offsets             int64 [blobs + 1]: blob b owns vertices offsets[b]:offsets[b+1]
    blob_names               str   [blobs]
    target_area              float64 [blobs]  (m²)
    mass                     float64 [blobs]  (kg)
    scene                    str: the scene's TOML text
      attrs: dt, substeps, max_substeps, iterations, method, damping, gravity, sleep, sleep_speed, time_to_sleep, steps,
             every, source,
             blobsim_version, python, numpy, core, compiler, h5py, hdf5, platform, machine,
             threads, env_OMP_NUM_THREADS, env_OPENBLAS_NUM_THREADS,
             env_PYTHONHASHSEED
/restart                     the exact state at the last recorded frame (for --resume)
    position, velocity       float64 [vertices, 2]
    impact                   float64 [blobs, 4]: each blob's latest impact on statics (restitution): fastest
                             approach (m/s), energy it left with (J/kg, -inf before), kinetic and potential
                             energy it came with (J/kg)
    pair_key                 int64 [pairs]: blob pairs a < b with an impact record, as a × blobs + b, sorted
    pair_impact              float64 [pairs, 4]: their impact records, as impact's
    awake                    uint8 [blobs]: 1 awake, 0 asleep
    still                    float64 [blobs]: how long each awake blob has been at rest (s) ...
    still_center             float64 [blobs, 2]: ... where its centre was when that rest began (m) ...
    still_angle              float64 [blobs]: ... and the angle of its first vertex about that centre then (rad)
    stick_edge               int64 [vertices, 2]: each vertex's blob contacts (up to 2) held by static friction:
                             the other blob's edge it sticks to (by the edge's first vertex; -1: none) ...
    stick_t                  float64 [vertices, 2]: ... and where along that edge (0 at its first vertex, 1 at
                             the next)
    static_pose              float64 [statics, 6]: each collider's pose: displacement dx, dy (m) and turn (rad)
                             since the scene's pose, a loaded wall's s (m) and speed V (m/s) along its load
                             direction, and s at the last substep's start (m) (format 7; absent before: at rest)
      attrs: step
"""
# /restart's datasets of fixed shape, each a State field stored row by row: (dataset = State field,
# rows: "vertices" or "blobs", columns (None: one value per row), HDF5 kinds). Per-vertex fields are
# (k, N) in the State (structure of arrays) and stored [vertices, k]. The pair records (pair_key,
# pair_impact) change length and are stored apart (restart_pairs).
RESTART_FIELDS = (("position", "vertices", 2, "f"), ("velocity", "vertices", 2, "f"), ("impact", "blobs", 4, "f"),
                  ("awake", "blobs", None, "u"), ("still", "blobs", None, "f"), ("still_center", "blobs", 2, "f"),
                  ("still_angle", "blobs", None, "f"), ("stick_edge", "vertices", 2, "i"),
                  ("stick_t", "vertices", 2, "f"), ("static_pose", "statics", 6, "f"))
SINCE_FORMAT = {"static_pose": 7}  # /restart datasets newer than format 6, the oldest resumable
RESTART_DTYPES = {"f": np.float64, "i": np.int64, "u": np.uint8}
_PER_VERTEX = {name for name, rows, *_ in RESTART_FIELDS if rows == "vertices"}
POSITION = "particles/blobs/position"
IMAGE = "particles/blobs/image"
EDGES = "particles/blobs/box/edges"
AREA = "observables/area"
KINETIC = "observables/kinetic_energy"
AWAKE = "observables/awake"
STATICS = "observables/statics"
SERIES = (POSITION, AREA, KINETIC, AWAKE)
PARAMETERS = "parameters"
RESTART = "restart"
BLOCK_BYTES = 4 << 20  # frames per block: about this many bytes of positions
FLUSH_SECONDS = 10.0  # and no block waits longer than this
DISK_RESERVE = 1 << 20  # bytes: a block is written only if this much stays free after it (HDF5 metadata,
#                         the closing attributes); HDF5 cannot recover from a write the disk refuses


def ascii(text: str) -> np.bytes_:
    """A fixed-length ASCII string, as H5MD asks for names and units (non-ASCII becomes ?)."""
    return np.bytes_(text.encode("ascii", "replace"))


def _series(group, name, shape, dtype=np.float64, unit=None, chunk=1):
    """An H5MD time-dependent element: value [frames, *shape], step, time."""
    g = group.create_group(name)
    v = g.create_dataset("value", shape=(0, *shape), maxshape=(None, *shape), dtype=dtype,
                         chunks=(chunk, *shape))
    if unit:
        v.attrs["unit"] = ascii(unit)
    g.create_dataset("step", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(max(chunk, 256),))
    t = g.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(max(chunk, 256),))
    t.attrs["unit"] = ascii("s")
    return g


def versions() -> dict:
    """Versions and settings a bit-for-bit reproduction needs."""
    from .. import __version__
    from ..core import load
    ffi, lib = load()
    env = {k: os.environ.get(k, "") for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "PYTHONHASHSEED")}
    return {"blobsim_version": __version__, "python": sys.version.split()[0], "numpy": np.__version__,
            "core": ffi.string(lib.bc_source_hash()).decode(), "compiler": ffi.string(lib.bc_compiler()).decode(),
            "h5py": h5py.__version__, "hdf5": h5py.version.hdf5_version, "platform": platform.platform(),
            "machine": platform.machine(), "threads": lib.bc_threads(), **{f"env_{k}": v for k, v in env.items()}}


class TrajectoryError(Exception):
    """A file that is not a readable blobsim trajectory; the message is one line."""


class DiskFull(OSError):
    """The next block of frames would not fit on the disk; nothing of it was written."""


class TrajectoryWriter:
    """Streams frames of one run into `<path>.partial`; `close` publishes it at `path`.

    The caller holds the output lock (blobcli.io.outputs.OutputLock)."""

    def __init__(self, path, scene, model, params, box_changes: bool = False):
        """`box_changes`: the periodic box changes from frame to frame though no schedule says so (`blobsim
        jam` shrinks it): its edges are a time series."""
        from .. import __version__
        self.path = Path(path)
        self.partial = create_partial(self.path)
        self.dt = params.dt
        n, b = model.vertex_count, model.blob_count
        frames = params.steps // params.every + 1  # expected; resumed or extended runs may add more
        self.block = max(1, min(4096, BLOCK_BYTES // (16 * n), frames))
        f = self.file = h5py.File(self.partial, "w")
        f.attrs["complete"] = False
        f.attrs["blobsim_format"] = FORMAT_VERSION
        h5 = f.create_group("h5md")
        h5.attrs["version"] = np.array([1, 1], dtype=np.int32)
        h5.create_group("author").attrs["name"] = ascii(os.environ.get("USER", "blobsim user"))
        creator = h5.create_group("creator")
        creator.attrs["name"] = ascii("blobsim")
        creator.attrs["version"] = ascii(__version__)
        units = h5.create_group("modules/units")
        units.attrs["version"] = np.array([1, 0], dtype=np.int32)
        units.attrs["system"] = ascii("SI")

        particles = f.create_group("particles/blobs")
        box = particles.create_group("box")
        box.attrs["dimension"] = 2
        self.box = np.array(params.box, dtype=np.float64) if params.box[0] > 0.0 else None
        box.attrs["boundary"] = np.array([b"none", b"none"] if self.box is None else [b"periodic", b"periodic"])
        self.position = _series(particles, "position", (n, 2), unit="m", chunk=self.block)
        self.image = None
        self.edges = None  # the box's sides (or vectors, sheared) frame by frame, when a schedule changes them
        self.sheared = any(s.key == "scene.shear" for s in scene.schedules)
        if self.box is not None and (box_changes or any(s.key in ("scene.periodic", "scene.shear")
                                                         for s in scene.schedules)):
            shape = (2, 2) if self.sheared else (2,)
            self.edges = _series(box, "edges", shape, unit="m", chunk=self.block)
            self._edges = np.empty((self.block, *shape))
        elif self.box is not None:
            box.create_dataset("edges", data=self.box).attrs["unit"] = ascii("m")
        if self.box is not None:
            self.image = _series(particles, "image", (n, 2), dtype=np.int32, chunk=self.block)
            self._image = np.empty((self.block, n, 2), np.int32)
            self._starts, self._counts = model.offsets[:-1], np.diff(model.offsets)
        particles.create_dataset("mass", data=1.0 / model.inv_mass).attrs["unit"] = ascii("kg")
        edges = f.create_group("connectivity").create_dataset(
            "edges", data=np.stack([np.arange(n), ring_next(model.offsets)], axis=1).astype(np.int64))
        edges.attrs["particles_group"] = particles.ref
        obs = f.create_group("observables")
        self.area = _series(obs, "area", (b,), unit="m+2", chunk=self.block)
        self.kinetic = _series(obs, "kinetic_energy", (b,), unit="J", chunk=self.block)
        self.awake = _series(obs, "awake", (b,), dtype=np.uint8, chunk=self.block)
        self.packing_series, self._packing = {}, {}  # what a packing measures: periodic box only
        if self.box is not None:
            self._rattler_below = packing.rattler_below(model.material)
            self.packing_series = {"packing_fraction": _series(obs, "packing_fraction", (), chunk=self.block),
                                   "contacts": _series(obs, "contacts", (b,), dtype=np.int32, chunk=self.block),
                                   "rattler": _series(obs, "rattler", (b,), dtype=np.uint8, chunk=self.block),
                                   "pressure": _series(obs, "pressure", (), unit="N m-1", chunk=self.block),
                                   "stress": _series(obs, "stress", (2, 2), unit="N m-1", chunk=self.block)}
            self._packing = {name: np.empty((self.block, *ds["value"].shape[1:]), ds["value"].dtype)
                             for name, ds in self.packing_series.items()}
        S = self.statics = len(model.walls.motion)
        self._pivot = model.walls.pivot
        if S:
            group = obs.create_group("statics")
            self.static_series = {"position": _series(group, "position", (S, 2), unit="m", chunk=self.block),
                                  "angle": _series(group, "angle", (S,), unit="deg", chunk=self.block),
                                  "force": _series(group, "force", (S, 2), unit="N", chunk=self.block),
                                  "torque": _series(group, "torque", (S,), unit="N m", chunk=self.block)}
            self._statics = {"position": np.empty((self.block, S, 2)), "angle": np.empty((self.block, S)),
                             "force": np.empty((self.block, S, 2)), "torque": np.empty((self.block, S))}
        else:
            self.static_series, self._statics = {}, {}

        p = f.create_group(PARAMETERS)
        p.create_dataset("blob_offsets", data=model.offsets)
        p.create_dataset("blob_names", data=np.array(model.names, dtype=object), dtype=h5py.string_dtype())
        p.create_dataset("target_area", data=np.abs(model.target_area))
        p.create_dataset("mass", data=model.mass)
        p.create_dataset("scene", data=scene.text, dtype=h5py.string_dtype())
        attrs = dict(dt=params.dt, substeps=params.substeps, max_substeps=params.max_substeps,
                     iterations=params.iterations, method=params.method,
                     damping=params.damping, gravity=params.gravity, sleep=params.sleep,
                     sleep_speed=params.sleep_speed, time_to_sleep=params.time_to_sleep, steps=params.steps,
                     every=params.every,
                     source=scene.source, **versions())
        for k, v in attrs.items():
            p.attrs[k] = v
        self._sign = np.sign(model.rest_area)
        # One block of frames, filled in place; and the state of the latest frame, for /restart.
        self._steps = np.empty(self.block, dtype=np.int64)
        self._pos = np.empty((self.block, n, 2))
        self._area = np.empty((self.block, b))
        self._kinetic = np.empty((self.block, b))
        self._awake = np.empty((self.block, b), np.uint8)
        self._last = {name: np.empty(_restart_shape(rows, columns, n, b, S), RESTART_DTYPES[kinds])
                      for name, rows, columns, kinds in RESTART_FIELDS
                      if name != "awake" and (name != "position" or self.box is not None)}
        # (awake, and position unless the frames store it wrapped: from the frame buffers)
        self._last_pairs = (np.zeros(0, np.int64), np.zeros((0, 4)))
        self._count = 0
        self._last_flush = time.monotonic()
        self._frame_bytes = 8 * (2 * n + 2 * b + 6 * S) + b + 16 + (8 * n + 5 * b + 48 if self.box is not None else 0)
        self.frames = 0

    def append(self, step: int, state, area, kinetic, box=None, shear=None):
        """Buffer one frame of `state` (copied); write the block when it is full or old. `box`, `shear`: the
        periodic box's sides and shear strain γ in this frame, when schedules change them."""
        k = self._count
        self._steps[k] = step
        if self.box is None:
            self._pos[k] = state.pos
        else:  # each blob whole, its centre in the box: n_y = floor(c_y / L_y + 1/2), then n_x along its row
            sides = self.box if box is None else np.asarray(box, dtype=np.float64)
            tilt = (shear or 0.0) * sides[1]  # γ L_y
            centre = np.add.reduceat(state.pos, self._starts, axis=0) / self._counts[:, None]
            ny = np.floor(centre[:, 1] / sides[1] + 0.5)
            nx = np.floor((centre[:, 0] - ny * tilt) / sides[0] + 0.5)
            image = np.repeat(np.stack([nx, ny], axis=1), self._counts, axis=0)
            self._image[k] = image
            self._pos[k] = state.pos - image * sides
            if tilt != 0.0:
                self._pos[k, :, 0] -= image[:, 1] * tilt
            if self.edges is not None:
                self._edges[k] = [[sides[0], 0.0], [tilt, sides[1]]] if self.sheared else sides
            self._measure_packing(k, step, state, area, sides)
        np.multiply(area, self._sign, out=self._area[k])
        self._kinetic[k] = kinetic
        self._awake[k] = state.awake
        if self.statics:
            st = self._statics
            st["position"][k] = self._pivot + state.static_pose[:, :2]
            st["angle"][k] = np.degrees(state.static_pose[:, 2])
            st["force"][k] = state.static_impulse[:, :2] / self.dt if step > 0 else 0.0
            st["torque"][k] = state.static_impulse[:, 2] / self.dt if step > 0 else 0.0
        for name, kept in self._last.items():
            kept[...] = restart_view(state, name)
        self._last_pairs = restart_pairs(state)
        self._count = k + 1
        if self._count == self.block or time.monotonic() - self._last_flush > FLUSH_SECONDS:
            self.flush()

    def _measure_packing(self, k, step, state, area, sides):
        """Frame k's packing_fraction, contacts, rattlers, pressure and stress (sim/packing.py)."""
        virial, touching, count = state.packing
        touching = touching[:count[0]]
        blobs = len(area)
        sigma = packing.stress(virial, self.dt, sides) if step > 0 else np.zeros((2, 2))
        out = self._packing
        out["packing_fraction"][k] = packing.packing_fraction(area, sides)
        out["contacts"][k] = packing.contact_counts(touching, blobs)
        out["rattler"][k] = packing.rattlers(touching, blobs, self._rattler_below)
        out["stress"][k] = sigma
        out["pressure"][k] = packing.pressure(sigma)

    def flush(self):
        k = self._count
        if k == 0:
            return
        disk = os.statvfs(self.partial.parent)
        free, need = disk.f_bavail * disk.f_frsize, k * self._frame_bytes + DISK_RESERVE
        if free < need:
            raise DiskFull(28, f"no space left on the disk for {k} more frames ({free:,} bytes free, "
                               f"{need:,} needed)")
        steps = self._steps[:k]
        start, stop = self.frames, self.frames + k
        for group, values in ((self.position, self._pos[:k]), (self.area, self._area[:k]),
                              (self.kinetic, self._kinetic[:k]), (self.awake, self._awake[:k]),
                              *((self.static_series[name], self._statics[name][:k]) for name in self._statics),
                              *(((self.image, self._image[:k]),) if self.image is not None else ()),
                              *(((self.edges, self._edges[:k]),) if self.edges is not None else ()),
                              *((self.packing_series[name], self._packing[name][:k]) for name in self._packing)):
            for name, data in (("value", values), ("step", steps), ("time", steps * self.dt)):
                ds = group[name]
                ds.resize(stop, axis=0)
                ds[start:stop] = data
        self._write_restart({"position": self._pos[k - 1], **self._last, "awake": self._awake[k - 1]},
                            self._last_pairs, steps[-1])
        self.frames = stop
        self._count = 0
        self.file.flush()
        self._last_flush = time.monotonic()

    def _write_restart(self, fields, pairs, step):
        """/restart: `fields` (dataset name -> array, as restart_view), the pair records, the step."""
        restart = self.file.require_group(RESTART)
        for name, data in (*fields.items(), ("pair_key", pairs[0]), ("pair_impact", pairs[1])):
            if name not in restart:  # the pair records change length: resizable along axis 0
                restart.create_dataset(name, data=data, maxshape=(None, *data.shape[1:]), chunks=True)
            else:
                restart[name].resize(len(data), axis=0)
                restart[name][...] = data
        restart.attrs["step"] = step

    def adopt(self, source, state, stop_requested) -> int | None:
        """Resume: copy the frames and restart state of `source` (checked by the caller with
        `resume_problems`) and load that state. Returns the step to continue after, or None
        when `stop_requested()` turned true while copying (then this file is to be abandoned)."""
        with open_trajectory(source) as f, reading(source):
            restart = f[RESTART]
            step = int(restart.attrs["step"])
            pos = f[POSITION]
            keep = int(np.searchsorted(pos["step"][...], step, side="right"))
            self.flush()
            for start in range(0, keep, self.block):
                if stop_requested():
                    return None
                stop = min(start + self.block, keep)
                for group, name in ((self.position, POSITION), (self.area, AREA), (self.kinetic, KINETIC),
                                    (self.awake, AWAKE),
                                    *((g, f"{STATICS}/{n}") for n, g in self.static_series.items()),
                                    *(((self.image, IMAGE),) if self.image is not None else ()),
                                    *(((self.edges, EDGES),) if self.edges is not None else ()),
                                    *((g, f"observables/{n}") for n, g in self.packing_series.items())):
                    for key in ("value", "step", "time"):
                        ds = group[key]
                        ds.resize(self.frames + stop - start, axis=0)
                        if name in f:
                            ds[self.frames:] = f[name][key][start:stop]
                        elif key != "value":
                            ds[self.frames:] = f[POSITION][key][start:stop]
                        else:  # format 6 has no statics series: its colliders were fixed at their pivots (forces
                            #    not recorded: written as 0)
                            ds[self.frames:] = self._pivot if name.endswith("/position") else 0.0
                self.frames += stop - start
            for name, *_ in RESTART_FIELDS:
                if name in restart:  # static_pose: format 7 on (resume_problems refuses a moving scene before)
                    restart_view(state, name)[...] = restart[name][...]
            state.steps_done[0] = step
            keys = restart["pair_key"][...]
            if len(keys) > len(state.pair_key):
                raise TrajectoryError(f"{source}: {RESTART}/pair_key holds {len(keys)} blob pairs, more than this "
                                      f"scene keeps ({len(state.pair_key)})")
            state.pair_key[:len(keys)] = keys
            state.pair_impact[:len(keys)] = restart["pair_impact"][...]
            state.pair_count[0] = len(keys)
            # The restart state goes with the frames at once: a file resumed and stopped before
            # its next recorded frame must still be resumable.
            self._write_restart({name: restart_view(state, name) for name, *_ in RESTART_FIELDS},
                                restart_pairs(state), step)
            self.worst_area_error = _worst_area_error(f[AREA]["value"][1:keep], f[PARAMETERS]["target_area"][...])
        self.file.flush()
        return step

    def close(self, complete: bool, stopped: str = "", warnings: str = "", drop_buffered: bool = False):
        """Write what is buffered (unless drop_buffered: the disk is full), mark the file and
        move it into place at `path`."""
        if drop_buffered:
            self._count = 0
        self.flush()
        self.file.attrs["complete"] = complete
        self.file.attrs["stopped"] = stopped
        if warnings:
            self.file.attrs["warnings"] = warnings
        self.file.close()
        publish(self.partial, self.path)

    def abandon(self):
        """Close and delete the .partial: nothing is published, `path` is left as it was."""
        try:
            self.file.close()
        finally:
            self.partial.unlink(missing_ok=True)

    def salvage(self, reason: str) -> str:
        """After a failed write (disk full): keep the .partial if it is still a readable file,
        else remove it. Returns a sentence saying which, for the user."""
        try:
            self.file.close()
        except Exception:  # noqa: BLE001 - the file is already broken; what matters is below
            pass
        try:
            with h5py.File(self.partial, "r") as f:
                frames = len(f[POSITION]["step"])
            with h5py.File(self.partial, "r+") as f:
                f.attrs["complete"] = False
                f.attrs["stopped"] = reason
            return f"the {frames} frames written before it are in {self.partial} (readable, complete = false)"
        except Exception:  # noqa: BLE001 - unreadable: it would only fill the disk
            self.partial.unlink(missing_ok=True)
            return f"{self.partial} was unreadable and has been removed"


def _worst_area_error(area, target) -> float:
    """max |A - A_target| / A_target over frames and blobs (0 for no frames)."""
    return float(np.max(np.abs(area - target) / target, initial=0.0))


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
        problems += [_shape_problem(f, f"{RESTART}/{name}", _restart_shape(rows, columns, n, b, statics), kinds)
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


def restart_view(state, name):
    """State field `name` of RESTART_FIELDS as /restart stores it, row by row (a view: writing it writes the
    state)."""
    field = getattr(state, name)
    return field.T if name in _PER_VERTEX else field


def _restart_shape(rows, columns, n, b, statics) -> tuple:
    """The shape of a RESTART_FIELDS dataset in a file of n vertices, b blobs and that many colliders."""
    return ({"vertices": n, "blobs": b, "statics": statics}[rows],) + (() if columns is None else (columns,))


def restart_pairs(state):
    """The kept blob-pair impact records of a state (copies): (pair_key, pair_impact)."""
    n = int(state.pair_count[0])
    return state.pair_key[:n].copy(), state.pair_impact[:n].copy()


def text(value) -> str:
    """A string read from HDF5 (bytes or str) as str."""
    return value.decode() if isinstance(value, bytes) else str(value)


def resume_problems(path, scene, params) -> list[str]:
    """Why `path` cannot be resumed with this scene and these settings (empty: it can)."""
    try:
        f = open_trajectory(path, need_restart=True)
    except TrajectoryError as e:
        return [str(e)]
    try:
        return _resume_problems(f, path, scene, params)
    except TrajectoryError as e:
        return [str(e)]


def _resume_problems(f, path, scene, params) -> list[str]:
    with f, reading(path):
        p = f[PARAMETERS]
        problems = []
        if text(p["scene"][()]) != scene.text:
            problems.append(f"{path}: was run from a different scene text than {scene.source}")
        for key in ("dt", "substeps", "iterations", "method", "every", "max_substeps"):
            if key not in p.attrs:  # (max_substeps: not in files of blobsim 0.1 before 2026-11-26)
                continue
            was, now = p.attrs[key], getattr(params, key)
            if was != now:
                problems.append(f"{path}: was run with {key} = {was}, not {now}")
        complete = bool(f.attrs["complete"])
        last = int(p.attrs["steps"]) if complete else int(f[RESTART].attrs["step"])
        version = int(np.asarray(f.attrs["blobsim_format"]).flat[0])
        moving = [i for i, st in enumerate(scene.statics) if st.moves]
        if version < 7 and moving:
            problems.append(f"{path}: blobsim format {version} keeps no collider poses; static[{moving[0]}] moves")
        elif version >= 7 and f[f"{RESTART}/static_pose"].shape[0] != len(scene.statics):
            problems.append(f"{path}: holds {f[f'{RESTART}/static_pose'].shape[0]} colliders, the scene "
                            f"{len(scene.statics)}")
        if params.steps <= last:
            problems.append(f"{path}: the run {'is complete at' if complete else 'already reached'} step {last}; "
                            f"give more --steps (got {params.steps}) to extend it")
        return problems + [f"{path}: {x}; it cannot be resumed" for x in restart_value_problems(f)]


def restart_value_problems(f) -> list[str]:
    """Why the restart state of an open file (its shapes checked by trajectory_problems) is not one a step can
    start from: the blobs' or the colliders' (static_pose) values not all finite numbers (an impact record's
    energy left with is -inf before it bounces), a stick point on an edge the blobs do not have, or an impact
    record of a pair that is not two of its blobs, in order."""
    restart = f[RESTART]
    n, b = restart["position"].shape[0], f[f"{PARAMETERS}/blob_offsets"].shape[0] - 1
    for name, *_ in RESTART_FIELDS + (("pair_impact",),):
        if name not in restart or restart[name].dtype.kind != "f":
            continue
        values = restart[name][...]
        bad = ~np.isfinite(values)
        if name in ("impact", "pair_impact"):  # NO_BOUNCE: the energy it left with before a bounce
            bad[:, 1] &= values[:, 1] != -np.inf
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            return [f"{RESTART}/{name} holds a value that is not a finite number (row {row}: "
                    f"{values[row].tolist()})"]
    stick = restart["stick_edge"][...]
    if stick.size and (stick.min() < -1 or stick.max() >= n):
        return [f"{RESTART}/stick_edge holds an edge the {n} vertices do not have ({int(stick.min())} .. "
                f"{int(stick.max())}; -1: none)"]
    keys = restart["pair_key"][...]
    if len(keys) and (keys.min() < 0 or keys.max() >= b * b or np.any(keys // b >= keys % b)
                      or np.any(np.diff(keys) <= 0)):
        return [f"{RESTART}/pair_key holds a key that is not a pair a < b of the {b} blobs as a × {b} + b, "
                f"in increasing order"]
    return []


def stored_scene(f, path):
    """The validated scene stored in an open trajectory file; TrajectoryError if it is not valid."""
    from ..scene.schema import SceneError, parse_scene
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
