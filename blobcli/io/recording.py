"""Rerun recordings of a run, for playback in the rerun viewer. Only this module imports rerun.

Layout of a recording (timelines `step`, a sequence, and `sim_time`, a duration in s):

    world/blobs              LineStrips2D: one closed strip per blob, one stable colour per blob
    world/vertices           Points2D: every vertex
    world/statics/<i>        the static colliders, logged once as static data
    series/area_error        Scalars: one series per blob, (|A| - A_target) / A_target
    series/kinetic_energy    Scalars: one series per blob, J

plus a default blueprint: the 2D view framed on the scene beside the two time-series panels.
Frames are sent in batches with the columnar API (`send_columns`), which is several times
faster than logging frame by frame.
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from ..colliders import COLLIDERS

BATCH_FRAMES = 64  # frames per send_columns call


def blob_colors(count: int) -> np.ndarray:
    """(count, 4) uint8 RGBA: blob b always gets the same colour (golden-ratio hue steps)."""
    hues = (np.arange(count) * 0.618033988749895) % 1.0
    rgb = np.array([colorsys.hsv_to_rgb(h, 0.65, 0.9) for h in hues]) if count else np.zeros((0, 3))
    return np.concatenate([np.round(rgb * 255), np.full((count, 1), 255)], axis=1).astype(np.uint8)


class RerunRecorder:
    """Streams frames into a .rrd file (`append`, then `close`)."""

    def __init__(self, path, scene, offsets, names, target_area, dt, first_positions):
        import rerun as rr
        import rerun.blueprint as rrb
        self.rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.dt = dt
        self.offsets = np.asarray(offsets)
        self.target = np.abs(np.asarray(target_area))
        self.colors = blob_colors(len(self.offsets) - 1)
        # Closing index: each blob's ring followed by its first vertex again.
        self.closed = np.concatenate([np.append(np.arange(o, e), o)
                                      for o, e in zip(self.offsets[:-1], self.offsets[1:])])
        self.strip_ends = np.cumsum(np.diff(self.offsets) + 1)[:-1]

        lo, hi = first_positions.min(axis=0), first_positions.max(axis=0)
        finite = [s for s in scene.statics if s.kind != "plane"]
        for s in finite:
            strip = COLLIDERS[s.kind].outline(s, 0.0)
            lo, hi = np.minimum(lo, strip.min(axis=0)), np.maximum(hi, strip.max(axis=0))
        pad = 0.1 * max(hi[0] - lo[0], hi[1] - lo[1], 1.0)
        lo, hi = lo - pad, hi + pad
        blueprint = rrb.Blueprint(rrb.Horizontal(
            rrb.Spatial2DView(origin="world", name=scene.name,
                              visual_bounds=rrb.VisualBounds2D(x_range=[lo[0], hi[0]], y_range=[lo[1], hi[1]])),
            rrb.Vertical(rrb.TimeSeriesView(origin="series/area_error", name="area error"),
                         rrb.TimeSeriesView(origin="series/kinetic_energy", name="kinetic energy (J)")),
            column_shares=[3, 2]))
        self.rec = rr.RecordingStream("blobsim", recording_id=scene.name)
        self.rec.save(self.path, default_blueprint=blueprint)
        extent = 2.0 * max(hi[0] - lo[0], hi[1] - lo[1])
        for i, s in enumerate(scene.statics):
            outline = COLLIDERS[s.kind].outline(s, extent)
            self.rec.log(f"world/statics/{i}", rr.LineStrips2D([outline], colors=[[90, 90, 90, 255]],
                                                                radii=[0.01]), static=True)
        for series in ("area_error", "kinetic_energy"):
            self.rec.log(f"series/{series}", rr.SeriesLines(names=list(names), colors=self.colors), static=True)
        self._steps, self._pos, self._area_error, self._kinetic = [], [], [], []
        self.frames = 0

    def append(self, step: int, pos, area, kinetic):
        """Buffer one frame: positions (N, 2), signed or positive areas (B,), kinetic energy (B,)."""
        self._steps.append(step)
        self._pos.append(np.asarray(pos, dtype=np.float32))
        self._area_error.append((np.abs(area) - self.target) / self.target)
        self._kinetic.append(np.asarray(kinetic, dtype=np.float64))
        if len(self._steps) >= BATCH_FRAMES:
            self.flush()

    def flush(self):
        if not self._steps:
            return
        rr = self.rr
        frames, blobs = len(self._steps), len(self.offsets) - 1
        steps = np.array(self._steps, dtype=np.int64)
        times = [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("sim_time", duration=steps * self.dt)]
        pos = np.stack(self._pos)  # (F, N, 2)
        strips = [s for frame in pos for s in np.split(frame[self.closed], self.strip_ends)]
        self.rec.send_columns("world/blobs", indexes=times, columns=rr.LineStrips2D.columns(
            strips=strips, colors=np.tile(self.colors, (frames, 1))).partition([blobs] * frames))
        self.rec.send_columns("world/vertices", indexes=times, columns=rr.Points2D.columns(
            positions=pos.reshape(-1, 2), radii=np.full(pos.shape[0] * pos.shape[1], 0.008, np.float32)).partition(
            [pos.shape[1]] * frames))
        for name, values in (("area_error", self._area_error), ("kinetic_energy", self._kinetic)):
            self.rec.send_columns(f"series/{name}", indexes=times, columns=rr.Scalars.columns(
                scalars=np.concatenate(values)).partition([blobs] * frames))
        self.frames += frames
        self._steps, self._pos, self._area_error, self._kinetic = [], [], [], []

    def close(self):
        self.flush()
        self.rec.flush()
        self.rec.disconnect()


def replay(h5_path, rrd_path) -> int:
    """Write the recording of an existing trajectory file, without simulating. Returns frames."""
    from .h5md import AREA, KINETIC, PARAMETERS, POSITION, open_trajectory, reading, stored_scene, text
    with open_trajectory(h5_path) as f, reading(h5_path):
        p = f[PARAMETERS]
        scene = stored_scene(f, h5_path)
        pos = f[POSITION]
        area, kinetic = f[AREA]["value"], f[KINETIC]["value"]
        recorder = RerunRecorder(rrd_path, scene, p["blob_offsets"][...], [text(n) for n in p["blob_names"][...]],
                                 p["target_area"][...], float(p.attrs["dt"]), pos["value"][0])
        steps = pos["step"][...]
        try:
            for start in range(0, len(steps), BATCH_FRAMES):
                stop = min(start + BATCH_FRAMES, len(steps))
                block, a, k = pos["value"][start:stop], area[start:stop], kinetic[start:stop]
                for i in range(stop - start):
                    recorder.append(int(steps[start + i]), block[i], a[i], k[i])
        finally:
            recorder.close()
        return len(steps)


def read_positions(rrd_path) -> tuple[np.ndarray, np.ndarray]:
    """(steps (F,), positions (F, N, 2) float32) of world/vertices in a recording, by step."""
    import rerun.chunk as rc
    rows = {}
    for chunk in rc.RrdReader(str(rrd_path)).stream().to_chunks():
        if chunk.entity_path != "/world/vertices" or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        steps = batch.column("step").to_pylist()
        values = batch.column("Points2D:positions").to_pylist()
        for s, v in zip(steps, values):
            rows[s] = np.array(v, dtype=np.float32)
    order = sorted(rows)
    return np.array(order, dtype=np.int64), np.stack([rows[s] for s in order]) if order else np.zeros((0, 0, 2))
