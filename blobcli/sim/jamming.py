"""Jamming by compression: the protocol of the soft-matter codes (O'Hern, Silbert, Liu & Nagel, PRE 68,
011306 (2003); the deformable polygons of Boromand et al., Soft Matter 15, 5854 (2019), and their code
jacktreado/dpm), in a periodic box.

A packing is compressed in small steps of packing fraction φ and brought to rest after each; it is
jammed when, at rest, it still pushes back, its pressure p above a small target p*, through a network of
contacts that carry force (packing.bearing: a contact that touches but whose pushes the velocity stages take
back carries nothing) that can hold it: its blobs, the rattlers removed, have at least the contacts rigidity
needs (packing.rigid: 2N' - 1 without friction, Goodrich, Liu & Nagel, PRL 109, 095704 (2012)). The box is
shrunk (each blob's centre carried affinely, c <- c L_new / L_old: sim/schedule.py), so the blobs, their
stiffness and the unit of pressure stay as the scene made them. From the loosest packing, φ grows by
COARSE_STEP while it is plainly loose (p < p* / LOOSE), then by FIRST_STEP (at most half way to φ = 1, where
blobs of slack perimeter tile the plane), until a packing is jammed; then φ is bisected between the densest
unjammed packing and the loosest jammed one, each try starting again from the unjammed packing, until a
jammed packing's p is within PRESSURE_TOLERANCE of p* and it is in force balance, or the bracket is narrower
than SMALLEST_STEP. That packing is the jammed one: φ_J, its contact number z_J (contacts that carry force,
rattlers removed) and p. A try within the tolerance that does not balance is not read: it closes the bracket
from the side its p is on (below p* or above), and the bisection goes on.
Past it, the packing is compressed by PAST_ONSET more (each from the jammed packing) to measure how
contacts grow, z - z_J ∝ (φ - φ_J)^β (β = 1/2 for soft discs: O'Hern et al. 2003).

Pressure is dimensionless in the blobs' own stiffness, p̃ = p ᾱ, ᾱ their mean perimeter compliance
(m/N): a blob of n edges under a pressure p holds a perimeter tension T = p R (Laplace), which
stretches each edge by α T, a strain ε = α p R / (2π R / n) = n p̃ / 2π. `blobsim jam`'s default
p̃* = 3e-6 strains a 32-edge blob's perimeter by 1.5e-5: a packing on the edge of rigidity. It is as
near zero as the relaxation resolves: an unjammed packing brought to rest for MAX_RELAX steps keeps
p̃ ≈ 1e-6 at φ = 0.70-0.80 (a contact network close to rigid relaxes ever more slowly: the critical
slowing down of jamming), so a lower p* would call loose packings jammed.

At rest: the relaxation is the scene's own dynamics with a drag on all motion ([scene] drag, v decaying
as exp(-drag t); sleeping is off), run in blocks of RELAX_BLOCK steps. It ends when the packing is in force
balance, every blob of the force network with a net contact force |F̄_net| at most BALANCE of the mean push
f̄ (both the means over the block's last AVERAGE steps: force_balance), and its pressure has settled (changed
by under SETTLED of itself in the block) or MAX_RELAX steps have run. It ends early when the answer is plain:
below jamming p falls, and once it is under p* / CLEARLY the packing is unjammed (no network to balance).
An unjammed packing ends after MAX_RELAX steps in any case; a jammed one (rigid, p within PRESSURE_TOLERANCE
of p* or above) goes on, to MAX_BALANCE steps, until it balances: one that does not is not read (the
bisection goes on past it; when the bracket closes on it, jam says so instead of giving a φ).
The pressure read is the mean over the same AVERAGE steps (the virial of one step is noisy: sim/packing.py).
BALANCE is what the step reaches: a jammed packing held at one φ creeps, the worst blob's net force between
0.05 and 0.3 of f̄ from block to block (the same averaged over 120 or 600 steps), and that does not fall with
a longer relaxation (docs/jamming.md, "Known limits").
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, NamedTuple

import numpy as np

from . import packing
from .measure import blob_measures
from .model import Model, Params, State
from .pipeline import advance, settings
from .schedule import box_map, carry_blobs

COARSE_STEP = 0.04  # Δφ of the compression while p < p* / LOOSE ...
FIRST_STEP = 0.01  # ... and after, until the first jammed packing
SMALLEST_STEP = 2.5e-4  # the bisection stops when φ is bracketed this tightly ...
PRESSURE_TOLERANCE = 0.25  # ... or when |p / p* - 1| is below this
PAST_ONSET = (0.002, 0.005, 0.01, 0.02)  # φ - φ_J of the packings compressed past onset
RELAX_BLOCK = 120  # steps: the pressure is checked after each block ...
AVERAGE = 20  # ... as the mean over its last this many steps
MAX_RELAX = 2400  # steps at most for one relaxation ...
MAX_BALANCE = 4800  # ... and for a jammed packing not yet in force balance
SETTLED = 0.02  # a relaxation ends when p changes by less than this fraction of itself in a block ...
CLEARLY = 3.0  # ... or when p < p* / CLEARLY (plainly unjammed: the floor of an unjammed packing's p, docstring)
LOOSE = 10.0  # p < p* / LOOSE: far from jamming, compressed by COARSE_STEP
BALANCE = 0.1  # force balance: every blob of the force network has |F̄_net| <= this × the mean push (force_balance)


class Packing(NamedTuple):
    """One packing at rest, as measured."""
    phi: float  # packing fraction
    pressure: float  # p, N/m
    reduced: float  # p̃ = p ᾱ
    z: float  # contacts that carry force (packing.bearing) per blob, the rattlers of that network removed
    z_touching: float  # contacts per blob, touching or not carrying force, their rattlers removed
    z_all: float  # contacts per blob, every blob, every contact
    rattlers: int  # of the network of contacts that carry force
    kinetic: float  # J, the blobs' kinetic energy at the end
    steps: int  # steps of relaxation
    rigid: bool  # its network of contacts that carry force, rattlers removed, is rigid (packing.rigid)
    balance: float  # the largest net contact force on a blob of that network over the mean push (force_balance)


class Jammed(NamedTuple):
    """What the protocol found: the jammed packing, every packing it measured on the way (in order), and
    the ones past onset."""
    jammed: Packing
    path: list
    past: list


def mean_compliance(model: Model) -> float:
    """ᾱ (m/N), the unit of pressure: p̃ = p ᾱ."""
    return float(np.mean(model.compliance))


class Forces(NamedTuple):
    """The contact forces of one step's last substep: the pairs touching (P, 2), their normal forces f (P,) N and
    each blob's net contact force (B, 2) N (sim/packing.py)."""
    touching: np.ndarray
    normal: np.ndarray
    net: np.ndarray


def contact_forces(state: State, model: Model, params: Params) -> Forces:
    """The contact forces the last step left in state.packing."""
    _, touching, force, count = state.packing
    touching, force = touching[:count[0]], force[:count[0]]
    centre = packing.centres(state.pos, model.offsets)
    return Forces(touching, packing.normal_forces(touching, force, centre, params.box),
                  packing.net_forces(touching, force, model.blob_count))


def force_balance(forces: list[Forces], rattler: np.ndarray) -> float:
    """max over the blobs that are not rattlers of |F̄_net| / f̄: each blob's net contact force averaged over the
    steps `forces` were taken at, over the mean push f̄ over those steps (0 when nothing pushes; inf when only
    rattlers are left). A packing in mechanical equilibrium has 0: the tolerance is BALANCE."""
    pushes = [f.normal[f.normal > 0.0] for f in forces]
    mean_push = float(np.mean([p.mean() for p in pushes if len(p)])) if any(len(p) for p in pushes) else 0.0
    if mean_push == 0.0:
        return 0.0
    if rattler.all():
        return math.inf
    net = np.mean([f.net for f in forces], axis=0)
    return float(np.hypot(net[~rattler, 0], net[~rattler, 1]).max() / mean_push)


def measure_packing(state: State, model: Model, params: Params, pressure: float, steps: int,
                    forces: list[Forces]) -> Packing:
    """The packing's φ, contacts, rattlers and force balance now; `pressure` (N/m) and the contact `forces` of
    the last few steps measured by the caller (its last, the step now)."""
    area, kinetic = blob_measures(state, model)
    last = forces[-1]
    below = packing.rattler_below(model.material)
    carrying = last.touching[packing.bearing(last.normal)]
    rattler = packing.rattlers(carrying, model.blob_count, below)
    z_all, z_touching = packing.mean_contacts(last.touching, packing.rattlers(last.touching, model.blob_count,
                                                                               below))
    _, z = packing.mean_contacts(carrying, rattler)
    return Packing(phi=packing.packing_fraction(area, params.box), pressure=pressure,
                   reduced=pressure * mean_compliance(model), z=z, z_touching=z_touching, z_all=z_all,
                   rattlers=int(rattler.sum()), kinetic=float(kinetic.sum()), steps=steps,
                   rigid=packing.rigid(carrying, rattler, below), balance=force_balance(forces, rattler))


def relax(state: State, model: Model, params: Params, target: float, run=advance) -> Packing:
    """Run the scene's dynamics (with its drag) until the pressure settles (module docstring); the state
    is left where it came to rest. `run`: what advances the state (pipeline.advance's signature)."""
    step_settings = settings(model, params)
    alpha = mean_compliance(model)
    before, steps = None, 0
    while True:
        run(state, model, params, RELAX_BLOCK - AVERAGE, step_settings=step_settings)
        p, forces = 0.0, []
        for _ in range(AVERAGE):
            run(state, model, params, 1, step_settings=step_settings)
            p += packing.pressure(packing.stress(state.packing[0], params.dt, params.box))
            forces.append(contact_forces(state, model, params))
        p /= AVERAGE
        steps += RELAX_BLOCK
        found = measure_packing(state, model, params, p, steps, forces)
        settled = before is not None and abs(p - before) < SETTLED * abs(p)
        balanced = found.balance <= BALANCE
        pressed = found.rigid and found.reduced >= (1.0 - PRESSURE_TOLERANCE) * target  # jammed: read if balanced
        if (p * alpha < target / CLEARLY or ((settled or steps >= MAX_RELAX) and balanced)
                or steps >= (MAX_BALANCE if pressed else MAX_RELAX)):
            return found
        before = p


def compress(state: State, model: Model, params: Params, phi: float) -> Params:
    """Shrink (or grow) the box to packing fraction φ, carrying each blob's centre with it; the params of
    the new box. Every blob is woken (none sleeps while a drag relaxes them, but a state may come from
    a run that slept)."""
    area, _ = blob_measures(state, model)
    old = np.array(params.box, dtype=np.float64)
    new = old * np.sqrt(packing.packing_fraction(area, params.box) / phi)
    carry_blobs(state, model.offsets, box_map(old, new, 0.0))
    state.awake[:] = 1
    return replace(params, box=(float(new[0]), float(new[1])))


def copy_state(state: State) -> State:
    """A copy of every array of the state (a packing to come back to)."""
    def deep(x):
        return tuple(deep(y) for y in x) if isinstance(x, tuple) else x.copy()
    return State(*(deep(x) for x in state))


def jam(state: State, model: Model, params: Params, target: float,
        on_packing: Callable[[Packing, State, Params], None] | None = None,
        run=advance) -> Jammed:
    """Compress the scene's packing to jamming at reduced pressure `target` (module docstring): what was
    found. `on_packing(packing, state, params)` is called with every packing measured, in order (to record
    them); `run` advances the state (pipeline.advance's signature: `blobsim jam` passes one that picks the
    threads, io/threads.py)."""
    path = []

    def tried(state, params):
        found = relax(state, model, params, target, run)
        path.append(found)
        if on_packing is not None:
            on_packing(found, state, params)
        return found

    loose = tried(state, params)
    if loose.reduced >= target and loose.rigid:
        raise ValueError(f"the packing is jammed as placed (φ = {loose.phi:.3f}, p ᾱ = {loose.reduced:.2e} "
                         f">= {target:g}): start looser")
    low = (loose, copy_state(state), params)  # the densest unjammed packing: p < p* ...
    high = None  # ... and the loosest jammed one, p > p*: (packing, state, params)
    while True:
        if high is None:  # not yet bracketed: compress on, at most half way to φ = 1 (blobs that tile the plane)
            step = COARSE_STEP if low[0].reduced < target / LOOSE else FIRST_STEP
            phi = min(low[0].phi + step, 0.5 * (low[0].phi + 1.0))
        else:
            phi = 0.5 * (low[0].phi + high[0].phi)
        if high is None and 1.0 - low[0].phi < SMALLEST_STEP:
            raise ValueError(f"no jammed packing below φ = 1 (p ᾱ = {low[0].reduced:.2e} at φ = {low[0].phi:.4f})")
        state = copy_state(low[1])
        params = compress(state, model, low[2], phi)
        found = (tried(state, params), state, params)
        if (found[0].rigid and abs(found[0].reduced / target - 1.0) < PRESSURE_TOLERANCE
                and found[0].balance <= BALANCE):
            break
        if found[0].reduced < target or not found[0].rigid:
            low = found
        else:
            high = found
        if high is not None and high[0].phi - low[0].phi < SMALLEST_STEP:
            found = high  # bracketed as tightly as asked: the loosest jammed packing
            break
    found, jammed_state, jammed_params = found
    if found.balance > BALANCE:
        raise ValueError(f"the jammed packing (φ = {found.phi:.4f}) is not in force balance after {found.steps} steps: "
                         f"a blob's net contact force is {found.balance:.3f} of the mean push (at most {BALANCE})")
    past = []
    for dphi in PAST_ONSET:
        s = copy_state(jammed_state)
        p = compress(s, model, jammed_params, found.phi + dphi)
        past.append(tried(s, p))
    return Jammed(jammed=found, path=path, past=past)
