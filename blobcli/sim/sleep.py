"""Sleeping islands: blobs at rest stop costing anything but the broad phase.

After Box2D v3 (its islands and sleep timers, solver.c / island.c), for blobs. Once per step:

1. Each awake blob is still while it goes nowhere, on average: its still time grows by dt while
   its centre stays within d = sleep_speed × time_to_sleep of where its window began, and its
   first vertex has turned about the centre by less than d / r since (r its radius); the step it
   goes farther, its still time begins again, from there. A window begins where the still time
   begins and again after each whole time_to_sleep of it, the still time kept: a blob creeping
   slower than sleep_speed stays still. (Measured from where the still time began, a blob
   creeping at v passed d every d / v and began again, and in a pile of 300 one of them nearly
   always had less than time_to_sleep: the island slept 10.2 s after the drop, 4 s after all but
   10 of its blobs had been still for a second; now at 6.0 s.) So an island sleeps once every blob
   has gone slower than sleep_speed on average over its last window. Centre and turn are read from the
   positions, and only once per step: a vertex may flicker while its blob goes nowhere. Not the
   speed at each step: the bottom row of a pile of 1,000 blobs (24 rows on top) rocks in place at
   4-6 mm/s (spin × radius) with an excursion under 2 mm, and tested step by step one of its blobs
   always broke its still time, so the whole pile, one island, never slept. (Nor the spin
   integrated, ∫ω dt: ω read once per step from the last substep's velocities aliased that
   rocking into a steady turn.)
2. Islands are the connected groups of the broad phase's blob pairs (centres closer than
   r_a + r_b + margin: touching, or about to) of the step's last substep, found with a
   union-find over the pairs in pair order. A pair of two sleeping blobs still links them: the
   broad phase runs over every blob.
3. An island in which every awake blob has been still for `time_to_sleep` goes to sleep as a
   whole; an island with any other awake blob in it is awake as a whole: a moving blob that
   comes near a sleeping island wakes every blob of it (their still time starts again from 0,
   so a woken island stays awake at least `time_to_sleep`).

A sleeping blob is not simulated: every stage skips it, its positions stay exactly as they
were, its velocity is 0 (set when it falls asleep) and its contacts are cleared. Awake blobs
that touch it during the step (before the island wakes at its end) treat it as immovable: its
inverse mass in their contacts is 0, or the steady trade of area and contact pushes would
press into it every iteration. A collider that moves wakes the blobs near it (walls.place_walls), and
a blob touching a moving surface is never at rest.
"""

import math

import numpy as np

from ..jit import kernel
from .ring import ring_means, ring_radius


@kernel
def update_sleep(pos, prev, vel, offsets, pairs, contact_depth, contact_material, c_edge, awake, still, still_center,
                 still_angle, sleep_speed, time_to_sleep, dt):
    """One step's sleep bookkeeping (module docstring). awake (B,) uint8, still (B,) s, still_center
    (B, 2) m and still_angle (B,) rad are updated in place; blobs falling asleep get v = 0, x_prev = x
    and no contacts. Returns how many blobs are awake."""
    B = offsets.shape[0] - 1
    reach = sleep_speed * time_to_sleep  # d: how far a still blob may go in its still time
    for b in range(B):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        cx, cy, angle = _pose(pos, o, e)
        turn = angle - still_angle[b]
        turn -= 2.0 * math.pi * round(turn / (2.0 * math.pi))  # in [-π, π]
        moved2 = (cx - still_center[b, 0]) ** 2 + (cy - still_center[b, 1]) ** 2
        if (moved2 < reach * reach and abs(turn) * ring_radius(pos, o, e, cx, cy) < reach
                and not _on_moving_surface(contact_depth, contact_material, o, e)):
            windows = math.floor(still[b] / time_to_sleep)
            still[b] += dt
            if math.floor(still[b] / time_to_sleep) > windows:  # a whole window still: the next is measured
                still_center[b, 0], still_center[b, 1] = cx, cy  # from here, its still time kept
                still_angle[b] = angle
        else:  # it went somewhere: its still time begins again, from here
            _begin_still(b, cx, cy, angle, still, still_center, still_angle)
    # union-find over the pairs; the root is the smallest blob index of the island
    parent = np.arange(B)
    for k in range(pairs.shape[0]):
        ra, rb = _root(parent, pairs[k, 0]), _root(parent, pairs[k, 1])
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    restless = np.zeros(B, np.bool_)  # by root: the island has an awake blob not yet still long enough
    for b in range(B):
        if awake[b] and still[b] < time_to_sleep:
            restless[_root(parent, b)] = True
    for b in range(B):
        keep_awake = restless[_root(parent, b)]
        if keep_awake and not awake[b]:  # woken: its still time begins again, where it slept
            cx, cy, angle = _pose(pos, offsets[b], offsets[b + 1])
            _begin_still(b, cx, cy, angle, still, still_center, still_angle)
        elif awake[b] and not keep_awake:  # falls asleep: frozen exactly where it is
            for i in range(offsets[b], offsets[b + 1]):
                vel[0, i] = vel[1, i] = 0.0
                prev[0, i], prev[1, i] = pos[0, i], pos[1, i]
                contact_depth[i] = 0.0
                c_edge[:, i] = -1
        awake[b] = keep_awake
    return awake_count(awake)


@kernel
def awake_count(awake):
    """How many blobs are awake (a loop: numpy's count_nonzero is a kernel of its own to compile)."""
    count = 0
    for b in range(awake.shape[0]):
        count += awake[b] != 0
    return count


@kernel
def _on_moving_surface(contact_depth, contact_material, o, e):
    """Whether a vertex of ring o..e touches a moving surface (a conveyor, a moving or loaded wall): such
    a blob is never at rest, held in place against it or not, so its island never sleeps while it rides."""
    for i in range(o, e):
        if contact_depth[i] > 0.0 and (contact_material[3, i] != 0.0 or contact_material[4, i] != 0.0
                                       or contact_material[5, i] != 0.0):
            return True
    return False


@kernel
def begin_still(pos, offsets, still, still_center, still_angle):
    """Every blob's still time begins now, where it is (a state just built)."""
    for b in range(offsets.shape[0] - 1):
        cx, cy, angle = _pose(pos, offsets[b], offsets[b + 1])
        _begin_still(b, cx, cy, angle, still, still_center, still_angle)


@kernel
def _pose(pos, o, e):
    """Ring o..e's centre (the mean of its vertices) and the angle of its first vertex about it (rad)."""
    cx, cy, _, _ = ring_means(pos, pos, o, e)
    return cx, cy, math.atan2(pos[1, o] - cy, pos[0, o] - cx)


@kernel
def _begin_still(b, cx, cy, angle, still, still_center, still_angle):
    """Blob b's still time begins now, its centre at (cx, cy) and its first vertex at `angle` about it."""
    still[b] = 0.0
    still_center[b, 0], still_center[b, 1] = cx, cy
    still_angle[b] = angle


@kernel
def _root(parent, b):
    """Union-find root of b, halving the path on the way."""
    while parent[b] != b:
        parent[b] = parent[parent[b]]
        b = parent[b]
    return b
