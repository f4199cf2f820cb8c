"""Static model data and changing state, built once from a validated scene.

All vertices of all blobs live in one (N, 2) float64 array; blob b owns vertices
offsets[b]:offsets[b+1], in ring order, and edge i joins vertex i to the next vertex of
its ring. Only `State` changes during a step; `Model` and `Params` are read-only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..colliders import COLLIDERS, SOLVERS, default_pivot
from ..core import Views, load
from ..geometry import blob_points, ring_next, signed_area
from ..scene.placement import random_centres, ring_at_origin
from ..scene.schema import Scene, StaticDef, expanded_names

# The compiled core's sizes and codes (its headers are their one home)
_FFI, _CORE = load()
PAIRS_PER_BLOB = _CORE.BC_PAIRS_PER_BLOB  # past this many close blob pairs per blob the step stops
CONTACTS_PER_VERTEX = _CORE.BC_CONTACTS_PER_VERTEX  # a vertex keeps contacts with its two nearest blobs
SELF_PER_VERTEX = _CORE.BC_SELF_PER_VERTEX  # self-contact pairs kept per vertex
SELF_CHUNK_ROWS = _CORE.BC_SELF_CHUNK_ROWS  # rows of the self-contact chunk table
FIXED, VELOCITY, PATH, LOADED = _CORE.BC_FIXED, _CORE.BC_VELOCITY, _CORE.BC_PATH, _CORE.BC_LOADED  # Walls.motion
WALL_POSE_COLUMNS = _CORE.BC_WALL_POSE_COLUMNS  # State.static_pose: dx, dy, θ, s, V, s at the substep's start
NO_BOUNCE = -math.inf  # an impact record's leave energy before the contact has bounced (restitution.c)

PARALLEL_BLOBS = 32  # a parallel launch costs ~2 µs: smaller scenes run every stage on one thread


class SimulationError(Exception):
    """A step that cannot go on (e.g. far more overlapping blob pairs than memory can hold), after
    `steps_done` whole steps of the call that raised it."""

    def __init__(self, message: str, steps_done: int = 0):
        super().__init__(message)
        self.steps_done = steps_done


@dataclass(frozen=True)
class Params:
    """Resolved time stepping and world settings."""
    dt: float  # s
    substeps: int  # the least per step ...
    iterations: int
    gravity: np.ndarray  # (2,) m/s²
    damping: float  # 1/s
    method: str
    steps: int
    every: int
    sleep: bool = True  # islands at rest fall asleep (core/sleep.c) ...
    sleep_speed: float = 0.005  # m/s ... below this rigid speed ...
    time_to_sleep: float = 1.0  # s ... for this long
    box: tuple = (0.0, 0.0)  # m: the periodic box's sides [Lx, Ly]; (0, 0): an open world
    drag: float = 0.0  # 1/s: viscous drag on all motion
    shear: float = 0.0  # the periodic box's Lees–Edwards shear strain γ (a schedule's)
    max_substeps: int = 16  # ... and the most (core/integrate.c: bc_substeps_for)


@dataclass(frozen=True)
class StaticSet:
    """All static colliders run by one solver kernel, flattened.

    Shape s owns rows geom[shape_offsets[s]:shape_offsets[s+1]], laid out as blobcli/colliders.py says.
    """
    kind: str  # the solver: "plane", "segment", "circle" or "polygon" (boxes are polygons)
    geom: np.ndarray  # (rows, 4) float64
    shape_offsets: np.ndarray  # (shapes + 1,) int64
    material: np.ndarray  # (shapes, 4): static friction μ_s, kinetic μ_k, restitution e, surface velocity (m/s)
    aabb: np.ndarray  # (shapes, 4): xmin, ymin, xmax, ymax
    index: np.ndarray  # (shapes,) int64: each one's place among the scene's [[static]] tables


class Walls(NamedTuple):
    """How each collider moves (core/walls.c), by its place among the scene's [[static]] tables."""
    motion: np.ndarray  # (S,) int64: FIXED, VELOCITY, PATH or LOADED
    pivot: np.ndarray  # (S, 2) m: the point it turns about and is recorded at
    drive: np.ndarray  # (S, 3): VELOCITY: vx, vy (m/s), ω (rad/s); LOADED: load F (N), its unit direction e
    mass: np.ndarray  # (S,) kg: a loaded wall's mass
    path_offsets: np.ndarray  # (S + 1,) int64: collider k's keyframes are path[path_offsets[k]:path_offsets[k+1]] ...
    path: np.ndarray  # (K, 4) ... t (s), dx, dy (m), turn (rad)
    kind: np.ndarray  # (S,) int64: its solver kind (index into SOLVERS) ...
    shape: np.ndarray  # (S,) int64 ... and its place in that kind's StaticSet


class ModelArrays(NamedTuple):
    """The numeric arrays of a Model (same names, same meaning), for the compiled step; each static
    solver kind as (geom, shape_offsets, material, index) of its StaticSet, empty when absent."""
    offsets: np.ndarray
    blob_of: np.ndarray
    inv_mass: np.ndarray
    rest_length: np.ndarray
    rest_perimeter: np.ndarray
    target_area: np.ndarray
    compliance: np.ndarray
    material: np.ndarray
    orient: np.ndarray
    area_compliance: np.ndarray
    gas_pressure: np.ndarray
    spring_pairs: np.ndarray
    spring_rest: np.ndarray
    spring_compliance: np.ndarray
    driving: np.ndarray
    adhesion: np.ndarray
    static_adhesion: np.ndarray
    statics: tuple  # one per SOLVERS kind: its StaticSet's (geom, shape_offsets, material, index)
    walls: Walls


@dataclass(frozen=True)
class Model:
    """Arrays computed once per scene; never written during a step."""
    names: tuple[str, ...]  # (B,)
    offsets: np.ndarray  # (B + 1,) int64
    blob_of: np.ndarray  # (N,) int64, the blob owning each vertex
    inv_mass: np.ndarray  # (N,) 1/kg
    rest_length: np.ndarray  # (N,) m, edge i -> next vertex of its ring
    rest_perimeter: np.ndarray  # (B,) m, Σ rest_length over each ring
    rest_area: np.ndarray  # (B,) m², signed: > 0 for counter-clockwise rings
    target_area: np.ndarray  # (B,) m², signed, = pressure × rest_area
    compliance: np.ndarray  # (B,) m/N, XPBD α of the perimeter edges
    material: np.ndarray  # (B, 3): static friction μ_s, kinetic μ_k, restitution e
    mass: np.ndarray  # (B,) kg
    statics: tuple[StaticSet, ...]  # one per collider kind present, in a fixed order
    walls: Walls  # how each collider moves
    orient: np.ndarray  # (B,) +1 counter-clockwise, -1 clockwise: the sign of outward normals
    # Settings of the other area methods (see area.py):
    area_compliance: np.ndarray  # (B,) method xpbd: α of the area constraint
    gas_pressure: np.ndarray  # (B,) N/m, method gas: P₀ at the target area
    spring_pairs: np.ndarray  # (S, 2) int64, method springs: the internal springs' vertex pairs ...
    spring_rest: np.ndarray  # (S,) m, ... their rest lengths
    spring_compliance: np.ndarray  # (B,) m/N, ... and compliance, 1 / stiffness
    driving: np.ndarray  # (B, 3): each blob's driving force F_x, F_y (N) through its centre of mass and torque τ
    #                      (N m, counter-clockwise) about it (core/driving.h); 0: not driven
    adhesion: np.ndarray  # (B,) N/m: how hard each blob holds what it touches, per metre of contact (core/adhesion.c)
    static_adhesion: np.ndarray  # (S,) N/m: each collider's, by its place among the scene's [[static]] tables

    @cached_property
    def arrays(self) -> ModelArrays:
        """The model as the step's kernels read it."""
        kinds = {s.kind: (s.geom, s.shape_offsets, s.material, s.index) for s in self.statics}
        none = (np.zeros((0, 4)), np.zeros(1, dtype=np.int64), np.zeros((0, 4)), np.zeros(0, dtype=np.int64))
        return ModelArrays(self.offsets, self.blob_of, self.inv_mass, self.rest_length, self.rest_perimeter,
                           self.target_area,
                           self.compliance, self.material, self.orient, self.area_compliance, self.gas_pressure,
                           self.spring_pairs, self.spring_rest, self.spring_compliance, self.driving, self.adhesion,
                           self.static_adhesion, tuple(kinds.get(kind, none) for kind in SOLVERS), self.walls)

    @property
    def moving(self) -> bool:
        """Whether a collider moves (core/walls.c)."""
        return bool(np.any(self.walls.motion != FIXED))

    @property
    def loaded(self) -> bool:
        """Whether a collider is a loaded wall."""
        return bool(np.any(self.walls.motion == LOADED))

    @property
    def collides(self) -> bool:
        """Blob–blob collision stages run only with more than one blob."""
        return self.blob_count > 1

    @property
    def parallel(self) -> bool:
        """Whether the stages split their loops over threads (core/parallel.h): from PARALLEL_BLOBS."""
        return self.blob_count >= PARALLEL_BLOBS

    @property
    def blob_count(self) -> int:
        return len(self.offsets) - 1

    @property
    def vertex_count(self) -> int:
        return int(self.offsets[-1])


class State(NamedTuple):
    """What changes during a step, as the kernels read it: per-vertex vectors in structure-of-arrays
    layout, (2, N) with row 0 x and row 1 y, so that a loop over vertices reads contiguous memory
    (`pos` and `vel` are the (N, 2) views the rest of the program uses). position, velocity,
    the impact records, the sleep state and the blob contacts' stick points are the state proper (what
    /restart stores); the rest is scratch rewritten every substep, kept here so that the per-vertex
    arrays are allocated once. The blob–blob pair lists change length every substep and live inside
    the step (sim/pipeline.py)."""
    position: np.ndarray  # (2, N) m
    velocity: np.ndarray  # (2, N) m/s
    impact: np.ndarray  # (B, 4) each blob's latest impact on statics: fastest approach V (m/s), the energy it
    #                     bounced with (J/kg; -inf before), the kinetic and potential energy it came with (J/kg):
    #                     restitution.c: bounce
    pair_key: np.ndarray  # (PAIRS_PER_BLOB B,) int64: the blob pairs (a, b), a < b, as a B + b, sorted, that have had
    #                     an impact, in pair_key[:pair_count[0]] ...
    pair_impact: np.ndarray  # (PAIRS_PER_BLOB B, 4) ... and their impact records, like `impact`
    pair_count: np.ndarray  # (1,) int64
    awake: np.ndarray  # (B,) uint8: 1 awake, 0 asleep (core/sleep.c) ...
    still: np.ndarray  # (B,) s ... how long each awake blob has been still ...
    still_center: np.ndarray  # (B, 2) m ... where its centre was when that time began ...
    still_angle: np.ndarray  # (B,) rad ... and the angle of its first vertex about that centre then
    previous: np.ndarray  # (2, N) m, positions at the start of the substep
    predicted: np.ndarray  # (B, 4) each blob's centre-of-mass velocity (m/s), kinetic and potential energy (J/kg)
    #                        before this substep's constraints
    lam: np.ndarray  # (N,) accumulated XPBD multipliers of the perimeter edges
    contact_normal: np.ndarray  # (2, N) unit normal of the vertex's static contact
    contact_depth: np.ndarray  # (N,) m, total push-out this substep (0: no contact)
    contact_material: np.ndarray  # (6, N) combined μ_s, μ_k, e of that contact, its surface's velocity (m/s)
    #                                 along t = (n_y, -n_x) (core/statics.c), and the velocity of a moving collider's
    #                                 surface there, wx, wy (m/s; core/walls.c)
    perimeter_lam: np.ndarray  # (B,) the total-length constraints' multipliers this substep (perimeter.py)
    area_lam: np.ndarray  # (B,) method xpbd: the area constraints' multipliers this substep
    spring_lam: np.ndarray  # (S,) method springs: the internal springs' multipliers this substep
    # Blob–blob scratch: broad phase (per substep), narrow-phase contacts (per step).
    center: np.ndarray  # (B, 2) m, vertex-average centres
    radius: np.ndarray  # (B,) m, farthest vertex from the centre
    edges: np.ndarray  # (5, N) edge i at the current positions, by row: start x, y (m), vector x, y (m),
    #                    1/|edge|² (1/m²)
    c_edge: np.ndarray  # (CONTACTS_PER_VERTEX, N) int64, vertex i's kept contacts (core/narrow_phase.c): the nearest
    #                    edge (by its first vertex) of a neighbouring blob, or -1; found once per step and followed
    #                    along the ring ...
    c_hit: np.ndarray  # (CONTACTS_PER_VERTEX, N) uint8 ... 1 where that contact has pushed this substep ...
    c_normal: np.ndarray  # (2, CONTACTS_PER_VERTEX, N) ... and the unit normal of its last push (the velocity stage's)
    anchor: np.ndarray  # (2, N) m, positions when the contacts were found ...
    budget: np.ndarray  # (B,) m ... how far from there each blob's vertices may go before they are found again ...
    moved: np.ndarray  # (B,) m ... and how far they have gone
    blob_contact_depth: np.ndarray  # (N,) m, a vertex's total push-out by blobs this substep
    stick_edge: np.ndarray  # (CONTACTS_PER_VERTEX, N) int64: where each contact's static friction holds the vertex,
    #                        as a material point of the other blob: an edge (its first vertex; -1: none) ...
    stick_t: np.ndarray  # (CONTACTS_PER_VERTEX, N) ... and the point's place along it, t in [0, 1]
    steps_done: np.ndarray  # (1,) int64: steps since t = 0 (the time colliders move by)
    substeps_taken: np.ndarray  # (2,) int64: the most substeps a step took, and how many steps took more than the
    #                             scene's `substeps`, since the run (or its resume) began (core/integrate.c)
    static_pose: np.ndarray  # (S, 6) each collider's pose (core/walls.c): dx, dy (m), θ (rad), and a loaded wall's
    #                          s (m), V (m/s) along its load direction, and s at the substep's start (m)
    static_impulse: np.ndarray  # (S, 3) the impulses the blobs gave each collider over the last step: Jx, Jy (N s),
    #                              and their moment about its pivot (N m s)
    placed: tuple  # per SOLVERS kind, where its colliders are now: (geom, aabb, delta: the substep's motion)
    touch: tuple  # per vertex, this substep's pushes by colliders: (static_of (2, N) int64, static_push (4, N) m:
    #               up to two colliders and their pushes; wall_of (N,) int64, wall_push (2, N) m: a loaded wall's
    #               push this iteration)
    packing: tuple  # in a periodic box, what the last step's blob contacts did (sim/packing.py): (virial (B, 4) N m s:
    #                 each blob's Σ (x - c) ⊗ J over its contact impulses J at points x, as xx, xy, yx, yy;
    #                 touching (PAIRS_PER_BLOB B, 2) int64: the pairs in contact at the step's end ...;
    #                 touching_force (PAIRS_PER_BLOB B, 2) N: ... each one's contact force over the step's last
    #                 substep on its first blob ...; touching_count (1,) int64: ... how many); empty in an open world
    self_contact: tuple  # each ring's pairs of a vertex and an edge of its own this substep, and what finds them
    #                      (self_contact_records): scratch, but for `zoned`, a per-blob count
    #                      of the substeps the fail-safe acted in since the run (or its resume) began

    @property
    def pos(self) -> np.ndarray:
        """(N, 2) m: the positions, vertex by vertex (a view: writing it writes the state)."""
        return self.position.T

    @property
    def vel(self) -> np.ndarray:
        """(N, 2) m/s: the velocities, vertex by vertex (a view)."""
        return self.velocity.T


def self_contact_records(vertices: int, blobs: int) -> tuple:
    """State.self_contact for a scene of this many vertices and blobs (core/self_contact.c): (pairs
    (2, SELF_PER_VERTEX N) int64: each pair's vertex and edge (its first vertex); values (4, SELF_PER_VERTEX N):
    its side σ (±1, or 0: undecided), its gap g (m), the depth D it pushed out this substep (m) and the deepest
    it may act at (m); count (B,) int64: how many pairs each blob has, from slot SELF_PER_VERTEX × its first
    vertex on; near (B,) uint8: whether some of a ring's chunks may meet; chunks (SELF_CHUNK_ROWS, N): the chunk
    table; zoned (B,) int64: in how many substeps since the run began the fail-safe moved part of each ring
    rigidly)."""
    return (np.zeros((2, SELF_PER_VERTEX * vertices), np.int64), np.zeros((4, SELF_PER_VERTEX * vertices)),
            np.zeros(blobs, np.int64), np.zeros(blobs, np.uint8), np.zeros((SELF_CHUNK_ROWS, vertices)),
            np.zeros(blobs, np.int64))


def packing_records(blobs: int) -> tuple:
    """State.packing for a scene of this many blobs in a periodic box (0: an open world, which keeps none)."""
    pairs = PAIRS_PER_BLOB * blobs
    return np.zeros((blobs, 4)), np.zeros((pairs, 2), np.int64), np.zeros((pairs, 2)), np.zeros(1, np.int64)


def build_params(scene: Scene) -> Params:
    """Time stepping and world settings of a validated scene."""
    s = scene.settings
    return Params(dt=s.dt, substeps=s.substeps, iterations=s.iterations,
                  gravity=np.array(s.gravity, dtype=np.float64), damping=s.damping,
                  method=s.method, steps=scene.steps, every=scene.output.every, sleep=s.sleep and s.drag == 0.0,
                  sleep_speed=s.sleep_speed, time_to_sleep=s.time_to_sleep, box=s.periodic or (0.0, 0.0),
                  drag=s.drag, max_substeps=s.max_substeps)


def build(scene: Scene) -> tuple[Model, State]:
    """Model and initial state of a validated scene (grids and random copies expanded)."""
    rings, velocities, per_blob = [], [], []
    placed = random_centres(scene) if any(b.count > 1 for b in scene.blobs) else {}
    for i, b in enumerate(scene.blobs):
        if i in placed:  # copies at random (scene/placement.py), in the order of expanded_names
            base = ring_at_origin(b)
            shifts = placed[i]
        else:
            base = blob_points(b)
            nx, ny = b.grid
            # the copies in the order of expanded_names: x-major
            ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
            shifts = np.stack([ix.ravel() * (b.spacing or (0.0, 0.0))[0], iy.ravel() * (b.spacing or (0.0, 0.0))[1]],
                              axis=1).astype(np.float64)
        copies = len(shifts)
        rings.append((base[None, :, :] + shifts[:, None, :]).reshape(-1, 2))
        counts = np.full(copies, len(base))
        # v = v_0 + ω ẑ × (x - c), c the centre of mass (the vertex average: vertex masses are equal)
        r = base - base.mean(axis=0)
        spin = np.array(b.velocity) + b.angular_velocity * np.stack([-r[:, 1], r[:, 0]], axis=1)
        velocities.append(np.tile(spin, (copies, 1)))
        area = signed_area(base)
        per_blob.append((counts, b.mass, area, b.pressure, b.compliance,
                         (b.static_friction, b.friction, b.restitution), b.area_compliance, b.gas_pressure,
                         b.spring_stiffness, (*b.force, b.torque), b.adhesion))

    counts = np.concatenate([p[0] for p in per_blob])
    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    pos = np.ascontiguousarray(np.concatenate(rings), dtype=np.float64)
    vel = np.ascontiguousarray(np.concatenate(velocities), dtype=np.float64)

    def per(k):  # one value per blob, expanded over each blob's grid copies
        return np.concatenate([np.full(len(p[0]), p[k], dtype=np.float64) for p in per_blob])

    mass, rest_area, pressure, compliance = per(1), per(2), per(3), per(4)
    area_compliance, gas_pressure, spring_stiffness, adhesion = per(6), per(7), per(8), per(10)
    material = np.concatenate([np.tile(np.array(p[5], dtype=np.float64), (len(p[0]), 1)) for p in per_blob])
    driving = np.concatenate([np.tile(np.array(p[9], dtype=np.float64), (len(p[0]), 1)) for p in per_blob])
    blob_of = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    inv_mass = (counts / mass)[blob_of]
    rest_length = np.hypot(*(pos[ring_next(offsets)] - pos).T)

    statics = build_statics(scene.statics)
    walls = build_walls(scene.statics)
    springs = internal_springs(pos, offsets)
    model = Model(names=tuple(expanded_names(scene.blobs)), offsets=offsets, blob_of=blob_of, inv_mass=inv_mass,
                  rest_length=rest_length, rest_perimeter=np.add.reduceat(rest_length, offsets[:-1]),
                  rest_area=rest_area, target_area=pressure * rest_area,
                  compliance=compliance, material=material, mass=mass,
                  statics=statics, walls=walls,
                  orient=np.sign(rest_area), area_compliance=area_compliance, gas_pressure=gas_pressure,
                  spring_pairs=springs, spring_rest=np.hypot(*(pos[springs[:, 1]] - pos[springs[:, 0]]).T),
                  spring_compliance=1.0 / spring_stiffness, driving=driving, adhesion=adhesion,
                  static_adhesion=np.array([s.adhesion for s in scene.statics], dtype=np.float64))
    n, blobs = len(pos), len(counts)
    state = State(position=np.ascontiguousarray(pos.T), velocity=np.ascontiguousarray(vel.T),
                  impact=no_impact(blobs), pair_key=np.zeros(PAIRS_PER_BLOB * blobs, np.int64),
                  pair_impact=no_impact(PAIRS_PER_BLOB * blobs), pair_count=np.zeros(1, np.int64),
                  awake=np.ones(blobs, np.uint8), still=np.zeros(blobs),
                  still_center=np.zeros((blobs, 2)), still_angle=np.zeros(blobs),
                  previous=np.ascontiguousarray(pos.T), predicted=np.zeros((blobs, 4)), lam=np.zeros(n),
                  contact_normal=np.zeros((2, n)), contact_depth=np.zeros(n), contact_material=np.zeros((6, n)),
                  perimeter_lam=np.zeros(blobs), area_lam=np.zeros(blobs),
                  spring_lam=np.zeros(len(model.spring_pairs)),
                  center=np.zeros((blobs, 2)), radius=np.zeros(blobs), edges=np.zeros((5, n)),
                  c_edge=np.full((CONTACTS_PER_VERTEX, n), -1, dtype=np.int64),
                  c_hit=np.zeros((CONTACTS_PER_VERTEX, n), np.uint8), c_normal=np.zeros((2, CONTACTS_PER_VERTEX, n)),
                  anchor=np.zeros((2, n)), budget=np.zeros(blobs), moved=np.zeros(blobs),
                  blob_contact_depth=np.zeros(n),
                  stick_edge=np.full((CONTACTS_PER_VERTEX, n), -1, dtype=np.int64),
                  stick_t=np.zeros((CONTACTS_PER_VERTEX, n)), steps_done=np.zeros(1, np.int64),
                  substeps_taken=np.zeros(2, np.int64),
                  static_pose=np.zeros((len(scene.statics), WALL_POSE_COLUMNS)),
                  static_impulse=np.zeros((len(scene.statics), 3)), placed=initial_placed(statics),
                  touch=(np.full((2, n), -1, np.int64), np.zeros((4, n)), np.full(n, -1, np.int64), np.zeros((2, n))),
                  packing=packing_records(blobs if scene.settings.periodic is not None else 0),
                  self_contact=self_contact_records(n, blobs))
    views = Views(_FFI, model.arrays, state)
    if model.moving:  # the moving colliders where they are at t = 0
        _CORE.bc_place_initial(views.context)
    _CORE.bc_begin_still(views.context)  # every blob still from now on (sleep.c)
    return model, state


def no_impact(count: int) -> np.ndarray:
    """Impact records (V, E, K, P) of contacts that are not bouncing (restitution.c: bounce)."""
    return np.tile([0.0, NO_BOUNCE, 0.0, 0.0], (count, 1))


def internal_springs(pos, offsets) -> np.ndarray:
    """(S, 2) vertex pairs of the classic spring blob: each vertex to the opposite one and
    to the one two along the ring (its neighbours' neighbours), without duplicates."""
    pairs = []
    for o, e in zip(offsets[:-1], offsets[1:]):
        n = e - o
        k = np.arange(n)
        opposite = np.stack([o + k, o + (k + n // 2) % n], axis=1)[: (n + 1) // 2 if n % 2 else n // 2]
        second = np.stack([o + k, o + (k + 2) % n], axis=1) if n > 4 else np.zeros((0, 2), dtype=np.int64)
        pairs += [opposite, second]
    return np.ascontiguousarray(np.concatenate(pairs).astype(np.int64)) if pairs else np.zeros((0, 2), np.int64)


def build_statics(statics: tuple[StaticDef, ...]) -> tuple[StaticSet, ...]:
    """Group colliders by solver kernel (boxes join the polygons), in the fixed order of SOLVERS."""
    rows: dict[str, list] = {k: [] for k in SOLVERS}
    for k, s in enumerate(statics):
        kind = COLLIDERS[s.kind]
        geom, box = kind.rows(s)
        rows[kind.solver].append((geom, (s.static_friction, s.friction, s.restitution, s.surface_velocity), box, k))
    out = []
    for kind in SOLVERS:
        if not rows[kind]:
            continue
        sizes = [len(g) for g, *_ in rows[kind]]
        offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        out.append(StaticSet(kind=kind, geom=np.ascontiguousarray(np.concatenate([g for g, *_ in rows[kind]])),
                             shape_offsets=offsets,
                             material=np.array([m for _, m, _, _ in rows[kind]], dtype=np.float64),
                             aabb=np.array([b for _, _, b, _ in rows[kind]], dtype=np.float64),
                             index=np.array([k for *_, k in rows[kind]], dtype=np.int64)))
    return tuple(out)


def build_walls(statics: tuple[StaticDef, ...]) -> Walls:
    """How each collider moves, from its [[static]] table (core/walls.c)."""
    S = len(statics)
    motion, pivot, drive, mass = np.zeros(S, np.int64), np.zeros((S, 2)), np.zeros((S, 3)), np.ones(S)
    path_offsets, path = np.zeros(S + 1, np.int64), []
    kind, shape, seen = np.zeros(S, np.int64), np.zeros(S, np.int64), dict.fromkeys(SOLVERS, 0)
    for k, s in enumerate(statics):
        solver = COLLIDERS[s.kind].solver
        kind[k], shape[k] = SOLVERS.index(solver), seen[solver]
        seen[solver] += 1
        pivot[k] = default_pivot(s)
        if s.load is not None:
            e = np.array(s.load_direction) / math.hypot(*s.load_direction)
            motion[k], drive[k], mass[k] = LOADED, (s.load, *e), s.mass
        elif s.path is not None:
            motion[k] = PATH
            path += [(t, dx, dy, math.radians(turn)) for t, dx, dy, turn in s.path]
        elif s.moves:
            motion[k], drive[k] = VELOCITY, (*(s.velocity or (0.0, 0.0)), s.angular_velocity or 0.0)
        path_offsets[k + 1] = len(path)
    return Walls(motion=motion, pivot=pivot, drive=drive, mass=mass, path_offsets=path_offsets,
                 path=np.array(path, dtype=np.float64).reshape(-1, 4), kind=kind, shape=shape)


def initial_placed(statics: tuple[StaticSet, ...]) -> tuple:
    """The state's `placed` rows, per SOLVERS kind: every collider where the scene wrote it, not moving
    (place_initial then puts the ones that move where they are at t = 0)."""
    kinds = {s.kind: s for s in statics}
    out = []
    for kind in SOLVERS:
        s = kinds.get(kind)
        geom, aabb = (s.geom.copy(), s.aabb.copy()) if s else (np.zeros((0, 4)), np.zeros((0, 4)))
        delta = np.zeros((len(aabb), 5))
        delta[:, 0] = 1.0  # the identity map: cos 0 = 1
        out.append((geom, aabb, delta))
    return tuple(out)
