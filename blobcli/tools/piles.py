"""`python -m blobcli.tools.piles`: do piles come to rest, and what does a sleeping pile cost?

Prints, for a pile of blobs dropped into a box (bench.scene_text, "piled") and for the shipped
scenes/stack.toml: the fastest blob centre and the fastest vertex over the last second before
`--seconds` with sleeping off, and with sleeping on (the default) the share of blobs asleep and
the wall time of that last second against the same second awake; with `--each-second-from S`,
the pile's fastest centre and vertex (sleeping off) in every second from S to `--seconds`. Figures,
not tests: the tests (tests/test_sleep.py) hold smaller cases to tolerances.
"""

from __future__ import annotations

import argparse
import copy
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _run(scene, seconds: float):
    """(model, state after `seconds`, params, steps per second) of `scene`."""
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance
    model, state = build(scene)
    params = build_params(scene)
    advance(state, model, params, int(round(seconds / params.dt)))
    return model, state, params, int(round(1.0 / params.dt))


def last_second(scene, seconds: float) -> dict:
    """Run `scene` for `seconds`; over the last second: the fastest centre and vertex (m/s), the share
    of blobs asleep at the end and the wall time of that second (s)."""
    from ..sim.pipeline import advance
    model, state, params, per_second = _run(scene, seconds - 1.0)
    timed = copy.deepcopy(state)  # the last second again, in one compiled call, for the wall time
    t0 = time.perf_counter()
    advance(timed, model, params, per_second)
    wall = time.perf_counter() - t0
    centre, vertex = fastest(state, model, params, per_second)
    return {"centre_m_s": centre, "vertex_m_s": vertex, "asleep": 1.0 - float(state.awake.mean()), "wall_s": wall}


def fastest(state, model, params, steps: int) -> tuple[float, float]:
    """Advance `steps` steps one at a time; the fastest blob centre and the fastest vertex seen (m/s)."""
    from ..sim.pipeline import advance
    centre = vertex = 0.0
    sizes = np.diff(model.offsets)[:, None]
    for _ in range(steps):
        advance(state, model, params, 1)
        v = state.vel
        centre = max(centre, float(np.hypot(*(np.add.reduceat(v, model.offsets[:-1]) / sizes).T).max()))
        vertex = max(vertex, float(np.hypot(*v.T).max()))
    return centre, vertex


def each_second(scene, first: int, last: int) -> list[tuple[int, float, float]]:
    """Run `scene` to `last` seconds; for each second from `first` on: (its start, fastest centre, fastest
    vertex) in m/s. One second alone can mislead in a pile still settling (a blob that slips)."""
    model, state, params, per_second = _run(scene, first)
    return [(second, *fastest(state, model, params, per_second)) for second in range(first, last)]


def sleep_setting(scene, sleep: bool):
    return replace(scene, settings=replace(scene.settings, sleep=sleep))


def main(argv=None) -> int:
    from ..scene.schema import load_scene, parse_scene
    from .bench import scene_text
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blobs", type=int, default=60)
    ap.add_argument("--seconds", type=float, default=14.0, help="simulated time after the drop (s)")
    ap.add_argument("--each-second-from", type=int, metavar="S",
                    help="also print the pile's fastest centre and vertex (sleeping off) for every second from S on")
    args = ap.parse_args(argv)
    cases = [(f"pile of {args.blobs} blobs", parse_scene(scene_text(args.blobs, "piled"), "pile")),
             ("scenes/stack.toml", load_scene(ROOT / "scenes" / "stack.toml"))]
    for name, scene in cases:
        awake = last_second(sleep_setting(scene, False), args.seconds)
        asleep = last_second(sleep_setting(scene, True), args.seconds)
        print(f"{name}, second {args.seconds - 1:g}-{args.seconds:g} after the drop:")
        print(f"  sleep = false: fastest centre {1e3 * awake['centre_m_s']:.2f} mm/s, fastest vertex "
              f"{1e3 * awake['vertex_m_s']:.2f} mm/s; wall {1e3 * awake['wall_s']:.1f} ms")
        print(f"  sleep = true:  {100 * asleep['asleep']:.0f}% of blobs asleep; wall {1e3 * asleep['wall_s']:.1f} ms, "
              f"{100 * asleep['wall_s'] / awake['wall_s']:.1f}% of awake")
    if args.each_second_from is not None:
        print(f"pile of {args.blobs} blobs, sleep = false, each second (fastest centre / vertex, mm/s):")
        for second, centre, vertex in each_second(sleep_setting(cases[0][1], False), args.each_second_from,
                                                  int(args.seconds)):
            print(f"  {second}-{second + 1} s: {1e3 * centre:.2f} / {1e3 * vertex:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
