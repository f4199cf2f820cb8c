"""Collider stages: push vertices out of the colliders, fixed or moving. One signature, by kind.

Each stage projects a penetrating vertex to the nearest surface, applies static friction
there (`_stuck`), and records the contact (normal, push-out depth, combined material) for the
velocity update, which applies kinetic friction, and for restitution. Static friction is
applied here rather than after all stages so that a shape can refuse a hold that would put
the vertex inside it (beside a reflex corner of a concave polygon, or on a curved circle).

Tunnelling: at 100 m/s and h = 1/240 s a vertex moves 0.42 m per substep, through any
thin wall. So the segment, circle and polygon stages are swept: they test the path
x_prev -> x of the substep, and a vertex whose path entered the shape is put back on
the tangent line where it entered, not on the nearest (possibly far) side.

Materials combine as Box2D does: μ = √(μ_blob μ_static), e = max(e_blob, e_static). A collider's
`surface_velocity` u (a conveyor belt) moves its surface along t = (n_y, -n_x), n the normal out
of the solid, without moving the collider: friction, static here and kinetic in the velocity
update, acts on the slip relative to the surface, so a scene on a belt is the same scene on a fixed
floor seen from a frame moving with the belt (Galilean invariance, tested).

Colliders that move (walls.py) are where they are at the substep's end (`geom`, `aabb`: the state's
placed rows), and each kernel tests a vertex's path relative to the collider: from its start carried
with the collider, Δ(x_prev) (`delta`), to x. Fixed colliders in a scene where nothing moves skip that
(MOVING, bound per scene), so their bits are what they were. Every push is recorded per vertex
(walls.account), for the force the blobs exert on each collider, and a loaded wall's for its share of
the push (walls.yield_loaded_walls).
"""

import math

import numba

from ..colliders import SOLVERS
from ..jit import inline_kernel, stage_kernel
from .ring import crosses_ray
from .walls import account

SKIN = 1e-6  # m: vertices rest this far from a zero-thickness segment, so their side is known
# Whether a collider of the scene moves, and whether one is a loaded wall (pipeline.Configuration), bound per
# scene: these module values are never run. (A loaded wall's records, left in every build, cost a one-blob step
# 4.8 µs of its 11.)
MOVING = LOADED = True


@inline_kernel
def _record(i, nx, ny, depth, wx, wy, blob_material, shape_material, contact_normal, contact_depth, contact_material):
    contact_normal[0, i] = nx
    contact_normal[1, i] = ny
    contact_depth[i] += depth
    contact_material[0, i] = math.sqrt(blob_material[0] * shape_material[0])
    contact_material[1, i] = math.sqrt(blob_material[1] * shape_material[1])
    contact_material[2, i] = max(blob_material[2], shape_material[2])
    contact_material[3, i] = shape_material[3]
    contact_material[4, i] = wx
    contact_material[5, i] = wy


@inline_kernel
def _stuck(i, x, y, x0, y0, contact_normal, contact_depth, contact_material, h):
    """Where static friction holds the vertex: its slip along the surface this substep undone,
    if |Δx_t| <= μ_s D (Coulomb, at position level: Müller et al. 2020), D being how far the
    surfaces pushed it out this substep, and Δx = x - x0 its motion relative to the collider (x0: its
    start, carried with a moving collider). Returns (x, y) unchanged when it slides. On a moving
    surface (a conveyor: speed u along t = (n_y, -n_x)) the slip is relative to it, Δx_t - u h t:
    a held vertex moves with the belt."""
    nx, ny = contact_normal[0, i], contact_normal[1, i]
    dx, dy = x - x0, y - y0
    dn = dx * nx + dy * ny
    tx, ty = dx - dn * nx, dy - dn * ny
    u = contact_material[3, i]
    if u != 0.0:  # (a branch, not u h t = 0 added: fixed surfaces keep their bits)
        tx -= u * h * ny
        ty += u * h * nx
    if tx * tx + ty * ty <= (contact_material[0, i] * contact_depth[i]) ** 2:
        return x - tx, y - ty
    return x, y


@inline_kernel
def _carried(delta, s, x, y):
    """Δ(x): where a point at x at the substep's start is now, carried with collider s."""
    return delta[s, 0] * x - delta[s, 1] * y + delta[s, 2], delta[s, 1] * x + delta[s, 0] * y + delta[s, 3]


@inline_kernel
def _surface_velocity(delta, s, x, y, h):
    """w = (x - Δ⁻¹(x)) / h: the velocity of collider s's material point at x over the substep."""
    ux, uy = x - delta[s, 2], y - delta[s, 3]
    return (x - (delta[s, 0] * ux + delta[s, 1] * uy)) / h, (y - (delta[s, 0] * uy - delta[s, 1] * ux)) / h


@inline_kernel
def _pushed(i, k, dx, dy, loaded, static_of, static_push, wall_of, wall_push):
    """Record collider k's push (dx, dy) of vertex i: for its force, and a loaded wall's share. (The arrays
    come unpacked from `touch` once per kernel.)"""
    account(i, k, dx, dy, static_of, static_push)
    if loaded != 0.0:
        wall_of[i] = k
        wall_push[0, i] += dx
        wall_push[1, i] += dy


@inline_kernel
def _stuck_outside_circle(i, x, y, x0, y0, cx, cy, r, contact_normal, contact_depth, contact_material, h):
    """_stuck, but only where that is outside the circle (a chord of a curved surface is not)."""
    sx, sy = _stuck(i, x, y, x0, y0, contact_normal, contact_depth, contact_material, h)
    if (sx - cx) ** 2 + (sy - cy) ** 2 >= r * r:
        return sx, sy
    return x, y


@inline_kernel
def _inside_shape(geom, start, stop, x, y):
    """Crossing-number test against the edges geom[start:stop] of one polygon."""
    inside = False
    for k in range(start, stop):
        if crosses_ray(geom[k, 0], geom[k, 1], geom[k, 2], geom[k, 3], x, y):
            inside = not inside
    return inside


@stage_kernel
def _collide_plane(pos, prev, blob_of, awake, blob_material, geom, aabb, delta, shape_offsets, shape_material, index,
                   contact_normal, contact_depth, contact_material, touch, h):
    static_of, static_push, wall_of, wall_push = touch
    # Half-space n · (x - p) >= 0: nothing can pass an infinite plane, so no sweep is needed.
    for i in numba.prange(pos.shape[1]):
        if not awake[blob_of[i]]:
            continue
        x, y = pos[0, i], pos[1, i]
        for s in range(geom.shape[0]):
            px, py, nx, ny = geom[s, 0], geom[s, 1], geom[s, 2], geom[s, 3]
            d = (x - px) * nx + (y - py) * ny
            if d < 0.0:
                qx, qy = x - d * nx, y - d * ny  # onto the plane
                x0, y0, wx, wy = prev[0, i], prev[1, i], 0.0, 0.0
                if MOVING:
                    x0, y0 = _carried(delta, s, x0, y0)
                    wx, wy = _surface_velocity(delta, s, qx, qy, h)
                _record(i, nx, ny, -d, wx, wy, blob_material[blob_of[i]], shape_material[s],
                        contact_normal, contact_depth, contact_material)
                # held there by static friction (it stays on a flat plane)
                qx, qy = _stuck(i, qx, qy, x0, y0, contact_normal, contact_depth, contact_material, h)
                _pushed(i, index[s], qx - x, qy - y, delta[s, 4] if LOADED else 0.0,
                        static_of, static_push, wall_of, wall_push)
                x, y = qx, qy
        pos[0, i], pos[1, i] = x, y


@stage_kernel
def _collide_segment(pos, prev, blob_of, awake, blob_material, geom, aabb, delta, shape_offsets, shape_material,
                     index, contact_normal, contact_depth, contact_material, touch, h):
    static_of, static_push, wall_of, wall_push = touch
    # A zero-thickness wall, solid from both sides. The side a vertex belongs to is the
    # side its substep began on (d0 = n · (x_prev - a)); if its path reaches within SKIN
    # of the line inside the segment's extent, it is put back at distance SKIN.
    for i in numba.prange(pos.shape[1]):
        if not awake[blob_of[i]]:
            continue
        x, y = pos[0, i], pos[1, i]
        for s in range(geom.shape[0]):
            x0, y0 = prev[0, i], prev[1, i]
            if MOVING:
                x0, y0 = _carried(delta, s, x0, y0)
            if (max(x, x0) < aabb[s, 0] - SKIN or min(x, x0) > aabb[s, 2] + SKIN
                    or max(y, y0) < aabb[s, 1] - SKIN or min(y, y0) > aabb[s, 3] + SKIN):
                continue
            ax, ay, bx, by = geom[s, 0], geom[s, 1], geom[s, 2], geom[s, 3]
            ex, ey = bx - ax, by - ay
            length = math.sqrt(ex * ex + ey * ey)
            tx, ty = ex / length, ey / length
            nx, ny = -ty, tx
            d0 = (x0 - ax) * nx + (y0 - ay) * ny
            d1 = (x - ax) * nx + (y - ay) * ny
            if d0 != 0.0:
                side = 1.0 if d0 > 0.0 else -1.0
            else:  # began exactly on the line: it came from where it is moving away from
                side = -1.0 if d1 > 0.0 else 1.0
            s0, s1 = side * d0, side * d1
            if s1 >= SKIN:
                continue
            # Where the path reaches the skin line (or the end point, if it began inside it).
            t = (s0 - SKIN) / (s0 - s1) if s0 > SKIN else 1.0
            cx, cy = x0 + t * (x - x0), y0 + t * (y - y0)
            u = (cx - ax) * tx + (cy - ay) * ty
            if u < 0.0 or u > length:
                continue
            depth = SKIN - s1
            qx, qy = x + depth * side * nx, y + depth * side * ny
            wx = wy = 0.0
            if MOVING:
                wx, wy = _surface_velocity(delta, s, qx, qy, h)
            _record(i, side * nx, side * ny, depth, wx, wy, blob_material[blob_of[i]], shape_material[s],
                    contact_normal, contact_depth, contact_material)
            qx, qy = _stuck(i, qx, qy, x0, y0, contact_normal, contact_depth, contact_material, h)
            _pushed(i, index[s], qx - x, qy - y, delta[s, 4] if LOADED else 0.0,
                    static_of, static_push, wall_of, wall_push)
            x, y = qx, qy
        pos[0, i], pos[1, i] = x, y


@stage_kernel
def _collide_circle(pos, prev, blob_of, awake, blob_material, geom, aabb, delta, shape_offsets, shape_material, index,
                    contact_normal, contact_depth, contact_material, touch, h):
    static_of, static_push, wall_of, wall_push = touch
    for i in numba.prange(pos.shape[1]):
        if not awake[blob_of[i]]:
            continue
        x, y = pos[0, i], pos[1, i]
        for s in range(geom.shape[0]):
            x0, y0 = prev[0, i], prev[1, i]
            if MOVING:
                x0, y0 = _carried(delta, s, x0, y0)
            if (max(x, x0) < aabb[s, 0] or min(x, x0) > aabb[s, 2]
                    or max(y, y0) < aabb[s, 1] or min(y, y0) > aabb[s, 3]):
                continue
            cx, cy, r = geom[s, 0], geom[s, 1], geom[s, 2]
            bx, by = x, y  # before this circle
            wx = wy = 0.0
            if geom[s, 3] != 0.0:  # a container
                x, y, nx, ny, depth = _inside_circle(x, y, cx, cy, r)
                if depth > 0.0:
                    if MOVING:
                        wx, wy = _surface_velocity(delta, s, x, y, h)
                    _record(i, nx, ny, depth, wx, wy, blob_material[blob_of[i]], shape_material[s], contact_normal,
                            contact_depth, contact_material)
                    x, y = _held_inside_circle(i, x, y, x0, y0, cx, cy, r, contact_normal, contact_depth,
                                               contact_material, h)
                    _pushed(i, index[s], x - bx, y - by, delta[s, 4] if LOADED else 0.0,
                            static_of, static_push, wall_of, wall_push)
                continue
            fx, fy = x0 - cx, y0 - cy
            dx, dy = x - x0, y - y0
            # Swept: first t in [0, 1] with |x0 + t d - c| = r, for a path that began outside.
            A = dx * dx + dy * dy
            B = 2.0 * (fx * dx + fy * dy)
            C = fx * fx + fy * fy - r * r
            disc = B * B - 4.0 * A * C
            if C > 0.0 and A > 0.0 and disc >= 0.0:
                t = (-B - math.sqrt(disc)) / (2.0 * A)
                if 0.0 <= t <= 1.0:
                    nx, ny = (fx + t * dx) / r, (fy + t * dy) / r
                    d = (x - (x0 + t * dx)) * nx + (y - (y0 + t * dy)) * ny
                    if d < 0.0:  # onto the tangent line at the entry point
                        x -= d * nx
                        y -= d * ny
                        if MOVING:
                            wx, wy = _surface_velocity(delta, s, x, y, h)
                        _record(i, nx, ny, -d, wx, wy, blob_material[blob_of[i]], shape_material[s],
                                contact_normal, contact_depth, contact_material)
                        x, y = _stuck_outside_circle(i, x, y, x0, y0, cx, cy, r, contact_normal, contact_depth,
                                                     contact_material, h)
                        _pushed(i, index[s], x - bx, y - by, delta[s, 4] if LOADED else 0.0,
                                static_of, static_push, wall_of, wall_push)
                        continue
            rx, ry = x - cx, y - cy
            dist = math.sqrt(rx * rx + ry * ry)
            if dist < r:
                if dist > 0.0:
                    nx, ny = rx / dist, ry / dist
                else:
                    nx, ny = 0.0, 1.0
                x, y = cx + r * nx, cy + r * ny
                if MOVING:
                    wx, wy = _surface_velocity(delta, s, x, y, h)
                _record(i, nx, ny, r - dist, wx, wy, blob_material[blob_of[i]], shape_material[s],
                        contact_normal, contact_depth, contact_material)
                x, y = _stuck_outside_circle(i, x, y, x0, y0, cx, cy, r, contact_normal, contact_depth,
                                             contact_material, h)
                _pushed(i, index[s], x - bx, y - by, delta[s, 4] if LOADED else 0.0,
                        static_of, static_push, wall_of, wall_push)
        pos[0, i], pos[1, i] = x, y


@inline_kernel
def _inside_circle(x, y, cx, cy, r):
    """A circle with blobs inside, solid outside (a drum): a vertex beyond the radius goes back to the
    nearest point of the circle, along the radius (no sweep needed: the solid has no far side to
    tunnel to), with the inward normal. Returns (x, y, nx, ny, depth), depth 0 inside."""
    rx, ry = x - cx, y - cy
    dist = math.sqrt(rx * rx + ry * ry)
    if dist <= r:
        return x, y, 0.0, 0.0, 0.0
    return cx + r * rx / dist, cy + r * ry / dist, -rx / dist, -ry / dist, dist - r


@inline_kernel
def _held_inside_circle(i, x, y, x0, y0, cx, cy, r, contact_normal, contact_depth, contact_material, h):
    """Static friction holds a vertex on a drum's wall: the held point, on the tangent line, is brought
    back onto the circle along its radius."""
    sx, sy = _stuck(i, x, y, x0, y0, contact_normal, contact_depth, contact_material, h)
    qx, qy = sx - cx, sy - cy
    q = math.sqrt(qx * qx + qy * qy)
    if q > r:
        return cx + r * qx / q, cy + r * qy / q
    return sx, sy


@stage_kernel
def _collide_polygon(pos, prev, blob_of, awake, blob_material, geom, aabb, delta, shape_offsets, shape_material,
                     index, contact_normal, contact_depth, contact_material, touch, h):
    static_of, static_push, wall_of, wall_push = touch
    # Polygons are counter-clockwise, so edge (a, b) has outward normal (e_y, -e_x)/|e|.
    for i in numba.prange(pos.shape[1]):
        if not awake[blob_of[i]]:
            continue
        x, y = pos[0, i], pos[1, i]
        for s in range(shape_offsets.shape[0] - 1):
            x0, y0 = prev[0, i], prev[1, i]
            if MOVING:
                x0, y0 = _carried(delta, s, x0, y0)
            if (max(x, x0) < aabb[s, 0] or min(x, x0) > aabb[s, 2]
                    or max(y, y0) < aabb[s, 1] or min(y, y0) > aabb[s, 3]):
                continue
            bx0, by0 = x, y  # before this polygon
            wx = wy = 0.0
            inside = False
            best_t, best = 2.0, -1
            for k in range(shape_offsets[s], shape_offsets[s + 1]):
                ax, ay, bx, by = geom[k, 0], geom[k, 1], geom[k, 2], geom[k, 3]
                if crosses_ray(ax, ay, bx, by, x, y):  # crossing number: is x inside the polygon?
                    inside = not inside
                # Swept: did the path enter through this edge (outside its line, then inside)?
                ex, ey = bx - ax, by - ay
                d0 = (x0 - ax) * ey - (y0 - ay) * ex  # × |e|; the sign is what matters
                d1 = (x - ax) * ey - (y - ay) * ex
                if d0 >= 0.0 and d1 < 0.0:
                    t = d0 / (d0 - d1)
                    u = ((x0 + t * (x - x0) - ax) * ex + (y0 + t * (y - y0) - ay) * ey) / (ex * ex + ey * ey)
                    if 0.0 <= u <= 1.0 and t < best_t:
                        best_t, best = t, k
            if best >= 0:
                # Entered through edge `best`: back onto its line (on the side it came from).
                ax, ay, bx, by = geom[best, 0], geom[best, 1], geom[best, 2], geom[best, 3]
                ex, ey = bx - ax, by - ay
                length = math.sqrt(ex * ex + ey * ey)
                nx, ny = ey / length, -ex / length
                d = (x - ax) * nx + (y - ay) * ny
                x -= d * nx
                y -= d * ny
                if MOVING:
                    wx, wy = _surface_velocity(delta, s, x, y, h)
                _record(i, nx, ny, -d, wx, wy, blob_material[blob_of[i]], shape_material[s],
                        contact_normal, contact_depth, contact_material)
                # Beside a reflex corner that line runs inside the solid: check again.
                inside = _inside_shape(geom, shape_offsets[s], shape_offsets[s + 1], x, y)
            if inside:
                # Began inside (spawned there, pushed in by another stage), or still inside after
                # the swept projection: out to the nearest boundary point.
                best_d2, qx, qy, face = math.inf, x, y, -1
                for k in range(shape_offsets[s], shape_offsets[s + 1]):
                    ax, ay, bx, by = geom[k, 0], geom[k, 1], geom[k, 2], geom[k, 3]
                    ex, ey = bx - ax, by - ay
                    u = min(max(((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey), 0.0), 1.0)
                    cx, cy = ax + u * ex, ay + u * ey
                    d2 = (cx - x) ** 2 + (cy - y) ** 2
                    if d2 < best_d2:
                        best_d2, qx, qy, face = d2, cx, cy, k if 0.0 < u < 1.0 else -1
                depth = math.sqrt(best_d2)
                if depth > 0.0:
                    # Out along the nearest face's normal; (q - x) / depth only at a corner: for a vertex
                    # left on a face by the swept projection, depth is round-off and (q - x) points anywhere
                    # (a box's side face gave n = (0, ±1), which the velocity update then clamped along).
                    if face >= 0:
                        ex, ey = geom[face, 2] - geom[face, 0], geom[face, 3] - geom[face, 1]
                        length = math.sqrt(ex * ex + ey * ey)
                        nx, ny = ey / length, -ex / length
                    else:
                        nx, ny = (qx - x) / depth, (qy - y) / depth
                    x, y = qx, qy
                    if MOVING:
                        wx, wy = _surface_velocity(delta, s, x, y, h)
                    _record(i, nx, ny, depth, wx, wy, blob_material[blob_of[i]], shape_material[s],
                            contact_normal, contact_depth, contact_material)
            if best >= 0 or inside:
                # Static friction, unless holding the vertex would put it inside (reflex corners).
                sx, sy = _stuck(i, x, y, x0, y0, contact_normal, contact_depth, contact_material, h)
                if not _inside_shape(geom, shape_offsets[s], shape_offsets[s + 1], sx, sy):
                    x, y = sx, sy
                _pushed(i, index[s], x - bx0, y - by0, delta[s, 4] if LOADED else 0.0,
                        static_of, static_push, wall_of, wall_push)
        pos[0, i], pos[1, i] = x, y


assert SOLVERS == ("plane", "segment", "circle", "polygon")  # the order collide_statics runs them in


# The collider kinds a scene has, bound per scene (jit.build, pipeline.Configuration): a kind it lacks
# is not compiled. These module values (every kind) are never run.
PLANES = SEGMENTS = CIRCLES = POLYGONS = True


@stage_kernel
def collide_statics(pos, prev, blob_of, awake, blob_material, rest, placed, contact_normal, contact_depth,
                    contact_material, touch, h):
    """Push vertices out of every collider: one kernel per solver kind present. Each kind comes as its
    model rows (rest: geom as written, shape_offsets, material, index: its colliders' places in the
    scene) and the state's (placed: geom and aabb where they are now, delta: their motion this substep),
    empty if absent."""
    if PLANES:
        _collide_plane(pos, prev, blob_of, awake, blob_material, *placed[0], *rest[0][1:], contact_normal,
                       contact_depth, contact_material, touch, h)
    if SEGMENTS:
        _collide_segment(pos, prev, blob_of, awake, blob_material, *placed[1], *rest[1][1:], contact_normal,
                         contact_depth, contact_material, touch, h)
    if CIRCLES:
        _collide_circle(pos, prev, blob_of, awake, blob_material, *placed[2], *rest[2][1:], contact_normal,
                        contact_depth, contact_material, touch, h)
    if POLYGONS:
        _collide_polygon(pos, prev, blob_of, awake, blob_material, *placed[3], *rest[3][1:], contact_normal,
                         contact_depth, contact_material, touch, h)
