"""Running a scene to a trajectory file: the loop around `step`.

The loop records frame 0 and every `every`-th step, checks for runaway positions after
every step, and stops cleanly at a step boundary on SIGINT or SIGTERM: the frames
computed so far are always written, and `<path>` always holds a readable file.
"""

from __future__ import annotations

import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scene.schema import Scene
from ..sim.measure import blob_measures, first_runaway
from ..sim.model import build, build_params
from ..sim.pipeline import step
from .h5md import TrajectoryWriter


@dataclass
class RunResult:
    path: Path
    steps: int  # steps completed
    sim_time: float  # s
    wall_time: float  # s
    worst_area_error: float  # max over recorded frames after frame 0, over blobs, of |A - A_target| / |A_target|
    status: str  # "complete", "interrupted" or "runaway"
    message: str = ""

    @property
    def exit_code(self) -> int:
        return {"complete": 0, "runaway": 1, "interrupted": 130}[self.status]

    def summary(self) -> str:
        rate = self.steps / self.wall_time if self.wall_time > 0 else float("inf")
        head = {"complete": "blobsim", "interrupted": "blobsim: interrupted",
                "runaway": "blobsim: stopped"}[self.status]
        return (f"{head}: {self.steps} steps, {self.sim_time:.4g} s simulated in {self.wall_time:.3g} s "
                f"({rate:.4g} steps/s), worst area error {self.worst_area_error:.2e}, wrote {self.path}")


class _StopFlag:
    """Turns SIGINT/SIGTERM into a flag the loop reads between steps."""

    def __init__(self):
        self.signal = None

    def __enter__(self):
        self._old = {s: signal.signal(s, self._set) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _set(self, signum, frame):
        self.signal = signum

    def __exit__(self, *exc):
        for s, handler in self._old.items():
            signal.signal(s, handler)


def simulate(scene: Scene, path: str | Path | None = None, progress: bool = False,
             resume: str | Path | None = None) -> RunResult:
    """Run `scene` and write its trajectory to `path` (default: the scene's output path).

    With `resume` (an interrupted run's file, checked with h5md.resume_problems), the new
    file starts with that run's frames and continues from its last state: the result is
    bit for bit the trajectory of a run that was never interrupted."""
    path = Path(path) if path is not None else scene.output_path
    model, state = build(scene)
    params = build_params(scene)
    target = np.abs(model.target_area)
    worst = 0.0
    writer = TrajectoryWriter(path, scene, model, params)

    def record(n):
        nonlocal worst
        area, kinetic = blob_measures(state, model)
        if n > 0:  # frame 0 is the shape as given: at rest area, not at pressure × rest area
            worst = max(worst, float(np.max(np.abs(np.abs(area) - target) / target)))
        writer.append(n, state, area, kinetic)

    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=params.steps, unit="step", file=sys.stderr, mininterval=0.25, leave=False)
    status, message, done = "complete", "", 0
    start = time.perf_counter()
    try:
        if resume is not None:
            done = writer.adopt(resume, state)
            worst = writer.worst_area_error
        else:
            record(0)
        if bar is not None:
            bar.update(done)
        with _StopFlag() as stop:
            for n in range(done + 1, params.steps + 1):
                step(state, model, params)
                bad = first_runaway(state)
                if bad >= 0:
                    blob = int(np.searchsorted(model.offsets, bad, side="right") - 1)
                    status = "runaway"
                    message = (f"step {n}: blob {blob} ({model.names[blob]}) vertex {bad - model.offsets[blob]} "
                               f"is at {state.pos[bad].tolist()}: non-finite or beyond 1e6 m")
                    break
                done = n
                if n % params.every == 0:
                    record(n)
                if bar is not None and n % 64 == 0:
                    bar.update(64)
                if stop.signal is not None:
                    status = "interrupted"
                    message = f"stopped by signal {stop.signal} after step {n}"
                    break
    finally:
        if bar is not None:
            bar.close()
        wall = time.perf_counter() - start
        writer.close(complete=status == "complete", stopped=message)
    return RunResult(path=path, steps=done, sim_time=done * params.dt, wall_time=wall,
                     worst_area_error=worst, status=status, message=message)
