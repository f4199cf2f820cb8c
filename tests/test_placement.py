"""Random starts: `[[blob]] count` copies placed without overlap in `region`, from `[scene] seed`."""

import numpy as np
import pytest

from blobcli import build
from blobcli.scene.schema import SceneError, parse_scene

MIX = """[scene]
gravity = [0.0, 0.0]
seed = {seed}
[[blob]]
name = "small"
radius = 0.1
vertices = 12
count = 15
region = [-1.2, -1.2, 1.2, 1.2]
[[blob]]
name = "large"
radius = 0.14
vertices = 12
count = 15
region = [-1.2, -1.2, 1.2, 1.2]
[[blob]]
name = "fixed"
center = [0.6, 0.6]
radius = 0.2
[[static]]
kind = "circle"
center = [0.0, 0.0]
radius = 0.3
[[static]]
kind = "segment"
a = [-1.0, -0.5]
b = [-0.2, -0.5]
"""


def discs(model, state):
    o = model.offsets
    centres = np.array([state.pos[o[b]:o[b + 1]].mean(axis=0) for b in range(model.blob_count)])
    radii = np.array([np.hypot(*(state.pos[o[b]:o[b + 1]] - centres[b]).T).max() for b in range(model.blob_count)])
    return centres, radii


def test_copies_lie_in_their_region_clear_of_each_other_blobs_and_colliders():
    model, state = build(parse_scene(MIX.format(seed=0)))
    assert model.names[:2] == ("small_0", "small_1") and model.names[15] == "large_0" and model.names[-1] == "fixed"
    c, r = discs(model, state)
    gaps = np.hypot(*(c[:, None] - c[None]).transpose(2, 0, 1)) - r[:, None] - r[None]
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= -1e-12  # no two bounding discs overlap (the fixed blob's included)
    random = slice(0, 30)
    assert np.all(c[random] - r[random, None] >= -1.2 - 1e-12) and np.all(c[random] + r[random, None] <= 1.2 + 1e-12)
    assert np.all(np.hypot(*c[random].T) - r[random] >= 0.3)  # clear of the circle collider
    near_segment = (c[random, 0] > -1.0 - r[random]) & (c[random, 0] < -0.2 + r[random])
    assert np.all(np.abs(c[random, 1][near_segment] + 0.5) >= r[random][near_segment] - 1e-12)
    assert np.allclose(r[:15], 0.1) and np.allclose(r[15:30], 0.14)  # a bidisperse mix, sizes as given


def test_the_same_seed_gives_the_same_scene_and_another_seed_another():
    a = build(parse_scene(MIX.format(seed=7)))[1].pos
    b = build(parse_scene(MIX.format(seed=7)))[1].pos
    c = build(parse_scene(MIX.format(seed=8)))[1].pos
    assert np.array_equal(a, b) and not np.allclose(a, c)


@pytest.mark.parametrize("extra, expected", [
    ("count = 3\n", "s.toml:4: blob[0].region: required with count (outside a periodic box)"),
    ("count = 3\nregion = [0.0, 0.0, 1.0]\n", "s.toml:5: blob[0].region: must be a list of 4 numbers [xmin, ymin, xmax, ymax] (got [0.0, 0.0, 1.0])"),
    ("count = 3\nregion = [1.0, 0.0, 0.0, 1.0]\n", "s.toml:5: blob[0].region: needs xmin < xmax and ymin < ymax (got [1.0, 0.0, 0.0, 1.0])"),
    ("center = [0.0, 0.0]\nregion = [0.0, 0.0, 1.0, 1.0]\n",
     "s.toml:5: blob[0].region: only with count > 1 (got [0.0, 0.0, 1.0, 1.0])"),
    ("count = 3\nregion = [0.0, 0.0, 5.0, 5.0]\ngrid = [2, 1]\nspacing = [1.0, 0.0]\n",
     "s.toml:6: blob[0].grid: not with count (its copies are placed at random in region) (got [2, 1])"),
    ("count = 50\nregion = [0.0, 0.0, 1.0, 1.0]\n",
     "s.toml:4: blob[0].count: only 1 of 50 copies (bounding radius 0.3 m) fitted in region without overlap after "
     "10,000 tries for the next: enlarge region or lower count (got 50)"),
])
def test_bad_random_starts_get_one_clear_line(extra, expected):
    with pytest.raises(SceneError) as e:
        parse_scene("[[blob]]\nradius = 0.3\nvertices = 8\n" + extra, "s.toml")
    assert e.value.problems == [expected]


def test_a_centre_with_count_is_refused():
    with pytest.raises(SceneError) as e:
        parse_scene("[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.1\ncount = 2\nregion = [0.0, 0.0, 1.0, 1.0]\n", "s.toml")
    assert e.value.problems == ["s.toml:2: blob[0].center: not with count (its copies are placed at random in region) "
                                "(got [0.0, 0.0])"]


def test_schedules_reach_random_copies_by_name():
    sc = parse_scene(MIX.format(seed=1) + "[[schedule]]\nkey = \"blob.small_*.mass\"\nat = [[0.0, 1.0], [1.0, 2.0]]\n")
    assert len(sc.schedules) == 1 and sc.blob_count == 31


def placed_by_testing_every_disc(scene):
    """Random addition as it was written first (every new disc tested against every disc placed before it): the
    reference the grid must agree with, draw for draw."""
    from blobcli.geometry import blob_points
    from blobcli.scene.placement import MAX_TRIES, ring_at_origin
    discs = []
    for b in scene.blobs:
        if b.count == 1:
            ring = blob_points(b)
            discs.append((*ring.mean(axis=0), float(np.hypot(*(ring - ring.mean(axis=0)).T).max())))
    placed = np.array(discs).reshape(-1, 3)
    rng = np.random.default_rng(scene.settings.seed)
    box = np.array(scene.settings.periodic or (np.inf, np.inf))
    out = {}
    for i, b in enumerate(scene.blobs):
        if b.count <= 1:
            continue
        r = float(np.hypot(*ring_at_origin(b).T).max())
        low, high = (-box / 2, box / 2) if b.region is None else (np.array(b.region[:2]) + r, np.array(b.region[2:]) - r)
        centres = []
        for _ in range(b.count):
            for _ in range(MAX_TRIES):
                c = rng.uniform(low, high)
                d = placed[:, :2] - c
                if np.isfinite(box[0]):
                    d -= box * np.round(d / box)
                if np.all(np.hypot(d[:, 0], d[:, 1]) - placed[:, 2] - r >= 0.0):
                    break
            centres.append(c)
            placed = np.vstack([placed, [*c, r]])
        out[i] = np.array(centres)
    return out


@pytest.mark.parametrize("text", [
    "[scene]\nseed = 3\n[[blob]]\ncenter = [0.3, 0.2]\nradius = 0.5\n[[blob]]\nradius = 0.1\nvertices = 8\ncount = 300\n"
    "region = [-5.0, -5.0, 5.0, 5.0]\n[[blob]]\nradius = 0.2\ncount = 60\nregion = [-5.0, -5.0, 5.0, 5.0]\n",
    "[scene]\nperiodic = [6.0, 5.0]\nseed = 7\n[[blob]]\ncenter = [2.9, 2.4]\nradius = 0.3\n[[blob]]\nradius = 0.1\n"
    "vertices = 8\ncount = 100\n[[blob]]\nradius = 0.15\ncount = 10\n",
    "[scene]\nperiodic = [1.0, 1.0]\n[[blob]]\nradius = 0.1\nvertices = 16\ncount = 12\n",  # fewer than 3 cells a side
])
def test_the_placement_grid_places_every_copy_where_testing_every_disc_would(text):
    from blobcli.scene.placement import random_centres
    sc = parse_scene(text)
    grid, every = random_centres(sc), placed_by_testing_every_disc(sc)
    assert grid.keys() == every.keys() and all(np.array_equal(grid[k], every[k]) for k in grid)


def test_forty_thousand_copies_are_placed_in_seconds_not_minutes():
    """check tested each new copy against every copy before it (40,000 copies: 30 s); the grid tests the few
    around it (1.5 s here)."""
    import time
    t0 = time.perf_counter()
    sc = parse_scene("[scene]\ngravity = [0.0, 0.0]\n[[blob]]\nradius = 0.1\nvertices = 8\ncount = 40000\n"
                     "region = [-100.0, -100.0, 100.0, 100.0]\n")
    assert sc.blob_count == 40_000 and time.perf_counter() - t0 < 10.0
