"""The /restart group: a State's fields as stored row by row, and whether a file can be resumed with a
scene and its settings (the state it holds is one a step can start from).
"""

from __future__ import annotations

import numpy as np

from .layout import PARAMETERS, RESTART, RESTART_FIELDS, TrajectoryError, text
from .reader import open_trajectory, reading

_PER_VERTEX = {name for name, rows, *_ in RESTART_FIELDS if rows == "vertices"}


def restart_view(state, name):
    """State field `name` of RESTART_FIELDS as /restart stores it, row by row (a view: writing it writes the
    state)."""
    field = getattr(state, name)
    return field.T if name in _PER_VERTEX else field


def restart_pairs(state):
    """The kept blob-pair impact records of a state (copies): (pair_key, pair_impact)."""
    n = int(state.pair_count[0])
    return state.pair_key[:n].copy(), state.pair_impact[:n].copy()


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
            if key not in p.attrs:  # (max_substeps: not in older files of blobsim 0.1)
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
