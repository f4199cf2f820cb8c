"""`blobsim jam`: compress a scene's packing until it jams (sim/jamming.py), from one random start or
from many on Dask, and report φ_J, z_J and the pressure as the soft-matter codes do.

Seed k's start is the scene with `[scene] seed` = the scene's seed + k (its blobs with `count` placed
anew); each runs on a worker (tools/executor.py) and writes DIR/seed-<seed>.h5: one frame per packing
the protocol brought to rest, in order (the compression, the bisection, then the packings past onset),
the box shrinking frame by frame; its last bisection frame is the jammed packing. The figures over all
seeds are mean ± standard error (the standard deviation over √K).

Past onset, z - z_J against φ - φ_J is fitted as a power law (least squares in log-log): the exponent β
(1/2 for soft discs, O'Hern et al. 2003). For one seed, over its packings past onset whose z rose; in the
mean, over the seeds' mean z - z_J at each Δφ (every seed, none dropped), as the soft-disc papers average
over configurations before they fit: a seed's z - z_J just past onset is a small difference of two noisy
counts, and the log of it, pooled, weighs that noise more than the trend (docs/jamming.md).
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import replace
from pathlib import Path

from ..scene.schema import Scene, SceneError, parse_scene, resolved_toml

SEED_MAX = 2 ** 63 - 1  # [scene] seed at most (scene/schema.py)

DEFAULT_PRESSURE = 3e-6  # p̃* = p* ᾱ: as near zero as the relaxation resolves (sim/jamming.py)
DEFAULT_DRAG = 1.0  # 1/s: the relaxation's drag when the scene has none
MAX_SEEDS = 10_000  # --seeds at most: each seed is a task, a trajectory file and a row of the JSON
KEYS = ("phi_j", "z_j", "z_j_touching", "z_j_all", "pressure", "reduced_pressure", "rattlers", "balance",
        "beta")  # per seed, in the JSON


def jam_problem(scene: Scene, seeds: int = 1) -> tuple[tuple, str] | None:
    """Why this scene cannot be jammed from `seeds` starts, or None: (the key's path, as `check` names it, what
    is wrong)."""
    if scene.settings.periodic is None:
        return ("scene", "periodic"), "jam compresses a periodic box: the scene needs [scene] periodic = [Lx, Ly]"
    if len(scene.statics) > 0:
        return ("static", 0), "jam compresses blobs alone: the scene has [[static]] colliders"
    if scene.schedules:
        return ("schedule", 0), "jam changes the box itself: the scene has [[schedule]] tables"
    if scene.blob_count < 2:
        return ("blob", 0), "jam needs more than one blob"
    soft = [i for i, b in enumerate(scene.blobs) if b.compliance == 0.0]
    if soft:
        return (("blob", soft[0], "compliance"), "jam measures pressure in units of the blobs' perimeter compliance: "
                "a blob has compliance = 0 (inextensible)")
    last = scene.settings.seed + seeds - 1
    if last > SEED_MAX:
        return (("scene", "seed"), f"the seeds run to {scene.settings.seed} + {seeds} - 1 = {last} with --seeds "
                f"{seeds}; at most {SEED_MAX}")
    return None


def seed_scene(scene: Scene, seed: int) -> Scene:
    """The scene with this placement seed (and a drag, if it has none), as its resolved TOML reads back."""
    s = replace(scene.settings, seed=seed, drag=scene.settings.drag or DEFAULT_DRAG)
    text = resolved_toml(replace(scene, settings=s))
    return parse_scene(text, scene.source)


def output_files(out: Path, scene: Scene, seeds: int) -> list[Path]:
    """Every file `run_jam` and the command write in `out`: summary.json, chart.png, then each seed's trajectory."""
    first = scene.settings.seed
    return [out / "summary.json", out / "chart.png", *(out / f"seed-{seed}.h5" for seed in range(first, first + seeds))]


def run_seed(base: Scene, seed: int, target: float, h5: str) -> dict:
    """Jam the scene's start from `seed` (on a worker; its copies placed here, so that no seed's scene is made
    before its turn): its figures, with status ok / interrupted / failed: reason."""
    import numpy as np

    from ..io import interrupts
    from ..io.h5md import TrajectoryWriter
    from ..io.threads import ThreadChoice
    from ..sim import jamming
    from ..sim.measure import blob_measures
    from ..sim.model import build, build_params
    if threading.current_thread() is not threading.main_thread():
        interrupts.clear()  # a Dask worker: a stop asked of an earlier task is not for this one
    try:
        scene = seed_scene(base, seed)
    except SceneError as e:  # its copies find no place: this seed fails, the others go on
        return {"seed": seed, "status": f"failed: {e.problems[0]}", "file": h5, "path": []}
    model, state = build(scene)
    params = build_params(scene)
    row = {"seed": scene.settings.seed, "status": "failed", "file": h5, "path": []}
    writer = TrajectoryWriter(h5, scene, model, params, box_changes=True)
    writer.file.attrs["jam_force_balance_tolerance"] = jamming.BALANCE
    steps = 0

    def record(found, state, params):
        nonlocal steps
        steps += found.steps
        area, kinetic = blob_measures(state, model)
        writer.append(steps, state, area, kinetic, box=params.box)
        row["path"].append(found._asdict())
        writer.file.attrs["jam_balance"] = np.array([p["balance"] for p in row["path"]])

    try:  # a signal is only recorded, and stops the seed between two compiled calls (chosen_threads)
        with interrupts.deferred(), ThreadChoice(None, model.parallel) as choice:
            result = jamming.jam(state, model, params, target, on_packing=record, run=chosen_threads(choice))
    except KeyboardInterrupt:
        writer.close(complete=False, stopped=f"stopped by signal {interrupts.pending()}")
        row["status"] = "interrupted"
        return row
    except ValueError as e:  # jammed as placed, or not below φ = 1
        writer.close(complete=False, stopped=str(e))
        row["status"] = f"failed: {e}"
        return row
    except OSError as e:  # the trajectory cannot be written (a full disk): the seed fails, the others go on
        row["status"] = f"failed: writing {h5}: {e}; {writer.salvage(str(e))}"
        return row
    writer.close(complete=True)
    j = result.jammed
    past = [p._asdict() for p in result.past]
    row.update(status="ok", phi_j=j.phi, z_j=j.z, z_j_touching=j.z_touching, z_j_all=j.z_all, pressure=j.pressure,
               reduced_pressure=j.reduced, balance=j.balance,
               rattlers=j.rattlers, beta=contact_exponent(excess_contacts(j._asdict(), past)), past=past)
    return {k: (float(v) if isinstance(v, np.floating) else v) for k, v in row.items()}


def excess_all(jammed: dict, past: list[dict]) -> list[tuple[float, float]]:
    """(φ - φ_J, z - z_J) of each packing past onset, in order."""
    return [(p["phi"] - jammed["phi"], p["z"] - jammed["z"]) for p in past]


def excess_contacts(jammed: dict, past: list[dict]) -> list[tuple[float, float]]:
    """(φ - φ_J, z - z_J) of the packings past onset whose z rose."""
    return [(x, y) for x, y in excess_all(jammed, past) if y > 0.0 and x > 0.0]


def chosen_threads(choice):
    """pipeline.advance, each call on the threads `choice` (io/threads.py) plans: one thread while the
    machine is busy (two runs side by side on two threads each ran 20-60× slower than alone). A pending
    signal (io/interrupts.py) stops it between calls, as KeyboardInterrupt."""
    import time

    from ..io import interrupts
    from ..sim.pipeline import advance

    def run(state, model, params, steps, step_settings=None):
        while steps > 0:
            if interrupts.pending() is not None:
                raise KeyboardInterrupt
            threads, count = choice.plan(steps)
            t0, cpu0 = time.perf_counter(), time.process_time()
            ran = advance(state, model, params, count, step_settings=step_settings)
            choice.observe(threads, ran, time.perf_counter() - t0, time.process_time() - cpu0)
            steps -= count
    return run


def mean_excess_contacts(rows: list[dict]) -> list[tuple[float, float]]:
    """(φ - φ_J, z - z_J) at each compression past onset, each the mean over the seeds (rows) that have it."""
    import numpy as np
    excess = [excess_all({"phi": r["phi_j"], "z": r["z_j"]}, r.get("past", [])) for r in rows]
    most = max(map(len, excess), default=0)
    return [tuple(float(v) for v in np.mean([e[k] for e in excess if len(e) > k], axis=0)) for k in range(most)]


def contact_exponent(points: list[tuple[float, float]]) -> float:
    """β of z - z_J ∝ (φ - φ_J)^β, least squares in log-log (NaN with fewer than 3 points)."""
    import numpy as np
    if len(points) < 3:
        return math.nan
    x, y = np.log(np.array(points)).T
    return float(np.polyfit(x, y, 1)[0])


def summary(rows: list[dict]) -> dict:
    """The JSON: every seed's figures, and their mean with the standard errors of φ_J and z_J."""
    import numpy as np
    ok = [r for r in rows if r["status"] == "ok"]
    seeds = [{"seed": r["seed"], **{k: r[k] for k in KEYS}} for r in ok]
    mean = {}
    if ok:
        for k in KEYS[:-1]:  # (β: below)
            values = np.array([r[k] for r in ok], dtype=float)
            mean[k] = float(values.mean())
        for k in ("phi_j", "z_j"):
            values = np.array([r[k] for r in ok])
            mean[f"{k}_sem"] = float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else math.nan
        # one fit of the seeds' mean z - z_J at each Δφ (a seed's own few scatter with its z_J)
        mean["beta"] = contact_exponent([(x, y) for x, y in mean_excess_contacts(ok) if y > 0.0 and x > 0.0])
    from ..sim.jamming import BALANCE
    from ..sim.packing import BEARING
    return {"seeds": seeds, "mean": mean, "force_balance_tolerance": BALANCE, "bearing_fraction": BEARING}


def report(figures: dict) -> str:
    """The printed lines of the summary."""
    m = figures["mean"]
    if not m:
        return "no seed jammed"
    k = len(figures["seeds"])
    pm = "" if k < 2 else " ± {:.4f}"
    fit = (f"z - z_J ~ (phi - phi_J)^{m['beta']:.2f}" if math.isfinite(m["beta"])
           else "no fit of z - z_J against phi - phi_J (fewer than 3 points past onset with z rising)")
    return (f"phi_J = {m['phi_j']:.4f}{pm.format(m['phi_j_sem'])}, "
            f"z_J = {m['z_j']:.3f}{pm.format(m['z_j_sem'])} (contacts that carry force, rattlers removed; "
            f"{m['z_j_touching']:.3f} touching; {m['z_j_all']:.3f} with the rattlers), "
            f"pressure {m['pressure']:.3g} N/m (p alpha = {m['reduced_pressure']:.2e}), "
            f"{m['rattlers']:.1f} rattlers, net force at most {m['balance']:.3f} of the mean push, {fit}; "
            f"{k} seed{'s' if k > 1 else ''}" + (" (mean ± standard error)" if k > 1 else ""))


def run_jam(scene: Scene, out: Path, seeds: int, target: float, scheduler=None, workers=None, progress=False,
            announce=print) -> tuple[list[dict], bool]:
    """Jam `seeds` starts of the scene through the executor; (rows in seed order, interrupted)."""
    from ..io.interrupts import caused_by_signal, pending, request_stop
    from .executor import run_tasks
    out.mkdir(parents=True, exist_ok=True)
    first = scene.settings.seed
    tasks = [(scene, seed, target, str(out / f"seed-{seed}.h5"))
             for seed in range(first, first + seeds)]
    announce(f"blobsim: jam {scene.name}: {seeds} seed{'s' if seeds > 1 else ''} "
             f"({first}..{first + seeds - 1}), p alpha = {target:g}, in {out}")
    rows = {}
    try:
        for i, row in run_tasks(run_seed, tasks, scheduler, workers, progress=progress, label="seeds",
                                stop=request_stop):
            rows[i] = row
            if row["status"] == "interrupted":  # (in this process: the seeds after it are not started)
                announce(f"  seed {row['seed']}: interrupted; its frames are kept in {row['file']}")
                break
            if row["status"] == "ok":
                announce(f"  seed {row['seed']}: phi_J = {row['phi_j']:.4f}, z_J = {row['z_j']:.3f} "
                         f"({row['rattlers']} rattlers), p alpha = {row['reduced_pressure']:.2e}, "
                         f"net force <= {row['balance']:.3f} of the mean push")
            else:
                announce(f"  seed {row['seed']}: {row['status']}")
    except (KeyboardInterrupt, Exception) as e:
        if not caused_by_signal(e):
            raise
        return [rows[k] for k in sorted(rows)], True
    return [rows[k] for k in sorted(rows)], pending() is not None


def write_json(figures: dict, path: Path) -> None:
    """The figures as JSON; a figure that could not be had (a standard error of one seed, an exponent
    without enough packings past onset) is null."""
    from ..io.outputs import write_text

    def plain(x):
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items()}
        if isinstance(x, list):
            return [plain(v) for v in x]
        return None if isinstance(x, float) and not math.isfinite(x) else x
    write_text(path, json.dumps(plain(figures), indent=2) + "\n")


def chart(rows: list[dict], png: Path, target: float) -> None:
    """Pressure and z against φ over each seed's compression (the packings brought to rest), the jammed
    ones marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ok = [r for r in rows if r["status"] == "ok"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    for r in ok:
        tried = sorted(r["path"] + r["past"], key=lambda p: p["phi"])
        phi = [p["phi"] for p in tried]
        line, = top.plot(phi, [max(p["reduced"], 1e-12) for p in tried], ".-", lw=0.8, ms=3)
        bottom.plot(phi, [p["z"] for p in tried], ".-", lw=0.8, ms=3, color=line.get_color())
        top.plot(r["phi_j"], r["reduced_pressure"], "o", mfc="none", color=line.get_color())
        bottom.plot(r["phi_j"], r["z_j"], "o", mfc="none", color=line.get_color())
    top.axhline(target, color="0.6", lw=0.6, ls=":")
    bottom.axhline(4.0, color="0.6", lw=0.6, ls="--")
    top.set_yscale("log")
    top.set_ylabel("pressure p ᾱ")
    bottom.set_ylabel("contacts per blob z (rattlers removed)")  # those that carry force
    bottom.set_xlabel("packing fraction φ")
    top.set_title(f"compression to jamming, {len(ok)} seed{'s' if len(ok) != 1 else ''} (circles: jammed)")
    fig.tight_layout()
    from ..io.outputs import replaced
    with replaced(png) as tmp:  # whole or not at all, and never through a link planted there
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
