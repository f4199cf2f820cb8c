"""Driving forces and torques, measured: the figures of docs/physics.md ("Driving: force and torque").

    python -m blobcli.tools.driving

prints the momentum and angular momentum a free blob gains under a force, a torque and both (against F T and
τ T), and the torque at which a ring on a 10° slope neither climbs nor rolls back (against m g R sin θ), with the
two parts of its moment balance. tests/test_driving.py asserts the same cases.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene.schema import parse_scene
from ..sim.model import build, build_params
from ..sim.pipeline import advance

G = 9.81
FLOOR = '\n[[static]]\nkind = "plane"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n'


def _run(text: str):
    scene = parse_scene(text, "driving")
    model, state = build(scene)
    return model, state, build_params(scene)


def momenta(state, model) -> tuple[np.ndarray, float]:
    """(P = Σ m v (2,) kg m/s, L = Σ m r × v about the centre of mass, kg m²/s) of a one-blob scene."""
    m = 1.0 / model.inv_mass
    r = state.pos - (m[:, None] * state.pos).sum(axis=0) / m.sum()
    L = (m * (r[:, 0] * state.vel[:, 1] - r[:, 1] * state.vel[:, 0])).sum()
    return (m[:, None] * state.vel).sum(axis=0), float(L)


IRREGULAR = [[0.0, 0.0], [0.9, -0.1], [1.2, 0.3], [1.0, 0.8], [0.3, 0.7], [-0.2, 0.4]]  # m: a lopsided hexagon


def free_blob(force=(0.0, 0.0), torque: float = 0.0, seconds: float = 2.0, mass: float = 2.0, points=None):
    """A blob at rest (a ring of r = 0.5 m, or the polygon `points`), no gravity, driven for `seconds`: (P, L) it
    gained, and (F T, τ T)."""
    shape = "center = [0.3, -0.2]\nradius = 0.5\n" if points is None else f"points = {points}\n"
    model, state, params = _run(f"[scene]\ngravity = [0.0, 0.0]\n[[blob]]\n{shape}"
                                f"mass = {mass!r}\nforce = [{force[0]!r}, {force[1]!r}]\ntorque = {torque!r}\n")
    steps = round(seconds / params.dt)
    advance(state, model, params, steps)
    P, L = momenta(state, model)
    return P, L, np.array(force) * steps * params.dt, torque * steps * params.dt


JUMP = """
[scene]
steps = 180
sleep = false
[[blob]]
name = "base"
center = [0.0, 0.6]
radius = 0.6
mass = 4.0
[[blob]]
name = "gish"
center = [0.0, 1.5]
radius = 0.3
[[schedule]]
key = "blob.gish.force"
at = [[1.5, 0.0, 0.0], [1.55, 0.0, 40.0], [1.8, 0.0, 40.0], [1.85, 0.0, 0.0]]
""" + FLOOR  # a 1 kg blob dropped on a 4 kg one, at rest by 1.5 s, then pushed up by 40 N for 0.3 s


def jump(off_blob: bool = True) -> tuple[float, float]:
    """JUMP's pushed blob, on the other blob or (off_blob false) beside it on the floor: (how high its centre rises
    above where it rested at 1.47 s, m; its fastest upward centre speed, m/s)."""
    from ..sim.schedule import Schedules
    text = JUMP if off_blob else JUMP.replace("center = [0.0, 1.5]", "center = [1.5, 0.4]")
    model, state, params = _run(text)
    schedules = Schedules(parse_scene(text, "driving"), model, params)
    gish = slice(model.offsets[1], model.offsets[2])
    heights, speeds = [], []
    for step in range(params.steps):
        advance(state, model, params, 1, step_settings=schedules.apply(step, None, state), arrays=schedules.arrays)
        heights.append(state.pos[gish, 1].mean())
        speeds.append(state.vel[gish, 1].mean())
    return float(max(heights[90:]) - heights[88]), float(max(speeds))


def slope_scene(ratio: float, degrees: float = 10.0, radius: float = 0.5, mass: float = 1.0, blob: str = "") -> str:
    """A default ring (friction 1: it rolls; `blob`: more of its keys) on a floor, gravity tilted by `degrees`
    (downhill is +x), under a counter-clockwise (uphill) torque of `ratio` × m g R sin θ."""
    th = math.radians(degrees)
    torque = float(ratio) * mass * G * radius * math.sin(th)
    return (f"[scene]\ngravity = [{G * math.sin(th)!r}, {-G * math.cos(th)!r}]\nsleep = false\n"
            f"[[blob]]\ncenter = [0.0, {radius!r}]\nradius = {radius!r}\nmass = {mass!r}\nfriction = 1.0\n"
            f"static_friction = 1.0\ntorque = {torque!r}\n{blob}" + FLOOR)


def slope_speed(ratio: float, seconds: tuple[float, float] = (2.0, 6.0), **kw) -> float:
    """The ring's mean speed down the slope (m/s, < 0: it climbs) over `seconds`."""
    model, state, params = _run(slope_scene(ratio, **kw))
    first, last = (round(t / params.dt) for t in seconds)
    advance(state, model, params, first)
    x = state.pos[:, 0].mean()
    advance(state, model, params, last - first)
    return float((state.pos[:, 0].mean() - x) / ((last - first) * params.dt))


def threshold(low: float = 0.8, high: float = 1.2, tolerance: float = 1e-3, **kw) -> float:
    """The torque, over m g R sin θ, at which the ring neither climbs nor rolls back (bisection on the sign of
    slope_speed: it rolls back at `low` and climbs at `high`)."""
    assert slope_speed(low, **kw) > 0.0 > slope_speed(high, **kw)
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        if slope_speed(middle, **kw) > 0.0:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def balance(ratio: float, seconds: tuple[float, float] = (2.0, 6.0), **kw) -> dict:
    """The moment balance about the ring's centre of mass, over `seconds`, from the floor's recorded impulses
    (State.static_impulse: J and its moment about the floor's point, the origin): the centre's height d above the
    floor (m), where the floor's push acts, e = its x less the centre's (m, < 0: uphill), and the mean speed."""
    model, state, params = _run(slope_scene(ratio, **kw))
    first, last = (round(t / params.dt) for t in seconds)
    advance(state, model, params, first)
    d, e, v = [], [], []
    for _ in range(last - first):
        advance(state, model, params, 1)
        jx, jy, moment = state.static_impulse[0]
        centre = state.pos.mean(axis=0)
        d.append(centre[1])
        e.append(moment / jy - centre[0])  # the push acts on y = 0: its moment about the origin is x J_y
        v.append(state.vel[:, 0].mean())
    return {"d": float(np.mean(d)), "e": float(np.mean(e)), "speed": float(np.mean(v))}


def main() -> None:
    print("case | physics says | blobsim")
    for shape, points in (("ring", None), ("lopsided hexagon", IRREGULAR)):
        for force, torque in (((3.0, -1.5), 0.0), ((0.0, 0.0), 0.7), ((3.0, -1.5), 0.7)):
            P, L, FT, tT = free_blob(force, torque, points=points)
            p_error = float(np.hypot(*(P - FT)) / np.hypot(*FT)) if any(force) else float(np.hypot(*P))
            l_error = abs(L - tT) / abs(tT) if torque else abs(L)
            print(f"free 2 kg {shape}, F = {force} N, τ = {torque} N m, 2 s | P = F T, L = τ T | "
                  f"{'|P - F T| / |F T|' if any(force) else '|P| (kg m/s)'} = {p_error:.1e}, "
                  f"{'|L - τ T| / |τ T|' if torque else '|L| (kg m²/s)'} = {l_error:.1e}")
    for ratio in (0.8, 1.2):
        print(f"ring on 10°, torque {ratio} m g R sin θ | {'climbs' if ratio > 1 else 'rolls back'} | "
              f"{slope_speed(ratio):+.3f} m/s down the slope, seconds 2-6")
    ratio = threshold()
    b = balance(ratio)
    th = math.radians(10.0)
    print(f"ring on 10°: torque that holds it | m g R sin θ for a rigid ring | {ratio:.3f} m g R sin θ "
          f"(mean speed {b['speed'] * 1e3:+.1f} mm/s): centre d = {b['d']:.4f} m above the slope "
          f"({b['d'] * math.sin(th) / (0.5 * math.sin(th)):.3f} from friction's moment), floor's push "
          f"{b['e'] * 1e3:+.1f} mm from under the centre ({-b['e'] * math.cos(th) / (0.5 * math.sin(th)):.3f} "
          "from the normal force's)")
    for ratio in (0.8, 1.2):
        b = balance(ratio)
        print(f"ring on 10°, torque {ratio} m g R sin θ, rolling | where the floor pushes | d = {b['d']:.4f} m, "
              f"e = {b['e'] * 1e3:+.2f} mm, speed {b['speed']:+.3f} m/s")
    hard = "pressure = 1.1\ncompliance = 1e-6\n"
    speeds = [(k / 100, slope_speed(k / 100, blob=hard)) for k in range(80, 122, 2)]
    print("hard ring (pressure 1.1, compliance 1e-6) on 10° | climbs above m g R sin θ, rolls back below | "
          + ", ".join(f"{k:.2f}: {v:+.3f}" for k, v in speeds) + " m/s down the slope, seconds 2-6")
    for off_blob in (False, True):
        rise, speed = jump(off_blob)
        print(f"1 kg blob at rest on {'a 4 kg blob' if off_blob else 'the floor'}, 40 N up for 0.3 s | 8.6 m/s "
              f"if it left at once | rises {rise:.2f} m, fastest {speed:.2f} m/s")
    for degrees, blob in ((5.0, ""), (20.0, ""), (10.0, "vertices = 64\n"), (10.0, "vertices = 128\n"),
                          (10.0, "pressure = 1.02\n"), (10.0, "compliance = 5e-5\n")):
        ratio = threshold(0.7, 1.3, degrees=degrees, blob=blob)
        b = balance(ratio, degrees=degrees, blob=blob)
        print(f"ring on {degrees:g}°{', ' + blob.strip() if blob else ''}: torque that holds it | m g R sin θ for a "
              f"rigid ring | {ratio:.3f} m g R sin θ: d = {b['d']:.4f} m, e = {b['e'] * 1e3:+.1f} mm")


if __name__ == "__main__":
    raise SystemExit(main())
