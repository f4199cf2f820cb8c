"""Rerun recordings of a run, for playback in the rerun viewer. Only this module imports rerun.

Layout of a recording (timelines `step`, a sequence, and `sim_time`, a duration in s):

    world/blobs              LineStrips2D: one closed strip per blob, one stable colour per blob (grey while
                             it sleeps)
    world/vertices           Points2D: every vertex
    world/statics/<i>        the colliders: logged once as static data, or, for one that moves, frame by frame
                             where it is (its outline turned by its recorded angle about its recorded pivot)
    series/statics/<i>/force Scalars: how hard the blobs push back against a loaded wall's load, N (-f · e: the
                             load itself once the wall is at rest)
    series/area_error        Scalars: one series per blob, (|A| - A_target) / A_target
    series/kinetic_energy    Scalars: one series per blob, J
    series/summary/area_error/{max,mean}   over the blobs
    series/summary/kinetic_energy/total    J

Positions are logged in physics coordinates (y up). Rerun's 2D views draw y down and have no
y-up option (rerun issue #1387), so world/blobs, world/vertices and world/statics carry a
static Transform3D that scales y by -1, and the view's bounds are flipped to match: the scene
is drawn the right way up, and hovering still shows the logged (physics) coordinates.

The default blueprint shows the 2D view framed on the scene beside the summary series; the
per-blob series are in the recording, to add to a view, and their legends are hidden past
LEGEND_BLOBS blobs. The application id is `blobsim-<scene name>`, so that rerun keeps one
blueprint per scene when several recordings are open. Frames are sent in batches with the
columnar API (`send_columns`), several times faster than logging frame by frame.
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from ..colliders import COLLIDERS, default_pivot
from .outputs import replaced

BATCH_FRAMES = 64  # frames per send_columns call
LEGEND_BLOBS = 8  # per-blob legends are shown up to this many blobs
Y_UP = [1.0, -1.0, 1.0]  # the scale that draws physics' y-up in rerun's y-down 2D views
SLEEPING_GREY = [150, 150, 150, 255]  # the colour of a sleeping blob (RGBA)


def blob_colors(count: int) -> np.ndarray:
    """(count, 4) uint8 RGBA: blob b always gets the same colour (golden-ratio hue steps)."""
    hues = (np.arange(count) * 0.618033988749895) % 1.0
    rgb = np.array([colorsys.hsv_to_rgb(h, 0.65, 0.9) for h in hues]) if count else np.zeros((0, 3))
    return np.concatenate([np.round(rgb * 255), np.full((count, 1), 255)], axis=1).astype(np.uint8)


class RerunRecorder:
    """Streams frames into a .rrd file (`append`, then `close`)."""

    def __init__(self, path, scene, offsets, names, target_area, dt, reach):
        """reach: (2, 2) [[xmin, ymin], [xmax, ymax]] of the vertices over the whole run (m)."""
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

        lo, hi = np.asarray(reach[0], dtype=float), np.asarray(reach[1], dtype=float)
        middle = (lo + hi) / 2
        for s in scene.statics:
            if s.kind == "plane":  # infinite: frame the stretch of it nearest the blobs
                n = np.array(s.normal) / np.hypot(*s.normal)
                strip = middle - ((middle - s.point) @ n) * n
                strip = strip[None, :]
            else:
                strip = COLLIDERS[s.kind].outline(s, 0.0)
            lo, hi = np.minimum(lo, strip.min(axis=0)), np.maximum(hi, strip.max(axis=0))
        if scene.settings.periodic is not None:  # frame the whole periodic box
            half = np.array(scene.settings.periodic) / 2
            lo, hi = np.minimum(lo, -half), np.maximum(hi, half)
        pad = 0.1 * max(hi[0] - lo[0], hi[1] - lo[1], 1.0)
        lo, hi = lo - pad, hi + pad
        legend = rrb.PlotLegend(visible=len(self.offsets) - 1 <= LEGEND_BLOBS)
        self.moving = [i for i, s in enumerate(scene.statics) if s.moves]
        self.loaded = {i: np.array(s.load_direction) / np.hypot(*s.load_direction)
                       for i, s in enumerate(scene.statics) if s.load is not None}
        forces = [rrb.TimeSeriesView(origin="series/statics", name="push against the load (N)")] if self.loaded else []
        blueprint = rrb.Blueprint(rrb.Horizontal(
            rrb.Spatial2DView(origin="world", name=scene.name,  # bounds in the flipped (drawn) frame
                              visual_bounds=rrb.VisualBounds2D(x_range=[lo[0], hi[0]], y_range=[-hi[1], -lo[1]])),
            rrb.Vertical(rrb.TimeSeriesView(origin="series/summary/area_error", name="area error (max, mean)"),
                         rrb.TimeSeriesView(origin="series/summary/kinetic_energy", name="kinetic energy (J)"),
                         rrb.TimeSeriesView(origin="series/area_error", name="area error per blob",
                                            plot_legend=legend, visible=False),
                         rrb.TimeSeriesView(origin="series/kinetic_energy", name="kinetic energy per blob (J)",
                                            plot_legend=legend, visible=False), *forces),
            column_shares=[3, 2]))
        import re
        import uuid
        app = "blobsim-" + re.sub(r"[^A-Za-z0-9_-]", "_", scene.name)
        self.rec = rr.RecordingStream(app, recording_id=str(uuid.uuid4()))
        self.rec.save(self.path, default_blueprint=blueprint)
        for entity in ("world/blobs", "world/vertices", "world/statics"):
            self.rec.log(entity, rr.Transform3D(scale=Y_UP), static=True)
        extent = 2.0 * max(hi[0] - lo[0], hi[1] - lo[1])
        self.outlines = {}  # of the colliders that move: outline relative to the pivot
        for i, s in enumerate(scene.statics):
            outline = COLLIDERS[s.kind].outline(s, extent)
            if i in self.moving:
                self.outlines[i] = outline - np.array(default_pivot(s))
                continue
            self.rec.log(f"world/statics/{i}", rr.LineStrips2D([outline], colors=[[90, 90, 90, 255]],
                                                                radii=[0.01]), static=True)
        if scene.settings.periodic is not None:  # the periodic box: its outline, in thin grey
            lx, ly = np.array(scene.settings.periodic) / 2
            corners = np.array([[-lx, -ly], [lx, -ly], [lx, ly], [-lx, ly], [-lx, -ly]])
            self.rec.log("world/statics/box", rr.LineStrips2D([corners], colors=[[150, 150, 150, 255]],
                                                              radii=[0.005]), static=True)
        for i in self.loaded:
            self.rec.log(f"series/statics/{i}/force", rr.SeriesLines(names=[f"static[{i}]"]), static=True)
        for series in ("area_error", "kinetic_energy"):
            self.rec.log(f"series/{series}", rr.SeriesLines(names=list(names), colors=self.colors), static=True)
        for path, color in (("area_error/max", [230, 90, 70]), ("area_error/mean", [90, 150, 230]),
                            ("kinetic_energy/total", [230, 180, 60])):
            self.rec.log(f"series/summary/{path}", rr.SeriesLines(names=[path.split("/")[1]], colors=[color]),
                         static=True)
        self._steps, self._pos, self._area_error, self._kinetic, self._awake = [], [], [], [], []
        self._statics = []
        self.frames = 0

    def append(self, step: int, pos, area, kinetic, awake, statics=None, target=None):
        """Buffer one frame: positions (N, 2), signed or positive areas (B,), kinetic energy (B,), awake (B,),
        and the colliders' recorded (position (S, 2), angle (S,) deg, force (S, 2)), or None if none move;
        `target`: the blobs' target areas in this frame, when schedules change them (else the scene's)."""
        self._steps.append(step)
        self._statics.append(statics)
        self._awake.append(np.asarray(awake, dtype=bool))
        self._pos.append(np.asarray(pos, dtype=np.float32))
        target = self.target if target is None else target
        self._area_error.append((np.abs(area) - target) / target)
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
            strips=strips, colors=np.where(np.concatenate(self._awake)[:, None], np.tile(self.colors, (frames, 1)),
                                           np.uint8(SLEEPING_GREY))).partition([blobs] * frames))
        self.rec.send_columns("world/vertices", indexes=times, columns=rr.Points2D.columns(
            positions=pos.reshape(-1, 2), radii=np.full(pos.shape[0] * pos.shape[1], 0.008, np.float32)).partition(
            [pos.shape[1]] * frames))
        area_error, kinetic = np.stack(self._area_error), np.stack(self._kinetic)  # (F, B)
        for series, values in (("area_error", area_error), ("kinetic_energy", kinetic)):
            self.rec.send_columns(f"series/{series}", indexes=times, columns=rr.Scalars.columns(
                scalars=values.ravel()).partition([blobs] * frames))
        for path, values in (("area_error/max", np.abs(area_error).max(axis=1)),
                             ("area_error/mean", np.abs(area_error).mean(axis=1)),
                             ("kinetic_energy/total", kinetic.sum(axis=1))):
            self.rec.send_columns(f"series/summary/{path}", indexes=times, columns=rr.Scalars.columns(scalars=values))
        recorded = self._statics[0] is not None  # (always, in a file of a scene whose colliders move)
        for i in self.moving if recorded else ():  # where each moving collider is, frame by frame
            strips = []
            for position, angle, _ in self._statics:
                c, t = np.cos(np.radians(angle[i])), np.sin(np.radians(angle[i]))
                strips.append(self.outlines[i] @ np.array([[c, t], [-t, c]]) + position[i])
            self.rec.send_columns(f"world/statics/{i}", indexes=times, columns=rr.LineStrips2D.columns(
                strips=strips, colors=np.tile(np.uint8([90, 90, 90, 255]), (frames, 1)),
                radii=np.full(frames, 0.01, np.float32)).partition([1] * frames))
        for i, e in self.loaded.items() if recorded else ():
            force = np.array([-(frame[2][i] @ e) for frame in self._statics])
            self.rec.send_columns(f"series/statics/{i}/force", indexes=times, columns=rr.Scalars.columns(scalars=force))
        self.frames += frames
        self._steps, self._pos, self._area_error, self._kinetic, self._awake = [], [], [], [], []
        self._statics = []

    def close(self):
        self.flush()
        self.rec.flush()
        self.rec.disconnect()


def replay(h5_path, rrd_path) -> int:
    """Write the recording of an existing trajectory file, without simulating. Returns frames."""
    from .h5md import AREA, AWAKE, KINETIC, PARAMETERS, POSITION, STATICS, open_trajectory, reading, stored_scene, text
    with open_trajectory(h5_path) as f, reading(h5_path):
        p = f[PARAMETERS]
        scene = stored_scene(f, h5_path)
        pos = f[POSITION]
        area, kinetic = f[AREA]["value"], f[KINETIC]["value"]
        awake = f[AWAKE]["value"] if AWAKE in f else np.ones(area.shape, np.uint8)  # formats 1-3: no sleeping
        steps = pos["step"][...]
        # a schedule of pressure or scale changes what each blob's area should be, frame by frame
        targets = None
        if any(s.key.rsplit(".", 1)[-1] in ("pressure", "scale") for s in scene.schedules):
            from ..sim.schedule import target_areas
            targets = target_areas(scene, steps)
        reach = np.array([[np.inf, np.inf], [-np.inf, -np.inf]])
        for start in range(0, len(steps), BATCH_FRAMES):  # where the blobs go, to frame the view on
            block = pos["value"][start:start + BATCH_FRAMES].reshape(-1, 2)
            block = block[np.all(np.isfinite(block), axis=1)]
            if len(block):
                reach = np.array([np.minimum(reach[0], block.min(axis=0)), np.maximum(reach[1], block.max(axis=0))])
        if not np.all(np.isfinite(reach)):
            reach = np.zeros((2, 2))
        Path(rrd_path).parent.mkdir(parents=True, exist_ok=True)
        with replaced(rrd_path) as tmp:  # whole or not at all, and never through a link planted there
            recorder = RerunRecorder(tmp, scene, p["blob_offsets"][...], [text(n) for n in p["blob_names"][...]],
                                     p["target_area"][...], float(p.attrs["dt"]), reach)
            try:
                for start in range(0, len(steps), BATCH_FRAMES):
                    stop = min(start + BATCH_FRAMES, len(steps))
                    block, a, k, w = pos["value"][start:stop], area[start:stop], kinetic[start:stop], awake[start:stop]
                    moves = recorder.moving and STATICS in f
                    sp, sa, sf = ((f[f"{STATICS}/{name}/value"][start:stop] for name in ("position", "angle", "force"))
                                  if moves else (None, None, None))
                    for i in range(stop - start):
                        recorder.append(int(steps[start + i]), block[i], a[i], k[i], w[i],
                                        (sp[i], sa[i], sf[i]) if moves else None,
                                        None if targets is None else targets[start + i])
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
