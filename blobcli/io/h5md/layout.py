"""Trajectory files: H5MD 1.1, blobsim format FORMAT_VERSION (a contract: docs/output-format.md).

The layout, `LAYOUT` below, is the one copy of the schema: docs/output-format.md shows it
verbatim (a test keeps the two equal) and `trajectory_problems` (h5md/reader.py) checks every
file read against it, so a crafted or damaged file is refused with one line instead of a traceback.
"""

from __future__ import annotations

import numpy as np

FORMAT_VERSION = 10
# Format 1 lacks /connectivity, particles/blobs/mass and the units module; formats 1 and 2 store impact_speed
# in /restart; formats 1-3 have no sleeping (no /observables/awake: every blob was awake); formats 1-5 are not
# resumable by this blobsim (their /restart lacks the stick points (1-4) or where each blob's rest began (5));
# formats 1-6 have no moving colliders (no /observables/statics, no /restart/static_pose: every collider at rest);
# formats 1-7 have no periodic box (their box's boundary is "none"); formats 8-9 have no contact forces (no
# bearing_contacts, net_force).
READS_FORMATS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10)
LAYOUT = """\
/                            attrs: complete (bool), blobsim_format = 10, stopped (str: why a run ended early),
                                    warnings (str: problems seen in the final state; may be absent); files of
                                    `blobsim jam`: jam_balance (float64 [frames]: each packing's force balance),
                                    jam_force_balance_tolerance (float)
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
                                      the pushes and the velocity stages' impulses (older files of blobsim 0.1:
                                      the pushes alone, too much while a blob settled after an impact)
      torque/{value,step,time}        value float64 [frames, statics]  unit "N m": their moment about its pivot
    (in a periodic box only, format 8: what the packing measures, sim/packing.py; 0 at frame 0)
    packing_fraction/{value,step,time}  value float64 [frames]: the blobs' area over the box's
    contacts/{value,step,time}        value int32 [frames, blobs]: the blobs each touches (contacts that pushed in
                                      the frame's step's last substep)
    bearing_contacts/{value,step,time}  value int32 [frames, blobs] (format 10): of those, the contacts that carry
                                      force (normal force above 0.01 of the mean push)
    net_force/{value,step,time}       value float64 [frames, blobs, 2]  unit "N" (format 10): each blob's net
                                      contact force over the frame's step's last substep
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


class TrajectoryError(Exception):
    """A file that is not a readable blobsim trajectory; the message is one line."""


def restart_shape(rows, columns, n, b, statics) -> tuple:
    """The shape of a RESTART_FIELDS dataset in a file of n vertices, b blobs and that many colliders."""
    return ({"vertices": n, "blobs": b, "statics": statics}[rows],) + (() if columns is None else (columns,))


def text(value) -> str:
    """A string read from HDF5 (bytes or str) as str."""
    return value.decode() if isinstance(value, bytes) else str(value)
