"""The `blobsim` command: parse arguments, call the library, format the result.

Heavy modules (numba, h5py) are imported inside the subcommands, so `blobsim --help`
stays instant. Exit codes: 0 ok, 1 the run failed (runaway), 2 bad input, 130 interrupted.
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


def _nonnegative_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number (got {text!r})") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0 (got {text})")
    return v


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number (got {text!r})") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0 (got {text})")
    return v


def parser() -> argparse.ArgumentParser:
    from . import __version__
    from .scene import METHODS
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
    run.add_argument("--resume", metavar="PARTIAL.h5",
                     help="continue an interrupted run of this scene from its last frame (output defaults to that file)")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")

    check = sub.add_parser("check", help="validate scenes and print them with every default filled in")
    check.add_argument("scenes", nargs="+", metavar="SCENE")

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


def cmd_run(args) -> int:
    from .scene import SceneError, load_scene, with_overrides
    try:
        scene = load_scene(args.scene)
    except SceneError as e:
        return _fail(e.problems)
    scene = with_overrides(scene, steps=args.steps, duration=args.duration, method=args.method)
    output = args.output
    if args.resume:
        from .h5md import resume_problems
        from .model import build_params
        problems = resume_problems(args.resume, scene, build_params(scene))
        if problems:
            return _fail(problems)
        output = output or args.resume
    from .run import simulate
    result = simulate(scene, output, progress=not args.quiet and sys.stderr.isatty(), resume=args.resume)
    if result.message:
        print(f"blobsim: {result.message}", file=sys.stderr)
    print(result.summary())
    return result.exit_code


def cmd_check(args) -> int:
    from .scene import SceneError, load_scene, resolved_toml
    problems = []
    for path in args.scenes:
        try:
            print(resolved_toml(load_scene(path)))
        except SceneError as e:
            problems += e.problems
    return _fail(problems) if problems else 0


def cmd_compare(args) -> int:
    import json

    from .compare import CannotCompare, compare_files
    try:
        report = compare_files(args.a, args.b, atol=args.atol, rtol=args.rtol, frames=args.frames, until=args.until,
                               allow_incomplete=args.allow_incomplete)
    except CannotCompare as e:
        return _fail([f"blobsim compare: {e}"])
    print(json.dumps(report.json(), indent=2) if args.json else report.text())
    return 0 if report.same else 1


COMMANDS = {"run": cmd_run, "check": cmd_check, "compare": cmd_compare}


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except KeyboardInterrupt:
        print("blobsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1


if __name__ == "__main__":
    sys.exit(main())
