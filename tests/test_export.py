"""blobsim export: XDMF (read back with meshio's own reader, as ParaView's loader would see it)
and extended XYZ (parsed here; OVITO, ASE and MDAnalysis read the same layout)."""

import h5py
import numpy as np
from conftest import ONE, cli


def run(tmp_path):
    (tmp_path / "s.toml").write_text(ONE.replace('name = "solo"', 'name = "solo"\ngrid = [2, 1]\nspacing = [1.5, 0.0]'))
    assert cli("run", tmp_path / "s.toml", "-o", tmp_path / "t.h5", "-q")[0] == 0
    with h5py.File(tmp_path / "t.h5") as f:
        return f["particles/blobs/position/value"][...], f["observables/area/value"][...], \
            f["parameters/target_area"][...]


def test_xdmf_time_series_holds_every_frame(tmp_path):
    import meshio
    pos, area, target = run(tmp_path)
    (tmp_path / "x").mkdir()
    code, out, err = cli("export", tmp_path / "t.h5", "--format", "xdmf", "-o", tmp_path / "x" / "t.xdmf")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == ["t.h5", "t.xdmf"]  # nothing left behind
    reader = meshio.xdmf.TimeSeriesReader(str(tmp_path / "x" / "t.xdmf"))
    points, cells = reader.read_points_cells()
    assert reader.num_steps == len(pos) and cells[0].type == "line" and cells[0].data.shape == (64, 2)
    assert list(cells[0].data[31]) == [31, 0]  # the first ring closes on itself
    t, point_data, cell_data = reader.read_data(len(pos) - 1)
    np.testing.assert_array_equal(point_data["position"][:, :2], pos[-1])
    np.testing.assert_allclose(points[:, :2] + point_data["displacement"][:, :2], pos[-1], atol=1e-12)
    np.testing.assert_allclose(cell_data["area_error"][0][[0, 40]], (area[-1] - target) / target)


def test_extended_xyz_frames(tmp_path):
    pos, _, _ = run(tmp_path)
    assert cli("export", tmp_path / "t.h5", "--format", "xyz", "-o", tmp_path / "t.xyz")[0] == 0
    lines = (tmp_path / "t.xyz").read_text().splitlines()
    assert len(lines) == len(pos) * 66 and lines[0] == "64"
    assert lines[1].startswith("Properties=species:S:1:pos:R:3:blob:I:1 step=0 time=0.0")
    last = np.array([[float(v) for v in line.split()[1:4]] for line in lines[-64:]])
    np.testing.assert_array_equal(last[:, :2], pos[-1])
    assert np.all(last[:, 2] == 0.0) and lines[-1].split()[-1] == "1"


def test_export_never_overwrites_its_input(tmp_path):
    run(tmp_path)
    code, _, err = cli("export", tmp_path / "t.h5", "--format", "xdmf", "-o", tmp_path / "t.xdmf")
    assert code == 2 and "the trajectory exported; choose another -o" in err
    assert h5py.File(tmp_path / "t.h5").attrs["complete"]
