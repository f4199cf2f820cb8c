"""Time integration stages: damping, prediction and the velocity update.

Position-based dynamics (Müller et al. 2007; XPBD small steps, Macklin et al. 2019):
each substep of length h predicts x* = x + h v + h² g (symplectic Euler), lets the
constraint stages move x*, and then reads the velocity back as v = (x - x_prev) / h.
"""

import math

import numba

from ..jit import stage_kernel

REST_SPEED_FACTOR = 2.0  # no bounce below this × |g| h of approach speed (kills contact jitter)


@stage_kernel
def damp_relative(vel, inv_mass, offsets, factor):
    """Decay each blob's velocity relative to its centre of mass by factor = exp(-damping h).

    This damps deformation and spin alike. Spin is damped on purpose: position-based
    projection conserves linear momentum exactly but angular momentum only to O(h), and a
    slack blob resting on a floor has a neutral rolling mode, so that small numerical
    torque kept a resting blob rocking forever (±2 mm at 4 mm/s) when only deformation was
    damped. Damping spin as well gives the blob rolling resistance, like a viscous
    filling, and it settles to rest (below 1e-4 m/s within seconds).
    """
    for b in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        m_sum = px = py = 0.0
        for i in range(o, e):
            m = 1.0 / inv_mass[i]
            m_sum += m
            px += m * vel[0, i]
            py += m * vel[1, i]
        vx, vy = px / m_sum, py / m_sum
        # v <- v_cm + (v - v_cm) f keeps Σ m v: damping never moves a blob's centre of mass.
        for i in range(o, e):
            vel[0, i] = vx + (vel[0, i] - vx) * factor
            vel[1, i] = vy + (vel[1, i] - vy) * factor



@stage_kernel
def predict(pos, prev, vel, lam, contact_depth, gx, gy, h):
    """x_prev <- x; v += g h; x += v h; clear this substep's multipliers and contacts."""
    for i in numba.prange(pos.shape[1]):
        prev[0, i] = pos[0, i]
        prev[1, i] = pos[1, i]
        vel[0, i] += gx * h
        vel[1, i] += gy * h
        pos[0, i] += vel[0, i] * h
        pos[1, i] += vel[1, i] * h
        lam[i] = 0.0  # XPBD multipliers accumulate over one substep's iterations only
        contact_depth[i] = 0.0



@stage_kernel
def update_velocities(pos, prev, vel, contact_normal, contact_depth, contact_material, h):
    """v = (x - x_prev) / h, then kinetic Coulomb friction at static contacts."""
    inv_h = 1.0 / h
    for i in numba.prange(pos.shape[1]):
        vel[0, i] = (pos[0, i] - prev[0, i]) * inv_h
        vel[1, i] = (pos[1, i] - prev[1, i]) * inv_h
        D = contact_depth[i]
        if D == 0.0:
            continue
        # At a static contact (static friction already held the vertex in the collider stage):
        nx, ny = contact_normal[0, i], contact_normal[1, i]
        vn = vel[0, i] * nx + vel[1, i] * ny
        vtx, vty = vel[0, i] - vn * nx, vel[1, i] - vn * ny
        # Kinetic friction: |Δv_t| <= μ_k |Δv_n|, with |Δv_n| = D / h.
        vt = math.sqrt(vtx * vtx + vty * vty)
        if vt > 0.0:
            s = max(vt - contact_material[1, i] * D * inv_h, 0.0) / vt
            vtx *= s
            vty *= s
        # A vertex in contact does not keep approaching the surface (inelastic vertex;
        # the bounce is the blob's, see `restitution`).
        vn = max(vn, 0.0)
        vel[0, i] = vtx + vn * nx
        vel[1, i] = vty + vn * ny



@stage_kernel
def restitution(vel, inv_mass, offsets, contact_normal, contact_depth, contact_material, impact_speed, rest_speed):
    """Bounce: a blob whose impact on statics has ended leaves at e × its approach speed.

    A vertex cannot bounce on its own: the perimeter and area stages average its reversed
    velocity away against the rest of the blob, which is still falling. So restitution
    acts on the whole blob. While it touches statics, its centre-of-mass approach speed
    V along the depth-weighted contact normal n̄ is tracked; once the centre stops
    approaching, every vertex gets Δv = (e V - u·n̄) n̄. Approaches slower than
    rest_speed = REST_SPEED_FACTOR |g| h never bounce, so resting contacts do not jitter.
    """
    for b in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        nx = ny = m_sum = ux = uy = 0.0
        e_max = 0.0  # the largest restitution among its contacts
        for i in range(o, e):
            m = 1.0 / inv_mass[i]
            m_sum += m
            ux += m * vel[0, i]
            uy += m * vel[1, i]
            D = contact_depth[i]
            if D > 0.0:
                nx += D * contact_normal[0, i]
                ny += D * contact_normal[1, i]
                e_max = max(e_max, contact_material[2, i])
        length = math.sqrt(nx * nx + ny * ny)
        if length == 0.0:  # airborne: any earlier impact is over
            impact_speed[b] = 0.0
            continue
        nx, ny = nx / length, ny / length
        un = (ux * nx + uy * ny) / m_sum  # centre-of-mass speed along the contact normal
        if un < 0.0:  # still approaching: compression goes on; remember the fastest approach
            impact_speed[b] = max(impact_speed[b], -un)
        elif impact_speed[b] > rest_speed:
            # Compression is over: leave at e times the approach speed (Poisson's view of
            # restitution), by one uniform Δv that does not disturb the blob's shape.
            dv = max(e_max * impact_speed[b] - un, 0.0)
            for i in range(o, e):
                vel[0, i] += dv * nx
                vel[1, i] += dv * ny
            impact_speed[b] = 0.0
        else:
            impact_speed[b] = 0.0

