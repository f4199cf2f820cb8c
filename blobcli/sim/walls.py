"""Walls that move: colliders on a prescribed motion, or pushed by a load (a piston).

Collider k's pose at time t is the rigid map T(t): p -> q + d + R(θ) (p - q) of the rows as the scene
wrote them (model.StaticSet.geom), q its pivot, d its displacement and θ its turn. It moves in one of
three ways (model.Walls.motion): at a constant velocity (d = v t, θ = ω t, as Box2D's kinematic bodies:
a velocity, not a force, drives them, and nothing the blobs do changes it); along a path (d, θ linear
between keyframes); or LOADED: along its load direction e only, d = s e, with Newton's law for s.

Each substep (of length h, from t), `place_walls` moves every collider that moves to its pose at t + h
(model rows -> the state's `placed` rows and bounding boxes) and writes its motion over the substep as
the rigid map Δ = T(t + h) ∘ T(t)⁻¹, p -> R(Δθ) p + τ (rows `delta`: cos Δθ, sin Δθ, τx, τy, loaded). The
collider kernels (statics.py) then test each vertex's path relative to the collider: from Δ(x_prev),
where the vertex would be had it been carried with the collider, to x, against the collider where it is
now. So the swept tests see the wall's own motion (a wall never passes a vertex, however fast), static
friction holds a vertex to the moving surface, and the velocity a contact is measured against is the
surface's, w = (x - Δ⁻¹(x)) / h (integrate.update_velocities, integrate.restitution).

A loaded wall (mass M, load F along e): s* = s + h V + h² F / M is predicted (gravity does not act on
it). The collider kernels push vertices out of it as if it were fixed; after each iteration,
`yield_loaded_walls` shares each of those pushes between the wall and the vertices by their masses.
Every vertex i it pushed by D_i along n_i stays on its surface, so if the wall moves σ along e, the
vertex moves σ c_i along n_i too (c_i = n_i · e), and momentum along e is kept (the wall's guide takes
the rest):
    M σ + Σ m_i (D_i + σ c_i) c_i = Σ m_i D_i c_i - Σ m_i D_i c_i  =>  σ = -Σ m_i D_i c_i / (M + Σ m_i c_i²),
the inelastic two-body split of PBD (a light wall yields, a heavy one barely), never an overshoot. After
the substep V = (s - s_start) / h; the contacts' velocity stages then share their impulses with it the same
way (`react_loaded_walls`). At rest the load and the blobs' pushes balance: the impulses the
blobs give it over a step are F dt, which is what `account_contacts` records.

Forces: the kernels record for each vertex the pushes Δx each collider gave it over the step (up to two
colliders a vertex; a third shares the second's record); `account_contacts` turns them into the impulses
-m Σ Δx / h the blobs exert on each collider, and their torques about its pivot, once a step, in vertex
order (the same bits for any thread count).
"""

import math

import numba
import numpy as np

from ..jit import inline_kernel, kernel, stage_kernel

FIXED, VELOCITY, PATH, LOADED = range(4)  # model.Walls.motion


@inline_kernel
def _pose_at(walls, k, t):
    """(dx, dy, θ) of a kinematic collider at time t."""
    if walls.motion[k] == VELOCITY:
        return walls.drive[k, 0] * t, walls.drive[k, 1] * t, walls.drive[k, 2] * t
    o, e = walls.path_offsets[k], walls.path_offsets[k + 1]
    path = walls.path
    if t <= path[o, 0]:
        return path[o, 1], path[o, 2], path[o, 3]
    for j in range(o + 1, e):
        if t < path[j, 0]:
            f = (t - path[j - 1, 0]) / (path[j, 0] - path[j - 1, 0])
            return (path[j - 1, 1] + f * (path[j, 1] - path[j - 1, 1]),
                    path[j - 1, 2] + f * (path[j, 2] - path[j - 1, 2]),
                    path[j - 1, 3] + f * (path[j, 3] - path[j - 1, 3]))
    return path[e - 1, 1], path[e - 1, 2], path[e - 1, 3]


@inline_kernel
def _map(walls, k, dx, dy, theta):
    """T as (cos θ, sin θ, tx, ty): p -> R(θ) p + t, t = q + d - R(θ) q."""
    c, s = math.cos(theta), math.sin(theta)
    qx, qy = walls.pivot[k, 0], walls.pivot[k, 1]
    return c, s, qx + dx - (c * qx - s * qy), qy + dy - (s * qx + c * qy)


@inline_kernel
def _apply(c, s, tx, ty, x, y):
    return c * x - s * y + tx, s * x + c * y + ty


@kernel
def any_moves(walls):
    """Whether any collider moves (a path, a velocity or a load)."""
    for k in range(walls.motion.shape[0]):
        if walls.motion[k] != FIXED:
            return True
    return False


@kernel
def place_walls(t, h, walls, pose, rest, placed, pos, offsets, awake, still):
    """Move every collider that moves from its pose at t to its pose at t + h (module docstring): its rows
    and bounding box in `placed`, its motion over the substep in `delta`, its pose in `pose` (dx, dy, θ,
    s, V, s at t). Wakes the sleeping blobs whose bounding box meets a moving collider's."""
    for k in range(walls.motion.shape[0]):
        motion = walls.motion[k]
        if motion == FIXED:
            continue
        dx0, dy0, th0 = pose[k, 0], pose[k, 1], pose[k, 2]
        if motion == LOADED:
            ex, ey = walls.drive[k, 1], walls.drive[k, 2]
            pose[k, 5] = pose[k, 3]
            pose[k, 3] += h * pose[k, 4] + h * h * walls.drive[k, 0] / walls.mass[k]
            dx1, dy1, th1 = pose[k, 3] * ex, pose[k, 3] * ey, 0.0
        else:
            dx1, dy1, th1 = _pose_at(walls, k, t + h)
        pose[k, 0], pose[k, 1], pose[k, 2] = dx1, dy1, th1
        _place(walls, k, rest, placed, dx0, dy0, th0, dx1, dy1, th1, motion == LOADED)
        _wake_near(walls, k, placed, pos, offsets, awake, still)


@kernel
def _place(walls, k, rest, placed, dx0, dy0, th0, dx1, dy1, th1, loaded):
    """Collider k's rows and bounding box at pose (dx1, dy1, θ1), and its delta row from pose 0 to pose 1."""
    c1, s1, tx1, ty1 = _map(walls, k, dx1, dy1, th1)
    c0, s0, tx0, ty0 = _map(walls, k, dx0, dy0, th0)
    # Δ = T1 ∘ T0⁻¹: p -> R1 R0ᵀ (p - t0) + t1
    cd, sd = c1 * c0 + s1 * s0, s1 * c0 - c1 * s0
    kind, shape = walls.kind[k], walls.shape[k]
    geom0, offsets, _, _ = rest[kind]
    geom, aabb, delta = placed[kind]
    delta[shape, 0], delta[shape, 1] = cd, sd
    delta[shape, 2] = tx1 - (cd * tx0 - sd * ty0)
    delta[shape, 3] = ty1 - (sd * tx0 + cd * ty0)
    delta[shape, 4] = 1.0 if loaded else 0.0
    x0 = y0 = math.inf
    x1 = y1 = -math.inf
    for r in range(offsets[shape], offsets[shape + 1]):
        ax, ay = _apply(c1, s1, tx1, ty1, geom0[r, 0], geom0[r, 1])
        if kind == 0:  # plane: point and normal
            geom[r, 0], geom[r, 1] = ax, ay
            geom[r, 2], geom[r, 3] = c1 * geom0[r, 2] - s1 * geom0[r, 3], s1 * geom0[r, 2] + c1 * geom0[r, 3]
        elif kind == 2:  # circle: centre (radius and inside as written)
            geom[r, 0], geom[r, 1] = ax, ay
            x0, y0 = min(x0, ax - geom0[r, 2]), min(y0, ay - geom0[r, 2])
            x1, y1 = max(x1, ax + geom0[r, 2]), max(y1, ay + geom0[r, 2])
        else:  # segment, polygon edge: both ends
            bx, by = _apply(c1, s1, tx1, ty1, geom0[r, 2], geom0[r, 3])
            geom[r, 0], geom[r, 1], geom[r, 2], geom[r, 3] = ax, ay, bx, by
            x0, y0, x1, y1 = min(x0, ax, bx), min(y0, ay, by), max(x1, ax, bx), max(y1, ay, by)
    if kind != 0 and not (kind == 2 and geom0[offsets[shape], 3] != 0.0):  # planes and drums: the whole plane
        aabb[shape, 0], aabb[shape, 1], aabb[shape, 2], aabb[shape, 3] = x0, y0, x1, y1


@kernel
def _wake_near(walls, k, placed, pos, offsets, awake, still):
    """Wake the sleeping blobs whose bounding box meets collider k's (its island wakes at the step's end:
    sleep.update_sleep)."""
    _, aabb, _ = placed[walls.kind[k]]
    shape = walls.shape[k]
    for b in range(offsets.shape[0] - 1):
        if awake[b]:
            continue
        x0 = y0 = math.inf
        x1 = y1 = -math.inf
        for i in range(offsets[b], offsets[b + 1]):
            x0, y0 = min(x0, pos[0, i]), min(y0, pos[1, i])
            x1, y1 = max(x1, pos[0, i]), max(y1, pos[1, i])
        if x1 >= aabb[shape, 0] and x0 <= aabb[shape, 2] and y1 >= aabb[shape, 1] and y0 <= aabb[shape, 3]:
            awake[b] = 1
            still[b] = 0.0


@kernel
def yield_loaded_walls(pos, inv_mass, walls, pose, rest, placed, touch):
    """Share this iteration's pushes of each loaded wall between it and the vertices it pushed (module
    docstring: σ = -Σ m D c / (M + Σ m c²)); then clear the iteration's records."""
    static_of, static_push, wall_of, wall_push = touch
    for k in range(walls.motion.shape[0]):
        if walls.motion[k] != LOADED:
            continue
        ex, ey = walls.drive[k, 1], walls.drive[k, 2]
        a = b = 0.0
        for i in range(pos.shape[1]):
            if wall_of[i] == k:
                px, py = wall_push[0, i], wall_push[1, i]
                d2 = px * px + py * py
                if d2 > 0.0:
                    m = 1.0 / inv_mass[i]
                    pe = px * ex + py * ey  # D c
                    a += m * pe
                    b += m * pe * pe / d2
        if b == 0.0:
            continue
        sigma = -a / (walls.mass[k] + b)
        for i in range(pos.shape[1]):
            if wall_of[i] == k:
                px, py = wall_push[0, i], wall_push[1, i]
                d2 = px * px + py * py
                if d2 > 0.0:  # along n by σ c: σ (D c / D) (Δx / D)
                    f = sigma * (px * ex + py * ey) / d2
                    pos[0, i] += f * px
                    pos[1, i] += f * py
                    account(i, k, f * px, f * py, static_of, static_push)
        pose[k, 3] += sigma
        pose[k, 0], pose[k, 1] = pose[k, 3] * ex, pose[k, 3] * ey
        # placed anew at s from s0: the delta row keeps the substep's whole motion (from s at t)
        _place(walls, k, rest, placed, pose[k, 5] * ex, pose[k, 5] * ey, 0.0, pose[k, 0], pose[k, 1], 0.0, True)
    for i in range(pos.shape[1]):
        if wall_of[i] >= 0:
            wall_of[i] = -1
            wall_push[0, i] = wall_push[1, i] = 0.0


@inline_kernel
def _velocity_impulse(pos, prev, vel, m, o, e, h):
    """J_b = Σ m v - Σ m (x - x_prev) / h over ring o..e (vertex mass m): what the substep's velocity stages
    gave the blob (the velocities read from the positions carry Σ m (x - x_prev) / h)."""
    jx = jy = 0.0
    for i in range(o, e):
        jx += m * (vel[0, i] - (pos[0, i] - prev[0, i]) / h)
        jy += m * (vel[1, i] - (pos[1, i] - prev[1, i]) / h)
    return jx, jy


@inline_kernel
def _is_loaded(walls, k):
    """Whether collider k is a loaded wall. (Not in a stage kernel's own code: there, LOADED is the name of the
    configuration flag that jit.build binds, not this module's motion code.)"""
    return walls.motion[k] == LOADED


@stage_kernel
def record_contact_impulses(pos, prev, vel, inv_mass, offsets, awake, contact_depth, walls, touch, h):
    """Record the velocity-level impulses of the substep's static contacts as the colliders' (a loaded wall's
    share is `react_loaded_walls`'). The velocity stages (integrate.update_velocities' clamp and kinetic
    friction, stop_impact_velocities, restitution) change blob b's momentum by J_b (`_velocity_impulse`); each
    of its contact vertices i takes the part D_i / D_b of it (its push depth over the blob's), for the collider
    that pushed it (half each for a vertex two colliders pushed this step). Without this
    the record held the position pushes only: a blob dropped on a floor at e = 0 put 2-9 times its weight on
    the floor's record for the next second while it lay still (its bounce, taken back by restitution, was
    recorded and the taking back was not; dev, 2026-11-26)."""
    static_of, static_push, _, _ = touch
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        depth = 0.0
        for i in range(o, e):
            depth += contact_depth[i]
        if depth == 0.0:
            continue
        m = 1.0 / inv_mass[o]
        jx, jy = _velocity_impulse(pos, prev, vel, m, o, e, h)
        for i in range(o, e):
            D = contact_depth[i]
            if D == 0.0:
                continue
            both = static_of[1, i] >= 0
            for slot in range(2 if both else 1):
                k = static_of[slot, i]
                if k < 0 or _is_loaded(walls, k):
                    continue
                part = D / depth * (0.5 if both else 1.0) * h / m  # recorded as a push: -m Σ Δx / h
                static_push[2 * slot, i] += part * jx
                static_push[2 * slot + 1, i] += part * jy


@kernel
def react_loaded_walls(pos, prev, vel, inv_mass, offsets, awake, contact_normal, contact_depth, walls, pose, touch, h):
    """The velocity-level impulses of the substep's static contacts (integrate.update_velocities' clamp and
    kinetic friction, stop_impact_velocities, restitution) act on a loaded wall too, shared as its pushes are.

    Those stages change blob b's momentum by J_b (`_velocity_impulse`), as if every collider were fixed. The
    part s_b = D_b,k / D_b of it (its static contacts' depth on wall k over all of them) is wall k's, along n̄_b
    (the depth-weighted normal of its contacts on k), c_b = n̄_b · e. Left one-sided, a light wall that jiggles
    under its load has its approaches stopped by the blobs and never feels it: the blobs got more than the load
    (1.44 N for a 1 N, 0.2 kg wall on 30 blobs of 1 kg; dev, 2026-11-26). Shared like the pushes (module
    docstring), the wall's velocity changes by ΔV and each blob follows it by ΔV s_b c_b n̄_b, so that momentum
    along e is kept:
        M ΔV + Σ s_b J_b · e + ΔV Σ m_b s_b c_b² = 0  =>  ΔV = -Σ s_b J_b · e / (M + Σ m_b s_b c_b²).
    The blobs' impulse on the wall, -(s_b J_b + m_b ΔV s_b c_b n̄_b), is recorded at b's deepest vertex on it."""
    static_of, static_push, _, _ = touch
    B = offsets.shape[0] - 1
    share = np.zeros(B)  # s_b
    normal = np.zeros((B, 2))  # n̄_b
    impulse = np.zeros((B, 2))  # s_b J_b
    deepest = np.full(B, -1)
    for k in range(walls.motion.shape[0]):
        if walls.motion[k] != LOADED:
            continue
        ex, ey = walls.drive[k, 1], walls.drive[k, 2]
        along = heavy = 0.0
        for b in range(B):
            share[b] = 0.0
            if not awake[b]:
                continue
            o, e = offsets[b], offsets[b + 1]
            total = on_k = nx = ny = most = 0.0
            for i in range(o, e):
                D = contact_depth[i]
                total += D
                if D > 0.0 and (static_of[0, i] == k or static_of[1, i] == k):
                    on_k += D
                    nx += D * contact_normal[0, i]
                    ny += D * contact_normal[1, i]
                    if D > most:
                        most, deepest[b] = D, i
            length = math.sqrt(nx * nx + ny * ny)
            if on_k == 0.0 or length == 0.0:
                continue
            m = 1.0 / inv_mass[o]
            jx, jy = _velocity_impulse(pos, prev, vel, m, o, e, h)
            share[b] = on_k / total
            normal[b, 0], normal[b, 1] = nx / length, ny / length
            impulse[b, 0], impulse[b, 1] = share[b] * jx, share[b] * jy
            c = normal[b, 0] * ex + normal[b, 1] * ey
            along += impulse[b, 0] * ex + impulse[b, 1] * ey
            heavy += m * (e - o) * share[b] * c * c
        if along == 0.0:
            continue
        dV = -along / (walls.mass[k] + heavy)
        pose[k, 4] += dV
        for b in range(B):
            if share[b] == 0.0:
                continue
            o, e = offsets[b], offsets[b + 1]
            c = normal[b, 0] * ex + normal[b, 1] * ey
            fx, fy = dV * share[b] * c * normal[b, 0], dV * share[b] * c * normal[b, 1]
            for i in range(o, e):
                vel[0, i] += fx
                vel[1, i] += fy
            i = deepest[b]
            mb, mi = (e - o) / inv_mass[o], 1.0 / inv_mass[i]
            # recorded as a push: account_contacts reads -m Σ Δx / h
            account(i, k, (impulse[b, 0] + mb * fx) * h / mi, (impulse[b, 1] + mb * fy) * h / mi, static_of,
                    static_push)


@kernel
def finish_loaded_walls(walls, pose, h):
    """After a substep: each loaded wall's velocity from its motion, V = (s - s_start) / h."""
    for k in range(walls.motion.shape[0]):
        if walls.motion[k] == LOADED:
            pose[k, 4] = (pose[k, 3] - pose[k, 5]) / h


@inline_kernel
def account(i, k, dx, dy, static_of, static_push):
    """Add collider k's push (dx, dy) of vertex i to i's record: its first slot, or its second."""
    slot = 0 if static_of[0, i] < 0 or static_of[0, i] == k else 1
    static_of[slot, i] = k
    static_push[2 * slot, i] += dx
    static_push[2 * slot + 1, i] += dy


@kernel
def account_contacts(pos, inv_mass, walls, pose, touch, impulse, h):
    """The impulses of the blobs on each collider over the step, -m Σ Δx / h (N s: the pushes of all its
    substeps, each of length h), and their moments about its pivot where it is at the step's end (N m s),
    as impulse[k] = (Jx, Jy, L); clear the vertices' records. Once a step: a serial pass over the vertices
    (in vertex order, the same bits for any thread count) every substep cost 1,000 blobs apart 5%."""
    static_of, static_push, _, _ = touch
    impulse[:] = 0.0
    for i in range(pos.shape[1]):
        for slot in range(2):
            k = static_of[slot, i]
            if k < 0:
                continue
            m = 1.0 / inv_mass[i]
            jx, jy = -m * static_push[2 * slot, i] / h, -m * static_push[2 * slot + 1, i] / h
            rx = pos[0, i] - (walls.pivot[k, 0] + pose[k, 0])
            ry = pos[1, i] - (walls.pivot[k, 1] + pose[k, 1])
            impulse[k, 0] += jx
            impulse[k, 1] += jy
            impulse[k, 2] += rx * jy - ry * jx
            static_of[slot, i] = -1
            static_push[2 * slot, i] = static_push[2 * slot + 1, i] = 0.0


@kernel
def place_initial(walls, pose, rest, placed):
    """A state just built: every collider that moves at its pose at t = 0 (a path may start displaced)."""
    for k in range(walls.motion.shape[0]):
        if walls.motion[k] == FIXED:
            continue
        dx, dy, th = (0.0, 0.0, 0.0) if walls.motion[k] == LOADED else _pose_at(walls, k, 0.0)
        pose[k, 0], pose[k, 1], pose[k, 2] = dx, dy, th
        _place(walls, k, rest, placed, dx, dy, th, dx, dy, th, walls.motion[k] == LOADED)


WALL_POSE_COLUMNS = 6  # pose: dx, dy (m), θ (rad), s (m), V (m/s), s at the substep's start (m)
