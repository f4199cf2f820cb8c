"""The scene: what a user writes in TOML, validated into frozen dataclasses.

Every scene key is one dataclass field below, with its default, unit and check (`key`).
The validator, `blobsim check` and the scene reference (docs/scenes.md) all read these fields,
so a default has exactly one home. Errors collect into one `SceneError`, one line each:
`file:line: blob[1].radius: must be > 0 (got -0.5)` (indices are 0-based).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from .tomlpos import key_lines, line_of

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
                     "instead of grid and center); copies get _<k>", "int", between(1, MAX_BLOBS))
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


def with_overrides(scene: Scene, *, steps=None, duration=None, method=None) -> Scene:
    """The scene with command-line overrides applied; SceneError if the run they ask for is too long."""
    s = scene.settings
    if steps is not None:
        s = replace(s, steps=steps, duration=None)
    if duration is not None:
        s = replace(s, duration=duration, steps=None)
    if method is not None:
        s = replace(s, method=method)
    scene = replace(scene, settings=s)
    problems = [f"{scene.source}: {'--steps' if steps is not None else '--duration'}: {message}"
                for _, message in run_length_problems(scene)]
    if problems:
        raise SceneError(problems)
    return scene


# --- loading -----------------------------------------------------------------------------

def fmt_path(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (("." if out else "") + str(p))
    return out


def fmt_value(v) -> str:
    if isinstance(v, str):
        return repr(v)
    if isinstance(v, dict):
        return "a table"
    text = repr(v) if not isinstance(v, (list, tuple)) else "[" + ", ".join(fmt_value(x) for x in v) + "]"
    return text if len(text) <= 60 else text[:57] + "..."


class _Problems:
    """Collects `file:line: path: message` lines."""

    def __init__(self, source: str, lines: dict):
        self.source, self.lines, self.items = source, lines, []

    def add(self, path: tuple, message: str, got=None, show_got=True, line_path=None):
        """One problem at `path`; its line is that of `line_path` (default: `path`)."""
        line = line_of(self.lines, line_path or path)
        text = f"{self.source}:{line}: {fmt_path(path)}: {message}"
        if show_got:
            text += f" (got {fmt_value(got)})"
        self.items.append(text)


def scene_problem(scene: Scene, path: tuple, message: str) -> str:
    """A problem with a valid scene that a command cannot use (`blobsim jam`'s), worded as `check` words its
    own: `file:line: key.path: message`, the line of the key (or of its table, when the key is not written)."""
    problems = _Problems(scene.source, key_lines(scene.text))
    problems.add(path, message, show_got=False)
    return problems.items[0]


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _finite(x) -> bool:
    """Finite as a float64 (a 400-digit integer is not)."""
    try:
        return math.isfinite(float(x))
    except OverflowError:
        return False


def _coerce(kind: str, v, path, problems: _Problems, unit: str = ""):
    """Check a raw TOML value against a key kind; return the typed value or None."""
    def bad(message):
        problems.add(path, message, v)

    if kind == "str":
        if not isinstance(v, str):
            return bad("must be a string")
        if any(ord(c) < 32 or ord(c) == 127 for c in v):
            return bad("must not contain control characters (NUL, newline, ...)")
        return v
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            return bad("must be an integer")
        return v
    if kind == "bool":
        if not isinstance(v, bool):
            return bad("must be true or false")
        return v
    if kind == "float":
        if not _number(v):
            return bad("must be a number")
        if not _finite(v):
            return bad("must be finite")
        return float(v)
    if kind in ("vec2", "int2"):
        if not isinstance(v, list) or len(v) != 2:
            return bad("must be a list of 2 numbers" if kind == "vec2" else "must be a list of 2 integers")
        if kind == "int2":
            if not all(isinstance(x, int) and not isinstance(x, bool) for x in v):
                return bad("must be a list of 2 integers")
            return tuple(v)
        if not all(_number(x) for x in v):
            return bad("must be a list of 2 numbers")
        if not all(_finite(x) for x in v):
            return bad("must be finite")
        if unit == "m" and max(abs(float(x)) for x in v) > MAX_COORDINATE:
            return bad(f"must be within ±{MAX_COORDINATE:g} m (positions beyond stop a run)")
        return (float(v[0]), float(v[1]))
    if kind == "box":  # [xmin, ymin, xmax, ymax]
        if not isinstance(v, list) or len(v) != 4 or not all(_number(x) for x in v):
            return bad("must be a list of 4 numbers [xmin, ymin, xmax, ymax]")
        if not all(_finite(x) for x in v) or max(abs(float(x)) for x in v) > MAX_COORDINATE:
            return bad(f"must be finite and within ±{MAX_COORDINATE:g} m")
        if not (v[0] < v[2] and v[1] < v[3]):
            return bad("needs xmin < xmax and ymin < ymax")
        return tuple(float(x) for x in v)
    if kind == "keyframes":  # [[t, values...], ...]: times in s, increasing
        if not isinstance(v, list) or not v:
            return bad("must be a list of keyframes [t, ...]")
        if len(v) > MAX_KEYFRAMES:
            return bad(f"at most {MAX_KEYFRAMES:,} keyframes")
        rows = []
        for i, row in enumerate(v):
            if not isinstance(row, list) or len(row) < 2 or not all(_number(x) for x in row):
                problems.add(path + (i,), "must be a list of numbers [t, value...]", row)
                return None
            if not all(_finite(x) for x in row):
                problems.add(path + (i,), "must be finite", row)
                return None
            rows.append(tuple(float(x) for x in row))
        if len({len(r) for r in rows}) > 1:
            return bad("every keyframe must have the same length")
        if rows[0][0] < 0.0 or any(b[0] <= a[0] for a, b in zip(rows, rows[1:])):
            return bad("times must be >= 0 and increasing")
        return tuple(rows)
    if kind == "points":
        if not isinstance(v, list) or len(v) < 3:
            return bad("must be a list of at least 3 [x, y] points")
        if len(v) > MAX_POLYGON_POINTS:
            problems.add(path, f"at most {MAX_POLYGON_POINTS:,} points (use center + radius + vertices for "
                         f"larger rings)", len(v))
            return None
        out = []
        for i, p in enumerate(v):
            q = _coerce("vec2", p, path + (i,), problems, "m")
            if q is None:
                return None
            out.append(q)
        return tuple(out)
    raise AssertionError(kind)


def _table(cls, raw, path: tuple, problems: _Problems, allowed=None):
    """Validate one TOML table into `cls`; unknown keys get a did-you-mean."""
    if not isinstance(raw, dict):
        problems.add(path, "must be a table", raw)
        return None
    names = [f.name for f in fields(cls)]
    allowed = names if allowed is None else allowed
    values, ok = {}, True
    for k, v in raw.items():
        if k not in allowed:
            hint = difflib.get_close_matches(k, allowed, n=1)
            where = f"not a key of {fmt_path(path) if path else 'a scene'}"
            if k in names:
                where = f"not a key of kind {raw.get('kind')!r}"
            problems.add(path + (k,), f"unknown key: {where}" + (f"; did you mean {hint[0]!r}?" if hint else ""),
                         show_got=False)
            ok = False
    for f in fields(cls):
        if f.name not in raw:
            continue
        value = _coerce(f.metadata["kind"], raw[f.name], path + (f.name,), problems, f.metadata["unit"])
        if value is None:
            ok = False
            continue
        check = f.metadata["check"]
        complaint = None
        if check is not None:
            items = value if f.metadata["kind"] == "int2" else [value]
            complaint = next((c for c in map(check, items) if c), None)
        if complaint:
            problems.add(path + (f.name,), complaint, raw[f.name])
            ok = False
        values[f.name] = value
    if "friction" in values and "static_friction" not in raw:
        # One coefficient given: it holds at rest too (a slippery 0.2 surface stays slippery).
        values["static_friction"] = values["friction"]
    return cls(**values) if ok else None


def _check_polygon(points, path, problems: _Problems):
    from ..geometry import (  # numpy: only for scenes with polygons, so --help stays instant
        first_crossing,
        signed_area,
    )
    crossing = first_crossing(points)
    if crossing:
        i, j = crossing
        problems.add(path, f"polygon intersects itself (edges {i} and {j} cross)", points)
    elif abs(signed_area(points)) <= 1e-12 * max(1.0, max(abs(c) for p in points for c in p)) ** 2:
        problems.add(path, "polygon has zero area", points)


def _check_blob(b: BlobDef, path, problems: _Problems, periodic: bool):
    ring = (b.center if b.count == 1 or b.points is not None else (0.0, 0.0), b.radius)  # count: no centre
    if b.count > 1:
        if b.region is None and not periodic:
            problems.add(path + ("region",), "required with count (outside a periodic box)", show_got=False,
                         line_path=path + ("count",))
        for name in ("grid", "center"):
            if getattr(b, name) != BlobDef.__dataclass_fields__[name].default:
                problems.add(path + (name,), "not with count (its copies are placed at random in region)",
                             getattr(b, name))
    elif b.region is not None:
        problems.add(path + ("region",), "only with count > 1", b.region)
    if b.points is not None and any(x is not None for x in ring):
        problems.add(path, "give either center + radius (+ vertices) or points, not both", show_got=False)
    elif b.points is None and None in ring:
        missing = " and ".join(n for n, x in zip(("center", "radius"), ring) if x is None)
        problems.add(path, f"needs center + radius (missing {missing}), or points", show_got=False)
    if b.points is not None:
        _check_polygon(b.points, path + ("points",), problems)
    if b.static_friction < b.friction:
        problems.add(path + ("static_friction",), f"must be >= friction ({b.friction})", b.static_friction)
    if b.grid != (1, 1) and b.spacing is None:
        problems.add(path + ("spacing",), "required with grid", show_got=False, line_path=path + ("grid",))
    elif b.spacing is not None and any(n > 1 and d == 0 for n, d in zip(b.grid, b.spacing)):
        problems.add(path + ("spacing",), "must be > 0 along an axis with more than one copy", b.spacing)
    elif b.spacing is not None:
        reach = max(abs(c) for c in (b.center or (0.0, 0.0))) + (b.radius or 0.0) if b.points is None else \
            max(abs(c) for p in b.points for c in p)
        reach += max((n - 1) * d for n, d in zip(b.grid, b.spacing))
        if reach > MAX_COORDINATE:
            problems.add(path + ("spacing",), f"the grid reaches {reach:.3g} m from the origin; "
                         f"positions beyond ±{MAX_COORDINATE:g} m stop a run", b.spacing)


def _check_static(s: StaticDef, raw: dict, path, problems: _Problems):
    before = len(problems.items)
    ways = [way for way, keys in (("velocity", ("velocity", "angular_velocity")), ("path", ("path",)),
                                  ("load", ("load",))) if any(k in raw for k in keys)]
    if len(ways) > 1:
        problems.add(path + (ways[1],), f"a collider moves in one way only: give {' or '.join(ways)}, not both",
                     show_got=False)
    if "pivot" in raw and not ({"angular_velocity", "path"} & set(raw)):
        problems.add(path + ("pivot",), "only for a collider that turns (angular_velocity or path)", s.pivot)
    for name in ("load_direction", "mass"):
        if name in raw and "load" not in raw:
            problems.add(path + (name,), "only for a loaded wall (give load)", getattr(s, name))
    if s.path is not None and len(s.path[0]) != 4:
        problems.add(path + ("path",), "keyframes are [t, dx, dy, turn]: 4 numbers each", list(s.path[0]))
    if s.path is not None and len(s.path[0]) == 4 and max(max(abs(r[1]), abs(r[2])) for r in s.path) > MAX_COORDINATE:
        problems.add(path + ("path",), f"displacements must be within ±{MAX_COORDINATE:g} m", show_got=False)
    if s.static_friction < s.friction:
        problems.add(path + ("static_friction",), f"must be >= friction ({s.friction})", s.static_friction)
    if s.kind == "segment" and math.dist(s.a, s.b) < MIN_LENGTH:
        problems.add(path + ("b",), f"segment must be at least {MIN_LENGTH:g} m long", s.b)
    if s.kind == "polygon":
        _check_polygon(s.points, path + ("points",), problems)
    if s.load is not None and s.load > MAX_LOAD_ACCELERATION * s.mass:
        problems.add(path + ("load",), f"load / mass is {s.load / s.mass:.4g} m/s²; at most "
                     f"{MAX_LOAD_ACCELERATION:,.0f} m/s² (mass {s.mass:g} kg)", s.load)
    if len(problems.items) == before and (s.angular_velocity is not None or s.path is not None):
        _check_surface_speed(s, path, problems)  # (of a collider that is otherwise well made)


def _check_surface_speed(s: StaticDef, path, problems: _Problems):
    """A collider that turns moves its surface fastest at its farthest point from its pivot, R: |v| + |ω| R at a
    velocity, |Δd| / Δt + |Δθ| / Δt R between a path's keyframes. The contacts keep a blob out of a wall up to
    MAX_SURFACE_SPEED (core/walls.c); a faster one is refused."""
    from ..colliders import surface_reach
    reach = surface_reach(s, MAX_COORDINATE)
    if s.angular_velocity is not None:
        speed = math.hypot(*(s.velocity or (0.0, 0.0))) + abs(s.angular_velocity) * reach
        if speed > MAX_SURFACE_SPEED:
            problems.add(path + ("angular_velocity",), f"moves its surface at up to {speed:.4g} m/s (|velocity| + "
                         f"|ω| × {reach:.4g} m, its farthest point from its pivot); at most {MAX_SURFACE_SPEED:,g} "
                         "m/s", s.angular_velocity)
        return
    for j, (a, b) in enumerate(zip(s.path, s.path[1:])):
        dt = b[0] - a[0]
        speed = math.hypot(b[1] - a[1], b[2] - a[2]) / dt + math.radians(abs(b[3] - a[3])) / dt * reach
        if speed > MAX_SURFACE_SPEED:
            problems.add(path + ("path", j + 1), f"moves its surface at up to {speed:.4g} m/s from keyframe {j} to "
                         f"{j + 1} (|Δ(dx, dy)| / Δt + |Δturn| / Δt × {reach:.4g} m, its farthest point from its "
                         f"pivot); at most {MAX_SURFACE_SPEED:,g} m/s", list(b))
            return


def parse_scene(text: str, source: str = "<scene>") -> Scene:
    """Parse and validate scene TOML text; raise SceneError listing every problem."""
    import tomli

    try:
        raw = tomli.loads(text)
    except tomli.TOMLDecodeError as e:
        line, col = getattr(e, "lineno", None), getattr(e, "colno", None)
        msg = getattr(e, "msg", str(e))
        where = f"{source}:{line}:{col}" if line else source
        raise SceneError([f"{where}: TOML syntax error: {msg}"]) from None
    except RecursionError:
        raise SceneError([f"{source}:1: TOML nested too deeply to read"]) from None

    problems = _Problems(source, key_lines(text))
    for k in raw:
        if k not in TABLES:
            hint = difflib.get_close_matches(k, list(TABLES), n=1)
            problems.add((k,), "unknown table" + (f"; did you mean {hint[0]!r}?" if hint else ""), show_got=False)

    settings = _table(SceneSettings, raw.get("scene", {}), ("scene",), problems) or SceneSettings()
    # whether the box is periodic, also when [scene] has a problem elsewhere (its blobs need no region then)
    periodic = settings.periodic is not None or (isinstance(raw.get("scene"), dict) and "periodic" in raw["scene"])
    if settings.duration is not None and settings.steps is not None:
        problems.add(("scene", "steps"), "give duration or steps, not both", show_got=False)
    if settings.method not in METHODS:
        hint = difflib.get_close_matches(settings.method, METHODS, n=1)
        problems.add(("scene", "method"), f"unknown method; one of {', '.join(METHODS)}"
                     + (f"; did you mean {hint[0]!r}?" if hint else ""), settings.method)
    output = _table(OutputSettings, raw.get("output", {}), ("output",), problems) or OutputSettings()

    blobs = _array(raw, "blob", problems)
    statics = _array(raw, "static", problems)
    if not blobs and isinstance(raw.get("blob", []), list):
        problems.add(("blob",), "a scene needs at least one [[blob]]", show_got=False)

    blob_defs = []
    for i, rb in enumerate(blobs):
        b = _table(BlobDef, rb, ("blob", i), problems)
        if b is not None:
            _check_blob(b, ("blob", i), problems, periodic)
            blob_defs.append(b)

    from ..colliders import (
        COLLIDERS,  # numpy: imported when a scene is read, not for --help
    )
    static_defs = []
    for i, rs in enumerate(statics):
        path = ("static", i)
        kind = rs.get("kind") if isinstance(rs, dict) else None
        if not isinstance(rs, dict):
            problems.add(path, "must be a table", rs)
            continue
        if not isinstance(kind, str) or kind not in COLLIDERS:
            hint = difflib.get_close_matches(str(kind), list(COLLIDERS), n=1) if isinstance(kind, str) else []
            problems.add(path + ("kind",), f"must be one of {', '.join(COLLIDERS)}"
                         + (f"; did you mean {hint[0]!r}?" if hint else ""), kind)
            continue
        geometry = COLLIDERS[kind].keys
        allowed = ["kind", *geometry, *STATIC_MATERIAL_KEYS, *STATIC_MOTION_KEYS]
        s = _table(StaticDef, rs, path, problems, allowed=allowed)
        if s is None:
            continue
        missing = [g for g in geometry if g != "angle" and getattr(s, g) is None]
        if missing:
            problems.add(path, f"{kind} needs {', '.join(missing)}", show_got=False)
            continue
        _check_static(s, rs, path, problems)
        static_defs.append(s)

    schedule_defs = []
    names = expanded_names(blob_defs)
    for i, rs in enumerate(_array(raw, "schedule", problems)):
        path = ("schedule", i)
        s = _table(ScheduleDef, rs, path, problems)
        if s is None:
            continue
        missing = [k for k in ("key", "at") if getattr(s, k) is None]
        if missing:
            problems.add(path, f"needs {' and '.join(missing)}", show_got=False)
            continue
        if _check_schedule(s, names, path, problems, periodic):
            schedule_defs.append(s)
    targets = [(s.key, tuple(schedule_targets(s, names))) for s in schedule_defs]
    for i, (k, blobs_hit) in enumerate(targets):
        for j in range(i):
            if targets[j][0].rsplit(".", 1)[-1] == k.rsplit(".", 1)[-1] and set(targets[j][1]) & set(blobs_hit):
                problems.add(("schedule", i, "key"), f"schedules the same property as schedule[{j}] "
                             f"({targets[j][0]})", k)

    scene = Scene(settings, output, tuple(blob_defs), tuple(static_defs), tuple(schedule_defs), source, text)
    if not problems.items:
        _check_size(scene, problems)
        _check_driving(scene, problems)
    if not problems.items and any(s.blob_key == "scale" for s in schedule_defs if s.key.startswith("blob.")):
        _check_scales(scene, problems)  # (before the box's cells, which it sizes)
    if not problems.items and settings.periodic is not None:
        _check_box(scene, problems)
    if not problems.items and any(b.count > 1 for b in blob_defs):
        from .placement import PlacementError, random_centres
        try:
            random_centres(scene)
        except PlacementError as e:
            problems.add(("blob", e.table, "count"), str(e), blob_defs[e.table].count)
    if problems.items:
        raise SceneError(problems.items)
    return scene


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
    import fnmatch
    pattern = s.key[len("blob."):].rsplit(".", 1)[0]
    return [k for k, name in enumerate(names) if fnmatch.fnmatchcase(name, pattern)]


SCHEDULE_CHECKS = {"mass": mass_value, "pressure": positive, "scale": positive, "friction": nonnegative,
                   "static_friction": nonnegative, "restitution": unit_interval,
                   "adhesion": nonnegative}  # force, torque: _check_driving


def _check_schedule(s: ScheduleDef, names, path, problems: _Problems, periodic: bool) -> bool:
    width = len(s.at[0])
    if s.key == "scene.shear":
        if width != 2:
            problems.add(path + ("at",), "shear keyframes are [t, γ]: 2 numbers each", list(s.at[0]))
            return False
        if not periodic:
            problems.add(path + ("key",), "only in a periodic box ([scene] periodic)", s.key)
            return False
        for j, (_, gamma) in enumerate(s.at):
            if abs(gamma) > MAX_SHEAR:
                problems.add(path + ("at", j), f"shear strain γ must be within ±{MAX_SHEAR:,g} (the images' shift "
                             "γ L_y stays a number the step can wrap)", gamma)
                return False
        return True
    if s.key in ("scene.gravity", "scene.periodic"):
        what = s.key.split(".")[1]
        if width != 3:
            problems.add(path + ("at",), f"{what} keyframes are [t, {'gx, gy' if what == 'gravity' else 'Lx, Ly'}]: "
                         "3 numbers each", list(s.at[0]))
            return False
        if what == "periodic" and not periodic:
            problems.add(path + ("key",), "only in a periodic box ([scene] periodic)", s.key)
            return False
        if what == "periodic" and min(min(row[1:]) for row in s.at) <= 0.0:
            problems.add(path + ("at",), "box sides must be > 0", [list(row) for row in s.at])
            return False
        return True
    parts = s.key.split(".")
    if len(parts) < 3 or parts[0] != "blob":
        problems.add(path + ("key",), "must be blob.NAME.KEY, scene.gravity, scene.periodic or scene.shear", s.key)
        return False
    if parts[-1] not in SCHEDULED_BLOB_KEYS:
        hint = difflib.get_close_matches(parts[-1], SCHEDULED_BLOB_KEYS, n=1)
        problems.add(path + ("key",), f"KEY must be one of {', '.join(SCHEDULED_BLOB_KEYS)}"
                     + (f"; did you mean {hint[0]!r}?" if hint else ""), s.key)
        return False
    if not schedule_targets(s, names):
        pattern = ".".join(parts[1:-1])
        hint = difflib.get_close_matches(pattern, names, n=1)
        problems.add(path + ("key",), f"no blob is named {pattern!r}" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                        " (a grid's copies: NAME_*)"), s.key)
        return False
    if width != (3 if parts[-1] == "force" else 2):
        problems.add(path + ("at",), "force keyframes are [t, Fx, Fy]: 3 numbers each" if parts[-1] == "force"
                     else "keyframes are [t, value]: 2 numbers each", list(s.at[0]))
        return False
    for j, (_, *value) in enumerate(s.at):
        check = SCHEDULE_CHECKS.get(parts[-1])
        complaint = check(value[0]) if check else None
        if complaint:
            problems.add(path + ("at", j), f"{parts[-1]} {complaint}", value[0])
            return False
    return True


def _array(raw: dict, name: str, problems: _Problems) -> list:
    value = raw.get(name, [])
    if not isinstance(value, list):
        problems.add((name,), f"must be an array of tables: write [[{name}]]", value)
        return []
    return value


def _check_size(scene: Scene, problems: _Problems):
    """Refuse scenes whose arrays would be too large, before anything is allocated."""
    for i, b in enumerate(scene.blobs):
        if blob_vertex_count(b) > MAX_BLOB_VERTICES:
            problems.add(("blob", i, "vertices"), f"at most {MAX_BLOB_VERTICES:,} vertices per blob",
                         blob_vertex_count(b))
    if scene.blob_count > MAX_BLOBS:
        problems.add(("blob",), f"scene has {scene.blob_count:,} blobs after grids; the limit is {MAX_BLOBS:,}",
                     show_got=False)
    if scene.vertex_count > MAX_VERTICES:
        problems.add(("blob",), f"scene has {scene.vertex_count:,} vertices after grids; "
                     f"the limit is {MAX_VERTICES:,}", show_got=False)
    for path, message in run_length_problems(scene):
        problems.add(path, message, show_got=False)


STRIDE = 0.5  # of a mean rest edge: the farthest a blob moves in one substep (core/integrate.c's STRIDE)


def _check_driving(scene: Scene, problems: _Problems):
    """Refuse a driving force or torque (a blob's, or a schedule keyframe's) that accelerates a blob faster than
    a step can follow. The substep rule (core/integrate.c: bc_substeps_for) keeps a blob's move within STRIDE of
    a mean rest edge L a substep, with at most `most` substeps (max_substeps, within the step's work bound:
    pipeline.settings); a blob driven from rest reaches a dt in one step, a = |F| / M + |τ| r / I (r its farthest
    vertex from the centre of mass, I = Σ m |r|², at the shape written), so a dt² must stay within most STRIDE L.
    M is the least mass a mass schedule gives the blob; a scale schedule is not checked."""
    s = scene.settings
    most = max(s.substeps, min(s.max_substeps, MAX_STEP_WORK // max(s.iterations * scene.vertex_count, 1)))
    names = expanded_names(scene.blobs)
    table_of = [i for i, b in enumerate(scene.blobs) for _ in range(b.copies)]
    # per [[blob]] table: the largest |F| and |τ| it is given, with where and as written, and its least mass
    force = [(math.hypot(*b.force), ("blob", i, "force"), list(b.force)) for i, b in enumerate(scene.blobs)]
    torque = [(abs(b.torque), ("blob", i, "torque"), b.torque) for i, b in enumerate(scene.blobs)]
    mass = [b.mass for b in scene.blobs]
    for k, sc in enumerate(scene.schedules):
        if sc.key.startswith("scene."):
            continue
        for i in sorted({table_of[x] for x in schedule_targets(sc, names)}):
            for j, row in enumerate(sc.at):
                if sc.blob_key == "mass":
                    mass[i] = min(mass[i], row[1])
                elif sc.blob_key == "force" and math.hypot(row[1], row[2]) > force[i][0]:
                    force[i] = (math.hypot(row[1], row[2]), ("schedule", k, "at", j), list(row))
                elif sc.blob_key == "torque" and abs(row[1]) > torque[i][0]:
                    torque[i] = (abs(row[1]), ("schedule", k, "at", j), list(row))
    for i, b in enumerate(scene.blobs):
        if force[i][0] == 0.0 and torque[i][0] == 0.0:
            continue
        if b.points is None:  # a ring: n edges of 2 R sin(π / n), every vertex at R
            edge, farthest, mean_square = 2.0 * b.radius * math.sin(math.pi / b.vertices), b.radius, b.radius ** 2
        else:
            n = len(b.points)
            cx, cy = sum(p[0] for p in b.points) / n, sum(p[1] for p in b.points) / n
            squares = [(x - cx) ** 2 + (y - cy) ** 2 for x, y in b.points]
            edge = sum(math.dist(b.points[j - 1], b.points[j]) for j in range(n)) / n
            farthest, mean_square = math.sqrt(max(squares)), sum(squares) / n
        pushed = force[i][0] / mass[i]  # m/s², and the torque's at the farthest vertex: |τ| r / (M mean |r|²)
        turned = torque[i][0] * farthest / (mass[i] * mean_square)
        limit = most * STRIDE * edge / s.dt ** 2
        if pushed + turned > limit:
            _, path, got = force[i] if pushed >= turned else torque[i]
            problems.add(path, f"drives {b.name or f'blob{i}'} at {pushed + turned:.4g} m/s² (|F| / M + |τ| r / I, "
                         f"M = {mass[i]:g} kg); at most {limit:.4g} m/s² here, or one step from rest moves it more "
                         f"than {STRIDE:g} × its edge ({STRIDE * edge:.3g} m) a substep at the most substeps a step "
                         f"takes ({most})", got)


PERIODIC_SIDE = 5.0  # × the largest blob radius: the least side of a periodic box
BROAD_MARGIN = 0.25  # × the larger radius: the broad phase's margin (core/broad_phase.c), its cells 2 r (1 + margin)


def _radii(scene: Scene) -> list[float]:
    """Each [[blob]] table's radius as written: its ring's farthest vertex from the vertex average (m)."""
    import numpy as np

    from ..sim.model import blob_points
    return [float(np.hypot(*(ring - ring.mean(axis=0)).T).max()) for ring in (blob_points(b) for b in scene.blobs)]


def _scales(scene: Scene) -> list[list[tuple[float, int, int]]]:
    """Each [[blob]] table's scale keyframes, (s, schedule index, keyframe index), from the scale schedules that
    reach its blobs ([] for none: its size as written)."""
    names = expanded_names(scene.blobs)
    table_of = [i for i, b in enumerate(scene.blobs) for _ in range(b.copies)]
    out = [[] for _ in scene.blobs]
    for k, sc in enumerate(scene.schedules):
        if sc.key.startswith("blob.") and sc.blob_key == "scale":
            for i in sorted({table_of[x] for x in schedule_targets(sc, names)}):
                out[i] += [(row[1], k, j) for j, row in enumerate(sc.at)]
    return out


def _check_scales(scene: Scene, problems: _Problems):
    """A scale schedule keeps each blob's radius × s from MIN_LENGTH (smaller, a blob loses its area to
    round-off) to MAX_COORDINATE (larger, it leaves the world)."""
    for i, (radius, keyframes) in enumerate(zip(_radii(scene), _scales(scene))):
        for factor, k, j in keyframes:
            if not MIN_LENGTH <= factor * radius <= MAX_COORDINATE:
                problems.add(("schedule", k, "at", j), f"scales blob[{i}] (radius {radius:.4g} m) to "
                             f"{factor * radius:.4g} m; its radius must stay from {MIN_LENGTH:g} to "
                             f"{MAX_COORDINATE:g} m", factor)
                return


def _check_box(scene: Scene, problems: _Problems):
    """A periodic box must be wider than any pair of blobs can reach (r_a + r_b + the broad phase's
    margin, at most 2.5 r_max) twice over, so that the nearest image of a blob is the only one that
    can touch another; and of at most MAX_BOX_CELLS cells of the broad phase's grid (core/broad_phase.c:
    periodic_grid), each 2 r_max (1 + margin) wide, r_max the largest radius of a blob when it is smallest (a
    scale schedule's least factor), whatever the box is (a periodic schedule's keyframes too)."""
    radii = _radii(scene)
    largest = max(radii)
    if min(scene.settings.periodic) < PERIODIC_SIDE * largest:
        problems.add(("scene", "periodic"), f"each side must be at least {PERIODIC_SIDE:g} × the largest blob's "
                     f"radius ({PERIODIC_SIDE * largest:.4g} m)", list(scene.settings.periodic))
    for i, s in enumerate(scene.schedules):  # (a scheduled scale may grow the blobs on top: not checked)
        if s.key == "scene.periodic" and min(min(row[1:]) for row in s.at) < PERIODIC_SIDE * largest:
            problems.add(("schedule", i, "at"), f"box sides must be at least {PERIODIC_SIDE:g} × the largest blob's "
                         f"radius ({PERIODIC_SIDE * largest:.4g} m)", show_got=False)
    r_max = max(r * min([1.0] if not keys else [f for f, _, _ in keys]) for r, keys in zip(radii, _scales(scene)))
    cell = 2.0 * r_max * (1.0 + BROAD_MARGIN)  # (r_max >= MIN_LENGTH: _check_scales)
    boxes = [(("scene", "periodic"), scene.settings.periodic)]
    boxes += [(("schedule", i, "at", j), row[1:]) for i, s in enumerate(scene.schedules) if s.key == "scene.periodic"
              for j, row in enumerate(s.at)]
    for path, (lx, ly) in boxes:
        nx, ny = max(1, math.floor(lx / cell)), max(1, math.floor(ly / cell))
        if nx * ny > MAX_BOX_CELLS:
            problems.add(path, f"the box is {nx:,} × {ny:,} cells of the broad phase's grid (each {cell:.4g} m, 2.5 × "
                         f"the largest blob's radius); at most {MAX_BOX_CELLS:,} cells", [lx, ly])
            return


def run_length_problems(scene: Scene) -> list[tuple[tuple, str]]:
    """(key path, message) for a run too long to finish or a step too long to interrupt."""
    s, out = scene.settings, []
    steps = s.steps if s.steps is not None else (s.duration or DEFAULT_DURATION) / s.dt
    if steps > MAX_STEPS:
        out.append((("scene", "duration"), f"duration / dt is {steps:.3g} steps; at most {MAX_STEPS:,}"))
    work = s.substeps * s.iterations * scene.vertex_count
    if work > MAX_STEP_WORK:
        out.append((("scene", "iterations"), f"substeps × iterations × vertices is {work:,} per step; at most "
                    f"{MAX_STEP_WORK:,}, so that a step stays interruptible"))
    return out


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file; raise SceneError (file problems included)."""
    source = str(path)
    p = Path(path)
    try:
        with open(p, "rb") as f:
            data = f.read(MAX_SCENE_BYTES + 1)  # a cap, not st_size: /dev/zero and pipes have none
        if len(data) > MAX_SCENE_BYTES:
            raise SceneError([f"{source}: file is larger than {MAX_SCENE_BYTES:,} bytes, the most a scene may be"])
    except FileNotFoundError:
        raise SceneError([f"{source}: no such file"]) from None
    except IsADirectoryError:
        raise SceneError([f"{source}: is a directory, not a scene file"]) from None
    except OSError as e:
        raise SceneError([f"{source}: cannot read ({e.strerror})"]) from None
    if b"\x00" in data:
        raise SceneError([f"{source}:1: not a text file (it contains NUL bytes)"])
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark, as some editors write
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[:e.start].count(b"\n") + 1
        raise SceneError([f"{source}:{line}: not UTF-8 text (byte 0x{data[e.start]:02x})"]) from None
    return parse_scene(text, source)


# --- presentation: `blobsim check` and docs/scenes.md --------------------------------------

def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return str(v)


def resolved_toml(scene: Scene) -> str:
    """The scene with every default filled in, as TOML (what `blobsim check` prints)."""
    s = replace(scene.settings, name=scene.name)
    if s.steps is None:
        s = replace(s, duration=s.duration or DEFAULT_DURATION)
    o = replace(scene.output, path=str(scene.output_path))
    out = [f"# {scene.source}: {scene.blob_count} blobs, {scene.vertex_count} vertices, {scene.steps} steps"]

    def table(header, obj, keys=None):
        out.append(header)
        for f in fields(obj):
            if keys is not None and f.name not in keys:
                continue
            v = getattr(obj, f.name)
            if v is not None:
                unit = f.metadata["unit"]
                out.append(f"{f.name} = {_toml_value(v)}" + (f"  # {unit}" if unit else ""))
        out.append("")

    table("[scene]", s)
    table("[output]", o)
    for b in scene.blobs:
        keys = None if b.points is None else [f.name for f in fields(b) if f.name not in ("vertices",)]
        table("[[blob]]", b, keys)
    from ..colliders import COLLIDERS
    for st in scene.statics:
        motion = [k for k in STATIC_MOTION_KEYS if k not in ("load_direction", "mass") or st.load is not None]
        table("[[static]]", st, ["kind", *COLLIDERS[st.kind].keys, *STATIC_MATERIAL_KEYS, *motion])
    for sc in scene.schedules:
        table("[[schedule]]", sc)
    return "\n".join(out).rstrip() + "\n"


def reference_markdown() -> str:
    """The scene reference of docs/scenes.md, generated from the dataclass fields."""
    out = []
    for name, cls in TABLES.items():
        header = f"[[{name}]]" if name in ("blob", "static", "schedule") else f"[{name}]"
        out.append(f"### `{header}`\n\n| key | default | unit | meaning |\n|---|---|---|---|")
        for f in fields(cls):
            d = f.default
            if d is None:
                default = "—"
            elif isinstance(d, float) and d == 1 / 60:
                default = "`1/60` (0.01667)"
            else:
                default = f"`{_toml_value(d)}`"
            out.append(f"| `{f.name}` | {default} | {f.metadata['unit'] or ''} | {f.metadata['doc']} |")
        out.append("")
    return "\n".join(out)


if __name__ == "__main__":  # python -m blobcli.scene.schema: print the scene reference of docs/scenes.md
    print(reference_markdown(), end="")
