"""The recording as a user sees it: opened in rerun's own native viewer under Xvfb (software
rendering), screenshot with `rerun --screenshot-to`, and the picture checked: a blob resting on
a floor is drawn above the floor line, in its colour. Skipped, saying why, only where Xvfb or
the viewer cannot run (.ci/run installs Xvfb and Mesa from Debian's packages when it can)."""

import os
import shutil
import subprocess
import time

import numpy as np
import pytest
from conftest import cli

from blobcli.io.recording import blob_colors

SCENE = """[scene]
steps = 90
[[blob]]
center = [0.0, 1.5]
radius = 0.5
[[static]]
kind = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
"""


@pytest.fixture(scope="module")
def display():
    xvfb, viewer = shutil.which("Xvfb"), shutil.which("rerun")
    if xvfb is None or viewer is None:
        pytest.skip(f"cannot open the viewer here: {'Xvfb (Debian: apt-get install xvfb)' if xvfb is None else ''}"
                    f"{' and ' if xvfb is None and viewer is None else ''}"
                    f"{'the rerun viewer (pip install rerun-sdk)' if viewer is None else ''} not found")
    number = 90 + os.getpid() % 9
    proc = subprocess.Popen([xvfb, f":{number}", "-screen", "0", "1400x900x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    if proc.poll() is not None:
        pytest.skip("Xvfb did not start")
    yield f":{number}", viewer
    proc.kill()
    proc.wait()


def screenshot(tmp_path, display, rrd):
    number, viewer = display
    png = tmp_path / "shot.png"
    env = {**os.environ, "DISPLAY": number, "XDG_RUNTIME_DIR": str(tmp_path)}
    r = subprocess.run([viewer, "--screenshot-to", str(png), "--window-size", "1200x700", str(rrd)], env=env,
                       capture_output=True, text=True, timeout=180)
    if r.returncode != 0 or not png.exists():
        pytest.skip(f"the viewer could not render here (exit {r.returncode}): {r.stderr.strip()[-300:]}")
    import matplotlib.image
    return (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int)


@pytest.mark.slow
def test_a_resting_blob_is_drawn_above_its_floor_in_its_colour(tmp_path, display):
    (tmp_path / "s.toml").write_text(SCENE)
    assert cli("run", tmp_path / "s.toml", "-o", tmp_path / "s.h5", "--rerun", tmp_path / "s.rrd", "-q")[0] == 0
    image = screenshot(tmp_path, display, tmp_path / "s.rrd")
    h, w, _ = image.shape
    view = image[int(0.08 * h):int(0.72 * h), int(0.18 * w):int(0.5 * w)]  # the 2D view, left of the plots
    blob = np.argwhere(np.abs(view - blob_colors(1)[0, :3]).max(axis=-1) <= 40)
    floor = np.argwhere(np.abs(view - 90).max(axis=-1) <= 12)
    assert len(blob) > 50, "the blob's colour is not in the 2D view"
    assert len(floor) > 50, "the floor line is not in the 2D view"
    floor_row = np.median(floor[:, 0])
    assert np.median(blob[:, 0]) < floor_row, "the blob is drawn below its floor: the view is upside down"
    assert blob[:, 0].max() <= floor_row + 3
