"""Twin runs for the compiled core: each C stage against its numba reference on the same inputs.

A scene is built and run some steps by the numba step, so that its state is one a stage really meets
(contacts, sleeping blobs, moving walls); then two copies of that state go one through the numba stage
and one through the C stage, and every array of both must agree bit for bit (`assert_same_bits`).
"""

from __future__ import annotations

import os

import numpy as np

from blobcli import build, build_params, parse_scene
from blobcli.core import Views
from blobcli.sim import pipeline
from blobcli.sim.jamming import copy_state


def core():
    """(ffi, lib) of the compiled core: the installed extension, or, with BLOBSIM_CORE_STAGES=a,b in the
    environment, a module built from those stage files alone (build.stage_module: for work on one stage)."""
    only = os.environ.get("BLOBSIM_CORE_STAGES")
    if only:
        from blobcli.core.build import stage_module
        return stage_module(only.split(","))
    from blobcli.core import load
    return load()


def scene_state(toml: str, steps: int = 0):
    """(model, state, params, step settings) of a scene given as TOML text, after `steps` numba steps."""
    scene = parse_scene(toml)
    model, state = build(scene)
    params = build_params(scene)
    if steps:
        pipeline.advance(state, model, params, steps)
    return model, state, params, pipeline.settings(model, params)


def twins(state):
    """Two independent copies of the state: one for the reference, one for the core."""
    return copy_state(state), copy_state(state)


def views(ffi, model, state, settings=None, parallel=False, arrays=None):
    """The C structs over these arrays (blobcli.core.Views)."""
    return Views(ffi, model.arrays if arrays is None else arrays, state, settings, parallel)


def _leaves(x, name=""):
    if isinstance(x, tuple):
        for k, y in enumerate(x):
            yield from _leaves(y, f"{name}[{k}]")
    else:
        yield name, x


def assert_same_bits(reference, core) -> None:
    """Every array of two states equal bit for bit (NaNs equal where their bits are): names the first that
    differs, with how many entries and the largest difference."""
    for field in reference._fields:
        for (name, a), (_, b) in zip(_leaves(getattr(reference, field), field), _leaves(getattr(core, field), field)):
            if a.tobytes() != b.tobytes():
                differ = np.flatnonzero((a != b).ravel())
                worst = np.max(np.abs(a.astype(float) - b.astype(float))) if a.size else 0.0
                raise AssertionError(f"{name}: {len(differ)} of {a.size} entries differ (first at flat index "
                                     f"{differ[:5].tolist()}, largest difference {worst:.3e})")


def fill_pairs(ffi, w, pairs, partners, strips, pair_impact=None) -> None:
    """Put the numba broad phase's output (collide.find_blob_pairs: pairs, partners, strips; carry_impacts:
    pair_impact) into the scratch `w` (a bcScratch *), as broad_phase.c leaves it, for the stages that read it."""
    def put(dest, array):
        array = np.ascontiguousarray(array)
        ffi.memmove(dest, ffi.from_buffer(array), array.nbytes)

    w.pair_count = len(pairs)
    put(w.pairs, pairs.astype(np.int64))
    start, partner, pair_of = partners
    put(w.partner_start, start)
    put(w.partner, partner)
    put(w.partner_pair, pair_of)
    strip_of, strip_start, strip_blobs, crossing, far = strips
    w.strip_count = len(strip_start) - 1
    put(w.strip_of, strip_of)
    put(w.strip_start, strip_start)
    put(w.strip_blobs, strip_blobs)
    put(w.crossing, crossing)
    w.far = int(far)
    if pair_impact is not None:
        put(w.pair_impact, pair_impact)
