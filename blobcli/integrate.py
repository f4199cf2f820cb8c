"""Time integration stages: damping, prediction and the velocity update.

Position-based dynamics (Müller et al. 2007; XPBD small steps, Macklin et al. 2019):
each substep of length h predicts x* = x + h v + h² g (symplectic Euler), lets the
constraint stages move x*, and then reads the velocity back as v = (x - x_prev) / h.
"""

import math

import numpy as np

from .jit import kernel


@kernel
def _damp_relative(vel, inv_mass, offsets, factor):
    for b in range(offsets.shape[0] - 1):
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
    _damp_relative(state.vel, model.inv_mass, model.offsets, math.exp(-params.damping * h))


@kernel
def _predict(pos, prev, vel, lam, contact_depth, gx, gy, h):
    for i in range(pos.shape[0]):
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
    _predict(state.pos, state.prev, state.vel, state.lam, state.contact_depth,
             params.gravity[0], params.gravity[1], h)


@kernel
def _update_velocities(pos, prev, vel, contact_normal, contact_depth, contact_material, h, rest_speed):
    inv_h = 1.0 / h
    for i in range(pos.shape[0]):
        D = contact_depth[i]
        if D > 0.0:
            nx, ny = contact_normal[i, 0], contact_normal[i, 1]
            mu_s, mu_k, e = contact_material[i, 0], contact_material[i, 1], contact_material[i, 2]
            # Static friction at position level (Müller et al. 2020): the surface pushed the
            # vertex out by D this substep, so Coulomb allows it to hold a tangential slip
            # |Δx_t| <= μ_s D. Undoing that slip is what keeps a resting blob from creeping.
            dx, dy = pos[i, 0] - prev[i, 0], pos[i, 1] - prev[i, 1]
            dn = dx * nx + dy * ny
            tx, ty = dx - dn * nx, dy - dn * ny
            stuck = tx * tx + ty * ty <= (mu_s * D) ** 2
            if stuck:
                pos[i, 0] -= tx
                pos[i, 1] -= ty
            vn_before = vel[i, 0] * nx + vel[i, 1] * ny  # the predicted, pre-contact velocity
            vx, vy = (pos[i, 0] - prev[i, 0]) * inv_h, (pos[i, 1] - prev[i, 1]) * inv_h
            vn = vx * nx + vy * ny
            vtx, vty = vx - vn * nx, vy - vn * ny
            if not stuck:
                # Kinetic friction: |Δv_t| <= μ_k |Δv_n|, with |Δv_n| = D / h.
                vt = math.sqrt(vtx * vtx + vty * vty)
                if vt > 0.0:
                    s = max(vt - mu_k * D * inv_h, 0.0) / vt
                    vtx *= s
                    vty *= s
            # Restitution: leave at -e times the approach speed; below the rest speed,
            # no bounce at all, so resting contacts do not jitter.
            vn_target = -e * vn_before if vn_before < -rest_speed else 0.0
            vn = max(vn, vn_target)
            vel[i, 0] = vtx + vn * nx
            vel[i, 1] = vty + vn * ny
        else:
            vel[i, 0] = (pos[i, 0] - prev[i, 0]) * inv_h
            vel[i, 1] = (pos[i, 1] - prev[i, 1]) * inv_h


def update_velocities(state, model, params, h, rest_speed_factor):
    """v = (x - x_prev) / h, then Coulomb friction and restitution at static contacts."""
    rest_speed = rest_speed_factor * float(np.hypot(*params.gravity)) * h
    _update_velocities(state.pos, state.prev, state.vel, state.contact_normal, state.contact_depth,
                       state.contact_material, h, rest_speed)
