"""`blobsim study`: speed against accuracy, per area method, as a work-precision chart.

For each method, every setting of a ladder (dt, substeps, iterations) runs the scene and is
compared with that method's converged reference: the same scene with 16 times as many
substeps (a step 16× smaller) and the same iterations. Each method is measured against its
own reference because each converges to its own physics (a gas blob is not a kot blob).
Frames are compared at common times, so a smaller dt records proportionally less often.

Errors of a run against its reference:
    trajectory   RMS over frames and vertices of |x - x_ref|, divided by the blob's radius
                 (√(A_rest / π))
    area         worst |A / A_target - 1| over the frames after frame 0 (against the target,
                 not the reference: it is what the method promises)
    perimeter    worst |P / P_rest - 1| over the frames after frame 0
Runs are sequential, so that wall times are not disturbed by one another.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..io.h5md import read_trajectory
from ..scene.schema import METHODS, with_overrides
from .executor import run_tasks

# (dt divisor, substeps, iterations), cheapest first
LADDER = [(1, 1, 1), (1, 1, 2), (1, 2, 1), (1, 2, 2), (1, 4, 1), (1, 4, 2), (1, 4, 4), (2, 4, 2), (1, 8, 2),
          (4, 4, 2), (1, 16, 2)]
REFERENCE_FACTOR = 16  # the reference's substeps = 16 × the scene's
FRAMES = 60  # about this many frames are compared


@dataclass
class Point:
    method: str
    dt: float
    substeps: int
    iterations: int
    wall_time: float
    trajectory_error: float
    area_error: float
    perimeter_error: float
    status: str
    divisor: int = 1  # dt = the scene's dt / divisor

    @property
    def label(self) -> str:
        return f"dt/{self.divisor} s{self.substeps} i{self.iterations}"


def _run(scene, out, method, dt, substeps, iterations, every):
    from ..io.run import simulate
    s = replace(scene.settings, method=method, dt=dt, substeps=substeps, iterations=iterations,
                steps=None, duration=scene.settings.duration)
    sc = replace(scene, settings=s, output=replace(scene.output, every=every))
    return simulate(sc, out)


def _perimeters(position, offsets):
    nxt = np.arange(position.shape[1]) + 1
    nxt[offsets[1:] - 1] = offsets[:-1]
    edge = np.linalg.norm(position[:, nxt] - position, axis=-1)
    return np.add.reduceat(edge, offsets[:-1], axis=1)


def errors(run_path, ref_path) -> tuple[float, float, float]:
    run, ref = read_trajectory(run_path), read_trajectory(ref_path)
    n = min(len(run.time), len(ref.time))
    offsets = run.offsets
    radius = np.sqrt(run.target_area / np.pi)  # of the target area; close to the rest radius
    per_vertex_radius = np.repeat(radius, np.diff(offsets))
    dev = np.linalg.norm(run.position[:n] - ref.position[:n], axis=-1) / per_vertex_radius
    trajectory = float(np.sqrt(np.mean(dev ** 2))) if np.all(np.isfinite(dev)) else float("inf")
    area = float(np.max(np.abs(run.area[1:n] / run.target_area - 1.0), initial=0.0))
    rest_perimeter = _perimeters(run.position[:1], offsets)[0]
    perimeter = float(np.max(np.abs(_perimeters(run.position[1:n], offsets) / rest_perimeter - 1.0), initial=0.0))
    return trajectory, area, perimeter


def output_files(out_dir, scene, methods=METHODS) -> list[Path]:
    """Every file `blobsim study` writes in `out_dir` (each run's beside the lock it holds): the chart and CSV,
    and each method's runs, removed once compared."""
    out_dir = Path(out_dir)
    runs = [f"{method}_{name}.h5" for method in methods
            for name in ("reference", "warm", *(f"dt{d}_s{s}_i{i}" for d, s, i in LADDER))]
    return [out_dir / f"{scene.name}_study.csv", out_dir / f"{scene.name}_study.png",
            *(out_dir / f"{run}{lock}" for run in runs for lock in ("", ".lock"))]


def run_study(scene, methods=METHODS, out_dir="outputs/study", duration=None, scheduler=None,
              workers=0) -> list[Point]:
    """Each method's ladder against its own reference; one executor task per method (its runs
    stay on one worker, one after another, so that their wall times compare)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if duration is not None:
        scene = with_overrides(scene, duration=duration)
    settings = scene.settings
    base_dt = settings.dt
    steps = scene.steps
    scene = replace(scene, settings=replace(settings, steps=None, duration=steps * base_dt))
    every = max(1, steps // FRAMES)
    tasks = [(scene, method, out_dir, every) for method in methods]
    by_method = {}
    for i, points in run_tasks(study_method, tasks, scheduler, workers, label="methods"):
        by_method[methods[i]] = points
    return [p for method in methods for p in by_method[method]]


def study_method(scene, method, out_dir: Path, every: int) -> list[Point]:
    """One method's ladder: its reference, a warm-up, then each setting timed and compared."""
    settings, base_dt = scene.settings, scene.settings.dt
    ref = out_dir / f"{method}_reference.h5"
    _run(scene, ref, method, base_dt, settings.substeps * REFERENCE_FACTOR, settings.iterations, every)
    warm = out_dir / f"{method}_warm.h5"
    _run(scene, warm, method, base_dt, 1, 1, every)  # compile before timing
    warm.unlink()
    points = []
    for divisor, substeps, iterations in LADDER:
        out = out_dir / f"{method}_dt{divisor}_s{substeps}_i{iterations}.h5"
        result = _run(scene, out, method, base_dt / divisor, substeps, iterations, every * divisor)
        traj, area, perim = errors(out, ref)
        points.append(Point(method, base_dt / divisor, substeps, iterations, result.wall_time, traj, area, perim,
                            result.status, divisor))
        out.unlink()
    ref.unlink()  # the runs are only needed for their errors: keep the CSV and the chart
    return points


def write_csv(points, path):
    from ..io.outputs import replaced
    with replaced(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["method", "dt_s", "substeps", "iterations", "wall_time_s", "trajectory_error", "area_error",
                    "perimeter_error", "status"])
        for p in points:
            w.writerow([p.method, f"{p.dt:.6g}", p.substeps, p.iterations, f"{p.wall_time:.4f}",
                        f"{p.trajectory_error:.4e}", f"{p.area_error:.4e}", f"{p.perimeter_error:.4e}", p.status])


def chart(points, path, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    floor = 1e-16  # errors of exactly 0 (e.g. kot's area) are drawn at this floor
    for ax, key, name in zip(axes, ("trajectory_error", "area_error", "perimeter_error"),
                             ("trajectory error (RMS / radius)", "worst area error", "worst perimeter error")):
        for method in dict.fromkeys(p.method for p in points):
            pts = sorted((p for p in points if p.method == method and np.isfinite(getattr(p, key))),
                         key=lambda p: p.wall_time)
            if not pts:
                continue
            x = [p.wall_time for p in pts]
            y = [max(getattr(p, key), floor) for p in pts]
            dots = ax.plot(x, y, "o", ms=4, alpha=0.5)[0]
            # the Pareto front: the runs no cheaper run beats
            front = [(xi, yi, p) for xi, yi, p in zip(x, y, pts) if yi < min(y[:x.index(xi)] or [np.inf])]
            ax.plot([f[0] for f in front], [f[1] for f in front], "-", color=dots.get_color(), label=method)
            if key == "trajectory_error":
                for xi, yi, p in front:
                    ax.annotate(p.label, (xi, yi), fontsize=6, alpha=0.8, xytext=(2, 2), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    from ..io.outputs import replaced
    with replaced(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def cheapest(points, tol: float) -> dict:
    """Per method, the fastest setting whose trajectory error is at most `tol` (or None)."""
    out = {}
    for method in dict.fromkeys(p.method for p in points):
        ok = [p for p in points if p.method == method and p.trajectory_error <= tol and p.status == "complete"]
        out[method] = min(ok, key=lambda p: p.wall_time) if ok else None
    return out


def format_points(points) -> str:
    lines = [f"{'method':8s} {'setting':>16s} {'wall s':>8s} {'trajectory':>11s} {'area':>10s} {'perimeter':>10s}"]
    for p in points:
        lines.append(f"{p.method:8s} {p.label:>16s} {p.wall_time:8.3f} {p.trajectory_error:11.2e} "
                     f"{p.area_error:10.2e} {p.perimeter_error:10.2e}"
                     + ("" if p.status == "complete" else f"  {p.status}"))
    return "\n".join(lines)
