"""Writing a trajectory: frames are buffered and written in blocks of about 4 MiB (and at least every
FLUSH_SECONDS) into `<path>.partial`, created exclusively (blobcli.io.outputs); only `close` marks the
file, `complete = true` only for a run that finished, and renames it to `<path>`.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

import h5py
import numpy as np

from ...geometry import ring_next
from ...sim import packing
from ..outputs import create_partial, publish
from .layout import (
    AREA,
    AWAKE,
    EDGES,
    FORMAT_VERSION,
    IMAGE,
    KINETIC,
    PARAMETERS,
    POSITION,
    RESTART,
    RESTART_DTYPES,
    RESTART_FIELDS,
    STATICS,
    TrajectoryError,
    restart_shape,
)
from .reader import open_trajectory, reading
from .restart import restart_pairs, restart_view

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
    from ... import __version__
    from ...core import load
    ffi, lib = load()
    env = {k: os.environ.get(k, "") for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "PYTHONHASHSEED")}
    return {"blobsim_version": __version__, "python": sys.version.split()[0], "numpy": np.__version__,
            "core": ffi.string(lib.bc_source_hash()).decode(), "compiler": ffi.string(lib.bc_compiler()).decode(),
            "h5py": h5py.__version__, "hdf5": h5py.version.hdf5_version, "platform": platform.platform(),
            "machine": platform.machine(), "threads": lib.bc_threads(), **{f"env_{k}": v for k, v in env.items()}}


class DiskFull(OSError):
    """The next block of frames would not fit on the disk; nothing of it was written."""


class TrajectoryWriter:
    """Streams frames of one run into `<path>.partial`; `close` publishes it at `path`.

    The caller holds the output lock (blobcli.io.outputs.OutputLock)."""

    def __init__(self, path, scene, model, params, box_changes: bool = False):
        """`box_changes`: the periodic box changes from frame to frame though no schedule says so (`blobsim
        jam` shrinks it): its edges are a time series."""
        from ... import __version__
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
                                   "bearing_contacts": _series(obs, "bearing_contacts", (b,), dtype=np.int32,
                                                               chunk=self.block),
                                   "net_force": _series(obs, "net_force", (b, 2), unit="N", chunk=self.block),
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
        self._last = {name: np.empty(restart_shape(rows, columns, n, b, S), RESTART_DTYPES[kinds])
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
            self._measure_packing(k, step, state, area, sides, tilt, centre)
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

    def _measure_packing(self, k, step, state, area, sides, tilt, centre):
        """Frame k's packing_fraction, contacts (all, and those that carry force), rattlers, net contact forces,
        pressure and stress (sim/packing.py)."""
        virial, touching, force, count = state.packing
        touching, force = touching[:count[0]], force[:count[0]]
        blobs = len(area)
        normal = packing.normal_forces(touching, force, centre, sides, tilt)
        out_bearing = touching[packing.bearing(normal)]
        sigma = packing.stress(virial, self.dt, sides) if step > 0 else np.zeros((2, 2))
        out = self._packing
        out["packing_fraction"][k] = packing.packing_fraction(area, sides)
        out["contacts"][k] = packing.contact_counts(touching, blobs)
        out["rattler"][k] = packing.rattlers(touching, blobs, self._rattler_below)
        out["bearing_contacts"][k] = packing.contact_counts(out_bearing, blobs)
        out["net_force"][k] = packing.net_forces(touching, force, blobs) if step > 0 else 0.0
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
