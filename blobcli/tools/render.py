"""`blobsim render`: a filmstrip picture of a run (frames side by side, blobs filled).

matplotlib (Agg backend, no display needed) is imported here only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..colliders import COLLIDERS, default_pivot
from ..io.h5md import TrajectoryError, open_trajectory, read_trajectory, reading, stored_scene
from ..io.recording import blob_colors


def draw_statics(ax, statics, lo, hi, position=None, angle=None):
    """The colliders, each where the frame's recorded `position` (its pivot, (S, 2) m) and `angle` ((S,) deg)
    put it, when given (format 7 on), else where the scene wrote it."""
    extent = 2.0 * float(np.max(hi - lo))
    for i, s in enumerate(statics):
        line = COLLIDERS[s.kind].outline(s, extent)
        normal = np.array(s.normal) / np.hypot(*s.normal) if s.kind == "plane" else None
        if position is not None:
            c, t = np.cos(np.radians(angle[i])), np.sin(np.radians(angle[i]))
            turn = np.array([[c, t], [-t, c]])  # row vectors: p @ turn = R(angle) p
            line = (line - np.array(default_pivot(s))) @ turn + position[i]
            normal = normal @ turn if normal is not None else None
        if s.kind == "segment" or (s.kind == "circle" and s.inside):  # a line: no solid, or one all around
            ax.plot(line[:, 0], line[:, 1], color="0.3", lw=2, zorder=1)
            continue
        if s.kind == "plane":  # the solid half-plane: a big quad behind the line
            line = np.array([line[0], line[1], line[1] - extent * normal, line[0] - extent * normal])
        ax.fill(line[:, 0], line[:, 1], color="0.55", zorder=1)


def _boxes(f, frames: int):
    """The periodic box's corners in each frame, (frames, 4, 2), or None in an open world: ±e_1/2 ± e_2/2 with the
    box vectors e_1 = (L_x, 0), e_2 = (γ L_y, L_y) (a parallelogram when sheared)."""
    import h5py

    from ..io.h5md import EDGES, IMAGE
    if IMAGE not in f:
        return None
    edges = f[EDGES]
    e = edges["value"][...] if isinstance(edges, h5py.Group) else np.tile(edges[...], (frames, 1))
    if e.ndim == 2:  # sides: a rectangle
        e = np.stack([np.diag(sides) for sides in e])
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) / 2
    return np.einsum("ck,fkj->fcj", signs, e)


def render(h5_path, png_path, frames: int = 6, width: float = 3.0, columns: int | None = None) -> Path:
    """Draw `frames` evenly spaced frames of a trajectory side by side into a PNG, each `width` inches wide, in rows
    of `columns` (default: one row)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = read_trajectory(h5_path)
    with open_trajectory(h5_path) as f, reading(h5_path):  # checked as every reader's (h5md.trajectory_problems)
        scene = stored_scene(f, h5_path)
        boxes = _boxes(f, len(t.step))
    picks = np.unique(np.linspace(0, len(t.step) - 1, frames).round().astype(int))
    finite = t.position[np.isfinite(t.position).all(axis=2)]
    if len(finite) == 0:
        raise TrajectoryError(f"{h5_path}: no vertex has a finite position in any frame: nothing to draw")
    lo, hi = finite.min(axis=0), finite.max(axis=0)
    if boxes is not None:  # frame the whole periodic box, in every frame
        corners = boxes.reshape(-1, 2)
        lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
    pad = 0.08 * max(float(np.max(hi - lo)), 0.5)
    lo, hi = lo - pad, hi + pad
    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    cols = min(columns or len(picks), len(picks))
    rows = -(-len(picks) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols, width * min(max(aspect, 0.3), 3.0) * rows),
                             squeeze=False)
    for ax in axes.flat[len(picks):]:  # a last row's empty places
        ax.set_axis_off()
    colors = blob_colors(len(t.offsets) - 1) / 255.0
    for ax, f in zip(axes.flat, picks):
        poses = (t.statics["position"][f], t.statics["angle"][f]) if t.statics else (None, None)
        draw_statics(ax, scene.statics, lo, hi, *poses)
        if boxes is not None:
            ax.add_patch(plt.Polygon(boxes[f], closed=True, fill=False, ec="0.5", lw=0.8, ls="--", zorder=1))
        for b in range(len(t.offsets) - 1):
            ring = t.position[f, t.offsets[b]:t.offsets[b + 1]]
            ax.fill(ring[:, 0], ring[:, 1], color=colors[b], alpha=0.85, lw=0.6, ec="0.15", zorder=2)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"t = {t.time[f]:.2f} s", fontsize=9)
    fig.suptitle(f"{scene.name}  ({t.attrs.get('method', '')}, {len(t.offsets) - 1} blobs)", fontsize=10)
    fig.tight_layout()
    png_path = Path(png_path)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    from ..io.outputs import replaced
    with replaced(png_path) as tmp:
        fig.savefig(tmp, dpi=100)
    plt.close(fig)
    return png_path
