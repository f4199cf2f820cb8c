"""The self-contact stages in C (blobcli/core/self_contact.c) against their numba twins (sim/self_contact.py),
bit for bit.

Each scene is run some steps by the numba step (core_twins.scene_state), then some more by the numba step's
driver (pipeline._advance) run as Python over the numba stage kernels, so that every call of a self-contact
stage sees the very inputs the step gives it: folds, pinches, rings the iterations left crossed, vertices a
collider holds. At every such call the C stage runs first on copies of the state (serially, and split over
threads), and each copy must come out as the numba stage leaves the state.
"""

import math
from collections import Counter

import numpy as np
import pytest
from core_twins import assert_same_bits, core, scene_state, views

from blobcli.sim import pipeline, ring
from blobcli.sim import self_contact as numba_stages
from blobcli.sim.jamming import copy_state

# the C stage's runs at every call: serial (0), and parallel on 1 and on 2 threads (a scene of one ring: 0 and 1,
# its parallel loop has one item)
THREADS, ONE_RING_THREADS = (0, 1, 2), (0, 1)


@pytest.fixture(scope="module")
def core_lib():
    ffi, lib = core()
    threads = lib.bc_threads()
    yield ffi, lib
    lib.bc_set_threads(threads)


def _strip(x0, x1, y, thickness, vertices_along):
    """An explicit polygon: a strip from x0 to x1, `thickness` high, its bottom edge at y (counter-clockwise)."""
    xs = np.linspace(x0, x1, vertices_along)
    points = [(x, y) for x in xs] + [(x, y + thickness) for x in xs[::-1]]
    return "points = [" + ", ".join(f"[{x:.4f}, {y:.4f}]" for x, y in points) + "]\n"


# A 2 m × 0.1 m strip dropped across a post: it folds in two, its halves swing into each other (pairs on both
# sides, held vertices on the post, zones where the iterations leave it crossed).
FOLDED = f"""
[scene]
duration = 3.0
method = "{{method}}"
[[blob]]
{_strip(-1.0, 1.0, 0.8, 0.1, 41)}
[[static]]
kind = "circle"
center = [0.0, 0.5]
radius = 0.05
[[static]]
kind = "plane"
point = [0.0, -0.6]
normal = [0.0, 1.0]
"""

# A strip folded over a post by a press coming down on it (a moving collider holds vertices of its folds).
PRESSED = f"""
[scene]
duration = 3.0
[[blob]]
{_strip(-0.6, 0.6, 0.3, 0.06, 31)}
friction = 0.8
[[static]]
kind = "circle"
center = [0.0, 0.2]
radius = 0.04
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "box"
center = [0.0, 0.8]
size = [1.6, 0.1]
path = [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, -0.65, 0.0]]
"""

# Soft blobs (pressure 0.5) dropped hard onto a row of posts, under a heavy one: 4 × 8 = 32 rings and more,
# the parallel stages' split; and rings of two chunks (8 and 6 vertices: each chunk the other's neighbour).
SOFT_RAIN = """
[scene]
duration = 2.0
[[blob]]
name = "octagon"
center = [-0.6, 2.2]
radius = 0.15
vertices = 8
pressure = 0.5
velocity = [0.0, -8.0]
[[blob]]
name = "hexagon"
center = [0.6, 2.2]
radius = 0.15
vertices = 6
pressure = 0.5
velocity = [0.0, -8.0]
[[blob]]
name = "soft"
center = [-1.4, 0.7]
radius = 0.18
vertices = 24
pressure = 0.5
velocity = [0.0, -6.0]
grid = [8, 4]
spacing = [0.4, 0.4]
[[blob]]
name = "heavy"
center = [0.0, 2.6]
radius = 0.3
mass = 40.0
velocity = [0.0, -8.0]
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[[static]]
kind = "circle"
center = [-1.2, 0.25]
radius = 0.04
[[static]]
kind = "circle"
center = [-0.4, 0.25]
radius = 0.04
[[static]]
kind = "circle"
center = [0.4, 0.25]
radius = 0.04
[[static]]
kind = "circle"
center = [1.2, 0.25]
radius = 0.04
"""


class Twinned:
    """The numba step's driver run as Python, with each self-contact stage checked against its C twin (see the
    module docstring). `seen` counts what the checked calls met (calls, pairs, zoned rings, held pairs)."""

    def __init__(self, core_lib, model, state, settings):
        self.ffi, self.lib = core_lib
        self.threads = THREADS if model.blob_count > 1 else ONE_RING_THREADS
        self.model, self.state, self.settings = model, state, settings
        self.views = views(self.ffi, model, state, settings)
        self.scratch = self.ffi.gc(self.lib.bc_scratch_new(self.views.model), self.lib.bc_scratch_free)
        self.seen = Counter()

    def _twin(self, stage, c_call, numba_call):
        """c_call(context) on copies of the state (serially, then split over threads), numba_call() on the state:
        every copy must equal the state after, and the C results the numba one."""
        copies = []
        for threads in self.threads:
            copy = copy_state(self.state)
            v = views(self.ffi, self.model, copy, self.settings, parallel=threads > 0)
            v.context.w = self.scratch
            self.lib.bc_set_threads(max(threads, 1))
            copies.append((threads, copy, c_call(v.context), v))
        expected = numba_call()
        for threads, copy, result, _ in copies:
            try:
                assert_same_bits(self.state, copy)
                assert result == expected, f"returned {result}, numba {expected}"
            except AssertionError as e:
                raise AssertionError(f"{stage} (call {self.seen[stage] + 1}, threads {threads}): {e}") from None
        self.seen[stage] += 1
        return expected

    def find_self_contacts(self, *args):
        self._twin("find_self_contacts", self.lib.bc_find_self_contacts, lambda: numba_stages.find_self_contacts(*args))
        count, near = self.state.self_contact[2:4]
        self.seen["pairs"] += int(count.sum())
        self.seen["near rings"] += int(near.sum())
        self.seen["full rings"] += int(np.sum(count == numba_stages.PER_VERTEX * np.diff(self.model.offsets)))

    def pairs_found(self, count):
        return self._twin("pairs_found", self.lib.bc_self_pairs_found, lambda: numba_stages.pairs_found.py_func(count))

    def resolve_self_contacts(self, pos, prev, inv_mass, held, normal, hold, *rest):
        reverse = rest[-1]
        if hold:
            self.seen["held pairs"] += self._held_pairs(held)
        self._twin("resolve_self_contacts", lambda context: self.lib.bc_resolve_self_contacts(context, hold, reverse),
                   lambda: numba_stages.resolve_self_contacts(pos, prev, inv_mass, held, normal, hold, *rest))

    def keep_rings_simple(self, pos, prev, vel, h, held, wall_velocity, inv_mass, offsets, awake, rest_perimeter,
                          target_area, exact_area, zoned, near, chunks):
        before = zoned.copy()
        self._twin("keep_rings_simple", lambda context: self.lib.bc_keep_rings_simple(context, h, exact_area),
                   lambda: numba_stages.keep_rings_simple(pos, prev, vel, h, held, wall_velocity, inv_mass, offsets,
                                                          awake, rest_perimeter, target_area, exact_area, zoned, near,
                                                          chunks))
        self.seen["zoned rings"] += int((zoned - before).sum())

    def _held_pairs(self, held):
        """How many of this substep's pairs have a vertex a collider pushed (the hold pass acts on them)."""
        pairs, _, count, _, _, _ = self.state.self_contact
        offsets, found = self.model.offsets, 0
        for b in range(len(count)):
            o, e = offsets[b], offsets[b + 1]
            slot0 = numba_stages.PER_VERTEX * o
            for k in range(slot0, slot0 + count[b]):
                p, j = pairs[0, k], pairs[1, k]
                found += bool(held[p] or held[j] or held[ring.next_in_ring.py_func(j, o, e)])
        return found

    def stages_once(self, exact_area):
        """The self-contact stages of one substep as the step calls them, on the state as it is (previous: where
        the substep began; position: where it ends), two iterations."""
        s, m = self.state, self.model.arrays
        pairs, values, count, near, chunks, zoned = s.self_contact
        h = self.settings.dt / self.settings.substeps
        self.find_self_contacts(s.previous, s.position, m.offsets, s.awake, m.orient, m.rest_perimeter, pairs, values,
                                count, near, chunks)
        self.pairs_found(count)
        for it in range(2):
            for hold in (False, True):
                self.resolve_self_contacts(s.position, s.previous, m.inv_mass, s.contact_depth, s.contact_normal, hold,
                                           m.offsets, s.awake, m.orient, m.material, pairs, values, count, it % 2 == 1)
        self.keep_rings_simple(s.position, s.previous, s.velocity, h, s.contact_depth, s.contact_material, m.inv_mass,
                               m.offsets, s.awake, m.rest_perimeter, m.target_area, exact_area, zoned, near, chunks)

    def run(self, monkeypatch, steps):
        """`steps` steps of the numba step's driver as Python, its self-contact stages checked."""
        for name in ("find_self_contacts", "pairs_found", "resolve_self_contacts", "keep_rings_simple"):
            monkeypatch.setattr(pipeline, name, getattr(self, name))
        # the driver's inlined helpers have no Python entry: their Python text; no clock
        monkeypatch.setattr(pipeline, "most_vertices", ring.most_vertices.py_func)
        monkeypatch.setattr(pipeline, "_lap", lambda clock, stage, t: t)
        monkeypatch.setattr(pipeline, "METHOD", self.settings.config.method)
        done, why, _ = pipeline._advance.py_func(steps, self.state, self.model.arrays, self.settings,
                                                 pipeline.NO_CLOCK)
        assert (done, why) == (steps, pipeline.DONE)


def _checked(core_lib, monkeypatch, toml, warm_up, steps, parallel=False):
    """What the self-contact stages met in `steps` checked steps of a scene, after `warm_up` steps of the numba step."""
    model, state, _, settings = scene_state(toml, warm_up)
    assert model.parallel == parallel
    twinned = Twinned(core_lib, model, state, settings)
    twinned.run(monkeypatch, steps)
    return twinned.seen


def test_constants_match_the_numba_stages(core_lib):
    _, lib = core_lib
    assert lib.BC_SELF_PER_VERTEX == numba_stages.PER_VERTEX
    assert lib.BC_SELF_CHUNK == numba_stages.CHUNK
    assert lib.BC_SELF_CHUNK_ROWS == numba_stages.CHUNK_ROWS
    assert numba_stages.CONE_COS == math.cos(math.radians(75.0))  # (self_contact.c holds these bits)


def test_a_folded_strip(core_lib, monkeypatch):
    """Folds, pairs on both sides of the strip, vertices held on the post, zones, the area projected again."""
    seen = _checked(core_lib, monkeypatch, FOLDED.format(method="kot"), 14, 12)
    assert seen["pairs"] > 0 and seen["zoned rings"] > 0 and seen["held pairs"] > 0, seen


def test_a_folded_strip_without_an_exact_area(core_lib, monkeypatch):
    """Method xpbd: the zones are not projected onto the area again. (All its steps run by the checked driver: no
    numba build of xpbd's whole step is needed.)"""
    seen = _checked(core_lib, monkeypatch, FOLDED.format(method="xpbd"), 0, 26)
    assert seen["pairs"] > 0 and seen["zoned rings"] > 0, seen


def test_a_strip_under_a_press(core_lib, monkeypatch):
    """A moving collider holds vertices of the folds."""
    seen = _checked(core_lib, monkeypatch, PRESSED, 10, 20)
    assert seen["pairs"] > 0 and seen["held pairs"] > 0, seen


def test_soft_blobs_dropped_hard_in_parallel(core_lib, monkeypatch):
    """32 rings and more (the step's parallel build): the stages split over threads."""
    seen = _checked(core_lib, monkeypatch, SOFT_RAIN, 6, 4, parallel=True)
    assert seen["pairs"] > 0 and seen["zoned rings"] > 0 and seen["held pairs"] > 0, seen


def _shrunk(state, model, rng):
    """Each ring drawn in to 2% of its size about its centre: every vertex within reach of every edge (more
    pairs than a ring has slots)."""
    for o, e in zip(model.offsets[:-1], model.offsets[1:]):
        centre = state.position[:, o:e].mean(axis=1, keepdims=True)
        state.position[:, o:e] = centre + 0.02 * (state.position[:, o:e] - centre)


def _shaken(state, model, rng):
    """Every vertex moved at random by about three mean edges: paths through many edges, rings crossed."""
    edge = model.arrays.rest_perimeter[model.blob_of] / np.diff(model.offsets)[model.blob_of]
    state.position[:] += rng.normal(size=state.position.shape) * 3.0 * edge


def _collapsed(state, model, rng):
    """Vertices 3 to 9 of each ring put on one point, at both ends of the substep: edges of no length, a chunk
    of no chord."""
    for o in model.offsets[:-1]:
        for x in (state.position, state.previous):
            x[:, o + 3:o + 10] = x[:, o + 3:o + 4]


@pytest.mark.parametrize("disturb", [_shrunk, _shaken, _collapsed])
def test_disturbed_states(core_lib, disturb):
    """States no step gives, for the stages' guards: the pair slots full, paths through many edges, rings
    crossed beyond ZONE_ROUNDS rounds, degenerate edges and chunks."""
    model, state, _, settings = scene_state(FOLDED.format(method="kot"), 16)
    rng = np.random.default_rng(7)
    twinned = Twinned(core_lib, model, state, settings)
    for _ in range(3):
        disturb(state, model, rng)
        twinned.stages_once(exact_area=True)
    assert twinned.seen["pairs"] > 0, twinned.seen
    assert disturb is not _shrunk or twinned.seen["full rings"] > 0, twinned.seen
