"""The scene's keys: every key a user writes in TOML is one field of a frozen dataclass below, with its default,
unit and check (`key`), and the limits those checks hold a scene to. A default has exactly one home: the
validator (scene/parse.py), `blobsim check` (scene/resolved.py) and the scene reference of docs/scenes.md
(scene/reference.py) all read these fields.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from pathlib import Path

MAX_SCENE_BYTES = 4 * 1024 * 1024  # a scene file larger than this is refused unread
MAX_VERTICES = 2_000_000  # total vertices after grids: ~0.4 GB of state arrays
MAX_BLOBS = 200_000
MAX_BLOB_VERTICES = 100_000  # one blob's ring (its area sums run in one thread)
MAX_POLYGON_POINTS = 5_000  # explicit `points`: the self-crossing check is O(n²) (~2 s at the limit)
MAX_STEPS = 1_000_000_000  # steps of one run (190 days of simulated time at dt = 1/60 s)
MAX_SUBSTEPS = 1_000
MAX_ITERATIONS = 1_000
MAX_STEP_WORK = 20_000_000  # substeps × iterations × vertices: one step stays under about a second on a
#                            2-core machine (a 4,000-vertex blob at 100 × 50: 0.7 s per step), so Ctrl-C,
#                            seen between compiled calls, is honoured within 2 s
MIN_DT = 1e-9  # s
MIN_LENGTH = 1e-6  # m: radii, sizes and segment lengths; smaller shapes lose their area to round-off
MAX_COORDINATE = 1e6  # m: positions beyond this stop a run as runaway, so no blob may start there
MAX_NAME = 100  # characters of a scene or blob name (the scene name becomes a file name)
MAX_SURFACE_SPEED = 1000.0  # m/s: a conveyor surface's speed, and a moving collider's surface's
MIN_MASS = 1e-6  # kg: a blob's or a loaded wall's mass (its inverse, 1 / m per vertex, stays a number)
MAX_LOAD_ACCELERATION = 1e6  # m/s²: a loaded wall's load / mass (about 10⁵ g)
MAX_SHEAR = 1000.0  # |γ| of a periodic box's shear keyframes: the images' shift γ L_y stays a number far from overflow
MAX_BOX_CELLS = 4_000_000  # a periodic box's broad-phase cells: (L_x / c)(L_y / c), c = 2.5 × the largest radius
STATIC_MATERIAL_KEYS = ("friction", "static_friction", "restitution", "surface_velocity", "adhesion")  # any kind
STATIC_MOTION_KEYS = ("velocity", "angular_velocity", "pivot", "path", "load", "load_direction", "mass")  # any kind
MAX_KEYFRAMES = 10_000  # rows of a path or a schedule
SCHEDULED_BLOB_KEYS = ("mass", "pressure", "scale", "friction", "static_friction", "restitution", "force", "torque",
                       "adhesion")

METHODS = ("kot", "xpbd", "gas", "springs")  # area methods, in blobcli/core/area.c (in this order)


class SceneError(Exception):
    """One or more problems with a scene, each already formatted as `file:line: ...`."""

    def __init__(self, problems: list[str]):
        super().__init__("\n".join(problems))
        self.problems = problems


# --- checks: each returns a complaint, or None when the value is fine -------------------

def positive(v):
    return None if v > 0 else "must be > 0"


def nonnegative(v):
    return None if v >= 0 else "must be >= 0"


def at_least(n):
    return lambda v: None if v >= n else f"must be >= {n}"


def between(lo, hi):
    return lambda v: f"must be >= {lo}" if v < lo else f"must be <= {hi:,}" if v > hi else None


def length(v):
    return None if v >= MIN_LENGTH else "must be > 0" if v <= 0 else f"must be >= {MIN_LENGTH:g} m"


def mass_value(v):
    return None if v >= MIN_MASS else "must be > 0" if v <= 0 else f"must be >= {MIN_MASS:g} kg"


def time_step(v):
    return None if v >= MIN_DT else "must be > 0" if v <= 0 else f"must be >= {MIN_DT:g} s"


def file_name(v):
    if len(v) > MAX_NAME:
        return f"must be at most {MAX_NAME} characters"
    if "/" in v or "\\" in v or v in (".", ".."):
        return "must not contain / or \\ or be . or .. (it names files)"
    return None


def unit_interval(v):
    return None if 0 <= v <= 1 else "must be in [0, 1]"


def nonzero_vec(v):
    return None if math.hypot(*v) > 0 else "must not be the zero vector"


def positive_vec(v):
    return None if min(v) > 0 else "both components must be > 0"


def nonnegative_vec(v):
    return None if min(v) >= 0 else "both components must be >= 0"


def key(default, unit: str, doc: str, kind: str, check=None):
    """A scene key: its default, unit, one-line doc, value kind and check."""
    return field(default=default, metadata=dict(unit=unit, doc=doc, kind=kind, check=check))


_key = key  # for a table with a key named `key` ([[schedule]])


@dataclass(frozen=True)
class SceneSettings:
    """`[scene]`: time stepping and the world."""
    name: str | None = key(None, "", "scene name; default: the file's stem", "str", file_name)
    duration: float | None = key(None, "s", "simulated time; default 5 s unless `steps` is given", "float", positive)
    steps: int | None = key(None, "", "number of steps (instead of `duration`)", "int", between(1, MAX_STEPS))
    dt: float = key(1 / 60, "s", "fixed time step", "float", time_step)
    substeps: int = key(4, "", "substeps per step (h = dt / substeps): the least; a step takes more where fewer "
                        "would let a blob move more than half an edge in one, or gravity sag it more than 5% of "
                        "an edge (docs/physics.md, 'Substeps')", "int", between(1, MAX_SUBSTEPS))
    max_substeps: int = key(16, "", "the most substeps a step may take (never fewer than `substeps`; set it to "
                            "`substeps` for a fixed count); also at most what keeps substeps × iterations × "
                            "vertices within the step's work bound", "int", between(1, MAX_SUBSTEPS))
    iterations: int = key(2, "", "solver iterations per substep", "int", between(1, MAX_ITERATIONS))
    gravity: tuple = key((0.0, -9.81), "m/s²", "gravitational acceleration", "vec2")
    method: str = key("kot", "", "area method: " + ", ".join(METHODS), "str")
    damping: float = key(2.0, "1/s", "decay rate of each blob's deformation: its velocity relative to its "
                         "best-fit rigid motion (moving, spinning and rolling are not damped)", "float", nonnegative)
    drag: float = key(0.0, "1/s", "viscous drag on all motion, velocities decaying as exp(-drag t): brings a "
                      "packing to rest (relaxation); sleeping is off while drag > 0", "float", nonnegative)
    sleep: bool = key(True, "", "let islands of touching blobs at rest fall asleep: frozen exactly, not simulated, "
                      "woken by a moving blob coming near", "bool")
    sleep_speed: float = key(0.005, "m/s", "a blob is at rest while it goes slower than this on average over "
                             "time_to_sleep: its centre stays within sleep_speed × time_to_sleep of where its rest "
                             "began (or its last whole time_to_sleep of rest ended), and its turn × radius too (at "
                             "most 0.1 m/s: faster is not at rest)", "float",
                             between(1e-9, 0.1))
    time_to_sleep: float = key(1.0, "s", "how long every blob of an island must stay at rest before it sleeps "
                               "(at least 0.1 s: a shorter rest is a blob at the top of a bounce)", "float",
                               between(0.1, 1e9))
    seed: int = key(0, "", "seed of the random placement of blobs with `count`: the same seed, the same scene",
                    "int", between(0, 2 ** 63 - 1))
    periodic: tuple | None = key(None, "m", "a periodic box [Lx, Ly]: [-Lx/2, Lx/2) × [-Ly/2, Ly/2), blobs leave "
                                 "through one edge and come back through the other; each side at least 5 × the "
                                 "largest blob's radius, and at most (L_x / c)(L_y / c) = "
                                 f"{MAX_BOX_CELLS:,} cells of the broad phase, c = 2.5 × that radius (as a scale "
                                 "schedule shrinks it most); default: an open world", "vec2", positive_vec)


@dataclass(frozen=True)
class OutputSettings:
    """`[output]`: where the trajectory goes."""
    path: str | None = key(None, "", "HDF5 file; default outputs/<name>.h5", "str")
    every: int = key(1, "steps", "record every k-th step (frame 0 is the initial state)", "int",
                     between(1, MAX_STEPS))
    rerun: str | None = key(None, "", "also write a rerun recording (.rrd) here; default: none", "str")


@dataclass(frozen=True)
class BlobDef:
    """`[[blob]]`: one blob, or a grid of copies of it."""
    name: str | None = key(None, "", "name; default blob<i>; grid copies get _<ix>_<iy>", "str", file_name)
    center: tuple | None = key(None, "m", "centre of a circular ring (with `radius`)", "vec2")
    radius: float | None = key(None, "m", "radius of a circular ring", "float", length)
    vertices: int = key(32, "", "vertex count of a circular ring", "int", between(3, MAX_BLOB_VERTICES))
    points: tuple | None = key(None, "m", "explicit simple polygon, either winding (instead of a ring)", "points")
    mass: float = key(1.0, "kg", f"total mass, spread evenly over the vertices (at least {MIN_MASS:g} kg)", "float",
                      mass_value)
    velocity: tuple = key((0.0, 0.0), "m/s", "initial velocity", "vec2")
    angular_velocity: float = key(0.0, "rad/s", "initial rigid spin about the blob's centre of mass, "
                                  "counter-clockwise positive; added to `velocity`", "float")
    force: tuple = key((0.0, 0.0), "N", "driving force [Fx, Fy] through the blob's centre of mass, shared over its "
                       "vertices by mass (each accelerated by F / mass); a schedule (blob.NAME.force) makes it a "
                       "player's input", "vec2")
    torque: float = key(0.0, "N m", "driving torque about the blob's centre of mass, counter-clockwise positive: "
                        "tangential forces that leave its momentum unchanged (docs/physics.md, 'Driving')", "float")
    pressure: float = key(1.0, "", "target area = pressure × rest area", "float", positive)
    compliance: float = key(2e-4, "m/N", "perimeter compliance α (XPBD); 0 = inextensible", "float", nonnegative)
    area_compliance: float = key(0.0, "m²/N", "method xpbd: compliance α of the area constraint; 0 = hard", "float",
                                 nonnegative)
    gas_pressure: float = key(20.0, "N/m", "method gas: pressure P₀ at the target area (P = P₀ A_target / A)",
                              "float", positive)
    spring_stiffness: float = key(2000.0, "N/m", "method springs: stiffness of the internal springs", "float", positive)
    friction: float = key(0.5, "", "kinetic (sliding) friction coefficient μ_k", "float", nonnegative)
    static_friction: float = key(0.6, "", "static friction coefficient μ_s (>= friction); "
                                 "default: `friction` when only that is given, else 0.6", "float", nonnegative)
    restitution: float = key(0.0, "", "restitution e in [0, 1]: the blob's centre leaves a contact at e × its "
                             "impact speed, never faster (rebound about e² of the drop)", "float", unit_interval)
    adhesion: float = key(0.0, "N/m", "sticky: what it touches (a collider, another blob) holds it with up to this "
                          "force per metre of contact, against separation (a larger load peels it off); combined "
                          "with the other side's as the max; a schedule (blob.NAME.adhesion) makes it stick and let "
                          "go on command (docs/physics.md, 'Adhesion')", "float", nonnegative)
    grid: tuple = key((1, 1), "", "replicate nx × ny times", "int2", between(1, MAX_BLOBS))
    spacing: tuple | None = key(None, "m", "grid spacing [dx, dy]; required with a grid", "vec2", nonnegative_vec)
    count: int = key(1, "", "place this many copies at random, without overlap, in `region` (from [scene] seed; "
                     "instead of grid and center): by random addition, or past it pushed apart (up to φ = 0.8 of "
                     "bounding discs); copies get _<k>", "int", between(1, MAX_BLOBS))
    region: tuple | None = key(None, "m", "with count: [xmin, ymin, xmax, ymax], where the copies' bounding discs "
                               "must lie; default in a periodic box: the whole box", "box")

    @property
    def copies(self) -> int:
        """How many blobs this table makes: its grid's, or its count."""
        return self.grid[0] * self.grid[1] * self.count


@dataclass(frozen=True)
class StaticDef:
    """`[[static]]`: a collider: fixed, or moving in one of three ways (walls.py): at a constant
    velocity, along a path of keyframes, or pushed by a load (a piston)."""
    kind: str = key(None, "", "plane, segment, box, circle or polygon", "str")
    point: tuple | None = key(None, "m", "plane: a point on it", "vec2")
    normal: tuple | None = key(None, "", "plane: normal pointing out of the solid side", "vec2", nonzero_vec)
    a: tuple | None = key(None, "m", "segment: first end (zero thickness, solid from both sides)", "vec2")
    b: tuple | None = key(None, "m", "segment: second end", "vec2")
    center: tuple | None = key(None, "m", "box, circle: centre", "vec2")
    size: tuple | None = key(None, "m", "box: [width, height]", "vec2", lambda v: length(min(v)))
    angle: float = key(0.0, "deg", "box: rotation, counter-clockwise", "float")
    radius: float | None = key(None, "m", "circle: radius", "float", length)
    inside: bool = key(False, "", "circle: true for a container (a drum): solid outside the circle, blobs inside",
                       "bool")
    points: tuple | None = key(None, "m", "polygon: simple polygon, concave allowed, either winding, solid inside",
                               "points")
    friction: float = key(0.5, "", "kinetic friction μ_k (combined with a blob's as √(μ₁μ₂))", "float", nonnegative)
    static_friction: float = key(0.6, "", "static friction μ_s (combined as √(μ₁μ₂)); "
                                 "default: `friction` when only that is given, else 0.6", "float", nonnegative)
    restitution: float = key(0.0, "", "bounciness (combined with a blob's as the max)", "float", unit_interval)
    surface_velocity: float = key(0.0, "m/s", "the surface moves along itself (a conveyor belt) without the "
                                  "collider moving: friction drags blobs toward t = (n_y, -n_x), n the normal out "
                                  "of the solid (a floor carries them toward +x, a circle's wall with blobs outside "
                                  "turns clockwise, a drum's (inside = true) counter-clockwise: u = ω R)", "float",
                                  between(-MAX_SURFACE_SPEED, MAX_SURFACE_SPEED))
    adhesion: float = key(0.0, "N/m", "a sticky collider: holds a blob that touches it with up to this force per "
                          "metre of contact (combined with the blob's as the max)", "float", nonnegative)
    velocity: tuple | None = key(None, "m/s", "moves at this constant velocity (with `angular_velocity`: a "
                                 "kinematic wall; default: fixed)", "vec2",
                                 lambda v: None if math.hypot(*v) <= MAX_SURFACE_SPEED
                                 else f"must be at most {MAX_SURFACE_SPEED:g} m/s")
    angular_velocity: float | None = key(None, "rad/s", "turns at this rate about `pivot`, counter-clockwise; its "
                                         "surface's fastest point, at the speed of `velocity` plus the rate × its "
                                         "farthest point from `pivot` (a plane's: where it leaves the ±10⁶ m world), "
                                         f"at most {MAX_SURFACE_SPEED:,g} m/s", "float", between(-1000.0, 1000.0))
    pivot: tuple | None = key(None, "m", "the point it turns about, whose position and angle are recorded; "
                              "default: a plane's point, a segment's midpoint, a box's or circle's centre, a "
                              "polygon's centroid", "vec2")
    path: tuple | None = key(None, "", "keyframes [t s, dx m, dy m, turn deg] of its displacement from the pose "
                             "given (turned about `pivot`), linear between, the first held before it and the last "
                             "after (instead of velocity); between two keyframes its surface's fastest point, at the "
                             "distance (dx, dy) moves over their Δt plus the turn over Δt (rad) × its farthest point "
                             f"from `pivot` (as for angular_velocity), at most {MAX_SURFACE_SPEED:,g} m/s", "keyframes")
    load: float | None = key(None, "N", "a loaded wall (a piston): pushed along `load_direction` by this force, "
                             "it moves along that line only, under the load and the blobs' contact forces (not "
                             "gravity: its weight, if wanted, is part of the load); load / mass at most "
                             f"{MAX_LOAD_ACCELERATION:,.0f} m/s²", "float", nonnegative)
    load_direction: tuple = key((0.0, -1.0), "", "a loaded wall's direction of motion and of its load",
                                "vec2", nonzero_vec)
    mass: float = key(1.0, "kg", f"a loaded wall's mass (at least {MIN_MASS:g} kg)", "float", mass_value)

    @property
    def moves(self) -> bool:
        """Whether it moves, in any of the three ways."""
        return self.velocity is not None or self.angular_velocity is not None or self.path is not None \
            or self.load is not None


@dataclass(frozen=True)
class ScheduleDef:
    """`[[schedule]]`: a property that changes in time, linear between keyframes, the first held before
    them and the last after; applied at the start of each step (t = step × dt)."""
    key: str = key(None, "", "what changes: blob.NAME.KEY (NAME a blob's name, or NAME_* for a grid's copies; "
                   "KEY one of " + ", ".join(SCHEDULED_BLOB_KEYS) + "), scene.gravity, scene.periodic or "
                   "scene.shear", "str")
    at: tuple = _key(None, "", "keyframes [t s, value] ([t, Fx, Fy] for a blob's force, [t, gx, gy] for gravity, "
                    "[t, Lx, Ly] for the periodic box, [t, γ] for its shear strain); `scale` is a linear size "
                    "factor, 1 the size written: rest edge lengths × s, target area × s²; bounds: γ within "
                    f"±{MAX_SHEAR:,g}, mass at least {MIN_MASS:g} kg, a scaled blob's radius (its farthest vertex "
                    f"from its centre) × s from {MIN_LENGTH:g} to {MAX_COORDINATE:,.0f} m", "keyframes")

    @property
    def blob_key(self) -> str:
        return self.key.rsplit(".", 1)[1]


TABLES = {"scene": SceneSettings, "output": OutputSettings, "blob": BlobDef, "static": StaticDef,
          "schedule": ScheduleDef}
DEFAULT_DURATION = 5.0  # s, when neither `duration` nor `steps` is given


@dataclass(frozen=True)
class Scene:
    """A validated scene, as written plus what it resolves to."""
    settings: SceneSettings
    output: OutputSettings
    blobs: tuple[BlobDef, ...]
    statics: tuple[StaticDef, ...]
    schedules: tuple[ScheduleDef, ...] = ()
    source: str = ""  # the file it came from
    text: str = ""  # its TOML text, stored in every output file

    @property
    def name(self) -> str:
        return self.settings.name or Path(self.source).stem or "scene"

    @property
    def steps(self) -> int:
        s = self.settings
        if s.steps is not None:
            return s.steps
        return max(1, round((s.duration or DEFAULT_DURATION) / s.dt))

    @property
    def output_path(self) -> Path:
        return Path(self.output.path) if self.output.path else Path("outputs") / f"{self.name}.h5"

    @property
    def blob_count(self) -> int:
        return sum(b.copies for b in self.blobs)

    @property
    def vertex_count(self) -> int:
        return sum(b.copies * blob_vertex_count(b) for b in self.blobs)


def blob_vertex_count(b: BlobDef) -> int:
    return len(b.points) if b.points is not None else b.vertices


def expanded_names(blobs) -> list[str]:
    """Every blob's name once grids are expanded, in model order (sim/model.build)."""
    out = []
    for i, b in enumerate(blobs):
        name = b.name or f"blob{i}"
        nx, ny = b.grid
        if b.count > 1:
            out += [f"{name}_{k}" for k in range(b.count)]
        else:
            out += [name] if (nx, ny) == (1, 1) else [f"{name}_{x}_{y}" for x in range(nx) for y in range(ny)]
    return out


def schedule_targets(s: ScheduleDef, names: list[str]) -> list[int]:
    """The blob indices a blob schedule applies to (none for a scene.* schedule)."""
    if s.key.startswith("scene."):
        return []
    pattern = s.key[len("blob."):].rsplit(".", 1)[0]
    return [k for k, name in enumerate(names) if fnmatch.fnmatchcase(name, pattern)]
