"""The checks that need a whole scene: schedules against the blobs they name, array sizes, how hard a blob
is driven, the sizes a scale schedule reaches, the periodic box, and how long the run is.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import replace
from typing import TYPE_CHECKING

from .keys import (
    DEFAULT_DURATION,
    MAX_BLOB_VERTICES,
    MAX_BLOBS,
    MAX_BOX_CELLS,
    MAX_COORDINATE,
    MAX_SHEAR,
    MAX_STEP_WORK,
    MAX_STEPS,
    MAX_VERTICES,
    MIN_LENGTH,
    SCHEDULED_BLOB_KEYS,
    Scene,
    SceneError,
    ScheduleDef,
    blob_vertex_count,
    expanded_names,
    mass_value,
    nonnegative,
    positive,
    schedule_targets,
    unit_interval,
)

if TYPE_CHECKING:
    from .parse import Problems


SCHEDULE_CHECKS = {"mass": mass_value, "pressure": positive, "scale": positive, "friction": nonnegative,
                   "static_friction": nonnegative, "restitution": unit_interval,
                   "adhesion": nonnegative}  # force, torque: check_driving


def check_schedule(s: ScheduleDef, names, path, problems: Problems, periodic: bool) -> bool:
    width = len(s.at[0])
    if s.key == "scene.shear":
        if width != 2:
            problems.add(path + ("at",), "shear keyframes are [t, γ]: 2 numbers each", list(s.at[0]))
            return False
        if not periodic:
            problems.add(path + ("key",), "only in a periodic box ([scene] periodic)", s.key)
            return False
        for j, (_, gamma) in enumerate(s.at):
            if abs(gamma) > MAX_SHEAR:
                problems.add(path + ("at", j), f"shear strain γ must be within ±{MAX_SHEAR:,g} (the images' shift "
                             "γ L_y stays a number the step can wrap)", gamma)
                return False
        return True
    if s.key in ("scene.gravity", "scene.periodic"):
        what = s.key.split(".")[1]
        if width != 3:
            problems.add(path + ("at",), f"{what} keyframes are [t, {'gx, gy' if what == 'gravity' else 'Lx, Ly'}]: "
                         "3 numbers each", list(s.at[0]))
            return False
        if what == "periodic" and not periodic:
            problems.add(path + ("key",), "only in a periodic box ([scene] periodic)", s.key)
            return False
        if what == "periodic" and min(min(row[1:]) for row in s.at) <= 0.0:
            problems.add(path + ("at",), "box sides must be > 0", [list(row) for row in s.at])
            return False
        return True
    parts = s.key.split(".")
    if len(parts) < 3 or parts[0] != "blob":
        problems.add(path + ("key",), "must be blob.NAME.KEY, scene.gravity, scene.periodic or scene.shear", s.key)
        return False
    if parts[-1] not in SCHEDULED_BLOB_KEYS:
        hint = difflib.get_close_matches(parts[-1], SCHEDULED_BLOB_KEYS, n=1)
        problems.add(path + ("key",), f"KEY must be one of {', '.join(SCHEDULED_BLOB_KEYS)}"
                     + (f"; did you mean {hint[0]!r}?" if hint else ""), s.key)
        return False
    if not schedule_targets(s, names):
        pattern = ".".join(parts[1:-1])
        hint = difflib.get_close_matches(pattern, names, n=1)
        problems.add(path + ("key",), f"no blob is named {pattern!r}" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                        " (a grid's copies: NAME_*)"), s.key)
        return False
    if width != (3 if parts[-1] == "force" else 2):
        problems.add(path + ("at",), "force keyframes are [t, Fx, Fy]: 3 numbers each" if parts[-1] == "force"
                     else "keyframes are [t, value]: 2 numbers each", list(s.at[0]))
        return False
    for j, (_, *value) in enumerate(s.at):
        check = SCHEDULE_CHECKS.get(parts[-1])
        complaint = check(value[0]) if check else None
        if complaint:
            problems.add(path + ("at", j), f"{parts[-1]} {complaint}", value[0])
            return False
    return True


def check_size(scene: Scene, problems: Problems):
    """Refuse scenes whose arrays would be too large, before anything is allocated."""
    for i, b in enumerate(scene.blobs):
        if blob_vertex_count(b) > MAX_BLOB_VERTICES:
            problems.add(("blob", i, "vertices"), f"at most {MAX_BLOB_VERTICES:,} vertices per blob",
                         blob_vertex_count(b))
    if scene.blob_count > MAX_BLOBS:
        problems.add(("blob",), f"scene has {scene.blob_count:,} blobs after grids; the limit is {MAX_BLOBS:,}",
                     show_got=False)
    if scene.vertex_count > MAX_VERTICES:
        problems.add(("blob",), f"scene has {scene.vertex_count:,} vertices after grids; "
                     f"the limit is {MAX_VERTICES:,}", show_got=False)
    for path, message in run_length_problems(scene):
        problems.add(path, message, show_got=False)


STRIDE = 0.5  # of a mean rest edge: the farthest a blob moves in one substep (core/integrate.c's STRIDE)


def check_driving(scene: Scene, problems: Problems):
    """Refuse a driving force or torque (a blob's, or a schedule keyframe's) that accelerates a blob faster than
    a step can follow. The substep rule (core/integrate.c: bc_substeps_for) keeps a blob's move within STRIDE of
    a mean rest edge L a substep, with at most `most` substeps (max_substeps, within the step's work bound:
    pipeline.settings); a blob driven from rest reaches a dt in one step, a = |F| / M + |τ| r / I (r its farthest
    vertex from the centre of mass, I = Σ m |r|², at the shape written), so a dt² must stay within most STRIDE L.
    M is the least mass a mass schedule gives the blob; a scale schedule is not checked."""
    s = scene.settings
    most = max(s.substeps, min(s.max_substeps, MAX_STEP_WORK // max(s.iterations * scene.vertex_count, 1)))
    names = expanded_names(scene.blobs)
    table_of = [i for i, b in enumerate(scene.blobs) for _ in range(b.copies)]
    # per [[blob]] table: the largest |F| and |τ| it is given, with where and as written, and its least mass
    force = [(math.hypot(*b.force), ("blob", i, "force"), list(b.force)) for i, b in enumerate(scene.blobs)]
    torque = [(abs(b.torque), ("blob", i, "torque"), b.torque) for i, b in enumerate(scene.blobs)]
    mass = [b.mass for b in scene.blobs]
    for k, sc in enumerate(scene.schedules):
        if sc.key.startswith("scene."):
            continue
        for i in sorted({table_of[x] for x in schedule_targets(sc, names)}):
            for j, row in enumerate(sc.at):
                if sc.blob_key == "mass":
                    mass[i] = min(mass[i], row[1])
                elif sc.blob_key == "force" and math.hypot(row[1], row[2]) > force[i][0]:
                    force[i] = (math.hypot(row[1], row[2]), ("schedule", k, "at", j), list(row))
                elif sc.blob_key == "torque" and abs(row[1]) > torque[i][0]:
                    torque[i] = (abs(row[1]), ("schedule", k, "at", j), list(row))
    for i, b in enumerate(scene.blobs):
        if force[i][0] == 0.0 and torque[i][0] == 0.0:
            continue
        if b.points is None:  # a ring: n edges of 2 R sin(π / n), every vertex at R
            edge, farthest, mean_square = 2.0 * b.radius * math.sin(math.pi / b.vertices), b.radius, b.radius ** 2
        else:
            n = len(b.points)
            cx, cy = sum(p[0] for p in b.points) / n, sum(p[1] for p in b.points) / n
            squares = [(x - cx) ** 2 + (y - cy) ** 2 for x, y in b.points]
            edge = sum(math.dist(b.points[j - 1], b.points[j]) for j in range(n)) / n
            farthest, mean_square = math.sqrt(max(squares)), sum(squares) / n
        pushed = force[i][0] / mass[i]  # m/s², and the torque's at the farthest vertex: |τ| r / (M mean |r|²)
        turned = torque[i][0] * farthest / (mass[i] * mean_square)
        limit = most * STRIDE * edge / s.dt ** 2
        if pushed + turned > limit:
            _, path, got = force[i] if pushed >= turned else torque[i]
            problems.add(path, f"drives {b.name or f'blob{i}'} at {pushed + turned:.4g} m/s² (|F| / M + |τ| r / I, "
                         f"M = {mass[i]:g} kg); at most {limit:.4g} m/s² here, or one step from rest moves it more "
                         f"than {STRIDE:g} × its edge ({STRIDE * edge:.3g} m) a substep at the most substeps a step "
                         f"takes ({most})", got)


PERIODIC_SIDE = 5.0  # × the largest blob radius: the least side of a periodic box
BROAD_MARGIN = 0.25  # × the larger radius: the broad phase's margin (core/broad_phase.c), its cells 2 r (1 + margin)


def _radii(scene: Scene) -> list[float]:
    """Each [[blob]] table's radius as written: its ring's farthest vertex from the vertex average (m)."""
    import numpy as np

    from ..geometry import blob_points
    return [float(np.hypot(*(ring - ring.mean(axis=0)).T).max()) for ring in (blob_points(b) for b in scene.blobs)]


def _scales(scene: Scene) -> list[list[tuple[float, int, int]]]:
    """Each [[blob]] table's scale keyframes, (s, schedule index, keyframe index), from the scale schedules that
    reach its blobs ([] for none: its size as written)."""
    names = expanded_names(scene.blobs)
    table_of = [i for i, b in enumerate(scene.blobs) for _ in range(b.copies)]
    out = [[] for _ in scene.blobs]
    for k, sc in enumerate(scene.schedules):
        if sc.key.startswith("blob.") and sc.blob_key == "scale":
            for i in sorted({table_of[x] for x in schedule_targets(sc, names)}):
                out[i] += [(row[1], k, j) for j, row in enumerate(sc.at)]
    return out


def check_scales(scene: Scene, problems: Problems):
    """A scale schedule keeps each blob's radius × s from MIN_LENGTH (smaller, a blob loses its area to
    round-off) to MAX_COORDINATE (larger, it leaves the world)."""
    for i, (radius, keyframes) in enumerate(zip(_radii(scene), _scales(scene))):
        for factor, k, j in keyframes:
            if not MIN_LENGTH <= factor * radius <= MAX_COORDINATE:
                problems.add(("schedule", k, "at", j), f"scales blob[{i}] (radius {radius:.4g} m) to "
                             f"{factor * radius:.4g} m; its radius must stay from {MIN_LENGTH:g} to "
                             f"{MAX_COORDINATE:g} m", factor)
                return


def check_box(scene: Scene, problems: Problems):
    """A periodic box must be wider than any pair of blobs can reach (r_a + r_b + the broad phase's
    margin, at most 2.5 r_max) twice over, so that the nearest image of a blob is the only one that
    can touch another; and of at most MAX_BOX_CELLS cells of the broad phase's grid (core/broad_phase.c:
    periodic_grid), each 2 r_max (1 + margin) wide, r_max the largest radius of a blob when it is smallest (a
    scale schedule's least factor), whatever the box is (a periodic schedule's keyframes too)."""
    radii = _radii(scene)
    largest = max(radii)
    if min(scene.settings.periodic) < PERIODIC_SIDE * largest:
        problems.add(("scene", "periodic"), f"each side must be at least {PERIODIC_SIDE:g} × the largest blob's "
                     f"radius ({PERIODIC_SIDE * largest:.4g} m)", list(scene.settings.periodic))
    for i, s in enumerate(scene.schedules):  # (a scheduled scale may grow the blobs on top: not checked)
        if s.key == "scene.periodic" and min(min(row[1:]) for row in s.at) < PERIODIC_SIDE * largest:
            problems.add(("schedule", i, "at"), f"box sides must be at least {PERIODIC_SIDE:g} × the largest blob's "
                         f"radius ({PERIODIC_SIDE * largest:.4g} m)", show_got=False)
    r_max = max(r * min([1.0] if not keys else [f for f, _, _ in keys]) for r, keys in zip(radii, _scales(scene)))
    cell = 2.0 * r_max * (1.0 + BROAD_MARGIN)  # (r_max >= MIN_LENGTH: check_scales)
    boxes = [(("scene", "periodic"), scene.settings.periodic)]
    boxes += [(("schedule", i, "at", j), row[1:]) for i, s in enumerate(scene.schedules) if s.key == "scene.periodic"
              for j, row in enumerate(s.at)]
    for path, (lx, ly) in boxes:
        nx, ny = max(1, math.floor(lx / cell)), max(1, math.floor(ly / cell))
        if nx * ny > MAX_BOX_CELLS:
            problems.add(path, f"the box is {nx:,} × {ny:,} cells of the broad phase's grid (each {cell:.4g} m, 2.5 × "
                         f"the largest blob's radius); at most {MAX_BOX_CELLS:,} cells", [lx, ly])
            return


def run_length_problems(scene: Scene) -> list[tuple[tuple, str]]:
    """(key path, message) for a run too long to finish or a step too long to interrupt."""
    s, out = scene.settings, []
    steps = s.steps if s.steps is not None else (s.duration or DEFAULT_DURATION) / s.dt
    if steps > MAX_STEPS:
        out.append((("scene", "duration"), f"duration / dt is {steps:.3g} steps; at most {MAX_STEPS:,}"))
    work = s.substeps * s.iterations * scene.vertex_count
    if work > MAX_STEP_WORK:
        out.append((("scene", "iterations"), f"substeps × iterations × vertices is {work:,} per step; at most "
                    f"{MAX_STEP_WORK:,}, so that a step stays interruptible"))
    return out


def with_overrides(scene: Scene, *, steps=None, duration=None, method=None) -> Scene:
    """The scene with command-line overrides applied; SceneError if the run they ask for is too long."""
    s = scene.settings
    if steps is not None:
        s = replace(s, steps=steps, duration=None)
    if duration is not None:
        s = replace(s, duration=duration, steps=None)
    if method is not None:
        s = replace(s, method=method)
    scene = replace(scene, settings=s)
    problems = [f"{scene.source}: {'--steps' if steps is not None else '--duration'}: {message}"
                for _, message in run_length_problems(scene)]
    if problems:
        raise SceneError(problems)
    return scene
