"""Running a scene to a trajectory file: the loop around the compiled step (pipeline.advance).

The loop records frame 0 and every `every`-th step, the step checks for runaway positions
after every step, and stops cleanly at a step boundary on SIGINT or SIGTERM. What a run leaves:

- finished: `<path>` with complete = true (and `warnings` if blobs ended inside out or
  self-intersecting);
- interrupted, runaway, or failed inside the loop: `<path>` with every frame computed so far
  and complete = false, the reason in `stopped`;
- interrupted before the first step: nothing new (an older `<path>` is left as it was);
- an in-place `--resume` interrupted while the old frames are copied: the original, unchanged;
- a failed write (disk full): the `.partial` kept and named if readable, else removed;
- killed (SIGKILL): `<path>.partial`, never a half-written `<path>`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..scene.schema import Scene
from ..sim.measure import RUNAWAY, blob_measures, first_runaway, first_runaway_wall, shape_warning
from ..sim.model import SimulationError, build, build_params
from ..sim.pipeline import advance, settings
from ..sim.schedule import Schedules
from . import interrupts
from .h5md import DiskFull, TrajectoryError, TrajectoryWriter
from .outputs import OutputError, OutputLock, output_problem
from .threads import ThreadChoice

PROGRESS_SECONDS = 0.25  # the progress bar is redrawn at most this often
CALL_SECONDS = 0.05  # wall time of one compiled call of the step at most (about): Python sees Ctrl-C,
#                      records and the progress bar between calls


class _WriteFailed(Exception):
    """The file system refused a write of the trajectory (quota, I/O error, a disk that another
    process filled after the free-space check): HDF5 reports these as OSError or RuntimeError."""


@dataclass
class RunResult:
    path: Path
    steps: int  # steps completed
    sim_time: float  # s
    wall_time: float  # s
    worst_area_error: float  # max over recorded frames after frame 0, over blobs, of |A - A_target| / |A_target|
    status: str  # "complete", "interrupted", "runaway" or "failed"
    message: str = ""
    warning: str = ""  # blobs that ended inside out or self-intersecting
    written: bool = True  # False: nothing was published at `path`
    more_substeps: tuple = (0, 0)  # (steps that took more substeps than the scene's `substeps`, the most one took)

    @property
    def exit_code(self) -> int:
        return {"complete": 0, "runaway": 1, "failed": 1, "interrupted": 130}[self.status]

    def summary(self) -> str:
        rate = self.steps / self.wall_time if self.wall_time > 0 else float("inf")
        head = {"complete": "blobsim", "interrupted": "blobsim: interrupted",
                "runaway": "blobsim: stopped", "failed": "blobsim: failed"}[self.status]
        where = f"wrote {self.path}" if self.written else "wrote nothing"
        line = (f"{head}: {self.steps} steps, {self.sim_time:.4g} s simulated in {self.wall_time:.3g} s "
                f"({rate:.4g} steps/s), worst area error {self.worst_area_error:.2e}, {where}")
        steps, most = self.more_substeps
        if steps:  # integrate.substeps_for
            line += f"; {steps} step{'s' if steps > 1 else ''} took more substeps than the scene's (up to {most})"
        return line + (f"; warning: {self.warning}" if self.warning else "")


def simulate(scene: Scene, path: str | Path | None = None, progress: bool = False,
             resume: str | Path | None = None, replace_stale_partial: bool = False,
             threads: int | None = None) -> RunResult:
    """Run `scene` and write its trajectory to `path` (default: the scene's output path).

    With `resume` (an interrupted run's file, checked with h5md/restart.py: resume_problems), the new
    file starts with that run's frames and continues from its last state: the result is
    bit for bit the trajectory of a run that was never interrupted. Raises OutputError
    (before any work) when `path` cannot be written or another run holds it. A `<path>.partial`
    left by a killed run is refused, unless `replace_stale_partial` (a sweep retrying a point
    whose worker died): holding the lock proves no live run owns it. `threads`: a fixed thread count
    for the step, or None for auto (io/threads.py)."""
    path = Path(path) if path is not None else scene.output_path
    problem = output_problem(path)
    if problem:
        raise OutputError(f"{path}: {problem}")
    with interrupts.deferred(), OutputLock(path):  # a signal since the command began stops it before its first step
        if replace_stale_partial:
            path.with_name(path.name + ".partial").unlink(missing_ok=True)
        return _run_locked(scene, path, progress, resume, threads)


def _run_locked(scene, path, progress, resume, threads) -> RunResult:
    model, state = build(scene)
    params = build_params(scene)
    with ThreadChoice(threads, model.parallel) as choice:  # before the writer: it records the threads
        return _run_chosen(scene, path, progress, resume, model, state, params, choice)


def _run_chosen(scene, path, progress, resume, model, state, params, choice) -> RunResult:
    worst = 0.0
    writer = TrajectoryWriter(path, scene, model, params)
    schedules = Schedules(scene, model, params)  # they change the step's arrays between steps
    live = schedules.arrays if schedules else model.arrays

    def record(n):
        nonlocal worst
        area, kinetic = blob_measures(state, model, live.inv_mass)
        if n > 0:  # frame 0 is the shape as given: at rest area, not at pressure × rest area
            target = np.abs(live.target_area)
            worst = max(worst, float(np.max(np.abs(np.abs(area) - target) / target)))
        try:
            writer.append(n, state, area, kinetic, schedules.current_box, schedules.current_shear)
        except DiskFull:
            raise
        except (OSError, RuntimeError) as e:
            raise _WriteFailed(e) from e

    def result(status, message="", warning="", written=True):
        return RunResult(path=path, steps=done, sim_time=done * params.dt, wall_time=time.perf_counter() - start,
                         worst_area_error=worst, status=status, message=message, warning=warning, written=written,
                         more_substeps=(int(state.substeps_taken[1]), int(state.substeps_taken[0])))

    bar = None
    status, message, done = "complete", "", 0
    start = time.perf_counter()
    try:
        if resume is not None:
            adopted = writer.adopt(resume, state, interrupts.pending)
            if adopted is None:  # stopped while copying: the original stays as it was
                writer.abandon()
                return result("interrupted", f"interrupted while copying the frames of {resume}; it is unchanged",
                              written=False)
            done, worst = adopted, writer.worst_area_error
        else:
            record(0)
        first = done
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=params.steps, initial=done, unit="step", file=sys.stderr, mininterval=PROGRESS_SECONDS,
                       leave=False)
        step_settings = settings(model, params)
        chunk = 1  # steps per compiled call: grown to about CALL_SECONDS of wall time
        while done < params.steps and interrupts.pending() is None:
            threads, count = choice.plan(min(chunk, params.steps - done, params.every - done % params.every))
            arrays = None
            if schedules:  # one step per compiled call, its values set before it
                count, arrays = 1, schedules.arrays
                step_settings = schedules.apply(done, step_settings, state)
            t0, cpu0 = time.perf_counter(), time.process_time()
            ran = advance(state, model, params, count, step_settings=step_settings, arrays=arrays)
            elapsed = time.perf_counter() - t0
            choice.observe(threads, ran, elapsed, time.process_time() - cpu0)
            done += ran
            if ran < count:
                status = "runaway"
                bad = first_runaway(state.position, RUNAWAY)
                if bad >= 0:
                    blob = int(np.searchsorted(model.offsets, bad, side="right") - 1)
                    message = (f"step {done + 1}: blob {blob} ({model.names[blob]}) vertex "
                               f"{bad - model.offsets[blob]} is at {state.pos[bad].tolist()}: non-finite or beyond "
                               f"{RUNAWAY:g} m")
                else:
                    wall = first_runaway_wall(state.static_pose, RUNAWAY)
                    message = (f"step {done + 1}: static[{wall}]'s pose {state.static_pose[wall].tolist()} "
                               f"(dx, dy, turn, s, V, s0) is non-finite or beyond {RUNAWAY:g} m")
                break
            if done % params.every == 0:
                record(done)
            if bar is not None:
                bar.update(ran)
            if threads == choice.current:  # not a probe of another thread count
                rate = ran / max(elapsed, 1e-9)  # steps per second
                chunk = max(1, min(2 * chunk, params.steps, int(rate * CALL_SECONDS)))
        if status == "complete" and interrupts.pending() is not None:
            status = "interrupted"
            message = f"stopped by signal {interrupts.pending()} after step {done}"
            if done == first and resume is None:  # not one step computed: keep whatever was there
                writer.abandon()
                return result(status, f"interrupted before the first step; {path} was not written", written=False)
        warning = shape_warning(state, model) if status == "complete" else ""
    except SimulationError as e:
        done += e.steps_done
        status, message, warning = "failed", f"step {done + 1}: {e}", ""
    except MemoryError:
        status, message, warning = "failed", f"step {done + 1}: out of memory", ""
    except DiskFull as e:  # checked before each block: the file is whole up to the last block
        return _disk_full(writer, e, result)
    except _WriteFailed as e:
        return _write_failed(writer, e.__cause__, result)
    except TrajectoryError:  # the file to resume from is damaged: leave everything as it was
        writer.abandon()
        raise
    except BaseException as e:  # a bug: keep the frames, marked incomplete, then let it surface
        writer.close(complete=False, stopped=f"step {done + 1}: {type(e).__name__}: {e}")
        raise
    finally:
        if bar is not None:
            bar.close()
    try:
        writer.close(complete=status == "complete", stopped=message, warnings=warning)
    except DiskFull as e:
        return _disk_full(writer, e, result)
    except (OSError, RuntimeError) as e:
        return _write_failed(writer, e, result)
    return result(status, message, warning)


def _disk_full(writer, error: DiskFull, result) -> RunResult:
    if writer.frames == 0:
        writer.abandon()
        return result("failed", f"{error.strerror}; nothing was written", written=False)
    writer.close(complete=False, stopped=str(error), drop_buffered=True)
    return result("failed", f"{error.strerror}; kept the {writer.frames} frames written before it "
                            f"(complete = false, resumable)")


def _write_failed(writer, error: Exception, result) -> RunResult:
    kept = writer.salvage(f"write failed: {error}")
    reason = getattr(error, "strerror", None) or str(error).split("\n")[0]
    return result("failed", f"cannot write {writer.partial} ({reason}); {kept}", written=False)
