"""Two fuzzers: scenes (valid-extreme and invalid) and trajectory files (truncated, byte-flipped,
crafted). Short in CI (the file fuzzer in the slow tier); run long by hand with, e.g.

    BLOBSIM_FUZZ_EXAMPLES=2000 pytest -m 'slow or not slow' tests/test_fuzz.py

The contract they check: exit 0, 1 or 2 only; never a traceback or an internal error; nothing
written for a refused scene; nothing written through a symlink, and no device or FIFO replaced,
among the output places they try (a new file, a symlink, a FIFO, a device node, a directory,
/proc). A third sends SIGINT or SIGTERM in the first 0.2 s of a run."""

import math
import os
import shutil
import signal
import stat
import string
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import ONE, cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blobcli.scene.schema import TABLES

EXAMPLES = int(os.environ.get("BLOBSIM_FUZZ_EXAMPLES", "40"))
# Derandomized unless run long by hand, so that CI's examples (and its time) are the same every run.
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize="BLOBSIM_FUZZ_EXAMPLES" not in os.environ,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
RUN_VERTICES, RUN_WORK = 2_000, 64  # valid scenes this small are also run (a few steps)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return '"' + "".join(c if c.isalnum() or c in " ._-/" else f"\\u{ord(c):04x}" for c in v) + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-320, 1e-9, 1e-6, 0.5, 1.0, 1e6, 1e300, 1e307, -1.0]),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([0, 1, 2, 3, 2**31, 2**63 - 1, 2**63, 10**12, -1]),
)
texts = st.text(alphabet=string.ascii_letters + "\x00\n\t\x7f/é. ", max_size=40) | st.just("x" * 300)
values = st.one_of(numbers, texts, st.booleans(), st.lists(numbers, max_size=4),
                   st.lists(st.lists(numbers, min_size=2, max_size=2), max_size=8), st.just({"a": 1}))


def table(cls, extra=()):
    keys = [f.name for f in cls.__dataclass_fields__.values()] + list(extra)
    return st.dictionaries(st.sampled_from(keys), values, max_size=6)


# Mostly sane values for the keys a runnable scene needs, and anything at all for the rest.
blob = st.fixed_dictionaries({"center": st.lists(st.floats(-5, 5), min_size=2, max_size=2),
                              "radius": st.floats(1e-7, 2.0), "vertices": st.integers(2, 40)}) | table(TABLES["blob"])
static = st.fixed_dictionaries({"kind": st.sampled_from(["plane", "segment", "box", "circle", "polygon", "cone"]),
                                "point": st.just([0.0, 0.0]), "normal": st.just([0.0, 1.0])}) | table(TABLES["static"])
schedule = st.fixed_dictionaries({"key": st.sampled_from(["blob.blob0.mass", "blob.blob0.scale", "blob.blob*.friction",
                                                          "scene.gravity", "blob.nobody.mass", "blob.blob0.colour",
                                                          "scene.dt"]),
                                  "at": st.lists(st.lists(numbers, min_size=2, max_size=3), min_size=1, max_size=4)}) \
    | table(TABLES["schedule"])
scenes = st.fixed_dictionaries({}, optional={
    "scene": table(TABLES["scene"], ["durtion"]) | st.fixed_dictionaries({"steps": st.integers(-2, 30),
                                                                          "substeps": st.integers(0, 8)}),
    "output": table(TABLES["output"]),
    "blob": st.lists(blob, max_size=3) | values,
    "static": st.lists(static, max_size=2),
    "schedule": st.lists(schedule, max_size=2),
    "bogus": values,
})


def scene_text(doc: dict) -> str:
    lines = []
    for name in ("scene", "output"):
        if name in doc:
            lines.append(f"[{name}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in doc[name].items()]
    for name in ("blob", "static", "schedule"):
        items = doc.get(name, [])
        if not isinstance(items, list) or not all(isinstance(x, dict) for x in items):
            lines.insert(0, f"{name} = {toml_value(items)}")
            continue
        for item in items:
            lines.append(f"[[{name}]]")
            lines += [f"{k} = {toml_value(v)}" for k, v in item.items()]
    if "bogus" in doc:
        lines.insert(0, f"bogus = {toml_value(doc['bogus'])}")
    return "\n".join(lines) + "\n"


@FUZZ
@given(doc=scenes)
def test_scene_fuzzer_exit_0_1_2_never_a_traceback(tmp_path_factory, doc):
    d = tmp_path_factory.mktemp("fuzz")
    path = d / "s.toml"
    path.write_text(scene_text(doc))
    code, out, err = cli("check", path)
    assert code in (0, 2) and "Traceback" not in err and "internal error" not in err, err
    if code == 2:
        assert cli("run", path, "-o", d / "o.h5", "-q")[0] == 2
        assert not list(d.glob("o.h5*"))  # nothing written when refused
        return
    from blobcli import load_scene
    scene = load_scene(path)
    s = scene.settings
    if scene.vertex_count <= RUN_VERTICES and s.substeps * s.iterations <= RUN_WORK:
        code, out, err = cli("run", path, "-o", d / "o.h5", "--steps", "3", "-q")
        assert code in (0, 1) and "internal error" not in err, err
        assert (d / "o.h5").exists() and not (d / "o.h5.partial").exists()


@st.composite
def damaged_files(draw):
    kind = draw(st.sampled_from(["truncate", "flip", "delete", "reshape", "attr"]))
    return kind, draw(st.integers(0, 2**31)), draw(st.integers(1, 64))


GOOD = {}


def good_trajectory(d):
    if "path" not in GOOD or not GOOD["path"].exists():
        scene = d / "s.toml"
        scene.write_text(ONE)
        assert cli("run", scene, "-o", d / "good.h5", "-q")[0] == 0
        GOOD.update(path=d / "good.h5", scene=scene)
    return GOOD["path"], GOOD["scene"]


NAMES = ["particles/blobs/position/value", "particles/blobs/position/step", "particles/blobs/position/time",
         "observables/area/value", "observables/kinetic_energy/value", "parameters/blob_offsets",
         "parameters/blob_names", "parameters/target_area", "parameters/mass", "parameters/scene",
         "restart/position", "restart/velocity", "restart/impact", "restart/pair_key", "restart/pair_impact"]


@pytest.mark.slow  # 40 damaged files, nine commands each: 16 s of the fast tier
@FUZZ
@given(damage=damaged_files())
def test_file_fuzzer_every_reader_exits_0_1_2_never_a_traceback(tmp_path_factory, damage):
    good, scene = good_trajectory(tmp_path_factory.getbasetemp())
    d = tmp_path_factory.mktemp("files")
    bad = d / "bad.h5"
    data = bytearray(good.read_bytes())
    kind, seed, count = damage
    rng = np.random.default_rng(seed)
    if kind == "truncate":
        bad.write_bytes(bytes(data[: int(rng.integers(0, len(data)))]))
    elif kind == "flip":
        for i in rng.integers(0, len(data), count):
            data[i] ^= int(rng.integers(1, 256))
        bad.write_bytes(bytes(data))
    else:
        bad.write_bytes(bytes(data))
        with h5py.File(bad, "r+") as f:
            name = NAMES[seed % len(NAMES)]
            if kind == "delete":
                del f[name]
            elif kind == "reshape":
                del f[name]
                f[name] = rng.normal(size=(count,) * int(rng.integers(0, 3)))
            else:
                key = ["complete", "blobsim_format"][seed % 2]
                del f.attrs[key]
                if seed % 3 == 0:
                    f.attrs[key] = "nonsense"
    place = output_place(d, ["new", "symlink", "fifo", "device", "directory", "proc"][seed % 6])
    for args in (("compare", bad, good, "--allow-incomplete"), ("compare", good, bad),
                 ("replay", bad, "-o", d / "r.rrd"), ("render", bad, "-o", d / "r.png"),
                 ("run", scene, "--resume", bad, "--steps", "60", "-o", d / "resumed.h5", "-q"),
                 ("view", bad), ("replay", good, "-o", place), ("render", good, "-o", place),
                 ("export", good, "--format", "xyz", "-o", place)):
        code, out, err = cli(*args)
        assert code in (0, 1, 2) and "Traceback" not in err and "internal error" not in err, (args, err)
    untouched(d)


PRECIOUS = "precious: no command was asked to write this"


def output_place(d, kind: str):
    """An output path of the given kind: a new file, a symlink to a precious file, a FIFO, a device
    node (as root; else a FIFO), a directory, or a place under /proc."""
    (d / "precious.txt").write_text(PRECIOUS)
    place = d / "place.png"  # .png: render keeps the name as given
    if kind == "symlink":
        place.symlink_to(d / "precious.txt")
    elif kind == "fifo" or (kind == "device" and os.geteuid() != 0):
        os.mkfifo(place)
    elif kind == "device":
        os.mknod(place, stat.S_IFCHR | 0o600, os.makedev(1, 3))
    elif kind == "directory":
        place.mkdir()
    elif kind == "proc":
        place = Path("/proc/blobsim-fuzz.png")
    return place


def untouched(d):
    """No command wrote through a link or replaced a special file."""
    assert (d / "precious.txt").read_text() == PRECIOUS
    place = d / "place.png"
    if place.exists() or place.is_symlink():
        mode = os.lstat(place).st_mode
        assert stat.S_ISREG(mode) or stat.S_ISDIR(mode) or stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)


@settings(max_examples=8, deadline=None, derandomize=True)
@given(delay=st.floats(0.1, 0.2), signum=st.sampled_from([signal.SIGINT, signal.SIGTERM]))
def test_a_signal_in_the_first_fifth_of_a_second_exits_0_or_130_never_a_traceback(tmp_path_factory, delay, signum):
    """The installed command, signalled while it starts (imports, scene, compile or load of the step).
    Before about 0.03 s (longer on a loaded machine) Python itself has not yet run any of blobsim's code
    (docs/cli.md), so the fuzzer starts at 0.1 s."""
    d = tmp_path_factory.mktemp("early")
    (d / "s.toml").write_text(ONE)
    script = shutil.which("blobsim", path=str(Path(sys.executable).parent))
    proc = subprocess.Popen([script, "run", d / "s.toml", "-o", d / "o.h5", "-q"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode in (0, 130) and "Traceback" not in err, (delay, signum, proc.returncode, err)
    assert not (d / "o.h5.partial").exists() and not (d / "o.h5.lock").exists()


# Worlds that move: periodic and sheared boxes, random starts, kinematic and loaded walls, schedules of the
# blobs' and the box's values, drives; sane shapes, extreme values. Every scene `check` accepts runs a few steps.
extreme = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, 5e-324, 1e-300, 1e-6, 1e6, 1e20, 1e300, -1e300]))
positive = st.one_of(st.floats(1e-3, 1e3), st.sampled_from([5e-324, 1e-300, 1e-9, 1e6, 1e20, 1e300]))
pair = st.lists(extreme, min_size=2, max_size=2)
moving_wall = st.one_of(
    st.fixed_dictionaries({"kind": st.just("box"), "center": st.just([0.0, -0.6]), "size": st.just([2.0, 0.2]),
                           "velocity": pair}, optional={"angular_velocity": extreme, "pivot": pair}),
    st.fixed_dictionaries({"kind": st.just("box"), "center": st.just([0.0, 1.2]), "size": st.just([2.0, 0.2]),
                           "load": positive, "mass": positive}, optional={"load_direction": pair}),
    st.fixed_dictionaries({"kind": st.just("segment"), "a": st.just([-1.0, -0.5]), "b": st.just([1.0, -0.5]),
                           "path": st.lists(st.tuples(st.floats(0.0, 1.0), extreme, extreme, extreme).map(list),
                                            min_size=1, max_size=3).map(sorted)}),
)
world_schedule = st.one_of(
    st.fixed_dictionaries({"key": st.sampled_from(["blob.b*.mass", "blob.b*.scale", "blob.b*.torque"]),
                           "at": st.lists(st.tuples(st.floats(0.0, 1.0), extreme).map(list), min_size=1,
                                          max_size=3).map(sorted)}),
    st.fixed_dictionaries({"key": st.just("blob.b*.force"),
                           "at": st.lists(st.tuples(st.floats(0.0, 1.0), extreme, extreme).map(list), min_size=1,
                                          max_size=3).map(sorted)}),
    st.fixed_dictionaries({"key": st.just("scene.shear"),
                           "at": st.lists(st.tuples(st.floats(0.0, 1.0), extreme).map(list), min_size=1,
                                          max_size=3).map(sorted)}),
    st.fixed_dictionaries({"key": st.just("scene.periodic"),
                           "at": st.lists(st.tuples(st.floats(0.0, 1.0), positive, positive).map(list), min_size=1,
                                          max_size=3).map(sorted)}),
)
worlds = st.fixed_dictionaries({
    "scene": st.fixed_dictionaries({"steps": st.integers(1, 20)},
                                   optional={"periodic": st.lists(positive, min_size=2, max_size=2),
                                             "gravity": pair, "seed": st.integers(0, 3)}),
    "blob": st.lists(st.fixed_dictionaries({"name": st.just("b"), "radius": st.floats(0.05, 0.4),
                                            "vertices": st.integers(3, 24)},
                                           optional={"count": st.integers(1, 12), "mass": positive,
                                                     "velocity": pair, "force": pair, "torque": extreme}),
                     min_size=1, max_size=1),
    "static": st.lists(moving_wall, max_size=2),
    "schedule": st.lists(world_schedule, max_size=2),
})


@pytest.mark.slow
@FUZZ
@given(doc=worlds)
def test_moving_worlds_fuzzer_exit_0_1_2_and_a_readable_file(tmp_path_factory, doc):
    """What `check` accepts runs: exit 0 (complete, every position finite) or 1 (stopped: a readable file that
    says it is not complete), never a crash, a traceback or an internal error; what it refuses writes nothing."""
    d = tmp_path_factory.mktemp("worlds")
    path = d / "s.toml"
    text = scene_text(doc)
    if "count" not in doc["blob"][0]:  # one blob at the origin, or `count` copies placed at random
        text = text.replace('name = "b"', 'name = "b"\ncenter = [0.0, 0.0]')
    elif "periodic" not in doc["scene"]:
        text = text.replace('name = "b"', 'name = "b"\nregion = [-3.0, -0.3, 3.0, 6.0]')
    path.write_text(text)
    out = d / "o.h5"
    code, _, err = cli("run", path, "-o", out, "-q")
    assert code in (0, 1, 2) and "Traceback" not in err and "internal error" not in err, (code, err, text)
    if code == 2:
        assert not list(d.glob("o.h5*")), text
        return
    with h5py.File(out) as f:
        assert bool(f.attrs["complete"]) == (code == 0), (code, err, text)
        if code == 0:
            assert np.isfinite(f["particles/blobs/position/value"][-1]).all(), text
