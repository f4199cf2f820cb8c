"""`python -m blobcli.tools.ab_step OTHER`: this tree's step against another tree's, in one process.

On a shared, noisy machine two separate runs of `blobsim bench` differ by more than most changes
do (the same 1,000 blobs apart: 7.2 and 11.6 ms per step ten minutes apart). So the other tree's
package (OTHER/blobcli, e.g. a `git worktree` of the commit before) is copied and imported under
another name, both build the same scene (bench.scene_text), settle it, and then the same steps are
timed from the same saved state, the two builds alternating round by round. It prints each build's
median and the ratio per round, and whether the two give the same bits (a change meant to be faster
only should). Figures, not a test.

The other tree's compiled core (blobcli/core, built by cffi) is imported with the copy. When the tree
has none built for this Python, or one older than its C sources, ab_step builds it in the copy first
(`python -m blobcli.core.build` run with the copy as `blobcli` in the working directory, a few seconds;
the tree itself is left as it is). To build it in the tree instead, once: `cd OTHER && python -m
blobcli.core.build`. A tree whose modules import numba (a commit from before numba left blobsim, with or
without a compiled core) needs numba in this environment, which blobsim does not install: `pip install
numba`; without it ab_step says so in one line and stops.

    git worktree add /tmp/before HEAD~1 && python -m blobcli.tools.ab_step /tmp/before

`--scene FILE` times a scene of one's own instead of the bench's, and `--phi PHI` (a periodic scene) first
compresses its packing as `blobsim jam` does, by Δφ = jamming.COARSE_STEP and RELAX_BLOCK steps of its drag at
a time, to packing fraction PHI: the jam's step on a dense packing, e.g.

    python -m blobcli.tools.ab_step /tmp/before --scene scenes/jamming/bidisperse.toml --phi 0.84 --steps 100
"""

from __future__ import annotations

import argparse
import importlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _arrays(state):
    """Every array of a state, its tuples of arrays (the colliders' rows) opened."""
    for x in state:
        yield from (_arrays(x) if isinstance(x, tuple) else (x,))


def _imports_numba(package: Path) -> bool:
    """Whether a module of the package imports numba at its top (as a numba step's modules do)."""
    return any(line.startswith(("import numba", "from numba"))
               for path in package.rglob("*.py") for line in path.read_text(errors="replace").splitlines())


def _has_numba() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def _ready_core(copy: Path, work: Path) -> str | None:
    """Make the copied package's compiled core loadable: when it has one (core/build.py) that does not load
    (not built for this Python, or older than its C sources), build it in the copy. None when ready (or
    there is no compiled core), else what went wrong, in one line."""
    if not (copy / "core" / "build.py").is_file():
        return None
    work.mkdir()
    (work / "blobcli").symlink_to(copy, target_is_directory=True)  # build.py builds beside its resolved self

    def run(*args):
        return subprocess.run([sys.executable, *args], cwd=work, capture_output=True, text=True)
    if run("-c", "from blobcli.core import load; load()").returncode == 0:
        return None
    print(f"ab_step: building the other tree's compiled core in a copy ({copy.name})", file=sys.stderr)
    built = run("-m", "blobcli.core.build")
    if built.returncode != 0:
        last = (built.stderr.strip() or built.stdout.strip() or "no output").splitlines()[-1]
        return f"its compiled core did not build (python -m blobcli.core.build: {last})"
    return None


def _runner(package: str, blobs: int, layout: str, lines: str, settle: int, steps: int, scene_file: Path | None,
            phi: float | None):
    """A function that restores the settled state, times `steps` steps and returns (seconds, positions)."""
    schema = importlib.import_module(f"{package}.scene.schema")
    bench = importlib.import_module(f"{package}.tools.bench")
    model_module = importlib.import_module(f"{package}.sim.model")
    pipeline = importlib.import_module(f"{package}.sim.pipeline")
    if scene_file is None:
        scene = schema.parse_scene(bench.scene_text(blobs, layout, lines), f"ab-{layout}-{blobs}")
    else:
        scene = schema.load_scene(scene_file)
    model, state = model_module.build(scene)
    params = model_module.build_params(scene)
    if phi is not None:  # compressed as `blobsim jam` compresses, each step brought toward rest by the drag
        jamming = importlib.import_module(f"{package}.sim.jamming")
        measure = importlib.import_module(f"{package}.sim.measure")
        packing = importlib.import_module(f"{package}.sim.packing")
        now = packing.packing_fraction(measure.blob_measures(state, model)[0], params.box)
        step = jamming.COARSE_STEP
        for target in [*np.arange(now + step, phi, step), phi]:
            params = jamming.compress(state, model, params, float(target))
            pipeline.advance(state, model, params, jamming.RELAX_BLOCK)
    settings = pipeline.settings(model, params)
    pipeline.advance(state, model, params, settle, step_settings=settings)
    settled = [a.copy() for a in _arrays(state)]

    def run():
        for array, saved in zip(_arrays(state), settled):
            array[...] = saved
        t0 = time.perf_counter()
        pipeline.advance(state, model, params, steps, step_settings=settings)
        return time.perf_counter() - t0, state.position.copy()
    return run


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", type=Path, help="the other source tree (holding blobcli/)")
    ap.add_argument("--blobs", type=int, default=1000)
    ap.add_argument("--layout", choices=("apart", "piled"), default="piled")
    ap.add_argument("--settle", type=int, default=120, help="steps before timing (the bench's pile: 120)")
    ap.add_argument("--steps", type=int, default=10, help="steps per timed round")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--scene-lines", default="", help=r"more [scene] lines, e.g. 'iterations = 10\nsubsteps = 1'")
    ap.add_argument("--scene", type=Path, help="a scene file to time instead of the bench's (--blobs, --layout and "
                    "--scene-lines are then not used)")
    ap.add_argument("--phi", type=float, help="a periodic scene's packing compressed to this packing fraction first")
    args = ap.parse_args(argv)
    if args.phi is not None:
        from ..scene.schema import load_scene
        if args.scene is None or load_scene(args.scene).settings.periodic is None:
            print("ab_step: --phi compresses a periodic scene's packing: give one with --scene", file=sys.stderr)
            return 2
    source = args.other / "blobcli"
    if not (source / "sim" / "pipeline.py").is_file():
        print(f"ab_step: {source}: not a blobcli package", file=sys.stderr)
        return 2
    if _imports_numba(source) and not _has_numba():
        print(f"ab_step: {source} steps with numba, which is not installed here: pip install numba", file=sys.stderr)
        return 2
    lines = args.scene_lines.replace("\\n", "\n")
    with tempfile.TemporaryDirectory(prefix="blobsim-ab-") as tmp:
        copy = Path(tmp) / "blobcli_other"
        shutil.copytree(source, copy, ignore=shutil.ignore_patterns("__pycache__"))
        problem = _ready_core(copy, Path(tmp) / "build")
        if problem:
            print(f"ab_step: {source / 'core'}: {problem}", file=sys.stderr)
            return 2
        sys.path.insert(0, tmp)
        runs = {name: _runner(package, args.blobs, args.layout, lines, args.settle, args.steps, args.scene, args.phi)
                for name, package in (("this", "blobcli"), ("other", "blobcli_other"))}
        (_, here), (_, there) = runs["this"](), runs["other"]()
        times = {"this": [], "other": []}
        for _ in range(args.rounds):
            for name, run in runs.items():
                times[name].append(run()[0] / args.steps)
    timed = f"{args.blobs} blobs {args.layout}" if args.scene is None else \
        f"{args.scene}" + (f" compressed to φ = {args.phi}" if args.phi is not None else "")
    print(f"{timed}, settled {args.settle} steps, {args.rounds} rounds of {args.steps} steps")
    print(f"same bits after {args.steps} steps: {here.tobytes() == there.tobytes()}")
    for name, t in times.items():
        print(f"{name:>5s}: {1e3 * statistics.median(t):.3f} ms per step (median), {1e3 * min(t):.3f} (min)")
    ratios = [a / b for a, b in zip(times["this"], times["other"])]
    print(f"this / other: {statistics.median(ratios):.3f} (median of rounds; each: "
          + " ".join(f"{r:.2f}" for r in ratios) + ")")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
