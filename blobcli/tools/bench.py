"""`blobsim bench`: how fast blobsim is on this machine, and beside the pymunk peer.

Every figure is a median of several repetitions, measured in one process, so that ratios
compare like with like on a noisy machine. Nothing here is a test: targets are printed
beside the figures, never asserted.
"""

from __future__ import annotations

import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

VERTICES = 32
RADIUS = 0.2  # m
TARGETS = {  # the figure bench reports beside each measurement, for this machine class (2 cores); nothing asserts them
    "core_ns_per_vertex_substep_1000": 20.0,
    "piled_ms_per_substep_1000": 4.0,
    "peer_speedup_piled": 10.0,
    "peer_speedup_240_1x10": 5.0,  # the 100-blob pile at pymunk's settings: dt = 1/240 s, 1 substep, 10 iterations
    "piled_over_apart_1000": 2.0,
    "one_blob_1000_steps_s": 1.0,
    "one_blob_step_us": 1.5,
    "scaling_1000_over_100": 11.0,
    "record_every_step_overhead": 0.10,
    "sweep_speedup_16_points": 3.0,
    "thread_speedup_2": 1.8,
    "sleeping_over_awake": 0.10,
    "walls_share_piston": 0.10,  # share of the piston scene's step spent on its moving walls and colliders
    "side_by_side_over_alone": 2.0,  # two runs of the 60-blob pile started together, each against its time alone
    "beside_busy_over_alone": 2.5,  # one beside a busy-loop process
}


def scene_text(blobs: int, layout: str, settings: str = "", sleep: bool = False) -> str:
    """Blobs of 32 vertices: "apart" in a row on a floor, or "piled" in a box (a grid falling in).
    `settings`: more [scene] lines. Sleeping is off unless asked: the figures are of blobs simulated."""
    head = f"[scene]\nsleep = {'true' if sleep else 'false'}\n{settings}\n"
    if layout == "apart":
        return head + f"""
[[blob]]
name = "b"
center = [0.0, {RADIUS + 0.001}]
radius = {RADIUS}
vertices = {VERTICES}
grid = [{blobs}, 1]
spacing = [{4 * RADIUS}, 0.0]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""
    # cols × rows = blobs exactly, the box about 1.6 times as wide as the pile is deep
    cols = min((d for d in range(1, blobs + 1) if blobs % d == 0), key=lambda d: abs(d - math.sqrt(1.6 * blobs)))
    rows = blobs // cols
    width = cols * 2 * RADIUS
    return head + f"""
[[blob]]
name = "b"
center = [{-width / 2 + RADIUS}, {RADIUS + 0.001}]
radius = {RADIUS}
vertices = {VERTICES}
grid = [{cols}, {rows}]
spacing = [{2 * RADIUS}, {2.1 * RADIUS}]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "box"
center = [{-width / 2 - 0.1}, {rows * RADIUS * 2.2}]
size = [0.2, {rows * RADIUS * 4.4 + 1.0}]
[[static]]
kind = "box"
center = [{width / 2 + 0.1}, {rows * RADIUS * 2.2}]
size = [0.2, {rows * RADIUS * 4.4 + 1.0}]
"""


def _median_time(fn, repeats: int, inner: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner)
    return statistics.median(times)


PEER_SETTINGS = f"dt = {1 / 240!r}\nsubsteps = 1\niterations = 10"  # pymunk's usual step and its 10 iterations


def measure_blobsim(blobs: int, layout: str, repeats: int, settle_steps: int, settings_: str = "") -> dict:
    """ms per step (and per substep, per vertex-substep) of `blobs` blobs, after `settle_steps` steps;
    `settings_`: more [scene] lines."""
    from ..scene.schema import parse_scene
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance, settings
    scene = parse_scene(scene_text(blobs, layout, settings_), f"bench-{layout}-{blobs}")
    model, state = build(scene)
    params = build_params(scene)
    step_settings = settings(model, params)
    advance(state, model, params, max(settle_steps, 1))  # piled: let them fall into a pile first
    inner = max(1, min(1000, 20000 // (blobs * VERTICES // 32 + 1)))  # steps per call (one bc_advance runs them all)
    sec = _median_time(lambda: advance(state, model, params, inner, step_settings=step_settings), repeats, 1) / inner
    n = model.vertex_count
    return {"blobs": blobs, "layout": layout, "vertices": n, "ms_per_step": sec * 1e3,
            "ms_per_substep": sec * 1e3 / params.substeps,
            "vertex_substeps_per_s": n * params.substeps / sec,
            "ns_per_vertex_substep": sec * 1e9 / (n * params.substeps)}


CORE_STAGES = ("predict", "perimeter", "area", "statics", "velocities", "restitution")


def _profile(scene_text_: str, name: str, settle_steps: int, steps: int) -> tuple[dict, int, object]:
    """Seconds per step by stage of the real step (pipeline.advance with a clock), after settling."""
    from ..scene.schema import parse_scene
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance
    scene = parse_scene(scene_text_, name)
    model, state = build(scene)
    params = build_params(scene)
    advance(state, model, params, settle_steps)
    advance(state, model, params, 1, {})  # one clocked step untimed: the step's views and scratch are made
    clock, contacts = {}, []
    for _ in range(steps):
        advance(state, model, params, 1, clock)
        contacts.append(int((state.c_edge >= 0).sum()))
    return {k: v / steps for k, v in clock.items()}, int(np.median(contacts)), (model, params)


def measure_threads(blobs: int, steps: int) -> dict:
    """The core substep of blobs apart on one thread and on every thread the step may use."""
    from ..core import load
    from ..io.threads import available
    lib = load()[1]
    threads, before = available(), lib.bc_threads()
    out = {}
    for n in sorted({1, threads}):
        lib.bc_set_threads(n)
        try:
            out[n] = measure_core(blobs, steps)["ns_per_vertex_substep"]
        finally:
            lib.bc_set_threads(before)
    return {"blobs": blobs, "threads": threads, "ns_by_threads": out, "speedup": out[1] / out[threads]}


def measure_one_blob_step(repeats: int) -> dict:
    """µs per step of one blob on a floor at the defaults, 1,000 steps per call of advance (one call of the
    core's bc_advance): what `study`, `stress` and small scenes pay per step, Python outside the loop."""
    from ..scene.schema import parse_scene
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance, settings
    scene = parse_scene(scene_text(1, "apart"), "bench-one")
    model, state = build(scene)
    params = build_params(scene)
    step_settings = settings(model, params)
    advance(state, model, params, 10)
    sec = _median_time(lambda: advance(state, model, params, 1000, step_settings=step_settings), repeats, 1) / 1000
    return {"us_per_step": sec * 1e6}


def measure_core(blobs: int, steps: int) -> dict:
    """The core substep (CORE_STAGES; the floor is the statics stage) of blobs apart on a floor,
    taken from the real step's stage clock; the blob-blob stages and damping are not counted."""
    per_step, _, (model, params) = _profile(scene_text(blobs, "apart"), "bench-core", 0, steps)
    sec = sum(per_step.get(k, 0.0) for k in CORE_STAGES) / params.substeps
    return {"blobs": blobs, "ns_per_vertex_substep": sec * 1e9 / model.vertex_count, "us_per_substep": sec * 1e6}


def measure_stages(blobs: int, settle_steps: int) -> dict:
    """Where a piled step's time goes: ms per step for each stage of the real step, and the
    number of vertices in blob contact after an iteration."""
    per_step, contacts, (model, _) = _profile(scene_text(blobs, "piled"), "bench-stages", settle_steps, 5)
    return {"blobs": blobs, "ms_per_step": {k: 1e3 * v for k, v in per_step.items()},
            "contacts_per_iteration": contacts, "vertices": model.vertex_count}


PISTON = Path(__file__).resolve().parents[2] / "scenes" / "piston.toml"  # the loaded wall measure_walls times


def inputs() -> list[tuple[Path, str]]:
    """The files `blobsim bench` reads (its other scenes it writes itself, in a temporary directory)."""
    return [(PISTON, "a scene bench measures")]


def measure_walls(settle_steps: int, steps: int) -> dict:
    """What scenes/piston.toml's loaded piston costs (stage clock, after settling): the walls stage (moving it)
    and the collider stage (every collider's contacts, the piston's share of its pushes, the forces), against
    the same scene with the piston fixed where it comes to rest."""
    text = PISTON.read_text()
    fixed = text.replace("center = [0.0, 2.6]", "center = [0.0, 1.3523]")
    for line in ("load = 200.0", "load_direction = [0.0, -1.0]", "mass = 5.0"):
        fixed = fixed.replace(line + "\n", "")
    per_step, _, _ = _profile(text, "bench-piston", settle_steps, steps)
    per_fixed, _, _ = _profile(fixed, "bench-piston-fixed", settle_steps, steps)
    total = sum(per_step.values())
    extra = per_step["walls"] + per_step["statics"] - per_fixed["statics"]
    return {"ms_per_step": 1e3 * total, "walls_ms": 1e3 * per_step["walls"], "statics_ms": 1e3 * per_step["statics"],
            "statics_fixed_ms": 1e3 * per_fixed["statics"], "share": extra / total}


def measure_sleeping(blobs: int, settle_steps: int, steps: int) -> dict:
    """A pile settled with sleeping on: the share asleep, and the cost of a step asleep against the same
    pile (same positions) with every blob woken and sleeping off."""
    from dataclasses import replace

    from ..scene.schema import parse_scene
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance, settings
    scene = parse_scene(scene_text(blobs, "piled", sleep=True), "bench-sleeping")
    model, state = build(scene)
    params = build_params(scene)
    advance(state, model, params, settle_steps)
    asleep = 1.0 - float(state.awake.mean())
    sleeping = settings(model, params)
    sec_asleep = _median_time(lambda: advance(state, model, params, steps, step_settings=sleeping), 3, 1) / steps
    state.awake[:] = 1
    awake = settings(model, replace(params, sleep=False))
    sec_awake = _median_time(lambda: advance(state, model, params, steps, step_settings=awake), 3, 1) / steps
    return {"blobs": blobs, "asleep": asleep, "settled_s": settle_steps * params.dt,
            "ms_per_step_asleep": sec_asleep * 1e3, "ms_per_step_awake": sec_awake * 1e3,
            "ratio": sec_asleep / sec_awake}


def measure_peer(blobs: int, layout: str, repeats: int, settle_steps: int, settings_: str = "") -> dict | None:
    """pymunk (Chipmunk2D): each blob a ring of 32 small circles joined by damped springs,
    with spokes to a centre body, at its 10 iterations; same counts, layouts, dt and substeps as
    blobsim (`settings_`: more [scene] lines)."""
    try:
        import pymunk
    except ImportError:
        return None
    space = pymunk.Space()
    space.gravity = (0.0, -9.81)
    space.iterations = 10
    floor = pymunk.Segment(space.static_body, (-1e4, 0.0), (1e4, 0.0), 0.01)
    floor.friction = 0.5
    space.add(floor)
    from ..colliders import polygon_outline
    from ..scene.schema import parse_scene
    from ..sim.model import build
    scene = parse_scene(scene_text(blobs, layout, settings_), "bench-peer")
    for s in scene.statics:
        if s.kind == "box":
            wall = pymunk.Poly(space.static_body, [tuple(p) for p in polygon_outline(s)])
            wall.friction = 0.5
            space.add(wall)
    model, state = build(scene)
    ring_mass, edge = 1.0 / VERTICES, 2 * math.pi * RADIUS / VERTICES
    stiffness, damping = 2000.0, 5.0
    for b in range(model.blob_count):
        ring = state.pos[model.offsets[b]:model.offsets[b + 1]]
        centre = pymunk.Body(0.2, pymunk.moment_for_circle(0.2, 0, RADIUS / 4))
        centre.position = tuple(ring.mean(axis=0))
        group = pymunk.ShapeFilter(group=b + 1)  # a blob's own parts do not collide
        core = pymunk.Circle(centre, RADIUS / 4)
        core.filter = group
        space.add(centre, core)
        bodies = []
        for x, y in ring:
            body = pymunk.Body(ring_mass, pymunk.moment_for_circle(ring_mass, 0, edge / 2))
            body.position = (x, y)
            shape = pymunk.Circle(body, edge / 2)
            shape.friction, shape.filter = 0.5, group
            space.add(body, shape)
            bodies.append(body)
        for i, body in enumerate(bodies):
            nxt = bodies[(i + 1) % len(bodies)]
            space.add(pymunk.DampedSpring(body, nxt, (0, 0), (0, 0), edge, stiffness, damping),
                      pymunk.DampedSpring(body, centre, (0, 0), (0, 0), RADIUS, stiffness, damping))
    dt, substeps = scene.settings.dt, scene.settings.substeps

    def step():
        for _ in range(substeps):
            space.step(dt / substeps)
    for _ in range(settle_steps):
        step()
    inner = max(1, min(20, 2000 // blobs))
    sec = _median_time(step, repeats, inner)
    return {"blobs": blobs, "layout": layout, "ms_per_step": sec * 1e3}


def measure_floor(blobs: int, settings_: str) -> dict:
    """The same blobs apart on the floor at these settings: no blob contacts, so the least any piled step
    of theirs can cost; with the stage clock's ms per step of its costliest stage."""
    apart = measure_blobsim(blobs, "apart", 3, 1, settings_)
    per_step, _, _ = _profile(scene_text(blobs, "apart", settings_), "bench-floor", 1, 20)
    stage = max(per_step, key=per_step.get)
    return {"apart_ms_per_step": apart["ms_per_step"], "apart_top_stage": stage,
            "apart_top_stage_ms": 1e3 * per_step[stage], "apart_clocked_ms": 1e3 * sum(per_step.values())}


def _run_seconds(args, env) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "blobcli", *args], check=True, env=env, capture_output=True)
    return time.perf_counter() - t0


def measure_startup(repeats: int) -> dict:
    """Wall time of `blobsim run` on a one-blob, 1,000-step scene, each run a new process from start to exit:
    Python's start, the imports, the compiled core loaded (nothing is compiled at run time), the run, the
    file written. The median of `repeats` runs."""
    with tempfile.TemporaryDirectory() as d:
        scene = Path(d) / "one.toml"
        scene.write_text(scene_text(1, "apart", "steps = 1000"))
        out = str(Path(d) / "one.h5")
        runs = [_run_seconds(["run", str(scene), "-o", out, "-q"], dict(os.environ)) for _ in range(repeats)]
    return {"run_s": statistics.median(runs)}


def measure_recording(blobs: int, steps: int, repeats: int) -> dict:
    """Run time with every step recorded versus every 10th (the writer's share of a run)."""
    from dataclasses import replace

    from ..io.run import simulate
    from ..scene.schema import parse_scene
    base = parse_scene(scene_text(blobs, "apart", f"steps = {steps}"), "bench-record")
    out = {}
    with tempfile.TemporaryDirectory() as d:
        for every in (1, 10):
            scene = replace(base, output=replace(base.output, every=every))
            simulate(scene, Path(d) / "warm.h5")
            out[every] = statistics.median(simulate(scene, Path(d) / f"e{every}.h5").wall_time for _ in range(repeats))
    return {"blobs": blobs, "steps": steps, "every_1_s": out[1], "every_10_s": out[10],
            "overhead": out[1] / out[10] - 1.0}


def measure_memory(blobs: int, steps: int) -> dict:
    """Peak resident memory (MiB) of `blobsim run` for a run and one 4× as long."""
    peaks = {}
    with tempfile.TemporaryDirectory() as d:
        scene = Path(d) / "m.toml"
        for n in (steps, 4 * steps):
            scene.write_text(scene_text(blobs, "apart", f"steps = {n}"))
            code = ("import resource, sys; from blobcli.cli import main; main(sys.argv[1:]); "
                    "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
            r = subprocess.run([sys.executable, "-c", code, "run", str(scene), "-o", str(Path(d) / "m.h5"), "-q"],
                               check=True, capture_output=True, text=True)
            peaks[n] = int(r.stdout.split()[-1]) / 1024
    return {"blobs": blobs, "steps": steps, "peak_mib": peaks[steps], "peak_mib_4x_steps": peaks[4 * steps]}


def measure_sweep(points: int, steps: int) -> dict:
    """`points` one-blob runs of `steps` steps: through `blobsim sweep` on the local cluster,
    against as many `blobsim run` processes one after another (what a shell loop does)."""
    with tempfile.TemporaryDirectory() as d:
        base = Path(d) / "one.toml"
        base.write_text(scene_text(1, "apart", f"steps = {steps}"))
        frictions = [0.1 + 0.5 * k / points for k in range(points)]
        sweep = Path(d) / "bench.toml"
        sweep.write_text(f'[sweep]\nscene = "one.toml"\n[[sweep.axis]]\nkey = "blob[*].friction"\n'
                         f'values = {frictions!r}\n')
        loop = 0.0
        for k, friction in enumerate(frictions):
            scene = Path(d) / f"p{k}.toml"
            scene.write_text(base.read_text().replace('name = "b"', f'name = "b"\nfriction = {friction!r}'))
            loop += _run_seconds(["run", str(scene), "-o", str(Path(d) / f"p{k}.h5"), "-q"], dict(os.environ))
        swept = _run_seconds(["sweep", str(sweep), "-o", str(Path(d) / "out"), "-q"], dict(os.environ))
    return {"points": points, "steps": steps, "loop_s": loop, "sweep_s": swept, "speedup": loop / swept}


def _start_run(scene: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "blobcli", "run", str(scene), "-o", str(out), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _run_wall(proc: subprocess.Popen) -> float:
    """The run's own wall time, from its summary line ("... simulated in X s ..."): not Python's start-up."""
    out, err = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"bench run failed: {err.strip()}")
    return float(out.split(" simulated in ")[1].split(" s ")[0])


def measure_busy(blobs: int, steps: int, tries: int) -> dict:
    """`blobsim run` of the piled scene (sleeping off, default threads: auto) alone, two started
    together, and one beside a busy-loop process (io/threads.py): the median alone, and the worst
    run of `tries` tries side by side and beside the busy loop."""
    with tempfile.TemporaryDirectory() as d:
        scene = Path(d) / "pile.toml"
        scene.write_text(scene_text(blobs, "piled", f"steps = {steps}"))
        _run_wall(_start_run(scene, Path(d) / "first.h5"))  # the files in the page cache, as for the runs timed
        alone, pair, busy = [], [], []
        for k in range(tries):
            alone.append(_run_wall(_start_run(scene, Path(d) / f"a{k}.h5")))
            both = [_start_run(scene, Path(d) / f"p{k}{j}.h5") for j in range(2)]
            pair += [_run_wall(p) for p in both]
            loop = subprocess.Popen([sys.executable, "-c", "while True: pass"])
            try:
                busy.append(_run_wall(_start_run(scene, Path(d) / f"b{k}.h5")))
            finally:
                loop.kill()
                loop.wait()
    solo = statistics.median(alone)
    return {"blobs": blobs, "steps": steps, "tries": tries, "alone_s": solo, "side_by_side_s": pair,
            "beside_busy_s": busy, "side_by_side_over_alone": max(pair) / solo,
            "beside_busy_over_alone": max(busy) / solo}


def run_bench(quick: bool = False) -> dict:
    counts = (1, 10) if quick else (1, 10, 100, 1000)
    repeats = 3 if quick else 5
    results = {"quick": quick, "machine": os.uname().machine, "cores": os.cpu_count(), "rows": [], "peer": [],
               "targets": TARGETS}
    for layout in ("apart", "piled"):
        for n in counts:
            settle = 0 if layout == "apart" else (30 if quick else 120)
            results["rows"].append(measure_blobsim(n, layout, repeats, settle))
            peer = None if quick else measure_peer(n, layout, 3, settle)
            if peer:
                results["peer"].append(peer)
    if not quick:  # both at pymunk's own settings
        ours, peer = (measure(100, "piled", 3, 4 * 120, PEER_SETTINGS) for measure in (measure_blobsim, measure_peer))
        results["peer_240"] = {"ms_per_step": ours["ms_per_step"], "peer_ms_per_step": peer["ms_per_step"],
                               **measure_floor(100, PEER_SETTINGS)} if peer else None
    results["core"] = measure_core(counts[-1], 10 if quick else 40)
    results["one_blob"] = measure_one_blob_step(repeats)
    results["threads"] = measure_threads(counts[-1], 10 if quick else 40)
    results["busy"] = measure_busy(60, 200 if quick else 600, 1 if quick else 5)
    results["stages"] = measure_stages(counts[-1], 30 if quick else 120)
    results["walls"] = measure_walls(60, 20 if quick else 200)
    results["sleeping"] = measure_sleeping(counts[-1], 240 if quick else 1500, 5 if quick else 20)
    results["startup"] = measure_startup(2 if quick else 5)
    results["recording"] = measure_recording(10 if quick else 100, 50 if quick else 600, 1 if quick else 3)
    results["memory"] = measure_memory(10 if quick else 100, 100 if quick else 1000)
    results["sweep"] = measure_sweep(1 if quick else 16, 10 if quick else 300)
    results["peak_rss_mib_bench"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return results


def format_bench(r: dict) -> str:
    lines = [f"blobsim bench ({'quick' if r['quick'] else 'full'}; {r['cores']} cores, {r['machine']}); "
             "medians of repeated runs",
             "", f"{'layout':7s} {'blobs':>6s} {'vertices':>9s} {'ms/step':>9s} {'ms/substep':>10s} "
             f"{'Mvertex-substeps/s':>19s} {'ns/vertex-substep':>18s} {'pymunk ms/step':>15s} {'speed-up':>9s}"]
    peers = {(p["layout"], p["blobs"]): p for p in r["peer"]}
    for row in r["rows"]:
        peer = peers.get((row["layout"], row["blobs"]))
        lines.append(f"{row['layout']:7s} {row['blobs']:6d} {row['vertices']:9d} {row['ms_per_step']:9.3f} "
                     f"{row['ms_per_substep']:10.3f} {row['vertex_substeps_per_s'] / 1e6:19.2f} "
                     f"{row['ns_per_vertex_substep']:18.1f} "
                     + (f"{peer['ms_per_step']:15.3f} {peer['ms_per_step'] / row['ms_per_step']:8.1f}x" if peer else
                        f"{'—':>15s} {'—':>9s}"))
    if not r["peer"] and not r["quick"]:
        lines.append("(pymunk peer skipped: pip install -e '.[bench]' to compare)")
    t = r["targets"]
    rows = {(x["layout"], x["blobs"]): x for x in r["rows"]}
    lines.append("")
    c = r["core"]
    lines.append(f"core substep ({', '.join(CORE_STAGES)}) at {c['blobs']} blobs: "
                 f"{c['ns_per_vertex_substep']:.1f} ns/vertex-substep "
                 f"(target <= {t['core_ns_per_vertex_substep_1000']:g})")
    lines.append(f"one-blob step at the defaults: {r['one_blob']['us_per_step']:.2f} µs "
                 f"(target <= {t['one_blob_step_us']:g})")
    th = r["threads"]
    lines.append(f"core at {th['blobs']} blobs: " + ", ".join(f"{ns:.1f} ns on {n} thread{'s' * (n > 1)}"
                                                             for n, ns in th["ns_by_threads"].items())
                 + f", {th['speedup']:.2f}x (target >= {t['thread_speedup_2']:g}x on 2)")
    b = r["busy"]
    lines.append(f"{b['blobs']}-blob pile, {b['steps']} steps, auto threads: {b['alone_s']:.2f} s alone; two side by "
                 f"side, worst of {b['tries']} tries {b['side_by_side_over_alone']:.2f}x (target <= "
                 f"{t['side_by_side_over_alone']:g}x); beside a busy loop {b['beside_busy_over_alone']:.2f}x "
                 f"(target <= {t['beside_busy_over_alone']:g}x)")
    if ("piled", 1000) in rows:
        piled, apart = rows[("piled", 1000)], rows[("apart", 1000)]
        lines.append(f"piled substep at 1000 blobs: {piled['ms_per_substep']:.2f} ms "
                     f"(target <= {t['piled_ms_per_substep_1000']:g}), "
                     f"{piled['ms_per_step'] / apart['ms_per_step']:.2f}x "
                     f"the same blobs apart (target <= {t['piled_over_apart_1000']:g}x)")
    if r.get("peer_240"):
        p = r["peer_240"]
        lines.append(f"100 blobs piled at dt = 1/240 s, 1 substep, 10 iterations: {p['ms_per_step']:.3f} ms/step vs "
                     f"pymunk {p['peer_ms_per_step']:.3f}, {p['peer_ms_per_step'] / p['ms_per_step']:.1f}x "
                     f"(target >= {t['peer_speedup_240_1x10']:g}x)")
        lines.append(f"  the same blobs apart on the floor (no blob contacts): {p['apart_ms_per_step']:.3f} ms/step, "
                     f"pymunk's pile {p['peer_ms_per_step'] / p['apart_ms_per_step']:.1f}x that: the most the pile "
                     f"could reach were its contacts free; {p['apart_top_stage']} {p['apart_top_stage_ms']:.3f} of "
                     f"{p['apart_clocked_ms']:.3f} ms (stage clock)")
    for layout in ("apart", "piled"):
        if (layout, 1000) in rows and (layout, 100) in rows:
            ratio = rows[(layout, 1000)]["ms_per_step"] / rows[(layout, 100)]["ms_per_step"]
            lines.append(f"scaling, {layout}: 1000 blobs cost {ratio:.1f}× 100 blobs "
                         f"(target <= {t['scaling_1000_over_100']:g})")
    st = r["stages"]
    lines.append(f"piled {st['blobs']} blobs, ms per step by stage: "
                 + ", ".join(f"{k} {v:.2f}" for k, v in st["ms_per_step"].items())
                 + f"; {st['contacts_per_iteration']} of {st['vertices']} vertices in blob contact per iteration")
    w = r["walls"]
    lines.append(f"scenes/piston.toml (a loaded piston on 18 blobs): {w['ms_per_step']:.3f} ms per step; moving the "
                 f"piston {w['walls_ms']:.3f} ms, all colliders' contacts {w['statics_ms']:.3f} ms against "
                 f"{w['statics_fixed_ms']:.3f} with the piston fixed: the piston's motion {100 * w['share']:.1f}% of "
                 f"the step (target <= {100 * t['walls_share_piston']:g}%)")
    sl = r["sleeping"]
    lines.append(f"settled pile of {sl['blobs']} blobs, {sl['settled_s']:g} s after the drop: "
                 f"{100 * sl['asleep']:.0f}% asleep; a step costs {sl['ms_per_step_asleep']:.3f} ms asleep vs "
                 f"{sl['ms_per_step_awake']:.3f} ms awake, {100 * sl['ratio']:.1f}% "
                 f"(target <= {100 * t['sleeping_over_awake']:g}%)")
    s = r["startup"]
    lines.append(f"blobsim run, 1 blob, 1000 steps, a new process from start to exit: {s['run_s']:.2f} s "
                 f"(target <= {t['one_blob_1000_steps_s']:g} s)")
    rec = r["recording"]
    lines.append(f"recording every step vs every 10th ({rec['blobs']} blobs, {rec['steps']} steps): "
                 f"{rec['every_1_s']:.3f} s vs {rec['every_10_s']:.3f} s, {100 * rec['overhead']:+.1f}% "
                 f"(target <= {100 * t['record_every_step_overhead']:g}%)")
    m = r["memory"]
    lines.append(f"peak memory of blobsim run ({m['blobs']} blobs): {m['peak_mib']:.0f} MiB for {m['steps']} steps, "
                 f"{m['peak_mib_4x_steps']:.0f} MiB for {4 * m['steps']}")
    sw = r["sweep"]
    lines.append(f"{sw['points']} one-blob points of {sw['steps']} steps: blobsim sweep (local cluster) "
                 f"{sw['sweep_s']:.2f} s vs {sw['points']} blobsim run processes {sw['loop_s']:.2f} s, "
                 f"{sw['speedup']:.1f}x (target >= {t['sweep_speedup_16_points']:g}x)")
    return "\n".join(lines)


def main(quick: bool, json_path: str | None) -> int:
    results = run_bench(quick)
    print(format_bench(results))
    if json_path:
        from ..io.outputs import write_text
        write_text(json_path, json.dumps(results, indent=2) + "\n")
    return 0
