"""Adhesion, measured: the figures of docs/physics.md ("Adhesion").

    python -m blobcli.tools.adhesion

prints the load a sticky blob hanging from a ceiling carries before it lets go (a flat-topped blob, its mass raised
by a schedule), against adhesion × its contact length and × its top face's length; how that load is shared along the
face (a ceiling of one box per face vertex, each box's recorded force); the adhesion a blob needs to stay on a wall;
the rebound of a bouncy blob dropped onto a sticky floor; the energy a blob pulled off a sticky floor has left; and
two sticky blobs that meet in zero gravity. tests/test_adhesion.py asserts the same cases.
"""

from __future__ import annotations

import numpy as np

from ..core import load
from ..scene.schema import parse_scene
from ..sim.model import build, build_params
from ..sim.pipeline import advance
from ..sim.schedule import Schedules

G = 9.81
CEILING = 1.0  # m: the underside of the ceiling box the hanging blobs start on
FACE = 0.8  # m: the flat-topped blob's top face (flat_top's width)


def flat_top(width: float = FACE, face_edges: int = 8, arc_edges: int = 12, top: float = CEILING) -> list:
    """A half disc, flat side up: its top face (face_edges edges of width / face_edges) on y = top, the arc below."""
    radius = width / 2
    points = [[radius - width * k / face_edges, top] for k in range(face_edges)]
    points += [[radius * np.cos(a), top + radius * np.sin(a)] for a in np.pi + np.pi * np.arange(arc_edges) / arc_edges]
    return [[round(float(x), 12), round(float(y), 12)] for x, y in points]


def on_wall(x: float = -1.0, y: float = 2.0) -> list:
    """flat_top turned a quarter: its flat face on the vertical line x, centred at height y, the arc to the right."""
    return [[round(x + CEILING - py, 12), round(y + px, 12)] for px, py in flat_top()]


def _run(text: str):
    """(model, state, params, schedules) of a scene's text"""
    scene = parse_scene(text, "adhesion")
    model, state = build(scene)
    params = build_params(scene)
    return model, state, params, Schedules(scene, model, params)


def _step(model, state, params, schedules, step: int) -> None:
    advance(state, model, params, 1, step_settings=schedules.apply(step, None, state), arrays=schedules.arrays)


def range_of(model, blob: int = 0) -> float:
    """m: how far from a surface blob `blob`'s vertices still hold to it (core/adhesion.c: RANGE_EDGES mean edges)"""
    _, lib = load()
    count = model.offsets[blob + 1] - model.offsets[blob]
    return float(lib.bc_adhesion_range_edges() * model.rest_perimeter[blob] / count)


def shares_of_length(pos: np.ndarray) -> np.ndarray:
    """ℓ_i of a one-ring state: half of each vertex's two edges (m)"""
    return 0.5 * (np.hypot(*(pos - np.roll(pos, -1, axis=0)).T) + np.hypot(*(pos - np.roll(pos, 1, axis=0)).T))


def hang_scene(adhesion: float, points=None, mass: float = 0.05, heavier: float = 2.0, seconds: float = 10.0,
               blob: str = "", ceiling: str = "") -> str:
    """A blob (flat_top, or `points`) hanging from a box whose underside is at CEILING, its mass raised from `mass`
    at 0.5 s to `heavier` at `seconds` (kg)."""
    ceiling = ceiling or f'kind = "box"\ncenter = [0.0, {CEILING + 0.1!r}]\nsize = [4.0, 0.2]\n'
    return (f"[scene]\nduration = {seconds!r}\n[[blob]]\nname = \"gish\"\npoints = {points or flat_top()}\n"
            f"mass = {mass!r}\nadhesion = {adhesion!r}\n{blob}\n[[schedule]]\nkey = \"blob.gish.mass\"\n"
            f"at = [[0.5, {mass!r}], [{seconds!r}, {heavier!r}]]\n[[static]]\n{ceiling}")


def hang(adhesion: float, **kw) -> dict:
    """Raise the mass of a blob hanging from the ceiling (hang_scene) until it lets go: the first step after which
    fewer of its vertices are within range of the ceiling (gap CEILING - y at most range_of) than at the start.
    Returns the time it let go (s; None: it held), the heaviest load it carried (M g at the last step before, N),
    its contact length then (Σ ℓ_i over its vertices in range, m), and the ceiling's largest recorded pull until
    then (N)."""
    model, state, params, schedules = _run(hang_scene(adhesion, **kw))
    r = range_of(model)
    start = int((CEILING - state.pos[:, 1] <= r).sum())
    out = {"let_go": None, "load": 0.0, "length": 0.0, "pull": 0.0, "touching": start}
    for step in range(params.steps):
        mass = model.vertex_count / schedules.arrays.inv_mass[0]
        _step(model, state, params, schedules, step)
        near = CEILING - state.pos[:, 1] <= r
        if near.sum() < start:
            out["let_go"] = step * params.dt
            return out
        out.update(load=mass * G, length=float(shares_of_length(state.pos)[near].sum()),
                   pull=max(out["pull"], -float(state.static_impulse[0, 1]) / params.dt))
    return out


def face_shares(adhesion: float, mass: float, face_edges: int = 8, seconds: float = 2.0) -> np.ndarray:
    """How a flat-topped blob of `mass` (reached by a ramp from 0.5 to 1.5 s) shares its load along its top face: the
    ceiling is one box per face vertex, each as wide as an edge, so each box's recorded pull (N, averaged over the
    last half second) is that vertex's; corners first and last."""
    boxes = "".join(f'[[static]]\nkind = "box"\ncenter = [{FACE / 2 - FACE * k / face_edges!r}, {CEILING + 0.1!r}]\n'
                    f"size = [{FACE / face_edges!r}, 0.2]\n" for k in range(face_edges + 1))
    text = hang_scene(adhesion, flat_top(face_edges=face_edges), heavier=mass, seconds=1.5, blob="",
                      ceiling=boxes.split("[[static]]\n", 1)[1])
    text = text.replace("duration = 1.5", f"duration = {seconds!r}\nsleep = false")
    model, state, params, schedules = _run(text)
    pulls, last = np.zeros(face_edges + 1), round(0.5 / params.dt)
    for step in range(params.steps):
        _step(model, state, params, schedules, step)
        if step >= params.steps - last:
            pulls -= state.static_impulse[:, 1] / params.dt / last
    return pulls


def wall_drift(adhesion: float, settle: float = 2.0, seconds: float = 5.0) -> float:
    """A 1 kg flat-sided blob (on_wall) on a vertical wall (a plane at x = -1, solid to its left), sleeping off: how
    far its centre moves (m) over `seconds` after `settle`."""
    text = (f"[scene]\nsleep = false\n[[blob]]\npoints = {on_wall()}\nadhesion = {adhesion!r}\n"
            "[[static]]\nkind = \"plane\"\npoint = [-1.0, 0.0]\nnormal = [1.0, 0.0]\n")
    model, state, params, _ = _run(text)
    advance(state, model, params, round(settle / params.dt))
    before = state.pos.mean(axis=0)
    advance(state, model, params, round(seconds / params.dt))
    return float(np.hypot(*(state.pos.mean(axis=0) - before)))


def drop(adhesion: float, height: float = 1.0, seconds: float = 6.0, radius: float = 0.3):
    """A stiff bouncy blob (pressure 1.2, compliance 1e-6, restitution 1, damping 0) dropped `height` above its rest
    onto a floor of `adhesion`: (its centre's rest height, m; every peak of its centre after, m)."""
    def text(y):
        return (f"[scene]\ndamping = 0.0\nsleep = false\n[[blob]]\ncenter = [0.0, {y!r}]\nradius = {radius!r}\n"
                "pressure = 1.2\ncompliance = 1e-6\nrestitution = 1.0\n[[static]]\nkind = \"plane\"\n"
                f"point = [0.0, 0.0]\nnormal = [0.0, 1.0]\nadhesion = {adhesion!r}\n")
    model, state, params, _ = _run(text(radius * 1.1))
    advance(state, model, params, 120)
    rest = float(state.pos[:, 1].mean())
    model, state, params, _ = _run(text(rest + height))
    heights = []
    for _ in range(round(seconds / params.dt)):
        advance(state, model, params, 1)
        heights.append(state.pos[:, 1].mean())
    h = np.array(heights)
    return rest, h[1:-1][(h[1:-1] >= h[:-2]) & (h[1:-1] > h[2:])]


def climb(adhesion: float, torque: float, corner: bool, seconds: float = 3.0) -> float:
    """Gish (r = 0.5 m, 1 kg, friction 1) against the wall of the Gish level's ledge (its face at x = 0, its top at
    y = 1.5 m), under a counter-clockwise torque (up the wall): from the corner, resting on a floor (corner), or
    thrown at the wall at 3 m/s beside it, 1.5 m below its top. Returns the highest its centre gets within `seconds`
    (m; over 1.5 + 0.5 it went over the top)."""
    floor = '[[static]]\nkind = "box"\ncenter = [3.5, -0.5]\nsize = [7.0, 1.0]\n' if corner else ""
    start = "center = [0.51, 0.51]\n" if corner else "center = [0.52, 0.0]\nvelocity = [-3.0, 0.0]\n"
    text = (f"[scene]\nduration = {seconds!r}\n[[blob]]\n{start}radius = 0.5\nfriction = 1.0\nstatic_friction = 1.0\n"
            f"adhesion = {adhesion!r}\ntorque = {torque!r}\n{floor}[[static]]\nkind = \"box\"\n"
            "center = [-4.0, -0.75]\nsize = [8.0, 4.5]\n")
    model, state, params, _ = _run(text)
    highest = -np.inf
    for _ in range(params.steps):
        advance(state, model, params, 1)
        highest = max(highest, float(state.pos[:, 1].mean()))
    return highest


PULL = """[scene]
duration = 2.5
damping = 0.0
sleep = false
[[blob]]
name = "gish"
center = [0.0, 0.5]
radius = 0.5
adhesion = {adhesion!r}
[[schedule]]
key = "blob.gish.force"
at = [[1.5, 0.0, 0.0], [1.5166666666666667, 0.0, 30.0], [1.8, 0.0, 30.0], [1.8166666666666667, 0.0, 0.0]]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


def pull_off(adhesion: float) -> tuple[float, float, float]:
    """A default blob at rest on a floor (damping 0), stuck to it by `adhesion`, pulled up by 30 N for 0.3 s from
    1.5 s: (E_after - E_before, the drive's work W over that time, J; the lowest vertex's height at the end, m). E is
    the kinetic and potential energy, Σ ½ m |v|² + m g y; E_before at 1.42 s, E_after at the end (in the air); W is
    Σ F · Δx_cm over the steps, F the schedule's force of each step."""
    model, state, params, schedules = _run(PULL.format(adhesion=adhesion))
    m = 1.0 / model.inv_mass

    def energy():
        return float((0.5 * m * (state.vel ** 2).sum(axis=1)).sum() + G * (m * state.pos[:, 1]).sum())

    def centre():
        return (m[:, None] * state.pos).sum(axis=0) / m.sum()

    begin, work = 85, 0.0
    for step in range(params.steps):
        if step == begin:
            before = energy()
        force = schedules.arrays.driving[0, :2].copy()
        c = centre()
        _step(model, state, params, schedules, step)
        if step >= begin:
            work += float(force @ (centre() - c))
    return energy() - before, work, float(state.pos[:, 1].min())


def pair(adhesion: float, restitution: float = 1.0, seconds: float = 4.0):
    """Two blobs (1 and 2 kg, r = 0.5 m) meeting in zero gravity at 0.4 and -0.1 m/s, restitution e, both of
    `adhesion`: (the distance between their centres at the end, m; the largest change of their total momentum over
    the run, kg m/s; the momentum, kg m/s)."""
    text = "[scene]\ngravity = [0.0, 0.0]\n" + "".join(
        f"[[blob]]\nname = \"{name}\"\ncenter = [{x!r}, {y!r}]\nradius = 0.5\nmass = {mass!r}\n"
        f"velocity = [{v!r}, 0.0]\n"
        f"restitution = {restitution!r}\nadhesion = {adhesion!r}\n"
        for name, x, y, mass, v in (("a", -0.55, 0.05, 1.0, 0.4), ("b", 0.55, -0.05, 2.0, -0.1)))
    text = text.replace("[scene]\n", f"[scene]\nduration = {seconds!r}\n")
    model, state, params, _ = _run(text)
    m = 1.0 / model.inv_mass
    p0 = (m[:, None] * state.vel).sum(axis=0)
    drift = 0.0
    for _ in range(params.steps):
        advance(state, model, params, 1)
        drift = max(drift, float(np.hypot(*((m[:, None] * state.vel).sum(axis=0) - p0))))
    o = model.offsets
    distance = np.hypot(*(state.pos[o[1]:o[2]].mean(axis=0) - state.pos[o[0]:o[1]].mean(axis=0)))
    return float(distance), drift, p0


LEVEL = "scenes/gish_level.toml"  # relative to the project's root


def play(text: str) -> dict:
    """A scene with schedules (the Gish level's text, or a variant of it), step by step: each blob's centre at every
    step ((steps + 1, B, 2) m, step 0 the start), the worst relative area error over the run (|A - A_target| / A_target
    at each step's end, A_target the schedules'), the first shape fault any step ended with (measure.shape_warning;
    "" for none) and the final state and model."""
    from ..geometry import signed_area
    from ..sim.measure import shape_warning
    model, state, params, schedules = _run(text)
    o = model.offsets
    worst, fault = 0.0, ""

    def centre_row():
        return np.array([state.pos[o[b]:o[b + 1]].mean(axis=0) for b in range(model.blob_count)])

    centres = [centre_row()]
    for step in range(params.steps):
        _step(model, state, params, schedules, step)
        centres.append(centre_row())
        for b in range(model.blob_count):
            area = abs(signed_area(state.pos[o[b]:o[b + 1]].tolist()))
            worst = max(worst, abs(area / abs(schedules.arrays.target_area[b]) - 1.0))
        fault = fault or shape_warning(state, model)
    return {"centres": np.array(centres), "area_error": worst, "fault": fault, "state": state, "model": model,
            "dt": params.dt, "masses": [float((o[b + 1] - o[b]) / schedules.arrays.inv_mass[o[b]])
                                        for b in range(model.blob_count)]}


def main() -> None:
    print("case | the law says | blobsim")
    for adhesion in (10.0, 20.0, 40.0):
        h = hang(adhesion)
        print(f"flat-topped blob (face {FACE} m) under a ceiling, adhesion {adhesion:g} N/m, mass raised 0.2 kg/s | "
              f"lets go at M g <= a L = {adhesion * h['length']:.2f} N (L = {h['length']:.3f} m in range) | lets go "
              f"at {h['let_go']:.2f} s, M g = {h['load']:.2f} N (recorded pull {h['pull']:.2f} N) = "
              f"{h['load'] / (adhesion * h['length']):.3f} a L = {h['load'] / (adhesion * FACE):.3f} a × face")
    for mass in (0.3, 0.5):
        pulls = face_shares(20.0, mass)
        corner = 20.0 * shares_of_length(np.array(flat_top()))[0]
        print(f"its load shared along the face, adhesion 20 N/m, {mass} kg ({mass * G:.2f} N) | at most "
              f"{corner:.2f} N at a corner (a ℓ) | " + " ".join(f"{p:.2f}" for p in pulls)
              + " N, corners first and last")
    for adhesion in (100.0, 120.0, 150.0, 300.0):
        print(f"1 kg flat-sided blob on a wall, adhesion {adhesion:g} N/m | | centre moves "
              f"{wall_drift(adhesion, settle=3.0) * 1e3:.3f} mm over 5 s after 3 s")
    for adhesion in (0.0, 10.0, 50.0, 200.0):
        rest, peaks = drop(adhesion)
        print(f"bouncy blob (e = 1, damping 0) dropped 1 m onto a floor of adhesion {adhesion:g} N/m | peaks <= 1 m "
              f"| peaks " + " ".join(f"{p - rest:.4f}" for p in peaks[:5]) + " m above its rest")
    for adhesion in (0.0, 20.0, 50.0, 100.0):
        gained, work, lowest = pull_off(adhesion)
        print(f"default blob pulled off a floor by 30 N for 0.3 s, adhesion {adhesion:g} N/m | E_after - E_before "
              f"<= W | {gained:.3f} J against W = {work:.3f} J: {gained - work:+.3f} J (lowest vertex {lowest:.2f} m "
              "up)")
    for adhesion in (0.0, 50.0):
        distance, drift, p0 = pair(adhesion)
        print(f"two blobs meet in zero gravity, e = 1, adhesion {adhesion:g} N/m | | centres {distance:.3f} m apart "
              f"after 4 s, momentum {p0[0]:.2f} kg m/s kept to {drift:.1e}")
    for corner in (True, False):
        for adhesion in (0.0, 100.0, 120.0, 200.0):
            print(f"Gish climbing a wall from {'the corner with a floor' if corner else 'the wall itself'}, adhesion "
                  f"{adhesion:g} N/m | over the top: centre above 2.0 m | highest centre, torque 6 / 8 / 12 / 16 N m: "
                  + " / ".join(f"{climb(adhesion, t, corner):.2f}" for t in (6.0, 8.0, 12.0, 16.0)) + " m")
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / LEVEL).read_text()
    for what, old, new in (("as shipped", "", ""),
                           ("without adhesion", "at = [[2.5, 0.0], [2.6, 120.0], [4.1, 120.0], [4.2, 0.0]]",
                            "at = [[2.5, 0.0]]"),
                           ("light (never heavy)", "at = [[4.9, 1.0], [5.3, 4.0]]", "at = [[4.9, 1.0]]")):
        run = play(text.replace(old, new) if old else text)
        (gx, gy), (bx, by) = run["centres"][-1]
        bx0, by0 = run["centres"][round(1.0 / run["dt"]), 1]
        print(f"{LEVEL}, {what} | | Gish ends at ({gx:.2f}, {gy:.2f}) m, the boulder moved ({bx - bx0:+.2f}, "
              f"{by - by0:+.2f}) m; worst area error {run['area_error']:.2%}; "
              f"{run['fault'] or 'no ring crossed itself'}")


if __name__ == "__main__":
    raise SystemExit(main())
