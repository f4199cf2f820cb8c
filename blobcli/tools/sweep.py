"""`blobsim sweep`: one base scene, axes of values, every point run (on Dask) and summarised.

The sweep file (TOML), validated like a scene (`file:line: key.path: message`):

    [sweep]
    scene = "pile.toml"          # the base scene, relative to this file
    name = "pile-friction"       # default: the file's stem
    mode = "grid"                # grid (every combination) or zip (axes side by side)
    [[sweep.axis]]
    key = "blob[*].friction"     # scene.<key>, output.<key>, blob[<i>|*].<key>, static[<i>|*].<key>
    values = [0.1, 0.3, 0.5, 0.8]

A point is the base scene's TOML with the axis values put in, validated by the scene's own
code and written as DIR/<name>/point-NNNN.toml (every default filled in), so that
`blobsim run point-NNNN.toml` reproduces DIR/<name>/point-NNNN.h5 bit for bit: the worker
runs exactly that file.
"""

from __future__ import annotations

import csv
import difflib
import itertools
import re
import threading
from dataclasses import dataclass, fields
from pathlib import Path

from ..scene.schema import MAX_SCENE_BYTES, TABLES, Problems, SceneError, fmt_value, load_scene, parse_scene
from ..scene.tomlpos import key_lines

MODES = ("grid", "zip")
MAX_POINTS = 100_000
KEY = re.compile(r"^(?:(scene|output)\.(\w+)|(blob|static)\[(\*|\d+)\]\.(\w+))$")
METRICS = ("worst_area_error", "final_kinetic_energy", "wall_time_s", "steps")
COLUMNS = ("point", "status", "steps", "sim_time_s", "wall_time_s", "worst_area_error", "final_kinetic_energy",
           "file")


@dataclass(frozen=True)
class Axis:
    key: str
    values: tuple


@dataclass(frozen=True)
class Sweep:
    source: Path
    base: Path  # the base scene file
    name: str
    mode: str
    axes: tuple[Axis, ...]
    points: tuple[tuple, ...]  # one tuple of axis values per point
    texts: tuple[str, ...]  # each point's resolved scene TOML


def load_sweep(path) -> Sweep:
    """Read and validate a sweep file and every point it makes; SceneError lists every problem."""
    source = Path(path)
    try:
        with open(source, "rb") as f:
            data = f.read(MAX_SCENE_BYTES + 1)
        text = data.decode("utf-8-sig")
    except FileNotFoundError:
        raise SceneError([f"{source}: no such file"]) from None
    except (IsADirectoryError, UnicodeDecodeError, OSError) as e:
        raise SceneError([f"{source}: cannot read a sweep file here ({e.__class__.__name__})"]) from None
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError([f"{source}: larger than {MAX_SCENE_BYTES:,} bytes"])
    import tomli
    try:
        raw = tomli.loads(text)
    except tomli.TOMLDecodeError as e:
        raise SceneError([f"{source}:{getattr(e, 'lineno', 1)}: TOML syntax error: {getattr(e, 'msg', e)}"]) from None
    problems = Problems(str(source), key_lines(text))
    sweep = raw.get("sweep")
    if not isinstance(sweep, dict):
        problems.add(("sweep",), "a sweep file needs a [sweep] table", show_got=False)
        raise SceneError(problems.items)
    for k in raw:
        if k != "sweep":
            problems.add((k,), "unknown table; a sweep file has only [sweep]", show_got=False)
    for k in sweep:
        if k not in ("scene", "name", "mode", "axis"):
            hint = difflib.get_close_matches(k, ["scene", "name", "mode", "axis"], n=1)
            problems.add(("sweep", k), "unknown key" + (f"; did you mean {hint[0]!r}?" if hint else ""),
                         show_got=False)
    base = sweep.get("scene")
    base_scene = None
    if not isinstance(base, str) or not base:
        problems.add(("sweep", "scene"), "must name the base scene file (relative to this file)", base)
    else:
        base = (source.parent / base).resolve() if not Path(base).is_absolute() else Path(base)
        try:
            base_scene = load_scene(base)
        except SceneError as e:
            problems.add(("sweep", "scene"), f"the base scene is not valid: {e.problems[0]}", show_got=False)
    name = sweep.get("name", source.stem)
    if not isinstance(name, str) or not re.fullmatch(r"[\w.-]{1,100}", name) or name in (".", ".."):
        problems.add(("sweep", "name"), "must be 1-100 letters, digits, '.', '_' or '-' (it names a directory)",
                     name)
    mode = sweep.get("mode", "grid")
    if mode not in MODES:
        problems.add(("sweep", "mode"), f"must be one of {', '.join(MODES)}", mode)
    axes = []
    raw_axes = sweep.get("axis", [])
    if not isinstance(raw_axes, list) or not raw_axes:
        problems.add(("sweep", "axis"), "needs at least one [[sweep.axis]] with key and values", show_got=False)
        raw_axes = []
    for i, ax in enumerate(raw_axes):
        path = ("sweep", "axis", i)
        if not isinstance(ax, dict):
            problems.add(path, "must be a table", ax)
            continue
        for k in ax:
            if k not in ("key", "values"):
                problems.add(path + (k,), "unknown key; an axis has key and values", show_got=False)
        key, values = ax.get("key"), ax.get("values")
        complaint = _key_problem(key, base_scene)
        if complaint:
            problems.add(path + ("key",), complaint, key)
        if not isinstance(values, list) or not values:
            problems.add(path + ("values",), "must be a non-empty list", values)
        if not complaint and any(a.key == key for a in axes):
            problems.add(path + ("key",), "the same key as an earlier axis (its points would repeat)", key)
        elif not complaint and isinstance(values, list) and values:
            axes.append(Axis(key, tuple(values)))
    if problems.items:
        raise SceneError(problems.items)
    if mode == "zip" and len({len(a.values) for a in axes}) > 1:
        problems.add(("sweep", "axis"), "mode zip needs axes of equal length",
                     [len(a.values) for a in axes])
        raise SceneError(problems.items)
    points = (list(itertools.product(*(a.values for a in axes))) if mode == "grid"
              else list(zip(*(a.values for a in axes))))
    if len(points) > MAX_POINTS:
        problems.add(("sweep", "axis"), f"makes {len(points):,} points; at most {MAX_POINTS:,}", show_got=False)
        raise SceneError(problems.items)
    texts = []
    base_raw = tomli.loads(base_scene.text)
    for k, values in enumerate(points):
        doc = _with_values(base_raw, axes, values)
        try:
            scene = parse_scene(_toml_text(doc), f"point-{k:04d}.toml")
        except SceneError as e:
            where = ", ".join(f"{a.key} = {fmt_value(v)}" for a, v in zip(axes, values))
            detail = e.problems[0].split(": ", 1)[1] if ": " in e.problems[0] else e.problems[0]
            problems.add(("sweep", "axis"), f"point {k} ({where}) is not a valid scene: {detail}", show_got=False)
            continue
        from ..scene.schema import resolved_toml
        texts.append(resolved_toml(scene))
    if problems.items:
        raise SceneError(problems.items[:20] + ([f"... and {len(problems.items) - 20} more"]
                                                if len(problems.items) > 20 else []))
    return Sweep(source, base, name, mode, tuple(axes), tuple(points), tuple(texts))


def _key_problem(key, base_scene) -> str | None:
    if not isinstance(key, str):
        return "must be a string like blob[*].friction"
    m = KEY.match(key)
    if not m:
        return "must be scene.<key>, output.<key>, blob[<i>|*].<key> or static[<i>|*].<key>"
    table = m.group(1) or m.group(3)
    field = m.group(2) or m.group(5)
    names = [f.name for f in fields(TABLES[table])]
    if field not in names:
        hint = difflib.get_close_matches(field, names, n=1)
        return f"{field!r} is not a key of [{table}]" + (f"; did you mean {hint[0]!r}?" if hint else "")
    if base_scene is not None and m.group(4) not in (None, "*"):
        count = len(base_scene.blobs if table == "blob" else base_scene.statics)
        if int(m.group(4)) >= count:
            return f"the base scene has {count} [[{table}]] tables (indices from 0)"
    return None


def _with_values(base_raw: dict, axes, values) -> dict:
    import copy
    doc = copy.deepcopy(base_raw)
    for axis, value in zip(axes, values):
        m = KEY.match(axis.key)
        if m.group(1):
            doc.setdefault(m.group(1), {})[m.group(2)] = value
        else:
            items = doc.get(m.group(3), [])
            chosen = items if m.group(4) == "*" else [items[int(m.group(4))]]
            for item in chosen:
                item[m.group(5)] = value
    return doc


def _toml_text(doc: dict) -> str:
    """TOML for a scene document (tables, arrays of tables, and plain values)."""
    from ..scene.schema import toml_value
    out = []
    for name, value in doc.items():
        if not isinstance(value, (dict, list)) or (isinstance(value, list) and not all(isinstance(x, dict)
                                                                                        for x in value)):
            out.insert(0, f"{name} = {toml_value(value)}")
    for name, value in doc.items():
        if isinstance(value, dict):
            out.append(f"[{name}]")
            out += [f"{k} = {toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and value and all(isinstance(x, dict) for x in value):
            for item in value:
                out.append(f"[[{name}]]")
                out += [f"{k} = {toml_value(v)}" for k, v in item.items()]
    return "\n".join(out) + "\n"


# --- running ------------------------------------------------------------------------------

def output_files(out: Path, sweep: Sweep) -> list[Path]:
    """Every file `blobsim sweep` writes in `out`: each point's scene, its trajectory and the lock its run holds,
    and the summary's table and chart."""
    points = (out / f"point-{k:04d}{suffix}" for k in range(len(sweep.points)) for suffix in (".toml", ".h5",
                                                                                              ".h5.lock"))
    return [*points, out / "summary.csv", out / "summary.png"]


def run_sweep(sweep: Sweep, out: Path, scheduler=None, workers=None, progress=False,
              announce=print) -> tuple[dict, bool]:
    """Write each point's scene, run the points that are not done (resuming interrupted ones)
    through the executor, and return ({point: summary row}, interrupted). A Ctrl-C stops the
    loop; points a worker finished but had not yet reported are read back from their files."""
    from ..io.interrupts import caused_by_signal, pending, request_stop
    from ..io.outputs import holds_text, write_text
    from .executor import run_tasks
    out.mkdir(parents=True, exist_ok=True)
    rows, tasks, index = {}, [], []
    for k, text in enumerate(sweep.texts):
        toml, h5 = out / f"point-{k:04d}.toml", out / f"point-{k:04d}.h5"
        if not holds_text(toml, text):
            write_text(toml, text)
        state = point_state(h5, text)
        if state == "done":
            rows[k] = reused_row(h5)
        else:
            tasks.append((str(toml), str(h5), state == "resume"))
            index.append(k)
    announce(f"blobsim: sweep {sweep.name}: {len(sweep.points)} points ({len(rows)} already done) in {out}")
    try:
        for i, row in run_tasks(run_point, tasks, scheduler, workers, progress=progress, label="points",
                                stop=request_stop):
            rows[index[i]] = row
    except (KeyboardInterrupt, Exception) as e:
        if not caused_by_signal(e):  # (Dask wraps one raised inside its event loop)
            raise
        for k in set(range(len(sweep.points))) - set(rows):
            h5 = out / f"point-{k:04d}.h5"
            if point_state(h5, sweep.texts[k]) == "done":
                rows[k] = reused_row(h5)
        return rows, True
    return rows, pending() is not None  # a signal whose raise Python swallowed (interrupts._quiet_interrupts)


def run_point(point_toml: str, h5: str, resume: bool) -> dict:
    """Run one point (on a worker): its summary row, with status ok / failed: reason."""
    from ..io import interrupts
    if threading.current_thread() is not threading.main_thread():
        interrupts.clear()  # a Dask worker: a stop the sweep asked of an earlier task is not for this one
    from ..io.h5md import TrajectoryError
    from ..io.outputs import OutputError
    from ..io.run import simulate
    row = {"status": "failed", "steps": 0, "sim_time_s": 0.0, "wall_time_s": 0.0, "worst_area_error": "",
           "final_kinetic_energy": "", "file": h5}
    try:
        scene = load_scene(point_toml)
        result = simulate(scene, h5, resume=h5 if resume else None, replace_stale_partial=True)
    except (SceneError, OutputError, TrajectoryError) as e:
        row["status"] = f"failed: {str(e).splitlines()[0]}"
        return row
    row.update(steps=result.steps, sim_time_s=result.sim_time, wall_time_s=result.wall_time,
               worst_area_error=result.worst_area_error)
    row["status"] = {"complete": "ok", "interrupted": "interrupted"}.get(result.status,
                                                                        f"failed: {result.message}")
    if result.written:
        row["final_kinetic_energy"] = final_kinetic_energy(h5)
    return row


def final_kinetic_energy(h5) -> float:
    from ..io.h5md import KINETIC, open_trajectory
    with open_trajectory(h5) as f:
        return float(f[KINETIC]["value"][-1].sum())


def point_state(h5: Path, text: str) -> str:
    """"done" (complete, same scene), "resume" (interrupted, same scene, resumable) or "run"."""
    from ..io.h5md import PARAMETERS, RESTART, TrajectoryError, open_trajectory
    from ..io.h5md import text as as_text
    if not h5.exists():
        return "run"
    try:
        with open_trajectory(h5) as f:
            if as_text(f[PARAMETERS]["scene"][()]) != text:
                return "run"
            if bool(f.attrs["complete"]):
                return "done"
            return "resume" if RESTART in f else "run"
    except TrajectoryError:
        return "run"


def reused_row(h5: Path) -> dict:
    import numpy as np

    from ..io.h5md import AREA, PARAMETERS, POSITION, open_trajectory
    with open_trajectory(h5) as f:
        steps = int(f[POSITION]["step"][-1])
        target = f[PARAMETERS]["target_area"][...]
        area = f[AREA]["value"][1:]
        worst = float(np.max(np.abs(area - target) / target, initial=0.0))
        dt = float(f[PARAMETERS].attrs["dt"])
    return {"status": "ok", "steps": steps, "sim_time_s": steps * dt, "wall_time_s": "",
            "worst_area_error": worst, "final_kinetic_energy": final_kinetic_energy(h5), "file": str(h5)}


def write_summary(sweep: Sweep, rows: dict, out: Path) -> Path:
    from ..io.outputs import replaced
    path = out / "summary.csv"
    with replaced(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point", *[a.key for a in sweep.axes], *COLUMNS[1:]])
        for k, values in enumerate(sweep.points):
            row = rows.get(k, {"status": "interrupted", "file": str(out / f"point-{k:04d}.h5")})
            w.writerow([k, *values, *[_cell(row.get(c, "")) for c in COLUMNS[1:]]])
    return path


def _cell(v):
    return f"{v:.6g}" if isinstance(v, float) else v


def chart(sweep: Sweep, rows: dict, png: Path, metrics=("worst_area_error",)) -> None:
    """Each metric against the first axis, one line per value of the second axis."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(metrics), figsize=(6 * len(metrics), 4), squeeze=False)
    for ax, metric in zip(axes[0], metrics):
        _plot_metric(ax, sweep, rows, metric)
    fig.tight_layout()
    from ..io.outputs import replaced
    with replaced(png) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def _plot_metric(ax, sweep: Sweep, rows: dict, metric: str) -> None:
    first = sweep.axes[0]
    second = sweep.axes[1] if len(sweep.axes) > 1 else None
    groups = {}
    for k, values in enumerate(sweep.points):
        row = rows.get(k)
        if not row or row.get("status") != "ok" or row.get(metric) in ("", None):
            continue
        groups.setdefault(values[1] if second else None, []).append((values[0], float(row[metric])))
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in first.values)
    order = {v: i for i, v in enumerate(dict.fromkeys(map(repr, first.values)))}
    for label, pts in groups.items():
        pts.sort(key=lambda p: p[0] if numeric else order[repr(p[0])])
        xs = [p[0] if numeric else order[repr(p[0])] for p in pts]
        ax.plot(xs, [p[1] for p in pts], marker="o", label=None if second is None else f"{second.key} = {label}")
    if not numeric:
        ax.set_xticks(range(len(order)), list(order))
    ax.set_xlabel(first.key)
    ax.set_ylabel(metric.replace("_", " "))
    if metric == "worst_area_error":
        ax.set_yscale("log")
    ax.set_title(f"{sweep.name}: {metric.replace('_', ' ')} (ok points)")
    if second is not None and groups:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
