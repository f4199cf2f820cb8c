"""A periodic box: contacts across its edges are the contacts in its middle, blobs cross it whole, the
file says so the H5MD way, and an open world keeps its bits."""

import os
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import blobsim

from blobcli import build, build_params, parse_scene
from blobcli.geometry import ring_next
from blobcli.scene.schema import SceneError
from blobcli.sim.measure import blob_measures
from blobcli.sim.pipeline import advance
from blobcli.tools.compare import compare_files

SCENES = Path(__file__).resolve().parent.parent / "scenes"
PAIR = """[scene]
gravity = [0.0, 0.0]
{box}
[[blob]]
center = [{xa}, 0.05]
radius = 0.4
velocity = [2.0, 0.0]
angular_velocity = 1.0
[[blob]]
center = [{xb}, -0.05]
radius = 0.3
mass = 0.6
velocity = [-2.0, 0.5]
"""


def run(text, steps):
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    advance(state, model, params, steps)
    return model, state


def momentum(model, state):
    return (state.vel / model.inv_mass[:, None]).sum(axis=0)


def test_a_periodic_box_with_no_contact_across_its_edges_gives_the_open_worlds_bits():
    _, open_world = run(PAIR.format(box="", xa=-0.6, xb=0.6), 60)
    _, boxed = run(PAIR.format(box="periodic = [4.0, 3.0]", xa=-0.6, xb=0.6), 60)
    assert np.array_equal(open_world.pos, boxed.pos) and np.array_equal(open_world.vel, boxed.vel)


def test_a_pair_colliding_across_an_edge_moves_as_the_same_pair_in_the_middle():
    """The pair straddles x = ±2 (one blob at 1.4, the other at 2.6 ≡ -1.4): the nearest images meet."""
    model, middle = run(PAIR.format(box="", xa=-0.6, xb=0.6), 60)
    _, edge = run(PAIR.format(box="periodic = [4.0, 3.0]", xa=1.4, xb=-1.4), 60)
    o = model.offsets
    assert middle.blob_contact_depth.max() >= 0.0 and np.abs(middle.vel[o[1]:, 0].mean() + 2.0) > 0.5  # they met
    for b in range(2):
        seen = edge.pos[o[b]:o[b + 1]] - [2.0, 0.0]
        seen[:, 0] -= 4.0 * np.round((seen[:, 0].mean() - middle.pos[o[b]:o[b + 1], 0].mean()) / 4.0)
        assert np.abs(seen - middle.pos[o[b]:o[b + 1]]).max() < 1e-10  # round-off of the shifted coordinates
    assert np.abs(momentum(model, edge) - momentum(model, middle)).max() < 1e-10


def test_a_blob_crossing_the_box_keeps_its_area_perimeter_and_momentum():
    text = PAIR.format(box="periodic = [3.0, 2.5]", xa=0.9, xb=-0.2).replace(
        "velocity = [-2.0, 0.5]", "velocity = [0.0, 0.0]").replace("[-0.2, -0.05]", "[-0.2, -0.9]")
    sc = parse_scene(text)
    model, state = build(sc)
    params = build_params(sc)
    def perimeters():
        ring = state.pos[ring_next(model.offsets)] - state.pos
        return np.add.reduceat(np.hypot(ring[:, 0], ring[:, 1]), model.offsets[:-1])
    p0, a0, l0 = momentum(model, state), blob_measures(state, model)[0], perimeters()
    for _ in range(60):  # 1 s: the first blob crosses x = 1.5 (and passes the second, 0.95 m below it)
        advance(state, model, params, 1)
        assert np.allclose(blob_measures(state, model)[0], a0, rtol=1e-12, atol=0)
        assert np.allclose(perimeters(), l0, rtol=1e-3, atol=0)
    assert np.abs(momentum(model, state) - p0).max() < 1e-12
    assert state.pos[:model.offsets[1], 0].min() > 1.5  # it crossed (the state keeps it continuous)
    assert state.blob_contact_depth.max() == 0.0


def test_the_file_has_the_box_the_image_and_each_blob_whole_inside(tmp_path):
    text = PAIR.format(box="periodic = [3.0, 2.5]", xa=0.9, xb=-0.5)
    (tmp_path / "cross.toml").write_text(text)
    out = tmp_path / "cross.h5"
    r = blobsim("run", tmp_path / "cross.toml", "-o", out, "--steps", "90", "-q")
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as f:
        box = f["particles/blobs/box"]
        assert list(box.attrs["boundary"]) == [b"periodic", b"periodic"] and box.attrs["dimension"] == 2
        edges = box["edges"][...]
        assert edges.tolist() == [3.0, 2.5] and f.attrs["blobsim_format"] == 8
        pos, image = f["particles/blobs/position/value"][...], f["particles/blobs/image/value"][...]
        offsets = f["parameters/blob_offsets"][...]
    centres = np.stack([pos[:, o:e].mean(axis=1) for o, e in zip(offsets[:-1], offsets[1:])], axis=1)
    assert np.all(np.abs(centres) <= edges / 2)  # every blob's centre in the box ...
    assert image[:, :offsets[1], 0].max() == 1  # ... the first one after crossing x = 1.5
    for o, e in zip(offsets[:-1], offsets[1:]):  # ... each blob whole (one image for all its vertices)
        assert np.all(image[:, o:e] == image[:, o:o + 1])
    unwrapped = pos + image * edges
    assert np.abs(np.diff(unwrapped, axis=0)).max() < 0.05  # continuous: no jump by a box side


def test_a_box_too_small_for_its_blobs_is_bad_input():
    with pytest.raises(SceneError) as e:
        parse_scene("[scene]\nperiodic = [1.0, 3.0]\n[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.3\n", "s.toml")
    assert e.value.problems == ["s.toml:2: scene.periodic: each side must be at least 5 × the largest blob's radius "
                                "(1.5 m) (got [1.0, 3.0])"]


def test_random_copies_fill_the_periodic_box_across_its_edges_without_overlap():
    sc = parse_scene("[scene]\nperiodic = [2.0, 2.0]\nseed = 4\n[[blob]]\nradius = 0.15\nvertices = 12\ncount = 30\n")
    model, state = build(sc)
    c = np.array([state.pos[o:e].mean(axis=0) for o, e in zip(model.offsets[:-1], model.offsets[1:])])
    d = c[:, None] - c[None]
    d -= 2.0 * np.round(d / 2.0)
    gaps = np.hypot(d[..., 0], d[..., 1]) - 0.3
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= -1e-12 and np.all(np.abs(c) <= 1.0)


@pytest.mark.slow
def test_the_periodic_scene_gives_the_same_bits_for_any_thread_count_and_when_resumed(tmp_path):
    """scenes/periodic.toml (80 blobs: the parallel build) on 1 and 2 threads, and stopped and resumed."""
    runs = []
    for threads in ("1", "2"):
        out = tmp_path / f"run{threads}.h5"
        env = {**os.environ, "NUMBA_NUM_THREADS": threads}
        r = blobsim("run", SCENES / "periodic.toml", "-o", out, "--steps", "240", "-q", env=env)
        assert r.returncode == 0, r.stderr
        runs.append(out)
    report = compare_files(*runs)
    assert report.same, report.text()
    first = tmp_path / "first.h5"
    assert blobsim("run", SCENES / "periodic.toml", "-o", first, "--steps", "131", "-q").returncode == 0
    r = blobsim("run", SCENES / "periodic.toml", "-q", "--steps", "240", "--resume", first)
    assert r.returncode == 0, r.stderr
    report = compare_files(runs[0], first)
    assert report.same and report.frames == 241, report.text()
