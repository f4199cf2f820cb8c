"""Reading a scene: TOML text in, a validated Scene out, or one SceneError that lists every problem,
one line each: `file:line: blob[1].radius: must be > 0 (got -0.5)` (indices are 0-based). Each table and
key is checked here; the checks that need the whole scene are in scene/checks.py.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import fields
from pathlib import Path

from .checks import check_box, check_driving, check_scales, check_schedule, check_size
from .keys import (
    MAX_COORDINATE,
    MAX_KEYFRAMES,
    MAX_LOAD_ACCELERATION,
    MAX_POLYGON_POINTS,
    MAX_SCENE_BYTES,
    MAX_SURFACE_SPEED,
    METHODS,
    MIN_LENGTH,
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
    expanded_names,
    schedule_targets,
)
from .tomlpos import key_lines, line_of


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


class Problems:
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
    problems = Problems(scene.source, key_lines(scene.text))
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


def _coerce(kind: str, v, path, problems: Problems, unit: str = ""):
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


def _table(cls, raw, path: tuple, problems: Problems, allowed=None):
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


def _check_polygon(points, path, problems: Problems):
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


def _check_blob(b: BlobDef, path, problems: Problems, periodic: bool):
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


def _check_static(s: StaticDef, raw: dict, path, problems: Problems):
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


def _check_surface_speed(s: StaticDef, path, problems: Problems):
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

    problems = Problems(source, key_lines(text))
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
        if check_schedule(s, names, path, problems, periodic):
            schedule_defs.append(s)
    targets = [(s.key, tuple(schedule_targets(s, names))) for s in schedule_defs]
    for i, (k, blobs_hit) in enumerate(targets):
        for j in range(i):
            if targets[j][0].rsplit(".", 1)[-1] == k.rsplit(".", 1)[-1] and set(targets[j][1]) & set(blobs_hit):
                problems.add(("schedule", i, "key"), f"schedules the same property as schedule[{j}] "
                             f"({targets[j][0]})", k)

    scene = Scene(settings, output, tuple(blob_defs), tuple(static_defs), tuple(schedule_defs), source, text)
    if not problems.items:
        check_size(scene, problems)
        check_driving(scene, problems)
    if not problems.items and any(s.blob_key == "scale" for s in schedule_defs if s.key.startswith("blob.")):
        check_scales(scene, problems)  # (before the box's cells, which it sizes)
    if not problems.items and settings.periodic is not None:
        check_box(scene, problems)
    if not problems.items and any(b.count > 1 for b in blob_defs):
        from .placement import PlacementError, random_centres
        try:
            random_centres(scene)
        except PlacementError as e:
            problems.add(("blob", e.table, "count"), str(e), blob_defs[e.table].count)
    if problems.items:
        raise SceneError(problems.items)
    return scene


def _array(raw: dict, name: str, problems: Problems) -> list:
    value = raw.get(name, [])
    if not isinstance(value, list):
        problems.add((name,), f"must be an array of tables: write [[{name}]]", value)
        return []
    return value


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
