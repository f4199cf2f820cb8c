"""The compiled core: the step in C11 (blobcore.h), built once at install (build.py), and the views
that hand it NumPy's arrays.

`load()` gives (ffi, lib) of the extension, refusing a library older than its C sources. `Views`
fills the C structs (bcModel, bcState, bcSettings) with pointers into a run's arrays once, and keeps
those arrays alive while the structs are in use. Nothing is copied: the C step writes the state's
own arrays.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


class StaleBuild(ImportError):
    """The compiled core was built from C sources other than the ones beside it."""


@functools.cache
def load():
    """(ffi, lib) of the compiled core. Raises StaleBuild when its C sources were edited after it was
    built, ImportError (with how to build it) when it is missing."""
    try:
        from . import _blobcore
    except ImportError as e:
        raise ImportError(f"blobsim's compiled core is not built ({e}): run `pip install -e .` in the project "
                          "(a C compiler and Python's headers are needed)") from e
    check_fresh(_blobcore.ffi.string(_blobcore.lib.bc_source_hash()).decode())
    return _blobcore.ffi, _blobcore.lib


def check_fresh(built: str, root: Path = HERE) -> None:
    """Raise StaleBuild when the library's source hash (`built`) is not that of the C sources in `root`
    (an editable install whose C was edited and not rebuilt); an install without its sources passes."""
    from .build import source_hash

    if any(root.glob("*.c")) and built != source_hash(root):
        raise StaleBuild(f"blobsim's compiled core ({built}) is older than its C sources ({source_hash(root)}): "
                         "rebuild it with `pip install -e .` (or `python -m blobcli.core.build`)")


_TYPES = {np.dtype(np.float64): "double *", np.dtype(np.int64): "int64_t *", np.dtype(np.uint8): "uint8_t *"}


class Views:
    """The C structs over one run's arrays, for the extension's `ffi`. Every array must be C-contiguous and
    of the type the header says; one that is not is refused (a copy would leave the step writing somewhere
    nobody reads)."""

    def __init__(self, ffi, arrays, state, settings=None, parallel: bool = False):
        self.ffi = ffi
        self._alive: list = []
        self.model = ffi.new("bcModel *")
        self.state = ffi.new("bcState *")
        self.settings = ffi.new("bcSettings *")
        self.fill_model(arrays)
        self.fill_state(state)
        if settings is not None:
            self.fill_settings(settings, parallel)
        self.context = ffi.new("bcContext *")
        self.context.m = self.model
        self.context.s = self.state
        self.context.c = self.settings
        self._alive += [self.model, self.state, self.settings]

    def pointer(self, array: np.ndarray):
        if not (array.flags.c_contiguous and array.dtype in _TYPES):
            raise ValueError(f"the core reads C-contiguous float64, int64 or uint8 arrays (got {array.dtype}, "
                             f"contiguous {array.flags.c_contiguous})")
        self._alive.append(array)
        return self.ffi.cast(_TYPES[array.dtype], array.ctypes.data)

    def fill_model(self, a) -> None:
        """bcModel from model.ModelArrays (a schedule's arrays too)."""
        m, p = self.model, self.pointer
        m.blob_count, m.vertex_count, m.spring_count = len(a.offsets) - 1, int(a.offsets[-1]), len(a.spring_rest)
        for name in ("offsets", "blob_of", "inv_mass", "rest_length", "rest_perimeter", "target_area", "compliance",
                     "material", "orient", "area_compliance", "gas_pressure", "spring_pairs", "spring_rest",
                     "spring_compliance", "driving", "adhesion", "static_adhesion"):
            setattr(m, name, p(getattr(a, name)))
        for k, (geom, shape_offsets, material, index) in enumerate(a.statics):
            s = m.statics[k]
            s.shapes, s.rows = len(index), len(geom)
            s.geom, s.shape_offsets, s.material, s.index = p(geom), p(shape_offsets), p(material), p(index)
        w = a.walls
        m.walls.count, m.walls.keyframes = len(w.motion), len(w.path)
        for name in w._fields:
            setattr(m.walls, name, p(getattr(w, name)))

    def fill_state(self, s) -> None:
        """bcState from model.State."""
        v, p = self.state, self.pointer
        for name in ("position", "velocity", "impact", "pair_key", "pair_impact", "pair_count", "awake", "still",
                     "still_center", "still_angle", "previous", "predicted", "lam", "contact_normal",
                     "contact_depth", "contact_material", "perimeter_lam", "area_lam", "spring_lam", "center",
                     "radius", "edges", "c_edge", "c_hit", "c_normal", "anchor", "budget", "moved",
                     "blob_contact_depth", "stick_edge", "stick_t", "steps_done", "substeps_taken", "static_pose",
                     "static_impulse"):
            setattr(v, name, p(getattr(s, name)))
        for k, (geom, aabb, delta) in enumerate(s.placed):
            v.placed[k].geom, v.placed[k].aabb, v.placed[k].delta = p(geom), p(aabb), p(delta)
        v.static_of, v.static_push, v.wall_of, v.wall_push = map(p, s.touch)
        virial, touching, touching_force, touching_count = s.packing
        if len(virial):  # an open world keeps no packing records
            v.virial, v.touching, v.touching_force, v.touching_count = (p(virial), p(touching), p(touching_force),
                                                                        p(touching_count))
        (v.self_pairs, v.self_values, v.self_count, v.self_near, v.self_chunks, v.zoned) = map(p, s.self_contact)

    def fill_settings(self, c, parallel: bool) -> None:
        """bcSettings from pipeline.StepSettings."""
        v = self.settings
        for name in ("dt", "substeps", "most_substeps", "iterations", "gx", "gy", "damping", "drag", "up_x", "up_y",
                     "sleep_speed", "time_to_sleep", "box_x", "box_y", "box_tilt"):
            setattr(v, name, getattr(c, name))
        v.method = c.config.method
        v.sleep, v.moving, v.loaded = c.config.sleep, c.config.moving, c.config.loaded
        v.parallel = parallel
