"""`python -m blobcli.tools.modes`: is a state at rest stable, and how fast do its slowest motions grow or die?

The step is a map z -> F(z) of the state z = (x, v), every vertex's position and velocity. Near a state z₀ at
rest, a small disturbance δ evolves as δ -> J δ, J = ∂F/∂z at z₀, as long as the same contacts act (a disturbance
far smaller than any contact's depth). Each eigenvalue λ of J is a mode that grows (|λ| > 1) or decays (|λ| < 1)
by |λ|^(1/dt) per second; a real λ > 1 is a state at rest that is not an equilibrium one stays in (a ball on a
ball), a complex pair an oscillation, λ = 1 a motion that costs nothing (a free blob's drift; a blob that rests
at any place on a floor).

J is found column by column with central differences: (F(z₀ + ε e_k) - F(z₀ - ε e_k)) / 2ε, two steps of the real
compiled step for each of the 4N coordinates (state_vector: every vertex's x, y, then every vertex's v_x, v_y),
each from its own copy of the state. The step is smooth only where no contact changes between stick and slip, or
touching and not, within ε, and at rest some do within 10⁻⁷ (SMALLEST's wedge): so ε = 10⁻⁸ (m, m/s), and the tool
checks it: J again at 10ε, and a warning where their leading eigenvalues differ (the figures then hold for
disturbances below ε only). Round-off splits a drift (x' = x + v dt, v' = v: λ = 1 twice) into 1 ± √(round-off /
ε) ≈ 1 ± 3·10⁻⁴, so |λ - 1| < NEUTRAL counts as 1.

Prints, for a scene (a TOML file, or one of tools/piles' SMALLEST), after it settles: how far it is from rest (the
largest change of z in one step: the analysis is of a state that stays where it is), the leading eigenvalues as
factors per second, and for each leading mode what it does to each blob (the BLOBS_SHOWN it moves most): its
centre's velocity and its spin ω (v), or for a mode with no velocity its centre's shift and its turn (x), and the
share of that which deforms the blob rather than moving it rigidly (the vector's scale is arbitrary: compare
blobs, and spin with velocity).
"""

from __future__ import annotations

import argparse
import copy
from dataclasses import replace

import numpy as np

EPS = 1e-8  # m and m/s: the central differences' step
BLOBS_SHOWN = 8  # a mode's blobs printed: those it moves most
AT_REST = 1e-4  # m, m/s: a state that a step changes by more is not at rest
NEUTRAL = 1e-3  # |λ - 1| below this: neutral (central differences split a drift into 1 ± ~3·10⁻⁴)


def settle(scene, seconds: float, drag: float = 0.0, turn_deg: float = 0.0):
    """(model, state, params) of `scene` with every blob turned by `turn_deg` about its centre and at rest (its
    velocities set to 0), after `seconds` of its dynamics; `drag` (1/s) is a `[scene] drag` for the settling only,
    to reach a rest the undamped dynamics leaves or only slowly nears. Sleeping is off (a sleeping blob is not
    moved: its modes would all be 1)."""
    from ..sim.model import build, build_params
    from ..sim.pipeline import advance
    model, state = build(scene)
    params = replace(build_params(scene), sleep=False)
    turn = np.radians(turn_deg)
    rotation = np.array([[np.cos(turn), np.sin(turn)], [-np.sin(turn), np.cos(turn)]])  # (row vectors) R(turn)ᵀ
    for o, e in zip(model.offsets[:-1], model.offsets[1:]):
        centre = state.pos[o:e].mean(axis=0)
        state.pos[o:e] = centre + (state.pos[o:e] - centre) @ rotation
    state.vel[:] = 0.0
    steps = int(round(seconds / params.dt))
    advance(state, model, replace(params, drag=drag), steps)
    return model, state, params


def state_vector(state) -> np.ndarray:
    """z = (x, v): every vertex's x, y, then every vertex's v_x, v_y"""
    return np.concatenate([state.pos.ravel(), state.vel.ravel()])


def step_map(model, state, params):
    """F: z -> the state after one step from z (the rest of `state`, its contacts' stick points and impact
    records, as they are), each call on its own copy"""
    from ..sim.pipeline import advance
    n = state.pos.shape[0]

    def F(z: np.ndarray) -> np.ndarray:
        s = copy.deepcopy(state)
        s.pos[:] = z[:2 * n].reshape(n, 2)
        s.vel[:] = z[2 * n:].reshape(n, 2)
        advance(s, model, params, 1)
        return state_vector(s)
    return F


def jacobian(model, state, params, eps: float = EPS) -> np.ndarray:
    """J = ∂F/∂z at the state (4N × 4N), by central differences"""
    F = step_map(model, state, params)
    z0 = state_vector(state)
    J = np.empty((z0.size, z0.size))
    for k in range(z0.size):
        dz = np.zeros_like(z0)
        dz[k] = eps
        J[:, k] = (F(z0 + dz) - F(z0 - dz)) / (2.0 * eps)
    return J


def leading_modes(J: np.ndarray, count: int) -> tuple[int, np.ndarray, np.ndarray]:
    """How many eigenvalues of J are 1 (to NEUTRAL), and of the others the `count` of greatest modulus (largest
    first, a complex pair once) with their eigenvectors (columns)"""
    values, vectors = np.linalg.eig(J)
    neutral = np.abs(values - 1.0) < NEUTRAL
    # (one of each complex pair: its conjugate is the same mode)
    order = [k for k in np.argsort(-np.abs(values), kind="stable") if not neutral[k] and values[k].imag >= 0.0]
    order = order[:count]
    return int(neutral.sum()), values[order], vectors[:, order]


def blob_shares(model, state, mode: np.ndarray, dt: float) -> tuple[str, list[tuple[float, ...]]]:
    """What a mode does to each blob: ("v", rows) from its velocity part, or ("x", rows) from its
    position part where the velocity part moves the blob by less than 0.1% of that in a step of dt (a state one can
    move to and stay in: λ = 1). A row per blob, (along x, along y, turn, deformed, size): the best-fit rigid
    motion u_c + ω ẑ × r of the part u on its vertices (u_c the mean, ω = Σ r × (u - u_c) / Σ |r|²), the share
    |u - u_rigid| / |u| that is not rigid, and |u|."""
    n = state.pos.shape[0]
    # a complex mode's phase is arbitrary: turned so that its velocity part's real part is largest,
    # |Re(e^{-iφ} u)|² = (|u|² + Re(e^{-2iφ} Σ u²)) / 2 at 2φ = arg Σ u²
    mode = mode * np.exp(-0.5j * np.angle(np.sum(mode[2 * n:] ** 2)))
    position, velocity = np.real(mode[:2 * n]).reshape(n, 2), np.real(mode[2 * n:]).reshape(n, 2)
    moving = np.linalg.norm(velocity) * dt > 1e-3 * np.linalg.norm(position)  # it moves the blob within a step
    which, part = ("v", velocity) if moving else ("x", position)
    shares = []
    for o, e in zip(model.offsets[:-1], model.offsets[1:]):
        r = state.pos[o:e] - state.pos[o:e].mean(axis=0)
        u = part[o:e]
        centre = u.mean(axis=0)
        spin = float(np.sum(r[:, 0] * (u[:, 1] - centre[1]) - r[:, 1] * (u[:, 0] - centre[0])) / np.sum(r * r))
        rigid = centre + spin * np.stack([-r[:, 1], r[:, 0]], axis=1)
        size = float(np.linalg.norm(u))
        shares.append((float(centre[0]), float(centre[1]), spin,
                       float(np.linalg.norm(u - rigid)) / size if size > 0.0 else 0.0, size))
    return which, shares


def main(argv=None) -> int:
    import sys

    from ..scene.schema import SceneError, load_scene, parse_scene
    from .piles import FLOOR, SMALLEST
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    which = ap.add_mutually_exclusive_group(required=True)
    which.add_argument("scene", nargs="?", help="a scene file")
    which.add_argument("--smallest", choices=list(SMALLEST), help="one of tools/piles' smallest scenes instead")
    ap.add_argument("--settle", type=float, default=3.0, metavar="S", help="seconds of the scene before the "
                    "analysis (default 3)")
    ap.add_argument("--settle-drag", type=float, default=0.0, metavar="D",
                    help="a drag (1/s) for the settling only (default 0)")
    ap.add_argument("--turn", type=float, default=0.0, metavar="DEG", help="turn every blob by DEG degrees about "
                    "its centre before settling (default 0)")
    ap.add_argument("--modes", type=int, default=6, metavar="K", help="how many leading modes to print (default 6)")
    args = ap.parse_args(argv)
    if args.settle < 0.0 or args.settle_drag < 0.0 or args.modes < 1:
        ap.error("--settle and --settle-drag are at least 0, --modes at least 1")
    if args.smallest:
        scene = parse_scene("[scene]\nsleep = false\n" + SMALLEST[args.smallest] + FLOOR, args.smallest)
    else:
        try:
            scene = load_scene(args.scene)
        except SceneError as e:
            print("\n".join(e.problems), file=sys.stderr)
            return 2
    model, state, params = settle(scene, args.settle, args.settle_drag, args.turn)
    rest = float(np.abs(step_map(model, state, params)(state_vector(state)) - state_vector(state)).max())
    neutral, values, vectors = leading_modes(jacobian(model, state, params), args.modes)
    _, coarse, _ = leading_modes(jacobian(model, state, params, 10.0 * EPS), args.modes)
    per_second = 1.0 / params.dt
    print(f"after {args.settle:g} s: a step moves the state by at most {rest:.2g} (m, m/s); "
          f"{len(state_vector(state))} coordinates, {neutral} neutral modes (λ = 1: a drift, a blob that static "
          "friction holds wherever it is put)")
    if rest > AT_REST:
        print("  not at rest: the modes are of a state in motion (a longer --settle, or --settle-drag, may reach "
              "rest)")
    if len(coarse) != len(values) or np.abs(np.abs(coarse) - np.abs(values)).max() > NEUTRAL:
        print(f"  not smooth within {10 * EPS:g} of this state (a contact changes between stick and slip, or touching "
              f"and not): the figures hold for disturbances below {EPS:g} only; at {10 * EPS:g} the leading |λ| are "
              + " ".join(f"{abs(v):.7f}" for v in coarse))
    for value, vector in zip(values, vectors.T):
        kind = "real" if abs(value.imag) < 1e-12 else f"period {2 * np.pi / abs(np.angle(value)) / per_second:.3g} s"
        print(f"  |λ| {abs(value):.7f}: ×{abs(value) ** per_second:.4g} per second ({kind})")
        which, shares = blob_shares(model, state, vector, params.dt)
        shown = sorted(np.argsort([-row[4] for row in shares], kind="stable")[:BLOBS_SHOWN])
        for b in shown:
            ux, uy, spin, deformed, _ = shares[b]
            print(f"    {model.names[b]}: {which} ({ux:+.3f}, {uy:+.3f}), turn {spin:+.3f}, "
                  f"deformed {100 * deformed:.0f}%")
        if len(shares) > len(shown):
            print(f"    (the {len(shown)} of {len(shares)} blobs it moves most)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
