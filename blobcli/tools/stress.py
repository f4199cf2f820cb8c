"""`blobsim stress`: the shipped stress scenes × area methods, each a pass or a stated failure.

Failure detectors (each a plain function over a recorded trajectory, so each is testable):
    non-finite       the run stopped: a position became NaN/inf or left the 10⁶ m box
    inside out       a blob's polygon crosses itself, or its signed area changed sign
    tunnelled        a vertex inside a solid collider, or its path crossed a segment
    area drift       |A / A_target - 1| > AREA_DRIFT after the first SETTLE seconds
    energy growth    kinetic + gravitational energy rose by more than ENERGY_GROWTH after
                     the first SETTLE seconds, with nothing doing work on the blobs (not checked
                     in a scene with a moving collider: it does work on them)
SETTLE skips each scene's start, which may be out of balance on purpose (a blob asked for
twice its rest area gains energy inflating; a fast blob is still landing).

A stability map runs one small scene over a grid of dt and each method's stiffness knob
(kot and xpbd: pressure; gas: gas_pressure; springs: spring_stiffness) and charts pass/fail.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..colliders import COLLIDERS
from ..geometry import first_crossing, ring_areas
from ..io.h5md import read_trajectory
from ..io.outputs import replaced, write_text
from ..scene.schema import METHODS, load_scene, parse_scene, with_overrides
from .executor import run_tasks

STRESS_DIR = Path(__file__).resolve().parent / "stress_scenes"
AREA_DRIFT = 0.10  # relative area error allowed after SETTLE
ENERGY_GROWTH = 0.05  # relative rise of kinetic + gravitational energy allowed after SETTLE
SETTLE = 0.5  # s
PENETRATION = 1e-6  # m: a vertex this deep inside a solid collider has tunnelled
RECORD_EVERY = 2  # steps between recorded frames of a stress run


@dataclass
class Verdict:
    scene: str
    method: str
    failures: list  # short reasons; empty: pass
    wall_time: float

    @property
    def passed(self) -> bool:
        return not self.failures

    def cell(self) -> str:
        return "pass" if self.passed else "FAIL: " + "; ".join(self.failures)


# --- detectors: (trajectory arrays, ...) -> reason or None ---------------------------------

def detect_nonfinite(status: str, position) -> str | None:
    if status == "runaway" or not np.all(np.isfinite(position)):
        return "non-finite"
    return None


def detect_inside_out(position, offsets, rest_sign) -> str | None:
    areas = ring_areas(position, offsets)
    flipped = np.argwhere(areas * rest_sign <= 0)
    if len(flipped):
        return f"inside out (blob {flipped[0][1]}, frame {flipped[0][0]})"
    for f in range(position.shape[0]):
        for b in range(len(offsets) - 1):
            if first_crossing(position[f, offsets[b]:offsets[b + 1]]) is not None:
                return f"self-intersecting (blob {b}, frame {f})"
    return None


def detect_tunnelled(position, statics) -> str | None:
    for k, s in enumerate(statics):
        for f in range(position.shape[0]):
            p = position[f]
            if s.kind == "segment":  # zero thickness: a vertex that crossed it between frames
                if f == 0:
                    continue
                a, b = np.array(s.a), np.array(s.b)
                t = (b - a) / np.hypot(*(b - a))
                n = np.array([-t[1], t[0]])
                d0, d1 = (position[f - 1] - a) @ n, (p - a) @ n
                crossing = d0 * d1 < 0
                where = d0 / np.where(d0 != d1, d0 - d1, 1.0)  # fraction of the path at the line
                u = ((position[f - 1] + (p - position[f - 1]) * where[:, None]) - a) @ t
                bad = crossing & (u >= 0) & (u <= np.hypot(*(b - a)))
            else:
                bad = COLLIDERS[s.kind].depth(p, s) > PENETRATION
            if np.any(bad):
                return f"tunnelled (static {k}, frame {f})"
    return None


def detect_area_drift(area, target, time) -> str | None:
    late = time >= SETTLE
    if not late.any():
        return None
    worst = float(np.max(np.abs(np.abs(area[late]) / target - 1.0)))
    return f"area drift {100 * worst:.0f}%" if worst > AREA_DRIFT else None


def detect_energy_growth(kinetic, position, vertex_mass, gravity, time) -> str | None:
    late = np.flatnonzero(time >= SETTLE)
    if len(late) < 2:
        return None
    potential = -(position @ gravity) @ vertex_mass  # (frames,): Σ m (-g · x)
    energy = kinetic.sum(axis=1) + potential
    e0 = energy[late[0]]
    scale = max(abs(e0), float(np.abs(gravity).max() * vertex_mass.sum()), 1e-9)
    rise = float(energy[late].max() - e0)
    return f"energy growth {rise:.3g} J" if rise > ENERGY_GROWTH * scale else None


def judge(path, status: str) -> list[str]:
    """All failures of a recorded stress run."""
    t = read_trajectory(path)
    scene = parse_scene(t.scene, str(path))
    failures = []
    reason = detect_nonfinite(status, t.position)
    if reason:
        return [reason]
    offsets = t.offsets
    counts = np.diff(offsets)
    vertex_mass = np.repeat(t.mass / counts, counts)
    rest_sign = np.sign(ring_areas(t.position[:1], offsets)[0])
    for reason in (detect_inside_out(t.position, offsets, rest_sign),
                   detect_tunnelled(t.position, scene.statics),
                   detect_area_drift(t.area, t.target_area, t.time),
                   # a moving collider does work on the blobs: their energy may rise, and is not checked
                   None if any(s.moves for s in scene.statics) else
                   detect_energy_growth(t.kinetic_energy, t.position, vertex_mass, np.array(scene.settings.gravity),
                                        t.time)):
        if reason:
            failures.append(reason)
    return failures


def run_one(scene, method: str, out: Path) -> Verdict:
    from ..io.run import simulate
    scene = with_overrides(scene, method=method)
    scene = replace(scene, output=replace(scene.output, every=RECORD_EVERY))
    result = simulate(scene, out)
    return Verdict(scene.name, method, judge(out, result.status), result.wall_time)


def stress_scenes(quick: bool):
    for path in sorted(STRESS_DIR.glob("*.toml")):
        scene = load_scene(path)
        yield with_overrides(scene, duration=0.5) if quick else scene


def inputs() -> list[tuple[Path, str]]:
    """The files `blobsim stress` reads: its scenes."""
    return [(path, "a stress scene") for path in sorted(STRESS_DIR.glob("*.toml"))]


def output_files(out_dir, methods, quick: bool) -> list[Path]:
    """Every file `blobsim stress` writes in `out_dir` (each run's beside the lock it holds): the table, CSV and
    map, each scene's run with each method, and the map's runs (removed once judged)."""
    out_dir = Path(out_dir)
    dts, knobs = map_axes(quick)
    runs = [f"{scene.name}_{method}.h5" for scene in stress_scenes(quick) for method in methods]
    runs += [f"map-{k}.h5" for k in range(sum(len(dts) * len(knobs[m][1]) for m in methods))]
    return [*(out_dir / name for name in ("stress.csv", "stress.md", "stability_map.json", "stability_map.png")),
            *(out_dir / f"{run}{lock}" for run in runs for lock in ("", ".lock"))]


def map_axes(quick: bool) -> tuple[list, dict]:
    """The stability map's dts and, per method, the stiffness it varies and its values."""
    dts = [1 / 240, 1 / 60] if quick else [1 / 240, 1 / 120, 1 / 60, 1 / 30, 1 / 15]
    knobs = {"kot": ("pressure", [1.0, 2.0] if quick else [0.7, 1.0, 1.5, 2.0, 3.0]),
             "xpbd": ("pressure", [1.0, 2.0] if quick else [0.7, 1.0, 1.5, 2.0, 3.0]),
             "gas": ("gas_pressure", [20.0, 500.0] if quick else [5.0, 20.0, 100.0, 500.0, 2000.0]),
             "springs": ("spring_stiffness", [2e3, 2e5] if quick else [5e2, 2e3, 2e4, 2e5, 2e6])}
    return dts, knobs


def stability_map(methods, out_dir: Path, quick: bool, scheduler=None, workers=0) -> dict:
    """Pass/fail of a blob dropped on a floor and a bump, over dt × each method's stiffness, each step one substep
    (max_substeps = 1: the method's own stability, without the steps' added substeps)."""
    dts, knobs = map_axes(quick)
    cells, tasks = [], []
    for method in methods:
        knob, values = knobs[method]
        for dt in dts:
            for v in values:
                text = f"""
[scene]
duration = {0.5 if quick else 2.0}
dt = {dt!r}
substeps = 1
max_substeps = 1
[[blob]]
center = [0.1, 1.0]
radius = 0.4
velocity = [0.0, -3.0]
{knob} = {v!r}
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "circle"
center = [0.0, 0.0]
radius = 0.2
"""
                cells.append((method, dt, v))
                tasks.append((parse_scene(text, f"map-{method}"), method, out_dir / f"map-{len(tasks)}.h5"))
    grid = {}
    for i, verdict in run_tasks(run_one, tasks, scheduler, workers, label="map"):
        grid[cells[i]] = verdict.failures
        tasks[i][2].unlink(missing_ok=True)
    return {"dts": dts, "knobs": knobs, "grid": grid}


def chart_map(smap: dict, methods, png: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(methods), figsize=(3.4 * len(methods), 3.2), squeeze=False)
    dts = smap["dts"]
    for ax, method in zip(axes[0], methods):
        knob, values = smap["knobs"][method]
        for i, dt in enumerate(dts):
            for j, v in enumerate(values):
                failures = smap["grid"][(method, dt, v)]
                ax.add_patch(plt.Rectangle((i, j), 1, 1, color="#7fc97f" if not failures else "#f0776a"))
                label = "ok" if not failures else failures[0].split(" (")[0].split(" ")[0]
                ax.text(i + 0.5, j + 0.5, label, ha="center", va="center", fontsize=6)
        ax.set_xlim(0, len(dts))
        ax.set_ylim(0, len(values))
        ax.set_xticks(np.arange(len(dts)) + 0.5, [f"1/{round(1 / d)}" for d in dts], fontsize=7)
        ax.set_yticks(np.arange(len(values)) + 0.5, [f"{v:g}" for v in values], fontsize=7)
        ax.set_xlabel("dt (s), 1 substep", fontsize=8)
        ax.set_ylabel(knob, fontsize=8)
        ax.set_title(method, fontsize=9)
    fig.suptitle("stability map: a blob dropped at 3 m/s onto a floor and a bump (2 s)", fontsize=9)
    fig.tight_layout()
    with replaced(png) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def run_stress(methods=METHODS, out_dir="outputs/stress", quick=False, scheduler=None, workers=0) -> dict:
    """Every stress scene with every method, then the stability map; the runs go through the
    executor (workers = 0: in this process)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tasks = [(scene, method, out_dir / f"{scene.name}_{method}.h5") for scene in stress_scenes(quick)
             for method in methods]
    verdicts = [None] * len(tasks)
    for i, verdict in run_tasks(run_one, tasks, scheduler, workers, label="runs"):
        verdicts[i] = verdict
    smap = stability_map(methods, out_dir, quick, scheduler, workers)
    chart_map(smap, methods, out_dir / "stability_map.png")
    with replaced(out_dir / "stress.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scene", "method", "passed", "failures", "wall_time_s"])
        for v in verdicts:
            w.writerow([v.scene, v.method, v.passed, "; ".join(v.failures), f"{v.wall_time:.3f}"])
    table = format_table(verdicts, methods)
    write_text(out_dir / "stress.md", table + "\n")
    write_text(out_dir / "stability_map.json", json.dumps(
        {f"{m} dt={dt:g} {smap['knobs'][m][0]}={v:g}": fails for (m, dt, v), fails in smap["grid"].items()}, indent=1))
    return {"verdicts": verdicts, "map": smap, "table": table, "out_dir": out_dir}


def format_table(verdicts, methods) -> str:
    scenes = list(dict.fromkeys(v.scene for v in verdicts))
    cells = {(v.scene, v.method): v.cell() for v in verdicts}
    lines = ["| scene | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for s in scenes:
        lines.append(f"| {s} | " + " | ".join(cells[(s, m)] for m in methods) + " |")
    return "\n".join(lines)
