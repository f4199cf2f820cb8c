"""Sleeping islands: blobs at rest stop costing anything but the broad phase.

After Box2D v3 (its islands and sleep timers, solver.c / island.c), for blobs. Once per step:

1. Each awake blob's rigid speed s = max(|v_c|, |ω| r), from its best-fit rigid motion
   (integrate.rigid_motion) and its radius r, is tested against `sleep_speed`: the blob's
   still time grows by dt while s stays below it and drops to 0 the step it does not. The
   centre and the spin are what is tested, not single vertices: a vertex may flicker while its
   blob goes nowhere, and sleeping is for blobs that go nowhere.
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
press into it every iteration. Static colliders never move, so only blobs wake islands.
"""

import math

import numpy as np

from ..jit import kernel
from .integrate import rigid_motion
from .ring import ring_radius


@kernel
def update_sleep(pos, prev, vel, offsets, pairs, contact_depth, c_edge, awake, still, sleep_speed, time_to_sleep, dt):
    """One step's sleep bookkeeping (module docstring). awake (B,) uint8 and still (B,) s are
    updated in place; blobs falling asleep get v = 0, x_prev = x and no contacts. Returns how many
    blobs are awake."""
    B = offsets.shape[0] - 1
    for b in range(B):
        if not awake[b]:
            continue
        o, e = offsets[b], offsets[b + 1]
        cx, cy, vx, vy, w = rigid_motion(pos, vel, o, e)
        speed = max(math.sqrt(vx * vx + vy * vy), abs(w) * ring_radius(pos, o, e, cx, cy))
        still[b] = still[b] + dt if speed < sleep_speed else 0.0
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
        if keep_awake and not awake[b]:  # woken: its still time starts again
            still[b] = 0.0
        elif awake[b] and not keep_awake:  # falls asleep: frozen exactly where it is
            for i in range(offsets[b], offsets[b + 1]):
                vel[0, i] = vel[1, i] = 0.0
                prev[0, i], prev[1, i] = pos[0, i], pos[1, i]
                contact_depth[i] = 0.0
                c_edge[:, i] = -1
        awake[b] = keep_awake
    return np.count_nonzero(awake)


@kernel
def _root(parent, b):
    """Union-find root of b, halving the path on the way."""
    while parent[b] != b:
        parent[b] = parent[parent[b]]
        b = parent[b]
    return b
