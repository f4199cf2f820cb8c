"""`python -m blobcli.tools.piles`: do piles come to rest, and what does a sleeping pile cost?

Prints, for a pile of blobs dropped into a box (bench.scene_text, "piled") and for the shipped
scenes/stack.toml (or, with `--layout NAME ...`, for piles unlike the bench's own: LAYOUTS): the
fastest blob centre and the fastest vertex over the last second before `--seconds` with sleeping
off, and with sleeping on (the default) the share of blobs asleep and the wall time of that last
second against the same second awake; with `--each-second-from S`, the pile's fastest centre and
vertex (sleeping off) in every second from S to `--seconds` (a layout's lines also give the fastest
vertex by its motion over a step: `fastest`; with `--perturb EPS`, each blob first moved by up to EPS); with
`--impact`, how a blob dropped onto the pile's end moves the blobs far from it; with `--smallest`, the smallest
scenes that do not rest (SMALLEST). Figures, not tests: the tests (tests/test_sleep.py) hold smaller cases to
tolerances.
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def _run(scene, seconds: float, perturb: float = 0.0, seed: int = 1):
    """(model, state after `seconds`, params, steps per second) of `scene`, each blob first moved rigidly by a
    random offset of up to `perturb` m per axis (uniform, numpy's default_rng(seed), blob by blob)."""
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance
    model, state = build(scene)
    params = build_params(scene)
    if perturb > 0.0:
        rng = np.random.default_rng(seed)
        for o, e in zip(model.offsets[:-1], model.offsets[1:]):
            state.pos[o:e] += rng.uniform(-perturb, perturb, 2)
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
    centre, vertex, _ = fastest(state, model, params, per_second)
    return {"centre_m_s": centre, "vertex_m_s": vertex, "asleep": 1.0 - float(state.awake.mean()), "wall_s": wall}


def fastest(state, model, params, steps: int) -> tuple[float, float, float]:
    """Advance `steps` steps one at a time; the fastest blob centre and the fastest vertex seen (m/s), and the
    fastest vertex as a recording of every step shows it: the most any vertex moved in one step, over dt (m/s).
    The last can be far below the second: a contact vertex can end every step where it began and still keep a
    velocity along its push normal (random-90's, docs/physics.md)."""
    from ..sim.packing import centres
    from ..sim.pipeline import advance
    centre = vertex = moved = 0.0
    for _ in range(steps):
        before = state.pos.copy()
        advance(state, model, params, 1)
        centre = max(centre, float(np.hypot(*centres(state.vel, model.offsets).T).max()))  # mean vertex velocity
        vertex = max(vertex, float(np.hypot(*state.vel.T).max()))
        moved = max(moved, float(np.hypot(*(state.pos - before).T).max()) / params.dt)
    return centre, vertex, moved


def each_second(scene, first: int, last: int, perturb: float = 0.0,
                seed: int = 1) -> list[tuple[int, float, float, float]]:
    """Run `scene` to `last` seconds; for each second from `first` on: (its start, fastest centre, fastest
    vertex, fastest vertex by its motion over a step: `fastest`) in m/s. One second alone can mislead in a pile
    still settling (a blob that slips). perturb, seed: see _run."""
    model, state, params, per_second = _run(scene, first, perturb, seed)
    return [(second, *fastest(state, model, params, per_second)) for second in range(first, last)]


FLOOR = '[[static]]\nkind = "plane"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n'  # the plane y = 0, solid below


def _segment_walls(half: float, top: float, floor: str) -> str:
    """A floor (a plane, or a segment from -half to half) at y = 0 and two segment walls up to `top`"""
    if floor == "plane":
        text = FLOOR
    else:
        text = f'[[static]]\nkind = "segment"\na = [{-half}, 0.0]\nb = [{half}, 0.0]\n'
    for x in (-half, half):
        text += f'[[static]]\nkind = "segment"\na = [{x}, 0.0]\nb = [{x}, {top}]\n'
    return text


def grid_pile(cols: int, rows: int, radius: float, vertices: int, half: float, floor: str = "plane") -> str:
    """cols × rows blobs dropped from a grid as wide as the box (2 half), segment walls"""
    dx = 2 * half / cols
    return (f'[scene]\nsleep = false\n[[blob]]\nname = "b"\ncenter = [{-half + dx / 2}, {radius + 0.05}]\n'
            f"radius = {radius}\nvertices = {vertices}\ngrid = [{cols}, {rows}]\nspacing = [{dx}, {2.15 * radius}]\n"
            + _segment_walls(half, rows * 2.15 * radius + 2.0, floor))


def tilted_pile(cols: int, rows: int, radius: float, vertices: int, half: float, degrees: float,
                friction: float) -> str:
    """A grid dropped onto a plane floor tilted by `degrees`, between box walls, blobs and floor of `friction`"""
    slope = math.tan(math.radians(degrees))
    top = rows * 2.15 * radius + 2.0 + half * slope
    return (f'[scene]\nsleep = false\n[[blob]]\nname = "b"\ncenter = [{-half + half / cols}, '
            f"{radius + 0.1 + half * slope}]\nradius = {radius}\nvertices = {vertices}\nfriction = {friction}\n"
            f"grid = [{cols}, {rows}]\nspacing = [{2 * half / cols}, {2.15 * radius}]\n"
            f'[[static]]\nkind = "plane"\npoint = [0.0, 0.0]\n'
            f"normal = [{-math.sin(math.radians(degrees))}, {math.cos(math.radians(degrees))}]\nfriction = {friction}\n"
            + "".join(f'[[static]]\nkind = "box"\ncenter = [{x}, {top / 2}]\nsize = [0.2, {top + 2.0}]\n'
                      for x in (-half - 0.1, half + 0.1)))


def random_pile(small: int, large: int, half: float, height: float, seed: int) -> str:
    """Two sizes (r 0.3 m of 48 vertices, r 0.42 m of 32 and twice the mass) placed at random in a channel
    of segments, then dropped"""
    region = f"[{-half}, 0.0, {half}, {height}]"
    return (f"[scene]\nsleep = false\nseed = {seed}\n"
            f'[[blob]]\nname = "s"\nradius = 0.3\nvertices = 48\ncount = {small}\nregion = {region}\n'
            f'[[blob]]\nname = "l"\nradius = 0.42\nvertices = 32\nmass = 2.0\ncount = {large}\nregion = {region}\n'
            + _segment_walls(half, height + 2.0, "segment"))


# Piles unlike the bench's own, so that a contact rule tuned to one pile cannot pass: boxes of segments and
# of boxes, plane and segment floors, a tilted floor, radius 0.3-0.5 m, 24-48 vertices, one and two sizes,
# grids and random starts, 48 to 1,000 blobs. (name: (scene text, seconds after which the pile should rest))
LAYOUTS = {
    "segment-box-60": (lambda: grid_pile(6, 10, 0.45, 24, 3.2, floor="segment"), 14.0),
    "plane-60": (lambda: grid_pile(6, 10, 0.45, 24, 3.2), 14.0),
    "offset-91": (lambda: grid_pile(7, 13, 0.4, 32, 3.3, floor="segment"), 16.0),
    "small-80": (lambda: grid_pile(10, 8, 0.3, 48, 3.2), 14.0),
    "tilted-48": (lambda: tilted_pile(8, 6, 0.4, 32, 3.4, 4.0, 0.7), 14.0),
    "tilted-60": (lambda: tilted_pile(6, 10, 0.45, 24, 3.2, 4.0, 0.7), 14.0),
    "random-90": (lambda: random_pile(45, 45, 2.6, 22.0, 1), 22.0),
    "plane-300": (lambda: grid_pile(15, 20, 0.5, 32, 7.75), 18.0),
    "plane-1000": (lambda: grid_pile(25, 40, 0.5, 32, 12.75), 25.0),
}


# One more blob of the pile's kind, on a frictionless shelf `drop` m above the pile's top over its last column; at
# `at` s the shelf slides 3 m aside in 0.05 s and the blob falls onto the pile's end.
DROPPED_ON_A_SHELF = """
[[blob]]
name = "dropped"
center = [{x}, {y}]
radius = {radius}
vertices = {vertices}
[[static]]
kind = "box"
center = [{x}, {shelf}]
size = [{width}, 0.1]
friction = 0.0
static_friction = 0.0
path = [[{at}, 0.0, 0.0, 0.0], [{gone}, 3.0, 0.0, 0.0]]
"""


def impact(blobs: int = 60, at: float = 12.0, drop: float = 3.0, settings: str = "") -> list[tuple[float, ...]]:
    """The bench's pile of `blobs` (sleeping off) at rest `at` s after its drop, and a blob dropped onto its end
    from about `drop` m: every quarter second for two seconds after the impact, (time after it (s), fastest
    centre and fastest vertex (m/s) of the blobs more than two diameters from the impact point). The impact is
    the first step the dropped blob's centre comes within 2.2 radii of another's."""
    from ..scene.schema import parse_scene
    from ..sim.model import build
    from ..sim.packing import centres
    from ..sim.pipeline import advance
    from .bench import RADIUS, VERTICES, scene_text
    pile = scene_text(blobs, "piled", settings)
    model, state = build(parse_scene(pile, "pile"))
    start = centres(state.pos, model.offsets)
    top = len(np.unique(np.round(start[:, 1], 6))) * 2 * RADIUS + drop  # rows at 2 R each, then the drop
    x = float(start[:, 0].max()) - 0.5 * RADIUS
    scene = parse_scene(pile + DROPPED_ON_A_SHELF.format(x=x, y=top + RADIUS + 0.01, radius=RADIUS,
                                                         vertices=VERTICES, shelf=top - 0.05, width=4 * RADIUS,
                                                         at=at, gone=at + 0.05), "impact")
    model, state, params, per_second = _run(scene, at)
    rows, hit = [], None
    for k in range(4 * per_second):
        advance(state, model, params, 1)
        centre = centres(state.pos, model.offsets)
        if hit is None and np.hypot(*(centre[:-1] - centre[-1]).T).min() < 2.2 * RADIUS:
            hit = (k, centre[-1].copy())
        if hit is not None and (k - hit[0]) % (per_second // 4) == 0:
            far = np.hypot(*(centre[:-1] - hit[1]).T) > 4 * RADIUS
            speed = np.hypot(*centres(state.vel, model.offsets)[:-1].T)  # each blob's mean vertex velocity
            vertex = np.hypot(*state.vel.T)
            far_vertex = np.repeat(np.append(far, False), np.diff(model.offsets))
            rows.append(((k - hit[0]) * params.dt, float(speed[far].max()), float(vertex[far_vertex].max())))
            if len(rows) == 9:
                break
    return rows


# The two smallest scenes that do not come to rest, at a fixed substep count. "resting": one blob on a plane, nudged
# at 0.1 mm/s: it settles on a vertex, at the defaults a saddle of its rolling (a polygon's weight rises and falls as
# it rolls through a vertex spacing), and rocks about the next edge, barely damped (tools/modes). "wedge": two blobs
# on a plane 0.3 m apart and a third dropped into the gap 5 cm off its middle; rigid discs so placed rest for any
# friction above tan(θ/2) = 0.38, θ = 41.8° the contact normals' angle from the vertical, and the blobs' is 0.6
# (though three discs that roll without slipping, the lower two on the floor and the top one the other way round, are
# a gear train that moves at no cost in energy).
SMALLEST = {
    "resting": """
[[blob]]
name = "resting"
center = [0.0, 0.46]
radius = 0.45
vertices = 24
velocity = [1e-4, 0.0]
""",
    "wedge": """
[[blob]]
name = "below"
center = [-0.6, 0.46]
radius = 0.45
vertices = 24
grid = [2, 1]
spacing = [1.2, 0.0]
[[blob]]
name = "top"
center = [0.05, 1.4]
radius = 0.45
vertices = 24
"""}


def smallest(name: str, substeps: int, seconds: int = 20) -> list[tuple[int, float, float, float]]:
    """SMALLEST[name] at a fixed substep count: each second's fastest centre, vertex and vertex moved (m/s;
    each_second)"""
    from ..scene.schema import parse_scene
    head = f"[scene]\nsleep = false\nsubsteps = {substeps}\nmax_substeps = {substeps}\n"
    return each_second(parse_scene(head + SMALLEST[name] + FLOOR, name), 1, seconds)


def sleep_setting(scene, sleep: bool):
    return replace(scene, settings=replace(scene.settings, sleep=sleep))


def main(argv=None) -> int:
    from ..scene.schema import load_scene, parse_scene
    from .bench import scene_text
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blobs", type=int, default=60)
    ap.add_argument("--seconds", type=float, help="simulated time after the drop (s; default 14, and with --layout "
                    "each pile's own time)")
    ap.add_argument("--each-second-from", type=int, metavar="S",
                    help="also print the pile's fastest centre and vertex (sleeping off) for every second from S on; "
                         "with --layout, instead of its last second alone")
    ap.add_argument("--layout", nargs="+", choices=[*LAYOUTS, "all"], metavar="NAME",
                    help=f"instead: the fastest centre and vertex (sleeping off) in the last second of each of these "
                         f"piles, by its own time ({', '.join(LAYOUTS)}, or all)")
    ap.add_argument("--perturb", type=float, default=0.0, metavar="EPS",
                    help="with --layout: move each blob by a random offset of up to EPS m per axis before the drop "
                         "(a grid's columns are otherwise mirror images of each other; default 0)")
    ap.add_argument("--seed", type=int, default=1, help="with --perturb: the offsets' random seed (default 1)")
    ap.add_argument("--impact", action="store_true",
                    help="instead: the pile of --blobs at rest, one blob dropped onto its end from about 3 m at 12 s; "
                         "the fastest centre and vertex of the blobs more than two diameters from the impact, every "
                         "quarter second for two seconds")
    ap.add_argument("--smallest", action="store_true",
                    help="instead: the smallest scenes that do not rest (SMALLEST: one blob on a floor, three in a "
                         "wedge) at 2, 4 and 16 substeps, the fastest centre and vertex each second for 20 s")
    args = ap.parse_args(argv)
    if (args.perturb != 0.0 or args.seed != 1) and not args.layout:
        ap.error("--perturb and --seed go with --layout")
    if args.perturb < 0.0:
        ap.error(f"--perturb: an offset bound in m, at least 0 (got {args.perturb:g})")
    if args.smallest:
        for name in SMALLEST:
            print(f"{name}: fastest centre / vertex each second from 1 s (mm/s)")
            for substeps in (2, 4, 16):
                print(f"  {substeps:2d} substeps: " + " ".join(f"{1e3 * centre:.2f}/{1e3 * vertex:.2f}"
                                                              for _, centre, vertex, _ in smallest(name, substeps)))
        return 0
    if args.impact:
        print(f"pile of {args.blobs} blobs at rest, a blob dropped onto its end from about 3 m: blobs more than two "
              "diameters from the impact, fastest centre / vertex (mm/s)")
        for after, centre, vertex in impact(args.blobs):
            print(f"  {after:.2f} s after the impact: {1e3 * centre:.2f} / {1e3 * vertex:.2f}")
        return 0
    if args.layout:
        for name in LAYOUTS if "all" in args.layout else args.layout:
            text, seconds = LAYOUTS[name]
            seconds = int(args.seconds or seconds)
            first = seconds - 1 if args.each_second_from is None else args.each_second_from
            for second, centre, vertex, moved in each_second(parse_scene(text(), name), first, seconds, args.perturb,
                                                             args.seed):
                print(f"{name}, second {second:g}-{second + 1:g}: fastest centre {1e3 * centre:.2f} mm/s, "
                      f"fastest vertex {1e3 * vertex:.2f} mm/s (moved over a step: {1e3 * moved:.2f} mm/s)")
        return 0
    seconds = args.seconds or 14.0
    cases = [(f"pile of {args.blobs} blobs", parse_scene(scene_text(args.blobs, "piled"), "pile")),
             ("scenes/stack.toml", load_scene(ROOT / "scenes" / "stack.toml"))]
    for name, scene in cases:
        awake = last_second(sleep_setting(scene, False), seconds)
        asleep = last_second(sleep_setting(scene, True), seconds)
        print(f"{name}, second {seconds - 1:g}-{seconds:g} after the drop:")
        print(f"  sleep = false: fastest centre {1e3 * awake['centre_m_s']:.2f} mm/s, fastest vertex "
              f"{1e3 * awake['vertex_m_s']:.2f} mm/s; wall {1e3 * awake['wall_s']:.1f} ms")
        print(f"  sleep = true:  {100 * asleep['asleep']:.0f}% of blobs asleep; wall {1e3 * asleep['wall_s']:.1f} ms, "
              f"{100 * asleep['wall_s'] / awake['wall_s']:.1f}% of awake")
    if args.each_second_from is not None:
        print(f"pile of {args.blobs} blobs, sleep = false, each second (fastest centre / vertex, mm/s):")
        for second, centre, vertex, _ in each_second(sleep_setting(cases[0][1], False), args.each_second_from,
                                                     int(seconds)):
            print(f"  {second}-{second + 1} s: {1e3 * centre:.2f} / {1e3 * vertex:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
