"""`blobsim export`: a trajectory in the formats scientists already open trajectories with.

- xdmf: an XDMF time series with its HDF5 heavy data, written by meshio's time-series writer
  (ParaView, VisIt). The mesh is frame 0: the vertices (z = 0) and each ring's edges as line
  cells (closed polylines). meshio's writer keeps one mesh for all steps, so the motion is the
  point data `displacement` (position − frame-0 position, m; ParaView: *Warp By Vector*; in a
  periodic box from the unwrapped positions, so a blob crossing an edge does not jump), next
  to `position`; per-blob `area_error` and `kinetic_energy` (J) are cell data on every edge of
  the blob.
- xyz: extended XYZ, one frame per block, z = 0 (OVITO, ASE, MDAnalysis): species `X`, the
  blob index as a per-atom property, and the step and time (s) in each comment line; a periodic
  box as `Lattice` and `pbc="T T F"`.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from .h5md import AREA, EDGES, IMAGE, KINETIC, PARAMETERS, POSITION, open_trajectory, reading

FORMATS = ("xdmf", "xyz")
BLOCK_FRAMES = 256  # frames read at a time


def sidecars(out, fmt: str) -> list[Path]:
    """Every file an export to `out` writes (XDMF keeps its heavy data in <out stem>.h5)."""
    out = Path(out)
    return [out, out.with_suffix(".h5")] if fmt == "xdmf" else [out]


def export(h5_path, out, fmt: str) -> int:
    """Write `out` (and its sidecars) in `fmt`; returns the number of frames. Everything is
    written in a hidden directory beside `out` and moved into place when whole (outputs.replaced_together)."""
    from .outputs import replaced_together
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with replaced_together(sidecars(out, fmt)) as work:
        return _export(h5_path, work / out.name, fmt)


def _export(h5_path, out: Path, fmt: str) -> int:
    with open_trajectory(h5_path) as f, reading(h5_path):
        pos, p = f[POSITION], f[PARAMETERS]
        offsets = p["blob_offsets"][...]
        blob_of = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
        steps, times = pos["step"][...], pos["time"][...]
        target = p["target_area"][...]
        box = None  # a periodic box (format 8): its box vectors (rows), frame by frame, (frames, 2, 2)
        if IMAGE in f:
            edges = f[EDGES]
            box = edges["value"][...] if isinstance(edges, h5py.Group) else np.tile(edges[...], (len(steps), 1))
            if box.ndim == 2:  # sides: a rectangular box
                box = np.stack([np.diag(sides) for sides in box])
        blocks = _blocks(pos["value"], f[IMAGE]["value"] if box is not None else None, box, f[AREA]["value"],
                         f[KINETIC]["value"], target)
        if fmt == "xdmf":
            _xdmf(Path(out), offsets, blob_of, steps, times, blocks)
        else:
            _xyz(Path(out), blob_of, steps, times, blocks, box)
        return len(steps)


def _blocks(position, image, box, area, kinetic, target):
    """(positions (k, N, 2), unwrapped positions (k, N, 2), area error (k, B), kinetic energy (k, B)) a block
    of frames at a time. Unwrapped: in a periodic box, position + image × edges (continuous); else position."""
    for start in range(0, position.shape[0], BLOCK_FRAMES):
        stop = start + BLOCK_FRAMES
        pos = position[start:stop]
        unwrapped = pos if image is None else pos + np.einsum("fni,fij->fnj", image[start:stop], box[start:stop])
        yield pos, unwrapped, (area[start:stop] - target) / target, kinetic[start:stop]


def _xdmf(out: Path, offsets, blob_of, steps, times, blocks):
    import meshio

    from ..geometry import ring_next
    n = len(blob_of)
    edges = np.stack([np.arange(n), ring_next(offsets)], axis=1)
    # meshio puts the heavy data, <stem>.h5, in the current directory (not beside the .xdmf,
    # which names it without a directory): write from the output's own directory.
    import os
    home = os.getcwd()
    os.chdir(out.parent)
    try:
        _xdmf_steps(meshio, out.name, n, edges, blob_of, times, blocks)
    finally:
        os.chdir(home)


def _xdmf_steps(meshio, name, n, edges, blob_of, times, blocks):
    first = None
    with meshio.xdmf.TimeSeriesWriter(name) as writer:
        k = 0
        for pos, unwrapped, area_error, kinetic in blocks:
            for frame in range(len(pos)):
                xyz = np.column_stack([pos[frame], np.zeros(n)])
                moved = np.column_stack([unwrapped[frame], np.zeros(n)])
                if first is None:
                    first = moved
                    writer.write_points_cells(xyz, [("line", edges)])
                writer.write_data(float(times[k]), point_data={"position": xyz, "displacement": moved - first},
                                  cell_data={"area_error": [area_error[frame][blob_of]],
                                             "kinetic_energy": [kinetic[frame][blob_of]]})
                k += 1


def _xyz(out: Path, blob_of, steps, times, blocks, box):
    n = len(blob_of)
    k = 0
    # a periodic box as extended XYZ has it: the lattice vectors, periodic in x and y (our box is centred on the
    # origin, [-L/2, L/2), where the lattice's cell starts at 0: the same periodic world)
    with open(out, "w") as f:
        for pos, _, _, _ in blocks:
            for frame in range(len(pos)):
                cell = 'pbc="F F F"'
                if box is not None:  # the lattice's rows: e_1, e_2 (z: 1, not periodic)
                    e = box[k].tolist()
                    cell = f'Lattice="{e[0][0]!r} {e[0][1]!r} 0.0 {e[1][0]!r} {e[1][1]!r} 0.0 0.0 0.0 1.0" pbc="T T F"'
                f.write(f"{n}\nProperties=species:S:1:pos:R:3:blob:I:1 step={int(steps[k])} time={float(times[k])!r} "
                        f"{cell}\n")
                lines = [f"X {x!r} {y!r} 0.0 {b}" for (x, y), b in zip(pos[frame].tolist(), blob_of.tolist())]
                f.write("\n".join(lines) + "\n")
                k += 1
