"""Time integration stages: damping, prediction and the velocity update.

Position-based dynamics (Müller et al. 2007; XPBD small steps, Macklin et al. 2019):
each substep of length h predicts x* = x + h v + h² g (symplectic Euler), lets the
constraint stages move x*, and then reads the velocity back from x - x_prev. The rigid part
of the motion (translation and rotation about the centre) is predicted and read back exactly
(`predict`, `update_velocities`); restitution is the blobs' (`bounce`).
"""

import math

import numba
import numpy as np

from ..jit import inline_kernel, stage_kernel
from .ring import ring_means

REST_SPEED_FACTOR = 2.0  # no bounce below this × |g| h of approach speed (kills contact jitter) ...
MIN_REST_SPEED = 0.01  # m/s ... nor below this (without gravity, jitter from pushing overlaps apart)
IMPACT_DEPTH = 0.1  # of a blob's radius (rest perimeter / 2π): a static push this deep in one substep is an impact
#                     that stops the whole blob (`stop_impacts`)
# A step takes more substeps than the scene's `substeps` where fewer would let a blob move more than STRIDE × the
# shortest mean rest edge L in one, at the fastest awake blob's rigid speed at the step's start plus g dt (a contact
# found at the substep's start would be passed through: a ring folds, a pile interpenetrates), or let gravity sag a
# blob by more than SAG × L in one, g h² (the contacts' push back after the area stage squeezes every blob of a pile
# by about that much each substep), n g h² for the blob at the bottom of a stack of n (rows_stacked): h = dt / k with
#     k = max(substeps, ⌈(v + g dt) dt / (STRIDE L)⌉, ⌈dt √(n g / (SAG L))⌉),  at most `max_substeps`.
# Chosen on `blobsim stress`'s pile at dt = 1/30 s and one substep (a prototype's sweep; area drift after settling,
# energy rise): STRIDE 0.5, SAG 0.05: 7%, 0.6%; STRIDE 1: 13%, 8%; STRIDE 0.75: 10%, 6%.
STRIDE = 0.5
SAG = 0.05
NO_BOUNCE = -math.inf  # leave energy of a contact that has not bounced yet (see `bounce`)
# Whether a collider of the scene moves (pipeline.Configuration), bound per scene: this module value is never run.
MOVING = True


@inline_kernel
def rigid_motion(pos, vel, o, e):
    """The rigid motion that best fits ring o..e's velocities: (c, v_c, ω) with c = Σ x / n,
    v_c = Σ v / n and ω = Σ r × v / Σ |r|², r = x - c. Vertex masses are equal within a blob,
    so c is the centre of mass, and v_c + ω ẑ × r is the least-squares (kinetic-energy) fit:
    ∂/∂v_c Σ |v - v_c - ω ẑ × r|² = 0 gives the mean (Σ r = 0), ∂/∂ω gives ω I = L. The residual
    v - v_c - ω ẑ × r, the deformation, carries neither momentum nor angular momentum."""
    cx, cy, vx, vy = ring_means(pos, vel, o, e)
    x, y, u, v = pos[0, o:e], pos[1, o:e], vel[0, o:e], vel[1, o:e]  # (views: perimeter.solve_perimeter)
    L = I = 0.0
    for i in range(e - o):
        rx, ry = x[i] - cx, y[i] - cy
        L += rx * (v[i] - vy) - ry * (u[i] - vx)
        I += rx * rx + ry * ry
    return cx, cy, vx, vy, L / I if I > 0.0 else 0.0


@stage_kernel
def damp_deformation(pos, vel, offsets, awake, factor):
    """Decay each blob's deformation velocity by factor = exp(-damping h): v <- v_rig + (v - v_rig) f,
    with v_rig = v_c + ω ẑ × r the best-fit rigid motion (rigid_motion). Neither momentum nor
    angular momentum changes, and a blob that moves, spins or rolls rigidly is not slowed."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        cx, cy, vx, vy, w = rigid_motion(pos, vel, o, e)
        x, y, u, v = pos[0, o:e], pos[1, o:e], vel[0, o:e], vel[1, o:e]  # (views: perimeter.solve_perimeter)
        for i in range(e - o):
            rigid_x = vx - w * (y[i] - cy)
            rigid_y = vy + w * (x[i] - cx)
            u[i] = rigid_x + (u[i] - rigid_x) * factor
            v[i] = rigid_y + (v[i] - rigid_y) * factor


@stage_kernel
def drag_motion(vel, offsets, awake, factor):
    """A viscous drag on all motion (`[scene] drag` γ): v <- v f, f = exp(-γ h), the exact decay of
    dv/dt = -γ v over the substep. Unlike damp_deformation it slows moving, spinning and rolling too:
    a damped dynamics that brings a packing to rest (the O'Hern group's deformable polygons relax the
    same way, or by FIRE). Momentum decays with it: the drag is a force from outside, the medium."""
    for b in numba.prange(offsets.shape[0] - 1):
        if awake[b]:
            # (views indexed from 0: perimeter.solve_perimeter)
            u, v = vel[0, offsets[b]:offsets[b + 1]], vel[1, offsets[b]:offsets[b + 1]]
            for i in range(u.shape[0]):
                u[i] *= factor
                v[i] *= factor


@stage_kernel
def rows_stacked(pos, offsets, rest_perimeter, up_x, up_y):
    """n: the most blobs in a chain each resting on the one below it, read from positions alone (a resumed run
    takes the same substeps): b rests on a when their centres are within 1.1 (R_a + R_b) and b's is higher by more
    than 0.2 (R_a + R_b), R the rest radius. Blobs side by side, or one alone, give 1. Blobs go up in height order,
    each one more than the deepest blob it rests on; its candidates are those within 1.1 (R_a + R_b) across (along
    the level), found by bisection in the blobs sorted that way. Serial, once a step."""
    count = offsets.shape[0] - 1
    if count < 2:
        return 1
    height, across, radius = np.empty(count), np.empty(count), np.empty(count)
    for b in range(count):
        sx = sy = 0.0
        for i in range(offsets[b], offsets[b + 1]):
            sx += pos[0, i]
            sy += pos[1, i]
        k = offsets[b + 1] - offsets[b]
        height[b] = (sx * up_x + sy * up_y) / k
        across[b] = (sx * up_y - sy * up_x) / k
        radius[b] = rest_perimeter[b] / (2.0 * math.pi)
    side = np.argsort(across, kind="mergesort")
    sorted_across = across[side]
    reach = 2.2 * radius.max()
    depth = np.ones(count, np.int64)
    most = 1
    for b in np.argsort(height, kind="mergesort"):
        for j in range(np.searchsorted(sorted_across, across[b] - reach), count):
            a = side[j]
            if sorted_across[j] > across[b] + reach:
                break
            both = radius[a] + radius[b]
            if (height[b] - height[a] > 0.2 * both
                    and math.hypot(height[b] - height[a], across[b] - across[a]) < 1.1 * both):
                depth[b] = max(depth[b], depth[a] + 1)
        most = max(most, depth[b])
    return most


@stage_kernel
def substeps_for(pos, velocity, offsets, awake, rest_perimeter, dt, g, up_x, up_y, least, most):
    """How many substeps this step takes: k above, at least `least` (the scene's substeps) and at most `most`. L is
    read from the rest perimeters as they are now (a scale schedule changes them); v is each awake blob's rigid
    speed |v_c| + |ω| R, R its rest radius (rigid_motion): a vertex's own jitter in a squeezed blob is not motion
    that passes a contact. Serial, once a step: two passes over the awake blobs' vertices, and with gravity one over
    every blob's (rows_stacked)."""
    edge, fastest = math.inf, 0.0
    for b in range(offsets.shape[0] - 1):
        edge = min(edge, rest_perimeter[b] / (offsets[b + 1] - offsets[b]))
        if awake[b]:
            _, _, vx, vy, omega = rigid_motion(pos, velocity, offsets[b], offsets[b + 1])
            fastest = max(fastest, math.hypot(vx, vy) + abs(omega) * rest_perimeter[b] / (2.0 * math.pi))
    if edge == math.inf:  # no blobs
        return least
    # the sag of the blob at the bottom of the deepest stack: it carries the n - 1 above it, n g h² (dev,
    # 2026-11-27: the 1,000-blob pile, ~25 rows, took 6 substeps by this and came to rest, fastest centre /
    # vertex 0.46 / 15 mm/s in seconds 21-25, against 1.77 / 58.5 at 4)
    rows = rows_stacked(pos, offsets, rest_perimeter, up_x, up_y) if g > 0.0 else 1
    need = max((fastest + g * dt) * dt / (STRIDE * edge), dt * math.sqrt(rows * g / (SAG * edge)))
    if not need < most:  # (also a non-finite speed: the runaway check ends the run after this step)
        return most
    return max(least, math.ceil(need))


@stage_kernel
def predict(pos, prev, vel, lam, contact_depth, offsets, awake, predicted, gx, gy, h):
    """x_prev <- x; v += g h; x moves by the rigid motion exactly and by the deformation to first
    order; clear this substep's multipliers and contacts. predicted[b] = (v_c, ½ mean |v|², -g · c), the
    blob's velocity, kinetic and potential energy per unit mass before the constraints (restitution).

    x += h v would move a spinning vertex along its tangent, off its circle around c by
    |r| (√(1 + ω²h²) - 1); the perimeter stage then pulls it back and the chord it travelled is
    short of ωh: spin decayed (35 % of 4 rad/s in 10 s at h = 1/240 s). So, with (c, v_c, ω) the
    best-fit rigid motion (rigid_motion) and R(φ) the rotation by φ,
        x <- c + h v_c + R(ωh) r + h (v - v_c - ω ẑ × r),
    which is x + h v to first order, and moves a rigid blob exactly: no edge changes length."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        n = e - o
        # the ring's arrays as views indexed from 0 (perimeter.solve_perimeter)
        x, y, u, v, x_prev, y_prev = pos[0, o:e], pos[1, o:e], vel[0, o:e], vel[1, o:e], prev[0, o:e], prev[1, o:e]
        ring_lam, depth = lam[o:e], contact_depth[o:e]
        for i in range(n):
            x_prev[i] = x[i]
            y_prev[i] = y[i]
            u[i] += gx * h
            v[i] += gy * h
            ring_lam[i] = 0.0  # XPBD multipliers accumulate over one substep's iterations only
            depth[i] = 0.0
        cx, cy, vx, vy, w = rigid_motion(pos, vel, o, e)
        kinetic = 0.0
        for i in range(n):
            kinetic += u[i] ** 2 + v[i] ** 2
        predicted[b, 0], predicted[b, 1], predicted[b, 2], predicted[b, 3] = vx, vy, 0.5 * kinetic / n, \
            -(gx * cx + gy * cy)
        cos, sin = math.cos(w * h), math.sin(w * h)
        for i in range(n):
            rx, ry = x[i] - cx, y[i] - cy
            dx = u[i] - vx + w * ry  # the deformation velocity v - v_c - ω ẑ × r
            dy = v[i] - vy - w * rx
            x[i] = cx + h * vx + cos * rx - sin * ry + h * dx
            y[i] = cy + h * vy + sin * rx + cos * ry + h * dy


@inline_kernel
def _impact(offsets, b, rest_perimeter, contact_normal, contact_depth):
    """Blob b's deepest static push this substep, if deeper than IMPACT_DEPTH × its radius (else 0), and
    the depth-weighted normal n̄ of its pushes (as restitution's)."""
    deepest = nx = ny = 0.0
    for i in range(offsets[b], offsets[b + 1]):
        D = contact_depth[i]
        if D > 0.0:
            deepest = max(deepest, D)
            nx += D * contact_normal[0, i]
            ny += D * contact_normal[1, i]
    length = math.sqrt(nx * nx + ny * ny)
    if deepest <= IMPACT_DEPTH * rest_perimeter[b] / (2.0 * math.pi) or length == 0.0:
        return 0.0, 0.0, 0.0
    return deepest, nx / length, ny / length


@stage_kernel
def stop_impacts(pos, offsets, awake, rest_perimeter, contact_normal, contact_depth):
    """A fast impact stops the whole blob, not only the vertices that reached the collider.

    At 100 m/s and h = 1/240 s a blob moves 0.42 m in a substep: the collider stage stops its front
    vertices at the surface while the rest go on, through them, and the ring folds across itself (no
    constraint can unfold a crossed ring: its signed area no longer measures it). So where a blob's
    deepest static push D this substep exceeds IMPACT_DEPTH × its radius, its vertices the colliders did
    not push move back along that push's normal n by D too, and after the velocity update no vertex of it
    keeps approaching along n (`stop_impact_velocities`): the blob stops where its front met the surface,
    as a rigid body would, and bounces as restitution says (from its approach speed before the
    constraints). Only motion toward the surface is taken: energy is lost, never made. Slower impacts (a
    0.5 m blob dropped 1 m at the defaults pushes 18 mm a substep, against 50 mm) are not touched."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        deepest, nx, ny = _impact(offsets, b, rest_perimeter, contact_normal, contact_depth)
        if deepest == 0.0:
            continue
        for i in range(offsets[b], offsets[b + 1]):
            if contact_depth[i] == 0.0:
                pos[0, i] += deepest * nx
                pos[1, i] += deepest * ny


@stage_kernel
def stop_impact_velocities(vel, offsets, awake, rest_perimeter, contact_normal, contact_depth):
    """After a fast impact (`stop_impacts`), no vertex of the blob approaches the surface along n."""
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        deepest, nx, ny = _impact(offsets, b, rest_perimeter, contact_normal, contact_depth)
        if deepest == 0.0:
            continue
        for i in range(offsets[b], offsets[b + 1]):
            vn = vel[0, i] * nx + vel[1, i] * ny
            if vn < 0.0:
                vel[0, i] -= vn * nx
                vel[1, i] -= vn * ny


@stage_kernel
def update_velocities(pos, prev, offsets, awake, vel, contact_normal, contact_depth, contact_material, h):
    """v from the substep's motion, rotation read as an angle; then kinetic Coulomb friction at
    static contacts.

    v = (x - x_prev) / h reads a rotation by θ as the chord (R(θ) - 1) r / h: shorter than
    ω |r| by sin(θ/2) / (θ/2), and turned: spin would decay every substep. So the motion is split
    into the centre's translation c - c_prev, the rotation R(θ) that best fits the ring's turn
    (2D Procrustes: θ minimizes Σ |r - R(θ) r_prev|², tan θ = Σ r_prev × r / Σ r_prev · r), and
    the rest, and
        v = (c - c_prev) / h + (θ / h) ẑ × r + (r - R(θ) r_prev) / h.
    The two rigid fields differ from the chord only in ways that carry no momentum (Σ r = 0):
    Σ m v is (x - x_prev) / h's; a rigid motion is read back exactly."""
    inv_h = 1.0 / h
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        cx, cy, px, py = ring_means(pos, prev, o, e)
        # the ring's arrays as views indexed from 0 (perimeter.solve_perimeter)
        x, y, x_prev, y_prev, u, v = pos[0, o:e], pos[1, o:e], prev[0, o:e], prev[1, o:e], vel[0, o:e], vel[1, o:e]
        cross = dot = 0.0
        for i in range(e - o):
            rx, ry, qx, qy = x[i] - cx, y[i] - cy, x_prev[i] - px, y_prev[i] - py
            cross += qx * ry - qy * rx
            dot += qx * rx + qy * ry
        theta = math.atan2(cross, dot)
        cos, sin, w = math.cos(theta), math.sin(theta), theta * inv_h
        for i in range(e - o):
            rx, ry, qx, qy = x[i] - cx, y[i] - cy, x_prev[i] - px, y_prev[i] - py
            u[i] = (cx - px) * inv_h - w * ry + (rx - (cos * qx - sin * qy)) * inv_h
            v[i] = (cy - py) * inv_h + w * rx + (ry - (sin * qx + cos * qy)) * inv_h
    for i in numba.prange(pos.shape[1]):
        D = contact_depth[i]
        if D == 0.0:
            continue
        # At a static contact (static friction already held the vertex in the collider stage), relative
        # to the collider's surface: a moving one's velocity w there (walls.py) ...
        vx, vy = vel[0, i], vel[1, i]
        if MOVING:
            vx -= contact_material[4, i]
            vy -= contact_material[5, i]
        nx, ny = contact_normal[0, i], contact_normal[1, i]
        vn = vx * nx + vy * ny
        vtx, vty = vx - vn * nx, vy - vn * ny
        # ... and a conveyor's, u along t = (n_y, -n_x) (statics.py)
        u = contact_material[3, i]
        if u != 0.0:
            vtx -= u * ny
            vty += u * nx
        # Kinetic friction: |Δv_t| <= μ_k |Δv_n|, with |Δv_n| = D / h.
        vt = math.sqrt(vtx * vtx + vty * vty)
        if vt > 0.0:
            s = max(vt - contact_material[1, i] * D * inv_h, 0.0) / vt
            vtx *= s
            vty *= s
        if u != 0.0:
            vtx += u * ny
            vty -= u * nx
        # A vertex in contact does not keep approaching the surface (inelastic vertex;
        # the bounce is the blob's, see `restitution`).
        vn = max(vn, 0.0)
        vel[0, i] = vtx + vn * nx
        vel[1, i] = vty + vn * ny
        if MOVING:
            vel[0, i] += contact_material[4, i]
            vel[1, i] += contact_material[5, i]


@inline_kernel
def bounce(record, k, approach, energy, potential, potential_now, u, other, e, rest_speed):
    """One substep of a contact's restitution rule along its normal, for record[k] = (V, E, K, P)
    of the contact; returns the change Δu of the normal speed u to apply.

    V is the contact's fastest approach so far, read before the substep's constraints
    (`approach`): after them a hard blob has already stopped, and what is left depends on the
    substeps and iterations, not on e. K and P are the kinetic and potential energy (per unit
    of the normal's mass) then (`energy`, `potential`; P_now after the solve). Once the solve
    leaves the bodies no longer approaching (u >= 0), they bounce: u is set to e V', up for a
    hard blob that stopped dead, down for a soft one whose own recoil would leave faster.
    V'² = V² + 2 (P - P_now) is
    the impact speed that the fall while squashing adds (coarse substeps squash a hard blob,
    which would otherwise rebound from lower), so the rebound is about e² of the fall whatever
    the step. Never more kinetic energy than came in: the solve has turned some into vibration
    (`other`: the kinetic energy besides ½ u²), so ½ u² <= K + P - P_now - other. E keeps the
    energy ½ u² + P_now it left with (-∞ before the bounce), and while the contact lasts u is
    never raised again (that would cancel gravity) nor let above √(2 (E - P_now)): the blob's
    recoil, pushing it up or on, would add energy. So no bounce goes higher than the drop. The
    record outlives the contact: a vibrating blob that has bounced touches again on its way up,
    and those touches, inelastic for the vertex, would turn vibration into lift. A new impact
    starts when the bodies approach faster than rest_speed after a bounce (or faster than V
    before it); slower approaches never bounce (resting)."""
    if approach > (rest_speed if record[k, 1] != NO_BOUNCE else record[k, 0]):
        record[k, 0], record[k, 1], record[k, 2], record[k, 3] = approach, NO_BOUNCE, energy, potential
    V = record[k, 0]
    if u < 0.0 or V <= rest_speed:
        return 0.0
    if record[k, 1] == NO_BOUNCE:
        fell = max(record[k, 3] - potential_now, 0.0)
        leave = min(e * math.sqrt(V * V + 2.0 * fell), math.sqrt(2.0 * max(record[k, 2] + fell - other, 0.0)))
        record[k, 1] = 0.5 * leave * leave + potential_now
        return leave - u
    return min(math.sqrt(2.0 * max(record[k, 1] - potential_now, 0.0)) - u, 0.0)


@stage_kernel
def restitution(pos, vel, offsets, awake, predicted, contact_normal, contact_depth, contact_material, impact, gx,
                gy, rest_speed):
    """Bounce off statics (the rule of `bounce`), of each blob's centre of mass; off a moving collider,
    in its frame: velocities relative to w̄, its surface's depth-weighted velocity at the contacts.

    A vertex cannot bounce on its own: the perimeter and area stages average its reversed
    velocity away against the rest of the blob, which is still falling. So restitution acts
    on the whole blob, along the depth-weighted normal n̄ of its static contacts, by one
    uniform Δv = Δu n̄ that does not disturb its shape. For a deformable blob, e is the ratio
    of its centre's leave and impact speeds: it rebounds to about e² of the drop, less what
    it keeps as vibration. Energies here are per unit mass: ½ mean |v|².
    """
    for b in numba.prange(offsets.shape[0] - 1):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        nx = ny = ux = uy = kinetic = cx = cy = 0.0
        e_max = 0.0  # the largest restitution among its contacts
        wx = wy = depth = 0.0  # Σ D w, Σ D: the contacts' surface velocity
        for i in range(o, e):
            cx += pos[0, i]
            cy += pos[1, i]
            ux += vel[0, i]
            uy += vel[1, i]
            kinetic += vel[0, i] ** 2 + vel[1, i] ** 2
            D = contact_depth[i]
            if D > 0.0:
                nx += D * contact_normal[0, i]
                ny += D * contact_normal[1, i]
                e_max = max(e_max, contact_material[2, i])
                if MOVING:
                    wx += D * contact_material[4, i]
                    wy += D * contact_material[5, i]
                    depth += D
        length = math.sqrt(nx * nx + ny * ny)
        if length == 0.0:  # airborne (its impact record is kept: see `bounce`)
            continue
        nx, ny = nx / length, ny / length
        count = e - o
        u = (ux * nx + uy * ny) / count  # the centre's speed along n̄, after the solve
        approach = -(predicted[b, 0] * nx + predicted[b, 1] * ny)
        came = predicted[b, 2]  # kinetic energy per unit mass before the solve ...
        kinetic = 0.5 * kinetic / count  # ... and after
        if MOVING:  # in the frame of the surface: v - w̄, ½ |v - w̄|² = ½ |v|² - w̄ · v + ½ |w̄|²
            wx, wy = wx / depth, wy / depth
            wn, w2 = wx * nx + wy * ny, 0.5 * (wx * wx + wy * wy)
            u -= wn
            approach += wn
            came += w2 - (wx * predicted[b, 0] + wy * predicted[b, 1])
            kinetic += w2 - (wx * ux + wy * uy) / count
        du = bounce(impact, b, approach, came, predicted[b, 3], -(gx * cx + gy * cy) / count, u,
                    kinetic - 0.5 * u * u, e_max, rest_speed)
        if du != 0.0:
            for i in range(o, e):
                vel[0, i] += du * nx
                vel[1, i] += du * ny
