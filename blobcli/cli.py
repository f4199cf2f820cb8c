"""The `blobsim` command: parse arguments, call the library, format the result.

Heavy modules (numpy, h5py, the compiled core, Dask) are imported inside the subcommands, so
`blobsim --help` stays instant. Exit codes: 0 ok, 1 the run failed (runaway), 2 bad input, 130 interrupted.
"""

from __future__ import annotations

import argparse
import math
import sys


def _positive_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer (got {text!r})") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1 (got {v})")
    return v


def _workers(text):
    """--workers: 0 (in this process) up to MAX_WORKERS_PER_CORE per core."""
    from .tools.executor import MAX_WORKERS_PER_CORE, default_workers
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer (got {text!r})") from None
    most = MAX_WORKERS_PER_CORE * default_workers()
    if not 0 <= v <= most:
        raise argparse.ArgumentTypeError(f"must be from 0 to {most} ({MAX_WORKERS_PER_CORE} per core) (got {v})")
    return v


def _seeds(text):
    """--seeds: 1 up to jam's MAX_SEEDS."""
    from .tools.jam import MAX_SEEDS
    v = _positive_int(text)
    if v > MAX_SEEDS:
        raise argparse.ArgumentTypeError(f"at most {MAX_SEEDS:,} (got {v})")
    return v


def _scheduler(text):
    """--scheduler: a Dask scheduler address, [protocol://]host:port."""
    import re
    if not re.fullmatch(r"((tcp|tls|ws|wss|ucx)://)?[A-Za-z0-9._\-\[\]:]+:\d{1,5}", text):
        raise argparse.ArgumentTypeError(f"must be a Dask scheduler address such as tcp://host:8786 (got {text!r})")
    return text


def _number(allow_zero: bool):
    """An argparse type: a finite float, > 0 (or >= 0 with allow_zero)."""
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number (got {text!r})") from None
        if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
            raise argparse.ArgumentTypeError(f"must be a finite number {'>=' if allow_zero else '>'} 0 (got {text})")
        return v
    return parse


class _CommaList(argparse.Action):
    """A list option that takes `--methods kot xpbd`, `--methods kot,xpbd` or both, checked
    against `choices` (argparse checks the raw strings, so choices are checked here)."""

    def __init__(self, *args, allowed=(), **kwargs):
        super().__init__(*args, nargs="+", **kwargs)
        self.allowed = tuple(allowed)

    def __call__(self, parser, namespace, values, option_string=None):
        items = [v for text in values for v in text.split(",") if v]
        bad = [v for v in items if v not in self.allowed]
        if bad or not items:
            parser.error(f"argument {option_string}: invalid choice: {', '.join(map(repr, bad)) or 'none given'} "
                         f"(choose from {', '.join(self.allowed)})")
        setattr(namespace, self.dest, list(dict.fromkeys(items)))


_positive_float = _number(allow_zero=False)
_nonnegative_float = _number(allow_zero=True)


def _cluster_options(command):
    command.add_argument("--scheduler", type=_scheduler, metavar="ADDRESS",
                         help="a running Dask scheduler (tcp://host:8786) instead of a local cluster")
    command.add_argument("--workers", type=_workers, metavar="N",
                         help="local worker processes (default: one per core; 0: in this process)")


def parser() -> argparse.ArgumentParser:
    from . import __version__
    from .scene.schema import METHODS
    p = argparse.ArgumentParser(prog="blobsim", description="Batch simulator for 2D soft blobs.")
    p.add_argument("--version", action="version", version=f"blobsim {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser("run", help="simulate a scene into an H5MD trajectory file")
    run.add_argument("scene", help="scene TOML file")
    run.add_argument("-o", "--output", metavar="OUT.h5", help="trajectory file (default: [output] path)")
    length = run.add_mutually_exclusive_group()
    length.add_argument("--steps", type=_positive_int, metavar="N", help="number of steps (overrides the scene)")
    length.add_argument("--duration", type=_positive_float, metavar="T", help="simulated seconds (overrides the scene)")
    run.add_argument("--method", choices=METHODS, help="area method (overrides the scene)")
    run.add_argument("--rerun", nargs="?", const="", metavar="OUT.rrd",
                     help="also write a rerun recording (default: beside the trajectory, as .rrd)")
    run.add_argument("--resume", metavar="PARTIAL.h5",
                     help="continue an interrupted run of this scene from its last frame "
                          "(output defaults to that file)")
    run.add_argument("--threads", type=_positive_int, metavar="N",
                     help="threads for the step, fixed (default: auto, all cores, one while more are slower)")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar and no compile line")

    check = sub.add_parser("check", help="validate scenes and print them with every default filled in")
    check.add_argument("scenes", nargs="+", metavar="SCENE")

    replay = sub.add_parser("replay", help="make the rerun recording of an existing trajectory file")
    replay.add_argument("trajectory", metavar="TRAJ.h5")
    replay.add_argument("-o", "--output", metavar="OUT.rrd", help="recording file (default: beside it, as .rrd)")

    view = sub.add_parser("view", help="open a recording (.rrd, or a .h5 converted first) in the rerun viewer")
    view.add_argument("file", metavar="FILE")

    render = sub.add_parser("render", help="draw a filmstrip picture of a run (PNG)")
    render.add_argument("trajectory", metavar="TRAJ.h5")
    render.add_argument("-o", "--output", metavar="PNG", help="picture file (default: beside it, as .png)")
    render.add_argument("--frames", type=_positive_int, default=6, metavar="K", help="frames side by side (default 6)")

    stress = sub.add_parser("stress", help="run the stress scenes with each method: pass or the reason it fails")
    stress.add_argument("--methods", action=_CommaList, allowed=METHODS, default=list(METHODS), metavar="M",
                        help=f"methods to test, space- or comma-separated (default: all of {','.join(METHODS)})")
    stress.add_argument("-o", "--output", default="outputs/stress", metavar="DIR",
                        help="where the table, CSV, stability map and runs go (default outputs/stress)")
    stress.add_argument("--quick", action="store_true", help="0.5 s runs and a 2 × 2 map (for smoke tests)")

    study = sub.add_parser("study", help="speed against accuracy per method: a work-precision chart and CSV")
    study.add_argument("scene", metavar="SCENE")
    study.add_argument("--methods", action=_CommaList, allowed=METHODS, default=list(METHODS), metavar="M",
                       help=f"space- or comma-separated (default: all of {','.join(METHODS)})")
    study.add_argument("--tol", type=_positive_float, metavar="E",
                       help="print each method's cheapest setting with trajectory error <= E")
    study.add_argument("--duration", type=_positive_float, metavar="T", help="simulated seconds (default: the scene's)")
    study.add_argument("-o", "--output", default="outputs/study", metavar="DIR", help="default outputs/study")

    export = sub.add_parser("export", help="write a trajectory as XDMF (ParaView, VisIt) or extended XYZ (OVITO, "
                                           "ASE, MDAnalysis)")
    export.add_argument("trajectory", metavar="TRAJ.h5")
    export.add_argument("--format", required=True, choices=("xdmf", "xyz"))
    export.add_argument("-o", "--output", metavar="OUT", help="default: beside it, <stem>_export.xdmf or .xyz")

    sweep = sub.add_parser("sweep", help="run a parameter sweep of a scene on a Dask cluster (local by default)",
                           description="Exit 0: every point ok; 1: some point failed; 2: a bad sweep file; "
                                       "130: interrupted (finished points and the summary are kept).")
    sweep.add_argument("sweep", metavar="SWEEP.toml")
    sweep.add_argument("-o", "--output", default="outputs/sweeps", metavar="DIR",
                       help="points and summary go to DIR/<name>/ (default outputs/sweeps)")
    _cluster_options(sweep)
    from .tools.sweep import METRICS  # light: no numpy, dask or matplotlib at import
    sweep.add_argument("--metrics", action=_CommaList, allowed=METRICS, default=["worst_area_error"],
                       metavar="M", help=f"what summary.png charts (default worst_area_error; of {','.join(METRICS)})")
    sweep.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    for command in (stress, study):
        _cluster_options(command)

    jam = sub.add_parser("jam", help="compress a periodic packing until it jams: phi_J, z_J and pressure",
                         description="Grows the packing fraction in small steps (the box shrinks), bringing each "
                                     "packing to rest, and bisects to the packing whose pressure is P (in units "
                                     "of the blobs' perimeter compliance). Exit 0: every seed jammed; 1: some seed "
                                     "failed; 2: bad input; 130: interrupted (finished seeds are kept).")
    jam.add_argument("scene", metavar="SCENE", help="a scene with [scene] periodic and blobs placed with count")
    from .tools.jam import DEFAULT_PRESSURE  # light: no numpy or dask at import
    jam.add_argument("--pressure", type=_positive_float, default=DEFAULT_PRESSURE, metavar="P",
                     help="target pressure p × the blobs' mean perimeter compliance, dimensionless "
                          f"(default {DEFAULT_PRESSURE:g})")
    from .tools.jam import MAX_SEEDS
    jam.add_argument("--seeds", type=_seeds, default=1, metavar="K",
                     help=f"independent random starts, seeds [scene] seed .. + K - 1 (default 1, at most "
                          f"{MAX_SEEDS:,})")
    jam.add_argument("-o", "--output", default="outputs/jam", metavar="DIR",
                     help="trajectories, summary.json and chart go to DIR/<scene name>/ (default outputs/jam)")
    jam.add_argument("--json", metavar="FILE", help="also write the figures here")
    _cluster_options(jam)
    jam.add_argument("-q", "--quiet", action="store_true", help="no progress bar")

    bench = sub.add_parser("bench", help="measure speed on this machine, beside the pymunk peer")
    bench.add_argument("--quick", action="store_true", help="small counts only (seconds, for smoke tests)")
    bench.add_argument("--json", metavar="OUT", help="also write the figures as JSON")

    compare = sub.add_parser("compare", help="compare two trajectory files frame by frame",
                             description="Exit 0: the same within tolerance; 1: different; 2: cannot compare.")
    compare.add_argument("a", metavar="A.h5")
    compare.add_argument("b", metavar="B.h5")
    compare.add_argument("--atol", type=_nonnegative_float, default=0.0, metavar="X", help="absolute tolerance, m")
    compare.add_argument("--rtol", type=_nonnegative_float, default=0.0, metavar="Y", help="relative tolerance")
    horizon = compare.add_mutually_exclusive_group()
    horizon.add_argument("--frames", type=_positive_int, metavar="K", help="compare only the first K frames")
    horizon.add_argument("--until", type=_nonnegative_float, metavar="T", help="compare only frames with time <= T s")
    compare.add_argument("--json", action="store_true", help="print the report as JSON")
    compare.add_argument("--allow-incomplete", action="store_true", help="compare files of interrupted runs too")
    return p


def _fail(problems) -> int:
    for line in problems:
        print(line, file=sys.stderr)
    return 2


def _output_problems(*pairs) -> list[str]:
    """One line for each (path, kind) that cannot be written: kind "file" or "dir"."""
    from .io.outputs import directory_problem, output_problem
    out = []
    for path, kind in pairs:
        if path is None:
            continue
        problem = directory_problem(path) if kind == "dir" else output_problem(path, suffixes=(".partial",))
        if problem:
            out.append(f"{path}: {problem}")
    return out


def _clobber_problems(outputs, inputs, option: str | None = "-o") -> list[str]:
    """One line for each of `outputs` that is a file the command reads, `inputs` ((path, what it is) pairs):
    the one rule every command applies to every output it writes, before any work (io/outputs.py). `option`:
    the one that chooses those outputs (None: none does)."""
    from .io.outputs import clobber_problems
    fix = f"choose another {option}" if option else "move it away"
    return [f"{path}: {why}; {fix}" for path, why in clobber_problems(outputs, inputs)]


def _trajectory_files(path) -> list:
    """A trajectory and the lock a run holds beside it (written, then removed: outputs.OutputLock)."""
    from pathlib import Path
    return [] if path is None else [Path(path), Path(f"{path}.lock")]


def cmd_run(args) -> int:
    from pathlib import Path

    from .scene.schema import SceneError, load_scene, with_overrides
    try:
        scene = with_overrides(load_scene(args.scene), steps=args.steps, duration=args.duration, method=args.method)
    except SceneError as e:
        return _fail(e.problems)
    problems = _output_problems((args.output, "file"))
    if args.threads is not None:
        from .io.threads import available
        if args.threads > available():
            problems.append(f"--threads: at most {available()}, the threads the step may use (OMP_NUM_THREADS, "
                            f"default: the cores) (got {args.threads})")
    if problems:
        return _fail(problems)
    output = args.output
    if args.resume:
        from .io.h5md import resume_problems
        from .sim.model import build_params
        problems = resume_problems(args.resume, scene, build_params(scene))
        if problems:
            return _fail(problems)
        output = output or args.resume
    output = Path(output) if output is not None else scene.output_path
    rerun = args.rerun if args.rerun is not None else scene.output.rerun
    if rerun == "":
        rerun = str(output.with_suffix(".rrd"))
    problems = _output_problems((rerun or None, "file"))
    scene_file, resumed = (args.scene, "the scene run"), (args.resume, "the trajectory resumed")
    problems += _clobber_problems([output], [scene_file])  # (in place: the resumed file is the output)
    problems += _clobber_problems(_trajectory_files(output)[1:], [scene_file, resumed])
    problems += _clobber_problems([rerun or None], [scene_file, resumed, (output, "the trajectory recorded")],
                                  "--rerun")
    if problems:
        return _fail(problems)
    for line in spawn_warnings(scene):
        print(line, file=sys.stderr)
    from .io import interrupts
    from .io.run import simulate
    with interrupts.deferred():  # a signal now would only cut the summary: the file is whole either way
        live = not args.quiet and sys.stderr.isatty()
        result = simulate(scene, output, progress=live, resume=args.resume, threads=args.threads)
        interrupts.clear()
        if result.message:
            print(f"blobsim: {result.message}", file=sys.stderr)
        print(result.summary())
    if rerun and result.written:
        # Written from the finished file, not during the run: rerun's encoder threads take the
        # cores the step's threads run on. An interrupted run's file holds every frame up to the
        # stop, so its recording does too.
        from .io.recording import replay
        frames = replay(result.path, rerun)
        print(f"blobsim: recorded {frames} frames into {rerun}")
    return result.exit_code


def spawn_warnings(scene) -> list[str]:
    from .scene.warnings import spawn_warnings as warnings_of
    return [f"warning: {w}" for w in warnings_of(scene)]


def cmd_check(args) -> int:
    from .scene.schema import SceneError, load_scene, resolved_toml
    problems = []
    for path in args.scenes:
        try:
            scene = load_scene(path)
        except SceneError as e:
            problems += e.problems
            continue
        print(resolved_toml(scene))
        for line in spawn_warnings(scene):
            print(line, file=sys.stderr)
    return _fail(problems) if problems else 0


def cmd_replay(args) -> int:
    from pathlib import Path
    out = args.output or str(Path(args.trajectory).with_suffix(".rrd"))
    problems = _output_problems((out, "file")) or _clobber_problems([out], [(args.trajectory,
                                                                            "the trajectory replayed")])
    if problems:
        return _fail(problems)
    from .io.recording import replay
    frames = replay(args.trajectory, out)
    print(f"blobsim: recorded {frames} frames of {args.trajectory} into {out}")
    return 0


def cmd_view(args) -> int:
    import os
    import shutil
    import subprocess
    from pathlib import Path
    path = Path(args.file)
    if not path.exists():
        return _fail([f"{path}: no such file"])
    if not path.is_file():
        return _fail([f"{path}: is not a file (give a .rrd recording or a .h5 trajectory)"])
    if path.suffix == ".h5":
        rrd = path.with_suffix(".rrd")
        problems = _output_problems((rrd, "file")) or _clobber_problems([rrd], [(path, "the trajectory viewed")], None)
        if problems:
            return _fail(problems)
        from .io.recording import replay
        replay(path, rrd)
        path = rrd
    viewer = shutil.which("rerun")
    if viewer is None:
        print(f"blobsim: the rerun viewer is not on PATH (pip install rerun-sdk puts it there); "
              f"the recording is {path}: open it with rerun {path}", file=sys.stderr)
        return 0
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print(f"blobsim: no display here (DISPLAY and WAYLAND_DISPLAY are unset); the recording is {path}. "
              f"Open it on a machine with a display with: rerun {path}", file=sys.stderr)
        return 0
    subprocess.Popen([viewer, str(path)])
    print(f"blobsim: opened {path} in the rerun viewer")
    return 0


def cmd_render(args) -> int:
    from pathlib import Path
    out = Path(args.output) if args.output else Path(args.trajectory).with_suffix(".png")
    if out.suffix.lower() != ".png":
        out = out.with_name(out.name + ".png")
    problems = _output_problems((out, "file")) or _clobber_problems([out], [(args.trajectory,
                                                                            "the trajectory drawn")])
    if problems:
        return _fail(problems)
    from .tools.render import render
    out = render(args.trajectory, out, frames=args.frames)
    print(f"blobsim: drew {out}")
    return 0


def cmd_stress(args) -> int:
    from .tools.stress import inputs, output_files
    problems = _output_problems((args.output, "dir"))
    problems = problems or _clobber_problems(output_files(args.output, args.methods, args.quick), inputs())
    if problems:
        return _fail(problems)
    from .tools.stress import run_stress
    result = run_stress(args.methods, args.output, args.quick, args.scheduler, args.workers)
    print(result["table"])
    print(f"\nblobsim: {sum(v.passed for v in result['verdicts'])} of {len(result['verdicts'])} runs passed; "
          f"table, CSV and stability map ({result['out_dir'] / 'stability_map.png'}) in {result['out_dir']}")
    return 0


def cmd_study(args) -> int:
    from pathlib import Path

    from .scene.schema import SceneError, load_scene
    try:
        scene = load_scene(args.scene)
    except SceneError as e:
        return _fail(e.problems)
    from .tools.study import output_files
    problems = _output_problems((args.output, "dir"))
    problems = problems or _clobber_problems(output_files(args.output, scene, args.methods),
                                             [(args.scene, "the scene studied")])
    if problems:
        return _fail(problems)
    from .tools.study import chart, cheapest, format_points, run_study, write_csv
    points = run_study(scene, args.methods, args.output, args.duration, args.scheduler, args.workers)
    out = Path(args.output)
    write_csv(points, out / f"{scene.name}_study.csv")
    chart(points, out / f"{scene.name}_study.png",
          f"{scene.name}: error against wall time (reference: substeps × 16, same method)")
    print(format_points(points))
    if args.tol is not None:
        print(f"\ncheapest setting with trajectory error <= {args.tol:g}:")
        for method, p in cheapest(points, args.tol).items():
            print(f"  {method:8s} " + (f"{p.label} ({p.wall_time:.3f} s)" if p else "none of the ladder"))
    print(f"\nblobsim: chart {out / (scene.name + '_study.png')}, numbers {out / (scene.name + '_study.csv')}")
    return 0


def cmd_export(args) -> int:
    from pathlib import Path

    from .io.export import sidecars
    source = Path(args.trajectory)
    out = Path(args.output) if args.output is not None else source.with_name(f"{source.stem}_export.{args.format}")
    if args.output == "":
        return _fail(["-o: is empty"])
    problems = _output_problems(*((p, "file") for p in sidecars(out, args.format)))
    problems = problems or _clobber_problems(sidecars(out, args.format), [(source, "the trajectory exported")])
    for p in [] if problems else sidecars(out, args.format):
        if p != out and p.exists() and not _export_wrote(p, out):
            problems.append(f"{p}: exists and is not the heavy data of an earlier export to {out} "
                            f"(XDMF writes its data there); move it away or choose another -o")
    if problems:
        return _fail(problems)
    from .io.export import export
    frames = export(source, out, args.format)
    print(f"blobsim: exported {frames} frames of {source} to {out}"
          + (f" (heavy data in {out.with_suffix('.h5')})" if args.format == "xdmf" else ""))
    return 0


def _export_wrote(sidecar, out) -> bool:
    """Whether `sidecar` is the heavy data of an earlier `export --format xdmf` to `out`: a regular file
    (not a link) beside an XDMF file `out` that names it, and no H5MD trajectory."""
    import os
    import stat
    try:
        if not (stat.S_ISREG(os.lstat(sidecar).st_mode) and stat.S_ISREG(os.lstat(out).st_mode)):
            return False
        import h5py
        with h5py.File(sidecar, "r") as f:
            if "h5md" in f:
                return False
        return f"{sidecar.name}:" in out.read_text(errors="replace")
    except (OSError, ValueError):
        return False


def cmd_sweep(args) -> int:
    from pathlib import Path

    from .scene.schema import SceneError
    from .tools import sweep as sw
    try:
        sweep = sw.load_sweep(args.sweep)
    except SceneError as e:
        return _fail(e.problems)
    out = Path(args.output) / sweep.name
    problems = _output_problems((args.output, "dir")) or _output_problems((out, "dir"))
    problems = problems or _clobber_problems(sw.output_files(out, sweep), [(sweep.source, "the sweep file"),
                                                                          (sweep.base, "the sweep's scene")])
    if problems:
        return _fail(problems)
    live = not args.quiet and sys.stderr.isatty()
    rows, interrupted = sw.run_sweep(sweep, out, args.scheduler, args.workers, progress=live,
                                     announce=lambda line: print(line, file=sys.stderr))
    summary = sw.write_summary(sweep, rows, out)
    sw.chart(sweep, rows, out / "summary.png", args.metrics)
    ok = sum(r["status"] == "ok" for r in rows.values())
    failed = sum(r["status"].startswith("failed") for r in rows.values())
    print(f"blobsim: {ok} of {len(sweep.points)} points ok, {failed} failed"
          + (", interrupted" if interrupted else "") + f"; summary {summary}, chart {out / 'summary.png'}")
    return 130 if interrupted else 1 if failed or ok < len(sweep.points) else 0


def cmd_jam(args) -> int:
    from pathlib import Path

    from .scene.schema import SceneError, load_scene, scene_problem
    from .tools import jam as jm
    try:
        scene = load_scene(args.scene)
    except SceneError as e:
        return _fail(e.problems)
    problem = jm.jam_problem(scene, args.seeds)
    if problem:
        return _fail([scene_problem(scene, *problem)])
    out = Path(args.output) / scene.name
    problems = _output_problems((args.output, "dir")) or _output_problems((out, "dir"), (args.json, "file"))
    files = jm.output_files(out, scene, args.seeds)
    problems = problems or _output_problems(*((p, "file") for p in (*files[:2], files[-1])))  # the last seed's: longest
    read = [(args.scene, "the scene jammed")]
    problems = problems or _clobber_problems(files, read) + _clobber_problems([args.json], read, "--json")
    if problems:
        return _fail(problems)
    live = not args.quiet and sys.stderr.isatty()
    rows, interrupted = jm.run_jam(scene, out, args.seeds, args.pressure, args.scheduler, args.workers,
                                   progress=live, announce=lambda line: print(line, file=sys.stderr))
    figures = jm.summary(rows)
    jm.write_json(figures, out / "summary.json")
    if args.json:
        jm.write_json(figures, Path(args.json))
    jm.chart(rows, out / "chart.png", args.pressure)
    print(f"blobsim: {jm.report(figures)}; summary {out / 'summary.json'}, chart {out / 'chart.png'}")
    ok = sum(r["status"] == "ok" for r in rows)
    return 130 if interrupted else 1 if ok < args.seeds else 0


def cmd_bench(args) -> int:
    from .tools.bench import inputs
    problems = _output_problems((args.json, "file")) or _clobber_problems([args.json], inputs(), "--json")
    if problems:
        return _fail(problems)
    from .tools.bench import main as bench_main
    return bench_main(args.quick, args.json)


def cmd_compare(args) -> int:
    import json

    from .tools.compare import CannotCompare, compare_files
    try:
        report = compare_files(args.a, args.b, atol=args.atol, rtol=args.rtol, frames=args.frames, until=args.until,
                               allow_incomplete=args.allow_incomplete)
    except CannotCompare as e:
        return _fail([f"blobsim compare: {e}"])
    print(json.dumps(report.json(), indent=2) if args.json else report.text())
    return 0 if report.same else 1


COMMANDS = {"run": cmd_run, "check": cmd_check, "compare": cmd_compare, "replay": cmd_replay, "view": cmd_view,
            "bench": cmd_bench, "render": cmd_render, "stress": cmd_stress,
            "study": cmd_study, "sweep": cmd_sweep, "export": cmd_export, "jam": cmd_jam}


def main(argv=None) -> int:
    """Exit codes: 0 ok, 1 failed (runaway, a difference, an internal error), 2 bad input,
    130 interrupted; one line on stderr, never a traceback (BLOBSIM_DEBUG=1 shows it)."""
    import os
    import warnings

    from .io import interrupts
    interrupts.install()
    interrupts.clear()  # none from an earlier command in this process
    try:
        args = parser().parse_args(argv)
        # Non-finite values are caught and reported by the run (runaway) and the readers.
        warnings.simplefilter("ignore", RuntimeWarning)
        return COMMANDS[args.command](args)
    except (KeyboardInterrupt, interrupts.Interrupted):
        print("blobsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1
    except Exception as e:  # noqa: BLE001 - the documented one-line contract of the command line
        if interrupts.caused_by_signal(e):  # raised inside code that wraps exceptions (a class's __set_name__)
            print("blobsim: interrupted", file=sys.stderr)
            return 130
        from .io.h5md import TrajectoryError
        from .io.outputs import OutputError
        from .tools.executor import SchedulerError
        if isinstance(e, (TrajectoryError, OutputError, SchedulerError)):
            return _fail([str(e)])
        if os.environ.get("BLOBSIM_DEBUG"):
            raise
        print(f"blobsim: internal error: {type(e).__name__}: {e} (BLOBSIM_DEBUG=1 shows the traceback)",
              file=sys.stderr)
        return 1
