"""Trajectory files: H5MD 1.1, blobsim format FORMAT_VERSION (a contract: docs/output-format.md).

  h5md/layout.py   the layout (`LAYOUT`, the one copy of the schema, shown verbatim in
                   docs/output-format.md) and its dataset paths,
  h5md/writer.py   TrajectoryWriter: frames in blocks into `<path>.partial`, published by `close`,
  h5md/reader.py   open_trajectory (checked against LAYOUT), read_trajectory, stored_scene,
  h5md/restart.py  the /restart group and whether a file can be resumed.
`from blobcli.io.h5md import X` reads every public name of the four from here.
"""

from __future__ import annotations

from .layout import (
           AREA,
           AWAKE,
           EDGES,
           FORMAT_VERSION,
           IMAGE,
           KINETIC,
           LAYOUT,
           PARAMETERS,
           POSITION,
           READS_FORMATS,
           RESTART,
           RESTART_DTYPES,
           RESTART_FIELDS,
           SERIES,
           SINCE_FORMAT,
           STATICS,
           TrajectoryError,
           restart_shape,
           text,
)
from .reader import (
           BOX_BLOCK,
           PROBE_BYTES,
           PROBE_SECONDS,
           Trajectory,
           open_trajectory,
           read_trajectory,
           reading,
           stored_scene,
           trajectory_problems,
)
from .restart import restart_pairs, restart_value_problems, restart_view, resume_problems
from .writer import BLOCK_BYTES, DISK_RESERVE, FLUSH_SECONDS, DiskFull, TrajectoryWriter, ascii, versions

__all__ = ['FORMAT_VERSION', 'READS_FORMATS', 'LAYOUT', 'RESTART_FIELDS', 'SINCE_FORMAT', 'RESTART_DTYPES',
           'POSITION', 'IMAGE', 'EDGES', 'AREA', 'KINETIC', 'AWAKE', 'STATICS', 'SERIES', 'PARAMETERS', 'RESTART',
           'TrajectoryError', 'restart_shape', 'text', 'BLOCK_BYTES', 'FLUSH_SECONDS', 'DISK_RESERVE', 'ascii',
           'versions', 'DiskFull', 'TrajectoryWriter', 'trajectory_problems', 'BOX_BLOCK', 'reading', 'PROBE_BYTES',
           'PROBE_SECONDS', 'open_trajectory', 'stored_scene', 'Trajectory', 'read_trajectory', 'restart_view',
           'restart_pairs', 'resume_problems', 'restart_value_problems']
