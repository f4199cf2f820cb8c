"""The bench runs and reports every figure (no timing is asserted: targets are printed, not tested)."""

import json
import subprocess
import sys

import pytest


@pytest.mark.slow
def test_quick_bench_runs_and_reports_every_figure(tmp_path):
    out = tmp_path / "bench.json"
    r = subprocess.run([sys.executable, "-m", "blobcli", "bench", "--quick", "--json", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    report = json.loads(out.read_text())
    assert {(row["layout"], row["blobs"]) for row in report["rows"]} == {
        ("apart", 1), ("apart", 10), ("piled", 1), ("piled", 10)}
    assert all(row["vertices"] == 32 * row["blobs"] for row in report["rows"])
    assert all(row["ms_per_step"] > 0 and row["ns_per_vertex_substep"] > 0 for row in report["rows"])
    for key in ("core", "startup", "recording", "memory", "sweep", "threads", "c_reference"):
        assert key in report
    for ref in report["c_reference"]:  # the C loop does the same work: the same bits as the numba step
        assert ref is None or ref["same_bits"], ref
    assert report["startup"]["cold_s"] is None and report["startup"]["warm_s"] > 0  # cold: full bench only
    for line in ("core substep", "blobsim run, 1 blob, 1000 steps", "recording every step", "peak memory",
                 "one-blob points of 10 steps: blobsim sweep", "thread"):
        assert line in r.stdout
    assert ("core vs a plain C loop" in r.stdout) or ("C reference: skipped (no C compiler" in r.stdout)


def test_ab_step_refuses_a_tree_without_blobcli(tmp_path):
    done = subprocess.run([sys.executable, "-m", "blobcli.tools.ab_step", str(tmp_path)], capture_output=True,
                          text=True)
    assert done.returncode == 2
    assert f"{tmp_path / 'blobcli'}: not a blobcli package" in done.stderr
    assert "Traceback" not in done.stderr
