"""Faithful-dynamics figures: the checks a user can make with a ruler and a stopwatch, measured.

    python -m blobcli.tools.dynamics

prints one line per case (what physics says, what blobsim does). The suite asserts the same
cases within the tolerances of tests/conftest.py (tests/test_invariants.py, test_collide.py);
this prints the numbers that docs/physics.md quotes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..scene.schema import parse_scene
from ..sim.model import build, build_params
from ..sim.pipeline import advance

G = 9.81
SCENES = Path(__file__).resolve().parents[2] / "scenes"
FLOOR = '\n[[static]]\nkind = "plane"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n'
HARD = "pressure = 1.1\ncompliance = 1e-6\n"  # a hard blob: over-pressured, nearly inextensible skin


def _run(text: str):
    scene = parse_scene(text, "dynamics")
    model, state = build(scene)
    return model, state, build_params(scene)


def _centre(state, o=0, e=None):
    return state.pos[o:e].mean(axis=0)


def _spin(state, o=0, e=None):
    r = state.pos[o:e] - _centre(state, o, e)
    v = state.vel[o:e]
    return float((r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]).sum() / (r ** 2).sum())


def rolling(vertices: int, degrees: float = 10.0) -> float:
    """A hard blob's acceleration down a slope (friction 1), over a ring's g sin θ / 2."""
    th = math.radians(degrees)
    model, state, params = _run(f"[scene]\ngravity = [{G * math.sin(th)!r}, {-G * math.cos(th)!r}]\n"
                                f"[[blob]]\ncenter = [0.0, 0.5]\nradius = 0.5\nvertices = {vertices}\n{HARD}"
                                "friction = 1.0\nstatic_friction = 1.0\n" + FLOOR)
    advance(state, model, params, 60)
    t, x = [], []
    for k in range(120):
        advance(state, model, params, 1)
        t.append(k / 60)
        x.append(_centre(state)[0])
    return 2 * np.polyfit(t, x, 2)[0] / (G * math.sin(th) / 2)


def spin_kept(seconds: float = 10.0) -> float:
    """A free blob spun at 4 rad/s, damping 0, no gravity: ω after `seconds` over ω before."""
    model, state, params = _run("[scene]\ngravity = [0.0, 0.0]\ndamping = 0.0\n"
                                "[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.5\nangular_velocity = 4.0\n")
    before = _spin(state)
    advance(state, model, params, round(seconds * 60))
    return _spin(state) / before


def _drop(restitution, substeps, iterations, height, damping, pressure, radius, seconds):
    """(rest height of the centre, the centre's peaks after it first turned upward)."""
    def text(y):
        return (f"[scene]\nsubsteps = {substeps}\niterations = {iterations}\ndamping = {damping}\n"
                f"[[blob]]\ncenter = [0.0, {y}]\nradius = {radius}\npressure = {pressure}\ncompliance = 1e-6\n"
                f"restitution = {restitution}\n" + FLOOR)
    model, state, params = _run(text(radius * 1.1))
    advance(state, model, params, 120)
    rest = float(_centre(state)[1])
    model, state, params = _run(text(rest + height))
    heights, rising = [], False
    for _ in range(round(seconds * 60)):
        advance(state, model, params, 1)
        rising = rising or state.vel[:, 1].mean() > 0
        if rising:
            heights.append(_centre(state)[1])
    y = np.array(heights)
    return rest, y[1:-1][(y[1:-1] >= y[:-2]) & (y[1:-1] > y[2:])]


def rebound(restitution: float, substeps: int, iterations: int) -> float:
    """A hard blob dropped 1.4 m: its first rebound over the drop."""
    rest, peaks = _drop(restitution, substeps, iterations, 1.4, 2.0, 1.1, 0.5, 2.5)
    return float(max(peaks[0] - rest, 0.0) / 1.4) if len(peaks) else 0.0


def highest_bounce(substeps: int, iterations: int) -> float:
    """A stiff blob (pressure 1.2), e = 1, damping 0, dropped 1.7 m: its highest peak over the drop."""
    rest, peaks = _drop(1.0, substeps, iterations, 1.7, 0.0, 1.2, 0.3, 8.0)
    return float((peaks.max() - rest) / 1.7)


def head_on(restitution: float, hard: bool = True, radius: float = 0.4, steps: int = 90,
            friction: float | None = None):
    """Two blobs meeting head-on at 3 m/s each, corner to corner (with the scene's default friction, or
    `friction` static and kinetic): (parting speed over approach speed, worst distance of a blob's centre
    from the axis in m, worst vertex mirror error in m)."""
    th = 2 * np.pi * np.arange(32) / 32
    a = np.stack([-1 + radius * np.cos(th), radius * np.sin(th)], axis=1)
    b = (a * [-1, 1])[::-1]

    def points(p):
        return "[" + ", ".join(f"[{float(x)!r}, {float(y)!r}]" for x, y in p) + "]"
    extra = f"restitution = {restitution}\n" + (HARD if hard else "")
    if friction is not None:
        extra += f"friction = {friction!r}\nstatic_friction = {friction!r}\n"
    model, state, params = _run(f"[scene]\ngravity = [0.0, 0.0]\n[[blob]]\npoints = {points(a)}\n"
                                f"velocity = [3.0, 0.0]\n{extra}[[blob]]\npoints = {points(b)}\n"
                                f"velocity = [-3.0, 0.0]\n{extra}")
    axis = mirror = 0.0
    for _ in range(steps):
        advance(state, model, params, 1)
        axis = max(axis, abs(_centre(state, 0, 32)[1]), abs(_centre(state, 32)[1]))
        mirror = max(mirror, float(np.abs(state.pos[:32] - (state.pos[32:] * [-1, 1])[::-1]).max()))
    parting = state.vel[32:, 0].mean() - state.vel[:32, 0].mean()
    return float(parting / 6.0), axis, mirror


def dropped_straight(seconds: float = 30.0) -> float:
    """A default r = 1 m blob dropped 0.2 m onto a level floor: its worst distance from the axis (m)."""
    model, state, params = _run("[[blob]]\ncenter = [0.0, 1.2]\nradius = 1.0\n" + FLOOR)
    worst = 0.0
    for _ in range(round(seconds * 2)):
        advance(state, model, params, 30)
        worst = max(worst, abs(float(_centre(state)[0])))
    return worst


def crushed_light_blob(seconds: float = 5.0) -> tuple[float, float, bool]:
    """scenes/crusher.toml at the defaults: the light blob's worst area error |A / A_0 - 1| over the
    run, at its end, and whether its polygon ever self-intersected (checked after every step)."""
    from ..geometry import first_crossing, signed_area
    model, state, params = _run((SCENES / "crusher.toml").read_text())
    light = slice(model.offsets[0], model.offsets[1])
    worst = error = 0.0
    crossed = False
    for _ in range(round(seconds / params.dt)):
        advance(state, model, params, 1)
        crossed |= first_crossing(state.pos[light]) is not None
        error = abs(signed_area(state.pos[light]) / model.target_area[0] - 1.0)
        worst = max(worst, error)
    return worst, error, crossed


def deepest_overlap(state, model) -> float:
    """The deepest vertex inside another blob (m), over the pairs whose bounding circles (about the vertex
    means, through the farthest vertex) overlap: the pairs that can overlap at all."""
    from ..geometry import depth_inside_polygon
    ring = [state.pos[model.offsets[b]:model.offsets[b + 1]] for b in range(model.blob_count)]
    center = np.array([r.mean(axis=0) for r in ring])
    radius = np.array([np.hypot(*(r - c).T).max() for r, c in zip(ring, center)])
    a, b = np.triu_indices(model.blob_count, 1)
    near = np.hypot(*(center[a] - center[b]).T) < radius[a] + radius[b]
    pairs = zip(a[near], b[near])
    return max((float(depth_inside_polygon(ring[x], ring[y]).max()) for a, b in pairs for x, y in ((a, b), (b, a))),
               default=0.0)


def settled_pile(seconds: tuple[float, float] = (6.0, 10.0), settings: str = "") -> dict:
    """scenes/pile.toml (120 blobs), sleeping off (and `settings`, more [scene] lines): the deepest
    vertex inside another blob (m) at the first of `seconds`, its median and worst over the window,
    and each blob's area error |A / A_0 - 1| at the first (mean, worst)."""
    from ..geometry import signed_area
    text = (SCENES / "pile.toml").read_text()
    model, state, params = _run(text.replace("[scene]\n", f"[scene]\nsleep = false\n{settings}", 1))
    first, last = (round(t / params.dt) for t in seconds)
    advance(state, model, params, first)
    error = [abs(signed_area(state.pos[model.offsets[b]:model.offsets[b + 1]]) / model.target_area[b] - 1.0)
             for b in range(model.blob_count)]
    depths = [deepest_overlap(state, model)]
    for _ in range(last - first):
        advance(state, model, params, 1)
        depths.append(deepest_overlap(state, model))
    return {"deepest_m": depths[0], "median_deepest_m": float(np.median(depths)), "worst_deepest_m": max(depths),
            "mean_area_error": float(np.mean(error)), "worst_area_error": float(np.max(error))}


def main() -> None:
    print("case | physics says | blobsim")
    for n in (32, 64, 128):
        print(f"hard blob rolling down 10°, {n} vertices | g sin θ / 2 | {rolling(n):.3f} of it")
    print(f"free spin 4 rad/s, damping 0, 10 s | kept | {spin_kept():.12f} of it")
    for s, i in ((4, 2), (16, 4), (32, 8)):
        print(f"stiff blob, e = 1, damping 0, {s} × {i}: highest bounce | ≤ drop | {highest_bounce(s, i):.4f} of it")
    for e in (0.0, 0.5, 1.0):
        print(f"hard blob dropped 1.4 m, e = {e} | rebound ≈ e² = {e * e:.2f} | "
              f"{rebound(e, 4, 2):.3f} at 4 × 2, {rebound(e, 16, 4):.3f} at 16 × 4")
    for e in (1.0, 0.0):
        parting, axis, _ = head_on(e)
        print(f"hard blobs head-on, e = {e} | part at ≈ {e:.0f} × approach | {parting:.3f}")
    _, axis, mirror = head_on(0.0, hard=False)
    print(f"default blobs head-on (r = 0.4 m) | stay on the axis | {axis * 1e3:.3f} mm off it, "
          f"vertices mirrored within {mirror * 1e3:.2f} mm")
    for seconds in (0.8, 3.0):
        _, axis, _ = head_on(0.0, hard=False, steps=round(seconds * 60), friction=0.0)
        print(f"default blobs head-on, frictionless, {seconds} s | stay on the axis | {axis * 1e3:.3f} mm off it")
    print(f"default r = 1 m blob dropped straight, 30 s | stays centred | {dropped_straight() * 1e3:.2g} mm off")
    worst, end, crossed = crushed_light_blob()
    print(f"crusher.toml: 0.1 kg blob under 3 × 15 kg | keeps its area, never tangles | within {worst:.2%} "
          f"(at 5 s {end:.2%}), {'self-intersected' if crossed else 'never self-intersected'}")
    pile = settled_pile()
    print(f"pile.toml settled, sleep off, 6 s | no vertex deep in another blob | "
          f"deepest {pile['deepest_m'] * 1e3:.3f} mm "
          f"(6-10 s: median {pile['median_deepest_m'] * 1e3:.3f}, worst {pile['worst_deepest_m'] * 1e3:.3f}); area "
          f"error mean {pile['mean_area_error']:.2%}, worst {pile['worst_area_error']:.2%}")
    pile = settled_pile(settings="substeps = 8\n")
    print(f"the same at 8 substeps | | deepest {pile['deepest_m'] * 1e3:.3f} mm, area error mean "
          f"{pile['mean_area_error']:.2%}")


if __name__ == "__main__":
    main()
