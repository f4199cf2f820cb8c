"""The bench runs and reports every figure (no timing is asserted: targets are printed, not tested)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import blobcli

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
# a figure as the page writes it: 0.973, 1,000, 26.2; not the digits of e0674ec, x86_64 or 10k
NUMBER = re.compile(r"(?<![\w./])(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?(?![\w/])")
DATA_LINK = re.compile(r"\]\((\.\./benchmarks/[^)]+\.json)\)")


def _without_numba(tmp_path) -> dict:
    """An environment where `import numba` fails, in this process's children and theirs (blobsim needs no
    numba): a module of that name first on PYTHONPATH raises ImportError."""
    stub = tmp_path / "no-numba"
    stub.mkdir()
    (stub / "numba.py").write_text('raise ImportError("no numba here (test)")\n')
    path = os.pathsep.join(p for p in (str(stub), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}


def _ab_step(other: Path, env: dict, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "blobcli.tools.ab_step", str(other), *args], capture_output=True,
                          text=True, env=env, timeout=600)


@pytest.mark.slow
def test_quick_bench_runs_and_reports_every_figure(tmp_path):
    out = tmp_path / "bench.json"
    r = subprocess.run([sys.executable, "-m", "blobcli", "bench", "--quick", "--json", str(out)],
                       capture_output=True, text=True, timeout=600, env=_without_numba(tmp_path))
    assert r.returncode == 0, r.stderr
    report = json.loads(out.read_text())
    assert {(row["layout"], row["blobs"]) for row in report["rows"]} == {
        ("apart", 1), ("apart", 10), ("piled", 1), ("piled", 10)}
    assert all(row["vertices"] == 32 * row["blobs"] for row in report["rows"])
    assert all(row["ms_per_step"] > 0 and row["ns_per_vertex_substep"] > 0 for row in report["rows"])
    for key in ("core", "startup", "recording", "memory", "sweep", "threads"):
        assert key in report
    assert report["startup"]["run_s"] > 0
    threads = report["threads"]
    assert set(threads["ns_by_threads"]) == {str(n) for n in {1, threads["threads"]}}  # (JSON's keys are text)
    assert all(ns > 0 for ns in threads["ns_by_threads"].values()) and threads["speedup"] > 0
    for line in ("core substep", "blobsim run, 1 blob, 1000 steps, a new process", "recording every step",
                 "peak memory", "one-blob points of 10 steps: blobsim sweep", "ns on 1 thread"):
        assert line in r.stdout
    for gone in ("numba", "cache", "compil", "plain C loop"):  # what the bench measures is the compiled core
        assert gone not in r.stdout.lower()


def test_ab_step_refuses_a_tree_without_blobcli(tmp_path):
    done = subprocess.run([sys.executable, "-m", "blobcli.tools.ab_step", str(tmp_path)], capture_output=True,
                          text=True)
    assert done.returncode == 2
    assert f"{tmp_path / 'blobcli'}: not a blobcli package" in done.stderr
    assert "Traceback" not in done.stderr


def _package(root: Path, files: dict) -> Path:
    """A source tree `root` holding blobcli/ with these files (path: text) and the step's module."""
    for name, text in {"__init__.py": "", "sim/__init__.py": "", "sim/pipeline.py": "", **files}.items():
        path = root / "blobcli" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_ab_step_says_a_numba_tree_needs_numba(tmp_path):
    other = _package(tmp_path / "old", {"jit.py": "import numba\n"})
    done = _ab_step(other, _without_numba(tmp_path))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [f"ab_step: {other / 'blobcli'} steps with numba, which is not installed "
                                        "here: pip install numba"]


def test_ab_step_says_when_the_other_core_does_not_build(tmp_path):
    """A tree with a compiled core but none built: ab_step builds it in its copy, and says in one line why
    that failed (here: a build that finds no compiler)."""
    why = "blobsim: building the compiled core needs a C compiler ('cc' not found)"
    other = _package(tmp_path / "c", {"core/__init__.py": "", "core/build.py": f"import sys\nsys.exit({why!r})\n"})
    done = _ab_step(other, _without_numba(tmp_path))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.splitlines()[-1] == (f"ab_step: {other / 'blobcli' / 'core'}: its compiled core did not build "
                                            f"(python -m blobcli.core.build: {why})")


@pytest.mark.slow
def test_ab_step_builds_the_other_trees_core_in_its_copy(tmp_path):
    """This tree's sources, the library not built: ab_step builds it in its copy (the tree is left as it
    is), steps both, and they give the same bits; no numba anywhere."""
    other = tmp_path / "other"
    shutil.copytree(Path(blobcli.__file__).parent, other / "blobcli",
                    ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.so.new", "*.pyd"))
    done = _ab_step(other, _without_numba(tmp_path), "--blobs", "4", "--layout", "apart", "--settle", "2",
                    "--steps", "3", "--rounds", "2")
    assert done.returncode == 0, done.stderr
    assert "building the other tree's compiled core in a copy" in done.stderr
    assert "same bits after 3 steps: True" in done.stdout
    assert "this / other:" in done.stdout
    assert not list((other / "blobcli" / "core").glob("_blobcore*"))


def _tables(lines: list[str]):
    """Each markdown table of a page: (its first line's number, its rows but the |---| one, the line
    after it that starts with "Data:", or None)."""
    i = 0
    while i < len(lines):
        if not lines[i].startswith("|"):
            i += 1
            continue
        j = i
        while j < len(lines) and lines[j].startswith("|"):
            j += 1
        rows = [row for row in lines[i:j] if not set(row) <= set("|-: ")]
        data = next((row for row in lines[j:j + 3] if row.startswith("Data:")), None)
        yield i + 1, rows, data
        i = j


def _numbers(value) -> set[float]:
    """Every number a JSON value holds (not its keys, not booleans, not digits inside strings)."""
    if isinstance(value, bool):
        return set()
    if isinstance(value, (int, float)):
        return {float(value)}
    if isinstance(value, dict):
        value = list(value.values())
    if isinstance(value, list):
        return set().union(*(_numbers(v) for v in value))
    return set()


def test_the_performance_page_s_tables_are_their_data_files():
    """docs/performance.md cannot drift from its data: every table names its data file on a "Data:" line
    just below it, and every number in the table (header and rows) is a number in that file."""
    page = ROOT / "docs" / "performance.md"
    lines = page.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, "docs/performance.md is a page, not a log: at most 200 lines"
    tables = list(_tables(lines))
    assert tables
    for line, rows, data in tables:
        assert data, f"docs/performance.md:{line}: a table without a 'Data:' line naming its benchmarks/ file"
        link = DATA_LINK.search(data)
        assert link, f"docs/performance.md:{line}: its Data line links no ../benchmarks/....json: {data}"
        path = (page.parent / link.group(1)).resolve()
        known = _numbers(json.loads(path.read_text(encoding="utf-8")))
        for row in rows:
            for figure in NUMBER.findall(row):
                assert float(figure.replace(",", "")) in known, (
                    f"docs/performance.md:{line}: {figure} is not in {path.relative_to(ROOT)} (row: {row})")


def test_every_benchmark_data_file_says_where_when_and_how():
    """benchmarks/<machine>/<date>[-<what>].json: the machine its folder, the date its name's start, and the
    command that measured it; a `blobsim bench --json` result keeps bench's own keys for its rows."""
    assert (BENCHMARKS / "README.md").is_file()
    files = sorted(BENCHMARKS.glob("*/*.json"))
    assert files
    for path in files:
        name = path.relative_to(ROOT)
        data = json.loads(path.read_text(encoding="utf-8"))
        assert re.fullmatch(r"\d{4}-\d{2}-\d{2}(-[\w.-]+)?", path.stem), f"{name}: not <date>[-<what>].json"
        assert data.get("host") == path.parent.name, f"{name}: host should be {path.parent.name!r}"
        assert data.get("date") == path.stem[:10], f"{name}: date should be {path.stem[:10]!r}"
        assert isinstance(data.get("command"), str) and data["command"], f"{name}: no command"
        for row in data.get("rows", []) if "peer" in data else []:
            assert {"blobs", "layout", "vertices", "ms_per_step", "ns_per_vertex_substep"} <= set(row), name


def test_ab_step_times_a_periodic_scene_compressed_as_jam_compresses_it(tmp_path):
    """`--scene FILE --phi PHI`: a scene of one's own, its packing compressed to PHI first (this tree against a
    copy of itself: the same bits); `--phi` without a periodic scene is refused in one line."""
    other = tmp_path / "other"
    shutil.copytree(Path(blobcli.__file__).parent, other / "blobcli", ignore=shutil.ignore_patterns("__pycache__"))
    scene = tmp_path / "packing.toml"
    scene.write_text('[scene]\ngravity = [0.0, 0.0]\nperiodic = [1.9286, 1.9286]\ndrag = 1.0\n[[blob]]\nradius = 0.14\n'
                     'vertices = 32\ncount = 16\n[[blob]]\nradius = 0.1\nvertices = 32\ncount = 16\n')
    done = _ab_step(other, os.environ, "--scene", str(scene), "--phi", "0.6", "--settle", "2", "--steps", "3",
                    "--rounds", "1")
    assert done.returncode == 0, done.stderr
    assert f"{scene} compressed to φ = 0.6, settled 2 steps" in done.stdout
    assert "same bits after 3 steps: True" in done.stdout
    refused = _ab_step(other, os.environ, "--phi", "0.6")
    assert refused.returncode == 2 and refused.stderr.splitlines() == [
        "ab_step: --phi compresses a periodic scene's packing: give one with --scene"]
