"""Comparing two trajectory files frame by frame (matched by step) and blob by blob.

A vertex coordinate agrees when |a - b| <= atol + rtol |b|; with both tolerances 0 (the
default) that is equality, bit for bit, except that NaN agrees with NaN. NaN against a
number is always a difference. Chaotic scenes diverge over time, so the report also says
where divergence starts: the first frame beyond 1e-12, 1e-9, 1e-6 and 1e-3 m. The colliders' recorded
positions (m) and angles (deg) are compared too (format 7 on), with the same tolerances.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..io.h5md import PARAMETERS, POSITION, STATICS, TrajectoryError, open_trajectory, reading, text

DIVERGENCE_LEVELS = (1e-12, 1e-9, 1e-6, 1e-3)  # m
FRAMES_PER_READ = 256  # frames read at a time, so files larger than memory compare too


class CannotCompare(Exception):
    """The files cannot be compared (exit 2): missing, unreadable, or not alike."""


@dataclass
class Report:
    a: str
    b: str
    atol: float
    rtol: float
    frames: int  # frames compared
    max_deviation: float  # m, largest |a - b| over all compared coordinates (inf if NaN vs number)
    rms_deviation: float  # m, root mean square of the per-vertex distance |a - b|
    first_difference: dict | None  # frame, step, time, blob, blob_name, vertex, a, b
    worst_blobs: list = field(default_factory=list)  # up to 5 (name, max deviation), largest first
    divergence: dict = field(default_factory=dict)  # level (m) -> first step beyond it, or None
    notes: list = field(default_factory=list)

    @property
    def same(self) -> bool:
        return self.first_difference is None and not self.notes

    def text(self) -> str:
        exact = self.atol == 0 and self.rtol == 0
        tol = "exact (bit for bit)" if exact else f"atol {self.atol:g} m, rtol {self.rtol:g}"
        lines = [f"compared {self.frames} frames of {self.a} and {self.b} ({tol})",
                 f"max deviation {self.max_deviation:.3e} m, rms {self.rms_deviation:.3e} m"]
        d = self.first_difference
        if d:
            lines.append(f"first difference: frame {d['frame']} (step {d['step']}, t = {d['time']:.6g} s), "
                         f"blob {d['blob']} ({d['blob_name']}) vertex {d['vertex']}: {d['a']} vs {d['b']}")
        if self.worst_blobs and self.max_deviation > 0:
            lines.append("worst blobs: " + ", ".join(f"{n} {v:.2e} m" for n, v in self.worst_blobs))
        if self.max_deviation > 0:
            lines.append("divergence: " + ", ".join(
                f"> {level:g} m from step {step}" if step is not None else f"never > {level:g} m"
                for level, step in self.divergence.items()))
        lines += self.notes
        lines.append("verdict: " + ("same" if self.same else "different"))
        return "\n".join(lines)

    def json(self) -> dict:
        out = asdict(self)
        out["same"] = self.same
        out["divergence"] = {f"{k:g}": v for k, v in self.divergence.items()}
        return out


def _open(path, allow_incomplete):
    try:
        f = open_trajectory(path)
    except TrajectoryError as e:
        raise CannotCompare(str(e)) from None
    try:
        with reading(path):
            pos = f[POSITION]
            meta = {"value": pos["value"], "step": pos["step"][...], "time": pos["time"][...],
                    "offsets": f[PARAMETERS]["blob_offsets"][...],
                    "names": [text(n) for n in f[PARAMETERS]["blob_names"][...]],
                    "complete": bool(f.attrs["complete"]),
                    "statics": {name: f[f"{STATICS}/{name}/value"] for name in ("position", "angle")}
                    if STATICS in f else {}}
    except TrajectoryError as e:
        f.close()
        raise CannotCompare(str(e)) from None
    if not meta["complete"] and not allow_incomplete:
        f.close()
        raise CannotCompare(f"{path}: incomplete run (complete = false); pass --allow-incomplete to compare it")
    return f, meta


def compare_files(path_a, path_b, atol=0.0, rtol=0.0, frames=None, until=None, allow_incomplete=False) -> Report:
    """Compare two trajectory files; raise CannotCompare when they are not comparable."""
    fa, a = _open(path_a, allow_incomplete)
    try:
        fb, b = _open(path_b, allow_incomplete)
        try:
            with reading(f"{path_a} or {path_b}"):
                return _compare(str(path_a), str(path_b), a, b, atol, rtol, frames, until)
        except TrajectoryError as e:
            raise CannotCompare(str(e)) from None
        finally:
            fb.close()
    finally:
        fa.close()


def _compare(name_a, name_b, a, b, atol, rtol, frames, until) -> Report:
    if not np.array_equal(a["offsets"], b["offsets"]):
        raise CannotCompare(f"different blob layout: {len(a['offsets']) - 1} blobs / {a['offsets'][-1]} vertices "
                            f"vs {len(b['offsets']) - 1} blobs / {b['offsets'][-1]} vertices")
    n = min(len(a["step"]), len(b["step"]))
    if not np.array_equal(a["step"][:n], b["step"][:n]):
        k = int(np.argmax(a["step"][:n] != b["step"][:n]))
        raise CannotCompare(f"different step grid: frame {k} is step {a['step'][k]} in {name_a} "
                            f"but step {b['step'][k]} in {name_b}")
    notes = []
    limit = n
    if frames is not None:
        limit = min(limit, frames)
    if until is not None:
        limit = min(limit, int(np.searchsorted(a["time"][:n], until, side="right")))
    wanted = frames if frames is not None else None
    if until is None and frames is None and len(a["step"]) != len(b["step"]):
        notes.append(f"different length: {len(a['step'])} frames in {name_a}, {len(b['step'])} in {name_b}")
    elif wanted is not None and limit < wanted and len(a["step"]) != len(b["step"]):
        # asked for frames one file has and the other lacks (both ending early alike is no difference)
        notes.append(f"only {limit} frames in common, {wanted} asked for")

    offsets, names = a["offsets"], a["names"]
    blob_of = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    max_dev, sum_sq, count = 0.0, 0.0, 0
    per_blob = np.zeros(len(offsets) - 1)
    first = None
    divergence = {level: None for level in DIVERGENCE_LEVELS}
    for start in range(0, limit, FRAMES_PER_READ):
        stop = min(start + FRAMES_PER_READ, limit)
        xa, xb = a["value"][start:stop], b["value"][start:stop]
        nan_a, nan_b = np.isnan(xa), np.isnan(xb)
        both_nan = nan_a & nan_b
        diff = np.where(both_nan, 0.0, np.abs(xa - xb))
        diff = np.where(nan_a ^ nan_b, np.inf, diff)
        allowed = atol + rtol * np.abs(np.where(nan_b, 0.0, xb))
        bad = (diff > allowed) if (atol or rtol) else ((xa != xb) & ~both_nan)
        vertex_dev = np.sqrt(np.sum(np.where(np.isinf(diff), 0.0, diff) ** 2, axis=2))
        vertex_dev = np.where(np.isinf(diff).any(axis=2), np.inf, vertex_dev)
        max_dev = max(max_dev, float(vertex_dev.max(initial=0.0)))
        finite = np.isfinite(vertex_dev)
        sum_sq += float(np.sum(vertex_dev[finite] ** 2))
        count += int(finite.sum())
        np.maximum(per_blob, np.maximum.reduceat(vertex_dev.max(axis=0), offsets[:-1]), out=per_blob)
        frame_dev = vertex_dev.max(axis=1)
        for level in DIVERGENCE_LEVELS:
            if divergence[level] is None and (frame_dev > level).any():
                divergence[level] = int(a["step"][start + int(np.argmax(frame_dev > level))])
        if first is None and bad.any():
            f, v, _ = np.unravel_index(int(np.argmax(bad)), bad.shape)
            frame, blob = start + int(f), int(blob_of[v])
            first = {"frame": frame, "step": int(a["step"][frame]), "time": float(a["time"][frame]),
                     "blob": blob, "blob_name": names[blob], "vertex": int(v - offsets[blob]),
                     "a": xa[f, v].tolist(), "b": xb[f, v].tolist()}
    notes += _compare_statics(a["statics"], b["statics"], a["step"], limit, atol, rtol)
    order = np.argsort(-per_blob, kind="stable")[:5]
    return Report(a=name_a, b=name_b, atol=atol, rtol=rtol, frames=limit, max_deviation=max_dev,
                  rms_deviation=(sum_sq / count) ** 0.5 if count else 0.0, first_difference=first,
                  worst_blobs=[(names[k], float(per_blob[k])) for k in order if per_blob[k] > 0],
                  divergence=divergence, notes=notes)


def _compare_statics(a, b, steps, limit, atol, rtol) -> list[str]:
    """Notes on where the two runs' colliders first differ (none: they agree, or a file has none recorded: a
    format before 7, whose colliders never moved)."""
    if not a or not b:
        return []
    if a["position"].shape[1] != b["position"].shape[1]:
        return [f"different colliders: {a['position'].shape[1]} vs {b['position'].shape[1]} recorded"]
    for name, unit in (("position", "m"), ("angle", "deg")):
        xa, xb = a[name][:limit], b[name][:limit]
        bad = ~np.isclose(xa, xb, rtol=rtol, atol=atol, equal_nan=True) if (atol or rtol) else \
            ((xa != xb) & ~(np.isnan(xa) & np.isnan(xb)))
        if bad.any():
            f, k = np.unravel_index(int(np.argmax(bad)), bad.shape)[:2]
            return [f"collider static[{k}] {name} differs from frame {f} (step {int(steps[f])}): "
                    f"{xa[f, k].tolist()} vs {xb[f, k].tolist()} {unit}"]
    return []
