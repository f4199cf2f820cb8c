"""`blobsim jam`: a packing compressed to jamming lands near the published φ_J and z_J, friction jams it
looser, and the command keeps its contract (bad input, JSON, one trajectory per seed)."""

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import blobsim

from blobcli.sim import jamming, packing
from blobcli.sim.jamming import BALANCE, PAST_ONSET, Forces, force_balance
from blobcli.sim.packing import rattler_below, rattlers
from blobcli.tools.jam import summary, write_json

JAMMING = Path(__file__).resolve().parent.parent / "scenes" / "jamming"
# scenes/jamming/bidisperse.toml at an eighth of its size: 16 + 16 blobs, the same box fraction (φ = 0.40)
SMALL = """[scene]
gravity = [0.0, 0.0]
periodic = [1.9286, 1.9286]
drag = 1.0
seed = {seed}
[[blob]]
name = "large"
radius = 0.14
vertices = 32
count = 16
friction = {mu}
[[blob]]
name = "small"
radius = 0.1
vertices = 32
count = 16
friction = {mu}
"""


def jam(tmp_path, name, seeds=1, mu=0.0, seed=0):
    scene = tmp_path / f"{name}.toml"
    scene.write_text(SMALL.format(seed=seed, mu=mu))
    out = tmp_path / "out"
    r = blobsim("jam", scene, "--seeds", seeds, "--workers", 0, "-o", out, "--json", tmp_path / f"{name}.json", "-q")
    assert r.returncode == 0, r.stderr
    return json.loads((tmp_path / f"{name}.json").read_text()), out / name


@pytest.mark.parametrize("text, says", [
    ("[scene]\ngravity = [0.0, 0.0]\n[[blob]]\ncenter = [0.0, 0.0]\nradius = 0.1\n[[blob]]\ncenter = [1.0, 0.0]\n"
     "radius = 0.1\n", "needs [scene] periodic"),
    (SMALL.format(seed=0, mu=0.0).replace("count = 16\nfriction = 0.0\n[[blob]]", "count = 16\ncompliance = 0.0\n"
                                                                              "friction = 0.0\n[[blob]]"),
     "compliance = 0"),
    (SMALL.format(seed=0, mu=0.0) + '[[schedule]]\nkey = "scene.periodic"\nat = [[0.0, 3.0, 3.0]]\n',
     "[[schedule]]"),
])
def test_a_scene_jam_cannot_compress_is_bad_input(tmp_path, text, says):
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    r = blobsim("jam", scene, "-o", tmp_path / "out")
    assert r.returncode == 2 and says in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()  # nothing written


def test_a_scene_jam_refuses_is_named_by_file_line_and_key(tmp_path):
    """jam's own refusals read as `check`'s: file:line: key.path: what is wrong."""
    scene = tmp_path / "bad.toml"
    scene.write_text(SMALL.format(seed=0, mu=0.0).replace("count = 16\nfriction = 0.0\n[[blob]]",
                                                          "count = 16\nfriction = 0.0\n[[blob]]\ncompliance = 0.0"))
    r = blobsim("jam", scene, "-o", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.startswith(f"{scene}:13: blob[1].compliance: jam measures pressure"), r.stderr
    scene.write_text(SMALL.format(seed=2 ** 63 - 2, mu=0.0))
    r = blobsim("jam", scene, "--seeds", 3, "-o", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.startswith(f"{scene}:5: scene.seed: the seeds run to"), r.stderr
    assert not (tmp_path / "out").exists()


def test_a_bad_seed_is_the_only_error_a_jam_scene_gets(tmp_path):
    """seed = -1 in a periodic scene: one error, the seed's, not a false one about its copies' region."""
    scene = tmp_path / "bad.toml"
    scene.write_text(SMALL.format(seed=-1, mu=0.0))
    r = blobsim("jam", scene, "-o", tmp_path / "out")
    assert r.returncode == 2 and r.stderr == f"{scene}:5: scene.seed: must be >= 0 (got -1)\n", r.stderr


def test_seeds_are_bounded_before_any_work(tmp_path):
    from blobcli.tools.jam import MAX_SEEDS
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL.format(seed=0, mu=0.0))
    r = blobsim("jam", scene, "--seeds", 1_000_000_000, "-o", tmp_path / "out")
    assert r.returncode == 2 and f"--seeds: at most {MAX_SEEDS:,}" in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


def test_an_output_name_too_long_is_bad_input_as_for_run(tmp_path):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL.format(seed=0, mu=0.0))
    for out in (tmp_path / ("x" * 300), tmp_path / ("x" * 300) / "y"):
        r = blobsim("jam", scene, "-o", out)
        assert r.returncode == 2 and "too long" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr


def test_the_chart_is_written_through_the_safe_path_never_through_a_link(tmp_path):
    """A symlink planted at DIR/<name>/chart.png is replaced by the chart, its target untouched (as summary.json
    and the trajectories already were)."""
    scene = tmp_path / "two.toml"  # two blobs: jam fails fast (exit 1), and still writes its chart
    scene.write_text("[scene]\ngravity = [0.0, 0.0]\nperiodic = [1.0, 1.0]\n[[blob]]\nradius = 0.1\nvertices = 16\n"
                     "count = 2\n")
    out = tmp_path / "out" / "two"
    out.mkdir(parents=True)
    precious = tmp_path / "precious.txt"
    precious.write_text("precious")
    (out / "chart.png").symlink_to(precious)
    r = blobsim("jam", scene, "-o", tmp_path / "out", "--workers", 0, "-q")
    assert r.returncode in (0, 1), r.stderr
    assert precious.read_text() == "precious"
    assert not (out / "chart.png").is_symlink() and (out / "chart.png").read_bytes()[:4] == b"\x89PNG"


def test_the_shipped_jamming_scenes_are_valid_and_differ_only_in_friction():
    scenes = sorted(JAMMING.glob("*.toml"))
    assert [s.stem for s in scenes] == ["bidisperse", "frictional"]
    assert blobsim("check", *scenes).returncode == 0
    texts = [[line for line in s.read_text().splitlines() if not line.startswith("#")] for s in scenes]
    differ = [(a, b) for a, b in zip(*texts) if a != b]
    assert differ == [("friction = 0.0", "friction = 1.0")] * 2


def test_the_json_has_every_seed_and_the_mean_with_standard_errors(tmp_path):
    def row(seed, phi, z):  # past onset, z - z_J = 3 (φ - φ_J)^0.5 exactly
        past = [{"phi": phi + d, "z": z + 3.0 * d ** 0.5} for d in (0.002, 0.01, 0.04)]
        return {"status": "ok", "seed": seed, "phi_j": phi, "z_j": z, "z_j_touching": z + 0.2, "z_j_all": z - 0.1,
                "pressure": 0.01, "reduced_pressure": 2e-6, "rattlers": 3, "balance": 0.05,
                "beta": math.nan if seed == 2 else 0.6, "past": past}
    rows = [row(0, 0.82, 4.0), row(1, 0.84, 4.2), row(2, 0.83, 4.1), {"status": "failed: no", "seed": 3}]
    figures = summary(rows)
    assert [s["seed"] for s in figures["seeds"]] == [0, 1, 2]
    m = figures["mean"]
    assert m["phi_j"] == pytest.approx(0.83) and m["z_j"] == pytest.approx(4.1)
    assert m["phi_j_sem"] == pytest.approx(0.01 / math.sqrt(3))  # std (ddof 1) 0.01 over √3
    assert m["beta"] == pytest.approx(0.5)  # one fit of the seeds' mean z - z_J at each Δφ
    write_json(summary(rows[:1]), tmp_path / "one.json")
    one = json.loads((tmp_path / "one.json").read_text())  # strict JSON: no NaN
    assert one["mean"]["phi_j_sem"] is None and one["seeds"][0]["beta"] == 0.6


def test_the_mean_exponent_fits_the_seeds_mean_excess_so_that_their_scatter_cancels():
    # two seeds whose z - z_J scatter by ±0.03 about 0.5 (φ - φ_J)^0.5, as a seed's few contacts past onset do:
    # the mean over the seeds at each Δφ is the law itself; pooling each seed's logs (dropping the packings whose
    # z did not rise) read 0.29
    def row(seed, scatter):
        past = [{"phi": 0.83 + d, "z": 4.1 + 0.5 * d ** 0.5 + scatter} for d in (0.002, 0.005, 0.01, 0.02)]
        return {"status": "ok", "seed": seed, "phi_j": 0.83, "z_j": 4.1, "z_j_touching": 4.2, "z_j_all": 4.0,
                "pressure": 0.01, "reduced_pressure": 2e-6, "rattlers": 3, "balance": 0.05, "beta": 0.5,
                "past": past}
    assert summary([row(0, 0.03), row(1, -0.03)])["mean"]["beta"] == pytest.approx(0.5, abs=1e-9)


def test_with_friction_two_contacts_hold_a_blob():
    touching = np.array([[0, 1], [0, 2], [0, 4], [1, 2], [1, 4], [2, 4], [3, 0], [3, 1]])  # 0, 1, 2, 4 each touch
    frictionless, frictional = np.zeros((5, 3)), np.array([[0.6, 0.5, 0.0]] * 5)  # the rest; 3 touches 0 and 1
    assert rattler_below(frictionless) == 3 and rattler_below(frictional) == 2
    assert rattlers(touching, 5, rattler_below(frictionless)).tolist() == [False, False, False, True, False]
    assert not rattlers(touching, 5, rattler_below(frictional)).any()


@pytest.mark.slow
def test_a_small_bidisperse_packing_jams_near_the_published_point(tmp_path):
    """32 blobs (an eighth of the shipped scene), two seeds: φ_J and z_J within loose bounds of the published
    0.842 and 4 (O'Hern et al. 2003), each jammed packing in force balance and its balance recorded; excess
    contacts grow past onset: the packing φ_J + 0.02 has more than z_J + 0.1 (one contact more among ~28 blobs
    is 0.07). The exponent of that growth is a figure of the full scene (docs/jamming.md):
    in a packing this small z moves by whole contacts, and the fit over two seeds scatters; each seed's trajectory is a complete file whose box shrinks to
    the jammed packing."""
    figures, out = jam(tmp_path, "small", seeds=2)
    for s in figures["seeds"]:
        assert 0.79 < s["phi_j"] < 0.86 and 3.7 < s["z_j"] < 4.4 and s["balance"] <= BALANCE
        # Removing a rattler of c <= 2 contacts from N blobs of mean z raises z exactly when c <= z / 2: always
        # once z >= 4, not below (seen: z 3.9375 with them, 3.9231 without)
        assert s["z_j_all"] <= s["z_j_touching"] + 1e-12 or s["z_j_all"] < 4.0
        with h5py.File(out / f"seed-{s['seed']}.h5") as f:  # the last packing is the most compressed one
            contacts = f["observables/contacts/value"][-1]
            rattler = f["observables/rattler/value"][-1].astype(bool)
            phi = f["observables/packing_fraction/value"][...]
        assert contacts[~rattler].mean() > s["z_j"] + 0.1
        # bisected to p ᾱ = 3e-6: within 25%, or above it with an unjammed packing less than 2.5e-4 below φ_J
        below = (phi < s["phi_j"]) & (phi > s["phi_j"] - 2.5e-4 - 1e-9)
        assert 0.75 * 3e-6 < s["reduced_pressure"] and (s["reduced_pressure"] < 1.25 * 3e-6 or below.any())
    assert figures["mean"]["phi_j_sem"] > 0.0
    with h5py.File(out / "seed-0.h5") as f:
        assert f.attrs["complete"]
        edges = f["particles/blobs/box/edges/value"][...]
        phi = f["observables/packing_fraction/value"][...]
        assert edges.shape[1] == 2 and edges[-1, 0] < edges[0, 0]
        # from the start to the last packing past onset
        assert phi[0] == pytest.approx(0.40, abs=0.01)
        assert phi[-1] == pytest.approx(figures["seeds"][0]["phi_j"] + PAST_ONSET[-1], abs=1e-4)  # (areas drift ~1e-5)
        assert np.min(np.abs(phi - figures["seeds"][0]["phi_j"])) < 1e-9  # the jammed packing is a frame
        balance, tolerance = f.attrs["jam_balance"], f.attrs["jam_force_balance_tolerance"]
        assert len(balance) == len(phi) and tolerance == BALANCE  # each packing's force balance, recorded
        assert balance[np.argmin(np.abs(phi - figures["seeds"][0]["phi_j"]))] <= tolerance
    assert (out / "chart.png").stat().st_size > 10_000


@pytest.mark.slow
def test_friction_jams_the_packing_looser_with_fewer_contacts(tmp_path):
    """The same start with μ = 1: φ_J at least 0.02 and z_J at least 0.3 below frictionless (the shipped scenes:
    0.764 and 3.09 against 0.842 and 4.05, docs/jamming.md)."""
    frictionless, _ = jam(tmp_path, "smooth")
    rough, _ = jam(tmp_path, "rough", mu=1.0)
    a, b = frictionless["seeds"][0], rough["seeds"][0]
    assert b["phi_j"] < a["phi_j"] - 0.02 and b["z_j"] < a["z_j"] - 0.3


@pytest.mark.slow
def test_a_stopped_jam_keeps_every_packing_it_brought_to_rest(tmp_path):
    """Ctrl-C mid-compression: exit 130 within seconds, the seed's file published incomplete with its
    frames (each a packing at rest), readable."""
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL.format(seed=0, mu=0.0))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "blobcli", "jam", str(scene), "--seeds", "2", "--workers", "0",
                             "-o", str(out), "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = out / "small" / "seed-0.h5.partial"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not partial.exists():
        time.sleep(0.05)
    time.sleep(3.0)  # a few packings brought to rest
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err, err
    with h5py.File(out / "small" / "seed-0.h5") as f:
        assert not f.attrs["complete"] and "signal" in f.attrs["stopped"]
        assert len(f["observables/packing_fraction/value"]) >= 2
    assert not (out / "small" / "seed-1.h5").exists()  # the seeds after it are not started


def test_a_fit_that_cannot_be_made_says_so_in_words():
    """One seed with fewer than three points past onset has no exponent: the summary says so, not `^nan`."""
    from blobcli.tools.jam import report
    mean = {"phi_j": 0.83, "z_j": 4.0, "z_j_touching": 4.2, "z_j_all": 4.2, "pressure": 1e-3,
            "reduced_pressure": 2e-6, "rattlers": 3.0, "balance": 0.05, "beta": math.nan, "phi_j_sem": None,
            "z_j_sem": None}
    line = report({"seeds": [{}], "mean": mean})
    assert "nan" not in line and "no fit of z - z_J" in line
    assert "^0.50" in report({"seeds": [{}], "mean": {**mean, "beta": 0.5}})


def test_a_pairs_normal_force_is_its_push_along_the_branch_across_the_box_edge():
    """Blob 0 at x = -0.9 and blob 1 at x = +0.9 in a 2 m box touch across its edge (their nearest images are
    0.2 m apart, 1 to the left of 0): a force F = (+3, 0) N on blob 0 pushes it away from 1, f = +3; the pair's
    net forces are ±F; a contact under 0.01 of the mean push carries none (blob 0 pushed down from blob 2 above
    it, by 1e-4 N)."""
    centre = np.array([[-0.9, 0.0], [0.9, 0.0], [0.0, 0.5], [0.0, -0.5]])
    touching = np.array([[0, 1], [2, 3], [0, 2]])
    force = np.array([[3.0, 0.0], [0.0, 1.0], [0.0, -1e-4]])  # on the first blob of each pair
    normal = packing.normal_forces(touching, force, centre, (2.0, 2.0))
    assert normal == pytest.approx([3.0, 1.0, 1e-4 * 0.5 / np.hypot(0.9, 0.5)])
    assert packing.bearing(normal).tolist() == [True, True, False]
    net = packing.net_forces(touching, force, 4)
    assert net[0] == pytest.approx([3.0, -1e-4]) and net[1] == pytest.approx([-3.0, 0.0])
    assert net.sum(axis=0) == pytest.approx([0.0, 0.0], abs=1e-15)


def test_force_balance_is_the_largest_mean_net_force_over_the_mean_push_without_rattlers():
    """Two steps: blob 0's net force (1, 0) then (-1, 0) averages to 0; blob 1's (0.3, 0) twice; blob 2, a
    rattler, (5, 0): the balance is 0.3 / the mean push 2."""
    touching, normal = np.array([[0, 1]]), np.array([2.0])
    steps = [Forces(touching, normal, np.array([[1.0, 0.0], [0.3, 0.0], [5.0, 0.0]])),
             Forces(touching, normal, np.array([[-1.0, 0.0], [0.3, 0.0], [5.0, 0.0]]))]
    assert force_balance(steps, np.array([False, False, True])) == pytest.approx(0.15)
    assert force_balance(steps, np.array([True, True, True])) == math.inf


def test_a_pressed_packings_contact_forces_give_its_pressure(tmp_path):
    """32 blobs compressed past jamming (φ = 0.87), 600 steps of the drag: the pressure read from the pairs'
    normal forces, p = Σ f |d| / (2 A) (frictionless: the virial of the pairs), is the stress's (the step's
    impulses per blob) within 5%; fewer contacts carry force than touch."""
    from blobcli.scene.parse import parse_scene
    from blobcli.sim.model import build, build_params
    from blobcli.sim.pipeline import advance
    scene = parse_scene(SMALL.format(seed=0, mu=0.0), "small.toml")
    model, state = build(scene)
    params = jamming.compress(state, model, build_params(scene), 0.87)
    advance(state, model, params, 600)
    forces = jamming.contact_forces(state, model, params)
    d = packing.centres(state.pos, model.offsets)
    d = d[forces.touching[:, 1]] - d[forces.touching[:, 0]]
    d -= np.asarray(params.box) * np.round(d / np.asarray(params.box))
    from_pairs = float((forces.normal * np.hypot(*d.T)).sum() / (2.0 * params.box[0] * params.box[1]))
    from_stress = packing.pressure(packing.stress(state.packing[0], params.dt, params.box))
    assert from_stress * jamming.mean_compliance(model) > 3e-6
    assert from_pairs == pytest.approx(from_stress, rel=0.05)
    assert 0 < packing.bearing(forces.normal).sum() < len(forces.normal)


@pytest.mark.slow
def test_blobs_with_slack_perimeters_jam_denser(tmp_path):
    """𝒜 = 1.10 (each blob's area 0.912 of its 32-gon's, its perimeter the polygon's): the blobs fill the gaps
    discs leave, φ_J above 0.95 (64 blobs, 4 seeds: 0.9908 ± 0.0003; docs/jamming.md), against about 0.84 for
    the regular polygons; seed 0 of the small scene."""
    from blobcli.tools.jam_shapes import regular_shape, shaped
    scene = tmp_path / "slack.toml"
    scene.write_text(shaped(SMALL.format(seed=0, mu=0.0), 1.10, None))
    assert f"pressure = {regular_shape(32) / 1.10!r}" in scene.read_text()
    r = blobsim("jam", scene, "--workers", 0, "-o", tmp_path / "out", "--json", tmp_path / "slack.json", "-q")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "slack.json").read_text())["seeds"][0]["phi_j"] > 0.95


@pytest.mark.slow
def test_a_jammed_packing_out_of_force_balance_is_not_read(monkeypatch):
    """With a tolerance the step cannot reach (1e-6 of the mean push), the protocol says the jammed packing is
    not in force balance, and how far, instead of returning its φ: here the bracket closes on the first jammed
    packing (a bracket of 0.02 is as tight as asked), which does not balance."""
    from blobcli.scene.parse import parse_scene
    from blobcli.sim.model import build, build_params
    monkeypatch.setattr(jamming, "BALANCE", 1e-6)
    monkeypatch.setattr(jamming, "MAX_BALANCE", jamming.MAX_RELAX)
    monkeypatch.setattr(jamming, "SMALLEST_STEP", 0.02)
    scene = parse_scene(SMALL.format(seed=0, mu=0.0), "small.toml")
    model, state = build(scene)
    with pytest.raises(ValueError, match=r"not in force balance after \d+ steps: a blob's net contact force is"):
        jamming.jam(state, model, build_params(scene), 3e-6)


def test_a_try_within_the_pressure_tolerance_that_does_not_balance_is_passed_over(monkeypatch):
    """The bisection reads a jammed packing only in force balance: a try at p* that does not balance closes the
    bracket from its side and the bisection goes on to one that does. The relaxation is scripted (p̃ rising
    through p* at φ = 0.842, rigid from 0.82, the first try within the tolerance out of balance)."""
    from blobcli.scene.parse import parse_scene
    from blobcli.sim.measure import blob_measures
    from blobcli.sim.model import build, build_params
    target, unbalanced = 3e-6, []

    def scripted(state, model, params, target, run=None):
        phi = packing.packing_fraction(blob_measures(state, model)[0], params.box)
        reduced = max(phi - 0.80, 0.0) / 0.042 * target
        near = abs(reduced / target - 1.0) < jamming.PRESSURE_TOLERANCE
        balance = 0.5 if near and not unbalanced else 0.05
        if balance > BALANCE:
            unbalanced.append(phi)
        return jamming.Packing(phi=phi, pressure=reduced, reduced=reduced, z=4.0, z_touching=4.2, z_all=4.2,
                               rattlers=0, kinetic=0.0, steps=120, rigid=phi > 0.82, balance=balance)

    monkeypatch.setattr(jamming, "relax", scripted)
    scene = parse_scene(SMALL.format(seed=0, mu=0.0), "small.toml")
    model, state = build(scene)
    found = jamming.jam(state, model, build_params(scene), target)
    assert len(unbalanced) == 1 and found.jammed.phi != unbalanced[0]
    assert found.jammed.balance <= BALANCE
    assert abs(found.jammed.reduced / target - 1.0) < jamming.PRESSURE_TOLERANCE
    assert [p.phi for p in found.path].index(unbalanced[0]) < [p.phi for p in found.path].index(found.jammed.phi)
