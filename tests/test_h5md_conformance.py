"""The trajectory file walked against the H5MD 1.1 rules blobsim implements (core spec, the
units module, connectivity), and read by third-party code: h5py's low level and, where it is
installed, h5dump."""

import re
import shutil
import subprocess

import h5py
import numpy as np
import pytest
from conftest import ONE, cli

UNIT_FACTOR = re.compile(r"^[A-Za-z]+([+-][1-9][0-9]*)?$")  # a symbol, optionally a signed non-zero power
NUMBER = re.compile(r"^[0-9]+(\.[0-9]+)?$")


def fixed_ascii(obj, name) -> bool:
    t = obj.attrs.get_id(name).get_type()
    return isinstance(t, h5py.h5t.TypeStringID) and not t.is_variable_str() and t.get_cset() == h5py.h5t.CSET_ASCII


def unit_problems(unit: str) -> list[str]:
    """The units module's grammar: factors separated by one space; at most one number, first;
    each symbol at most once."""
    factors = unit.split(" ")
    out = []
    if any(NUMBER.match(f) for f in factors[1:]):
        out.append(f"{unit!r}: a number may only come first")
    symbols = [re.sub(r"[+-].*", "", f) for f in factors if not NUMBER.match(f)]
    if any(not UNIT_FACTOR.match(f) for f in factors if not NUMBER.match(f)):
        out.append(f"{unit!r}: not symbol[+-power] factors")
    if len(set(symbols)) != len(symbols):
        out.append(f"{unit!r}: a symbol repeats")
    return out


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory):
    d = tmp_path_factory.mktemp("h5md")
    (d / "s.toml").write_text(ONE.replace('name = "solo"', 'name = "solo"\ngrid = [2, 1]\nspacing = [1.5, 0.0]'))
    assert cli("run", d / "s.toml", "-o", d / "t.h5", "-q")[0] == 0
    return d / "t.h5"


def test_h5md_group_version_author_creator(trajectory):
    with h5py.File(trajectory) as f:
        h5 = f["h5md"]
        assert h5.attrs["version"].dtype.kind == "i" and list(h5.attrs["version"]) == [1, 1]
        for group, names in (("author", ["name"]), ("creator", ["name", "version"])):
            for name in names:
                assert fixed_ascii(h5[group], name), f"h5md/{group} {name} must be a fixed-length ASCII string"


def test_every_unit_is_in_the_units_grammar_and_the_module_is_declared(trajectory):
    units = []
    with h5py.File(trajectory) as f:
        f.visititems(lambda name, obj: units.append((name, obj)) if "unit" in obj.attrs else None)
        assert units, "no unit attributes at all"
        for name, obj in units:
            assert fixed_ascii(obj, "unit"), f"{name}: unit must be fixed-length ASCII"
            assert unit_problems(obj.attrs["unit"].decode()) == [], name
        module = f["h5md/modules/units"]
        assert list(module.attrs["version"]) == [1, 0] and module.attrs["system"] == b"SI"
        assert fixed_ascii(module, "system")
        assert f["observables/area/value"].attrs["unit"] == b"m+2"
    assert unit_problems("m^2") and unit_problems("m m") and unit_problems("s 60") and not unit_problems("60 s")


def test_time_dependent_elements_and_the_box(trajectory):
    with h5py.File(trajectory) as f:
        for name in ("particles/blobs/position", "observables/area", "observables/kinetic_energy", "observables/awake"):
            g = f[name]
            frames = g["value"].shape[0]
            assert g["step"].dtype.kind == "i" and g["step"].shape == (frames,)
            assert g["time"].dtype.kind == "f" and g["time"].shape == (frames,)
            assert np.all(np.diff(g["step"][...]) > 0)
        box = f["particles/blobs/box"]
        assert box.attrs["dimension"] == 2 and len(box.attrs["boundary"]) == 2
        assert f["particles/blobs/position/value"].shape[-1] == box.attrs["dimension"]


def test_connectivity_and_per_vertex_mass(trajectory):
    with h5py.File(trajectory) as f:
        n = f["particles/blobs/position/value"].shape[1]
        edges = f["connectivity/edges"][...]
        assert edges.dtype.kind == "i" and edges.shape == (n, 2) and edges.min() >= 0 and edges.max() < n
        assert f[f["connectivity/edges"].attrs["particles_group"]].name == "/particles/blobs"
        offsets = f["parameters/blob_offsets"][...]
        for o, e in zip(offsets[:-1], offsets[1:]):  # each ring closes on itself
            assert list(edges[o:e, 0]) == list(range(o, e)) and list(edges[o:e, 1]) == [*range(o + 1, e), o]
        mass = f["particles/blobs/mass"][...]
        assert mass.shape == (n,) and np.all(mass > 0)
        np.testing.assert_allclose(np.add.reduceat(mass, offsets[:-1]), f["parameters/mass"][...])


def test_format_1_files_are_still_read_but_not_resumed(tmp_path):
    from pathlib import Path
    old = Path(__file__).parent / "golden" / "format1.h5"  # the gish golden as blobsim 0.1 wrote it
    with h5py.File(old) as f:
        assert f.attrs["blobsim_format"] == 1
    for args in (("compare", old, old), ("replay", old, "-o", tmp_path / "g.rrd"),
                 ("render", old, "-o", tmp_path / "g.png")):
        assert cli(*args)[0] == 0, args
    scene = Path(__file__).parent.parent / "scenes" / "gish.toml"
    code, _, err = cli("run", scene, "--resume", old, "--steps", 300, "-q")
    assert code == 2 and "resuming needs format 6" in err, err


def test_h5dump_reads_the_file(trajectory):
    h5dump = shutil.which("h5dump")
    if h5dump is None:
        pytest.skip("h5dump is not installed (Debian: apt-get install hdf5-tools)")
    r = subprocess.run([h5dump, "-H", str(trajectory)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "/connectivity" not in r.stderr and 'GROUP "connectivity"' in r.stdout


def test_a_periodic_box_is_written_the_h5md_way(tmp_path):
    """H5MD 1.1, particles group box: `boundary` a string per dimension, "periodic" or "none"; a
    rectangular periodic box's `edges` a D-vector of its sides; `image` a time-dependent integer
    element beside `position`. h5dump reads the file."""
    (tmp_path / "p.toml").write_text("[scene]\ngravity = [0.0, 0.0]\nperiodic = [2.0, 2.0]\nsteps = 20\n"
                                     "[[blob]]\ncenter = [0.9, 0.0]\nradius = 0.2\nvelocity = [3.0, 0.0]\n"
                                     "[[blob]]\ncenter = [-0.4, 0.5]\nradius = 0.2\n")
    assert cli("run", tmp_path / "p.toml", "-o", tmp_path / "p.h5", "-q")[0] == 0
    with h5py.File(tmp_path / "p.h5") as f:
        box = f["particles/blobs/box"]
        assert [b.decode() for b in box.attrs["boundary"]] == ["periodic", "periodic"]
        edges = box["edges"]
        assert edges.shape == (2,) and edges.dtype.kind == "f" and fixed_ascii(edges, "unit") and edges.attrs["unit"] == b"m"
        image = f["particles/blobs/image"]
        assert image["value"].dtype.kind == "i" and image["value"].shape == f["particles/blobs/position/value"].shape
        assert np.array_equal(image["step"][...], f["particles/blobs/position/step"][...])
        assert image["value"][-1, 0, 0] == 1  # the first blob crossed x = 1 (0.9 + 3 m/s × 20/60 s)
    h5dump = shutil.which("h5dump")
    if h5dump is not None:
        r = subprocess.run([h5dump, "-H", str(tmp_path / "p.h5")], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0 and 'DATASET "edges"' in r.stdout
