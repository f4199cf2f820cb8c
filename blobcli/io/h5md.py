"""Trajectory files: H5MD 1.1, blobsim format version 1 (a contract; see the README).

    /                      attrs: complete (bool), blobsim_format (int), stopped (str)
    /h5md                  attrs: version = [1, 1]
        author             attrs: name
        creator            attrs: name = "blobsim", version
    /particles/blobs/
        box                attrs: dimension = 2, boundary = ["none", "none"]
        position/{value [frames, N, 2] float64 (m), step [frames] int64, time [frames] float64 (s)}
    /observables/
        area/{value [frames, B] (m², positive for the blob's own winding), step, time}
        kinetic_energy/{value [frames, B] (J), step, time}
    /parameters/
        blob_offsets [B + 1] int64, blob_names [B] str, target_area [B] (m²), mass [B] (kg),
        scene (str: the scene's TOML), attrs: dt, substeps, iterations, method, damping,
        gravity, steps, every, source, and the versions a reproduction needs
    /restart/              the exact state at the last recorded frame, for --resume:
                           position [N, 2], velocity [N, 2], impact_speed [B], attr step

Frames are buffered and written in blocks of about 4 MiB (and at least every
FLUSH_SECONDS), into `<path>.partial`; `close` marks the file and renames it to `<path>`,
so `<path>` is never a half-written file.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

FORMAT_VERSION = 1
BLOCK_BYTES = 4 << 20  # frames per block: about this many bytes of positions
FLUSH_SECONDS = 10.0  # and no block waits longer than this


def _series(group, name, shape, dtype=np.float64, unit=None, chunk=1):
    """An H5MD time-dependent element: value [frames, *shape], step, time."""
    g = group.create_group(name)
    v = g.create_dataset("value", shape=(0, *shape), maxshape=(None, *shape), dtype=dtype,
                         chunks=(chunk, *shape))
    if unit:
        v.attrs["unit"] = unit
    g.create_dataset("step", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(max(chunk, 256),))
    t = g.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(max(chunk, 256),))
    t.attrs["unit"] = "s"
    return g


def versions() -> dict:
    """Versions and settings a bit-for-bit reproduction needs."""
    import llvmlite
    import numba

    from .. import __version__
    env = {k: os.environ.get(k, "") for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                               "PYTHONHASHSEED")}
    return {"blobsim_version": __version__, "python": sys.version.split()[0], "numpy": np.__version__,
            "numba": numba.__version__, "llvmlite": llvmlite.__version__, "h5py": h5py.__version__,
            "hdf5": h5py.version.hdf5_version, "platform": platform.platform(), "machine": platform.machine(),
            "numba_threads": numba.get_num_threads(), **{f"env_{k}": v for k, v in env.items()}}


class TrajectoryWriter:
    """Streams frames of one run into an H5MD file."""

    def __init__(self, path, scene, model, params):
        from .. import __version__
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.dt = params.dt
        n, b = model.vertex_count, model.blob_count
        frames = params.steps // params.every + 1  # expected; resumed or extended runs may add more
        self.block = max(1, min(4096, BLOCK_BYTES // (16 * n), frames))
        f = self.file = h5py.File(self.partial, "w")
        f.attrs["complete"] = False
        f.attrs["blobsim_format"] = FORMAT_VERSION
        h5 = f.create_group("h5md")
        h5.attrs["version"] = np.array([1, 1], dtype=np.int32)
        h5.create_group("author").attrs["name"] = os.environ.get("USER", "blobsim user")
        creator = h5.create_group("creator")
        creator.attrs["name"] = "blobsim"
        creator.attrs["version"] = __version__

        particles = f.create_group("particles/blobs")
        box = particles.create_group("box")
        box.attrs["dimension"] = 2
        box.attrs["boundary"] = np.array([b"none", b"none"])
        self.position = _series(particles, "position", (n, 2), unit="m", chunk=self.block)
        obs = f.create_group("observables")
        self.area = _series(obs, "area", (b,), unit="m^2", chunk=self.block)
        self.kinetic = _series(obs, "kinetic_energy", (b,), unit="J", chunk=self.block)

        p = f.create_group("parameters")
        p.create_dataset("blob_offsets", data=model.offsets)
        p.create_dataset("blob_names", data=np.array(model.names, dtype=object), dtype=h5py.string_dtype())
        p.create_dataset("target_area", data=np.abs(model.target_area))
        p.create_dataset("mass", data=model.mass)
        p.create_dataset("scene", data=scene.text, dtype=h5py.string_dtype())
        attrs = dict(dt=params.dt, substeps=params.substeps, iterations=params.iterations, method=params.method,
                     damping=params.damping, gravity=params.gravity, steps=params.steps, every=params.every,
                     source=scene.source, **versions())
        for k, v in attrs.items():
            p.attrs[k] = v
        self._sign = np.sign(model.rest_area)
        # One block of frames, filled in place; and the state of the latest frame, for /restart.
        self._steps = np.empty(self.block, dtype=np.int64)
        self._pos = np.empty((self.block, n, 2))
        self._area = np.empty((self.block, b))
        self._kinetic = np.empty((self.block, b))
        self._last_vel = np.empty((n, 2))
        self._last_impact = np.empty(b)
        self._count = 0
        self._last_flush = time.monotonic()
        self.frames = 0

    def append(self, step: int, state, area, kinetic):
        """Buffer one frame of `state` (copied); write the block when it is full or old."""
        k = self._count
        self._steps[k] = step
        self._pos[k] = state.pos
        np.multiply(area, self._sign, out=self._area[k])
        self._kinetic[k] = kinetic
        self._last_vel[...] = state.vel
        self._last_impact[...] = state.impact_speed
        self._count = k + 1
        if self._count == self.block or time.monotonic() - self._last_flush > FLUSH_SECONDS:
            self.flush()

    def flush(self):
        k = self._count
        if k == 0:
            return
        steps = self._steps[:k]
        start, stop = self.frames, self.frames + k
        for group, values in ((self.position, self._pos[:k]), (self.area, self._area[:k]),
                              (self.kinetic, self._kinetic[:k])):
            for name, data in (("value", values), ("step", steps), ("time", steps * self.dt)):
                ds = group[name]
                ds.resize(stop, axis=0)
                ds[start:stop] = data
        restart = self.file.require_group("restart")
        for name, data in (("position", self._pos[k - 1]), ("velocity", self._last_vel),
                           ("impact_speed", self._last_impact)):
            if name in restart:
                restart[name][...] = data
            else:
                restart.create_dataset(name, data=data)
        restart.attrs["step"] = steps[-1]
        self.frames = stop
        self._count = 0
        self.file.flush()
        self._last_flush = time.monotonic()

    def adopt(self, path, state) -> int:
        """Resume: copy the frames of an interrupted run's file and load its last state.

        Returns the step to continue after. The file must come from the same scene and
        settings (checked by the caller with `resume_problems`)."""
        with h5py.File(path, "r") as f:
            restart = f["restart"]
            step = int(restart.attrs["step"])
            pos = f["particles/blobs/position"]
            keep = int(np.searchsorted(pos["step"][...], step, side="right"))
            self.flush()
            for start in range(0, keep, self.block):
                stop = min(start + self.block, keep)
                for group, source in ((self.position, pos), (self.area, f["observables/area"]),
                                      (self.kinetic, f["observables/kinetic_energy"])):
                    for name in ("value", "step", "time"):
                        ds = group[name]
                        ds.resize(self.frames + stop - start, axis=0)
                        ds[self.frames:] = source[name][start:stop]
                self.frames += stop - start
            state.pos[...] = restart["position"][...]
            state.vel[...] = restart["velocity"][...]
            state.impact_speed[...] = restart["impact_speed"][...]
            self.worst_area_error = _worst_area_error(f["observables/area/value"][1:keep],
                                                      f["parameters/target_area"][...])
        return step

    def close(self, complete: bool, stopped: str = ""):
        """Write what is buffered, mark the file and move it into place at `path`."""
        self.flush()
        self.file.attrs["complete"] = complete
        self.file.attrs["stopped"] = stopped
        self.file.close()
        os.replace(self.partial, self.path)


def _worst_area_error(area, target) -> float:
    """max |A - A_target| / A_target over frames and blobs (0 for no frames)."""
    return float(np.max(np.abs(area - target) / target, initial=0.0))


def resume_problems(path, scene, params) -> list[str]:
    """Why `path` cannot be resumed with this scene and these settings (empty: it can)."""
    try:
        f = h5py.File(path, "r")
    except FileNotFoundError:
        return [f"{path}: no such file"]
    except OSError as e:
        return [f"{path}: not a readable HDF5 file ({e})"]
    with f:
        if "restart" not in f or "parameters" not in f:
            return [f"{path}: not a blobsim trajectory with a restart state"]
        p = f["parameters"]
        problems = []
        if p["scene"][()].decode() != scene.text:
            problems.append(f"{path}: was run from a different scene text than {scene.source}")
        for key in ("dt", "substeps", "iterations", "method", "every"):
            was, now = p.attrs[key], getattr(params, key)
            if was != now:
                problems.append(f"{path}: was run with {key} = {was}, not {now}")
        if bool(f.attrs["complete"]) and int(f["restart"].attrs["step"]) >= params.steps:
            problems.append(f"{path}: run is complete; nothing to resume")
        return problems


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
    target_area: np.ndarray  # (B,)
    mass: np.ndarray  # (B,) kg
    complete: bool
    attrs: dict  # /parameters attrs
    scene: str


def read_trajectory(path: str | Path) -> Trajectory:
    with h5py.File(path, "r") as f:
        pos = f["particles/blobs/position"]
        p = f["parameters"]
        return Trajectory(position=pos["value"][...], step=pos["step"][...], time=pos["time"][...],
                          offsets=p["blob_offsets"][...], names=[s.decode() for s in p["blob_names"][...]],
                          area=f["observables/area/value"][...],
                          kinetic_energy=f["observables/kinetic_energy/value"][...],
                          target_area=p["target_area"][...], mass=p["mass"][...], complete=bool(f.attrs["complete"]),
                          attrs=dict(p.attrs), scene=p["scene"][()].decode())
