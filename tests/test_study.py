"""blobsim study: the ladder runs, errors shrink with refinement, the chart and CSV are written."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest

from blobcli import load_scene
from blobcli.tools.study import LADDER, Point, cheapest, run_study

ROOT = Path(__file__).resolve().parent.parent


def test_study_measures_every_setting_and_errors_shrink_with_refinement(tmp_path):
    points = run_study(load_scene(ROOT / "scenes" / "gish.toml"), ("kot", "gas"), tmp_path, duration=1.0)  # lands at ~0.5 s
    assert len(points) == 2 * len(LADDER)
    kot = {(p.divisor, p.substeps, p.iterations): p for p in points if p.method == "kot"}
    # (from 4 substeps on, the error of this rolling, bouncing blob levels off at ~0.06-0.09 radii)
    assert max(kot[(1, 16, 2)].trajectory_error, kot[(1, 4, 2)].trajectory_error) < kot[(1, 1, 1)].trajectory_error / 3
    assert kot[(1, 16, 2)].area_error < kot[(1, 1, 1)].area_error
    # the same substep length h = dt / substeps gives the same run
    assert kot[(2, 4, 2)].trajectory_error == kot[(1, 8, 2)].trajectory_error
    assert all(p.wall_time > 0 for p in points)


def test_cheapest_setting_meeting_a_tolerance():
    def p(wall, err):
        return Point("kot", 0.01, 1, 1, wall, err, 0.0, 0.0, "complete")
    pts = [p(1.0, 0.5), p(2.0, 0.05), p(3.0, 0.01), p(0.5, 0.9)]
    assert cheapest(pts, 0.06)["kot"].wall_time == 2.0
    assert cheapest(pts, 0.001)["kot"] is None


@pytest.mark.slow
def test_study_command_writes_chart_and_csv(tmp_path):
    r = subprocess.run([sys.executable, "-m", "blobcli", "study", str(ROOT / "scenes" / "gish.toml"), "--methods", "kot",
                        "springs", "--duration", "0.3", "--tol", "0.5", "-o", str(tmp_path), "--workers", "0"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "cheapest setting with trajectory error <= 0.5:" in r.stdout
    assert (tmp_path / "gish_study.png").stat().st_size > 10_000
    rows = list(csv.DictReader(open(tmp_path / "gish_study.csv")))
    assert len(rows) == 2 * len(LADDER) and {r["method"] for r in rows} == {"kot", "springs"}
