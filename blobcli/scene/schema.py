"""The scene: what a user writes in TOML, validated into frozen dataclasses.

This module is the scene layer's front: it gathers the public names of
  scene/keys.py       every key (one dataclass field: default, unit, check) and the limits,
  scene/parse.py      TOML text or a file in, a validated Scene or one SceneError out,
  scene/checks.py     the checks that need the whole scene, and command-line overrides,
  scene/resolved.py   the scene written back as TOML (`blobsim check`),
  scene/reference.py  the scene reference of docs/scenes.md,
so that `from blobcli.scene.schema import parse_scene, SceneError, ...` reads from one place.
`python -m blobcli.scene.schema` prints the scene reference of docs/scenes.md.
"""

from __future__ import annotations

from .checks import (
    BROAD_MARGIN,
    PERIODIC_SIDE,
    SCHEDULE_CHECKS,
    STRIDE,
    check_box,
    check_driving,
    check_scales,
    check_schedule,
    check_size,
    run_length_problems,
    with_overrides,
)
from .keys import (
    DEFAULT_DURATION,
    MAX_BLOB_VERTICES,
    MAX_BLOBS,
    MAX_BOX_CELLS,
    MAX_COORDINATE,
    MAX_ITERATIONS,
    MAX_KEYFRAMES,
    MAX_LOAD_ACCELERATION,
    MAX_NAME,
    MAX_POLYGON_POINTS,
    MAX_SCENE_BYTES,
    MAX_SHEAR,
    MAX_STEP_WORK,
    MAX_STEPS,
    MAX_SUBSTEPS,
    MAX_SURFACE_SPEED,
    MAX_VERTICES,
    METHODS,
    MIN_DT,
    MIN_LENGTH,
    MIN_MASS,
    SCHEDULED_BLOB_KEYS,
    STATIC_MATERIAL_KEYS,
    STATIC_MOTION_KEYS,
    TABLES,
    BlobDef,
    OutputSettings,
    Scene,
    SceneError,
    SceneSettings,
    ScheduleDef,
    StaticDef,
    at_least,
    between,
    blob_vertex_count,
    expanded_names,
    file_name,
    key,
    length,
    mass_value,
    nonnegative,
    nonnegative_vec,
    nonzero_vec,
    positive,
    positive_vec,
    schedule_targets,
    time_step,
    unit_interval,
)
from .parse import Problems, fmt_path, fmt_value, load_scene, parse_scene, scene_problem
from .reference import reference_markdown
from .resolved import resolved_toml, toml_value

__all__ = ['MAX_SCENE_BYTES', 'MAX_VERTICES', 'MAX_BLOBS', 'MAX_BLOB_VERTICES', 'MAX_POLYGON_POINTS', 'MAX_STEPS',
           'MAX_SUBSTEPS', 'MAX_ITERATIONS', 'MAX_STEP_WORK', 'MIN_DT', 'MIN_LENGTH', 'MAX_COORDINATE', 'MAX_NAME',
           'MAX_SURFACE_SPEED', 'MIN_MASS', 'MAX_LOAD_ACCELERATION', 'MAX_SHEAR', 'MAX_BOX_CELLS',
           'STATIC_MATERIAL_KEYS', 'STATIC_MOTION_KEYS', 'MAX_KEYFRAMES', 'SCHEDULED_BLOB_KEYS', 'METHODS',
           'SceneError', 'positive', 'nonnegative', 'at_least', 'between', 'length', 'mass_value', 'time_step',
           'file_name', 'unit_interval', 'nonzero_vec', 'positive_vec', 'nonnegative_vec', 'key', 'SceneSettings',
           'OutputSettings', 'BlobDef', 'StaticDef', 'ScheduleDef', 'TABLES', 'DEFAULT_DURATION', 'Scene',
           'blob_vertex_count', 'expanded_names', 'schedule_targets', 'fmt_path', 'fmt_value', 'Problems',
           'scene_problem', 'parse_scene', 'load_scene', 'SCHEDULE_CHECKS', 'check_schedule', 'check_size', 'STRIDE',
           'check_driving', 'PERIODIC_SIDE', 'BROAD_MARGIN', 'check_scales', 'check_box', 'run_length_problems',
           'with_overrides', 'toml_value', 'resolved_toml', 'reference_markdown']


if __name__ == "__main__":  # python -m blobcli.scene.schema: print the scene reference of docs/scenes.md
    print(reference_markdown(), end="")
