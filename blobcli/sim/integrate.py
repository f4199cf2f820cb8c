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
def _damp_relative(vel, inv_mass, offsets, factor):
    for b in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        m_sum = px = py = 0.0
        for i in range(o, e):
            m = 1.0 / inv_mass[i]
            m_sum += m
            px += m * vel[i, 0]
            py += m * vel[i, 1]
        vx, vy = px / m_sum, py / m_sum
        # v <- v_cm + (v - v_cm) f keeps Σ m v: damping never moves a blob's centre of mass.
        for i in range(o, e):
            vel[i, 0] = vx + (vel[i, 0] - vx) * factor
            vel[i, 1] = vy + (vel[i, 1] - vy) * factor


def damp_relative(state, model, params, h):
    """Decay each blob's velocity relative to its centre of mass by exp(-damping h).

    This damps deformation and spin alike. Spin is damped on purpose: position-based
    projection conserves linear momentum exactly but angular momentum only to O(h), and a
    slack blob resting on a floor has a neutral rolling mode, so that small numerical
    torque kept a resting blob rocking forever (±2 mm at 4 mm/s) when only deformation was
    damped. Damping spin as well gives the blob rolling resistance, like a viscous
    filling, and it settles to rest (below 1e-4 m/s within seconds).
    """
    _damp_relative[model.parallel](state.vel, model.inv_mass, model.offsets, math.exp(-params.damping * h))


@stage_kernel
def _predict(pos, prev, vel, lam, contact_depth, gx, gy, h):
    for i in numba.prange(pos.shape[0]):
        prev[i, 0] = pos[i, 0]
        prev[i, 1] = pos[i, 1]
        vel[i, 0] += gx * h
        vel[i, 1] += gy * h
        pos[i, 0] += vel[i, 0] * h
        pos[i, 1] += vel[i, 1] * h
        lam[i] = 0.0  # XPBD multipliers accumulate over one substep's iterations only
        contact_depth[i] = 0.0


def predict(state, model, params, h):
    """x_prev <- x; v += g h; x += v h; clear this substep's multipliers and contacts."""
    _predict[model.parallel](state.pos, state.prev, state.vel, state.lam, state.contact_depth,
                             params.gravity[0], params.gravity[1], h)
    state.area_lam[:] = 0.0  # the xpbd and springs methods' multipliers, per substep too
    state.spring_lam[:] = 0.0


@stage_kernel
def _update_velocities(pos, prev, vel, contact_normal, contact_depth, contact_material, h):
    inv_h = 1.0 / h
    for i in numba.prange(pos.shape[0]):
        vel[i, 0] = (pos[i, 0] - prev[i, 0]) * inv_h
        vel[i, 1] = (pos[i, 1] - prev[i, 1]) * inv_h
        D = contact_depth[i]
        if D == 0.0:
            continue
        # At a static contact (static friction already held the vertex in the collider stage):
        nx, ny = contact_normal[i, 0], contact_normal[i, 1]
        vn = vel[i, 0] * nx + vel[i, 1] * ny
        vtx, vty = vel[i, 0] - vn * nx, vel[i, 1] - vn * ny
        # Kinetic friction: |Δv_t| <= μ_k |Δv_n|, with |Δv_n| = D / h.
        vt = math.sqrt(vtx * vtx + vty * vty)
        if vt > 0.0:
            s = max(vt - contact_material[i, 1] * D * inv_h, 0.0) / vt
            vtx *= s
            vty *= s
        # A vertex in contact does not keep approaching the surface (inelastic vertex;
        # the bounce is the blob's, see `restitution`).
        vn = max(vn, 0.0)
        vel[i, 0] = vtx + vn * nx
        vel[i, 1] = vty + vn * ny


def update_velocities(state, model, params, h):
    """v = (x - x_prev) / h, then kinetic Coulomb friction at static contacts."""
    _update_velocities[model.parallel](state.pos, state.prev, state.vel, state.contact_normal, state.contact_depth,
                                       state.contact_material, h)


@stage_kernel
def _restitution(vel, inv_mass, offsets, contact_normal, contact_depth, contact_material,
                 impact_speed, rest_speed):
    for b in numba.prange(offsets.shape[0] - 1):
        o, e = offsets[b], offsets[b + 1]
        nx = ny = m_sum = ux = uy = 0.0
        restitution = 0.0
        for i in range(o, e):
            m = 1.0 / inv_mass[i]
            m_sum += m
            ux += m * vel[i, 0]
            uy += m * vel[i, 1]
            D = contact_depth[i]
            if D > 0.0:
                nx += D * contact_normal[i, 0]
                ny += D * contact_normal[i, 1]
                restitution = max(restitution, contact_material[i, 2])
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
            dv = max(restitution * impact_speed[b] - un, 0.0)
            for i in range(o, e):
                vel[i, 0] += dv * nx
                vel[i, 1] += dv * ny
            impact_speed[b] = 0.0
        else:
            impact_speed[b] = 0.0


def restitution(state, model, params, h):
    """Bounce: a blob whose impact on statics has ended leaves at e × its approach speed.

    A vertex cannot bounce on its own: the perimeter and area stages average its reversed
    velocity away against the rest of the blob, which is still falling. So restitution
    acts on the whole blob. While it touches statics, its centre-of-mass approach speed
    V along the depth-weighted contact normal n̄ is tracked; once the centre stops
    approaching, every vertex gets Δv = (e V - u·n̄) n̄. Approaches slower than
    REST_SPEED_FACTOR |g| h never bounce, so resting contacts do not jitter.
    """
    rest_speed = REST_SPEED_FACTOR * math.hypot(params.gravity[0], params.gravity[1]) * h
    _restitution[model.parallel](state.vel, model.inv_mass, model.offsets, state.contact_normal, state.contact_depth,
                                 state.contact_material, state.impact_speed, rest_speed)

