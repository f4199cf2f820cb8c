"""Schedules: blob properties and gravity that change in time ([[schedule]] tables).

Each is linear between its keyframes, holds the first before them and the last after (np.interp), and
is applied at the start of each step, t = step × dt: a function of the step alone, so a resumed run
takes the same values as an uninterrupted one. The model stays as the scene built it; the step reads
`Schedules.arrays`, the model's arrays with its own copies of those a schedule changes:

    mass m:        inv_mass of each vertex = n / m (n vertices)
    pressure p, scale s:  target_area = p × rest_area × s²; rest edge lengths and perimeter × s
    friction, static_friction, restitution: the blob's material (combined at each contact as before)
    force [Fx, Fy], torque τ: the blob's row of `driving` (core/driving.h); the value at t = step × dt
        acts through the whole step, so the impulse a schedule gives is the sum of its values × dt: for keyframes
        at multiples of dt, the area under the keyframes' line less (last − first) dt / 2 (a pulse from 0 to 0:
        exactly its area)
    adhesion: the blob's row of `adhesion` (core/adhesion.c): sticky from the step it is above 0, free from the step
        it is 0 again
    scene.gravity: the step's settings (g, "up", the rest speed of restitution)
    scene.periodic: the periodic box's sides L; when they change, each blob moves with the box, its centre
        c remapped affinely, c <- c L_new / L_old (the whole blob shifted, not stretched; velocities kept:
        LAMMPS' `fix deform` with `remap x` does the same to its atoms)
    scene.shear: the box's Lees–Edwards shear strain γ: the row of images above is shifted along x by
        γ L_y, and when γ changes by Δγ each blob's centre moves affinely, c_x <- c_x + Δγ c_y: quasi-static
        simple shear, strain-controlled (the same remap)

A blob whose properties change is woken, every blob when gravity or the box does (a sleeping blob would
not feel it).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..scene.schema import Scene, expanded_names, schedule_targets
from .model import Model, Params
from .pipeline import StepSettings, settings

MATERIAL_COLUMN = {"static_friction": 0, "friction": 1, "restitution": 2}  # of Model.material
DRIVING_COLUMNS = {"force": [0, 1], "torque": [2]}  # of Model.driving


class Schedules:
    """The scene's schedules, and the arrays they write."""

    def __init__(self, scene: Scene, model: Model, params: Params):
        names = expanded_names(scene.blobs)
        self.model, self.params = model, params
        self.blob_items = []  # (key, blob indices, times, values)
        self.gravity = None  # (times, gx values, gy values)
        self.box = None  # (times, Lx values, Ly values)
        self.shear = None  # (times, γ values)
        self.current_shear = None  # γ of the latest step applied (None: no step yet)
        self.current_box = None  # the box of the latest step applied (None: no step yet)
        for s in scene.schedules:
            at = np.array(s.at)
            if s.key == "scene.gravity":
                self.gravity = (at[:, 0], at[:, 1], at[:, 2])
            elif s.key == "scene.periodic":
                self.box = (at[:, 0], at[:, 1], at[:, 2])
            elif s.key == "scene.shear":
                self.shear = (at[:, 0], at[:, 1])
            else:  # values: (K,), or (K, 2) for a force
                self.blob_items.append((s.blob_key, np.array(schedule_targets(s, names), np.int64), at[:, 0],
                                        at[:, 1] if s.blob_key != "force" else at[:, 1:]))
        a = model.arrays
        self.pressure = model.target_area / model.rest_area  # (B,): as the scene wrote it
        self.scale = np.ones(model.blob_count)
        self.arrays = a._replace(inv_mass=a.inv_mass.copy(), rest_length=a.rest_length.copy(),
                                 rest_perimeter=a.rest_perimeter.copy(), target_area=a.target_area.copy(),
                                 material=a.material.copy(), driving=a.driving.copy(), adhesion=a.adhesion.copy())

    def __bool__(self) -> bool:
        return bool(self.blob_items) or any(x is not None for x in (self.gravity, self.box, self.shear))

    def apply(self, step: int, step_settings: StepSettings, state) -> StepSettings:
        """Write every scheduled value at t = step × dt; return the step's settings (gravity). A blob whose
        properties change is woken (a growing blob is not at rest, though its centre stays put)."""
        t = step * self.params.dt
        m, a = self.model, self.arrays
        counts = np.diff(m.offsets)
        for key, blobs, times, values in self.blob_items:
            if key in DRIVING_COLUMNS:
                v = [np.interp(t, times, column) for column in values.reshape(len(times), -1).T]
                if v != [np.interp((step - 1) * self.params.dt, times, column)
                         for column in values.reshape(len(times), -1).T]:
                    state.awake[blobs] = 1
                    state.still[blobs] = 0.0
                a.driving[np.ix_(blobs, DRIVING_COLUMNS[key])] = v
                continue
            v = float(np.interp(t, times, values))
            if v != float(np.interp((step - 1) * self.params.dt, times, values)):
                state.awake[blobs] = 1
                state.still[blobs] = 0.0
            if key in MATERIAL_COLUMN:
                a.material[blobs, MATERIAL_COLUMN[key]] = v
                continue
            if key == "adhesion":
                a.adhesion[blobs] = v
                continue
            if key == "mass":
                for b in blobs:
                    a.inv_mass[m.offsets[b]:m.offsets[b + 1]] = counts[b] / v
                continue
            if key == "pressure":
                self.pressure[blobs] = v
            else:  # scale
                self.scale[blobs] = v
                for b in blobs:
                    o, e = m.offsets[b], m.offsets[b + 1]
                    a.rest_length[o:e] = m.rest_length[o:e] * v
                a.rest_perimeter[blobs] = m.rest_perimeter[blobs] * v
            a.target_area[blobs] = self.pressure[blobs] * m.rest_area[blobs] * self.scale[blobs] ** 2
        if self.gravity is None and self.box is None and self.shear is None:
            return step_settings
        params = self.params
        if self.shear is not None and self.current_shear is None:  # this run's first step: the strain it was left in
            times, values = self.shear
            self.current_shear = float(np.interp((step - 1) * self.params.dt, times, values)) if step > 0 else 0.0
        if self.gravity is not None:
            params = replace(params, gravity=self._at(step, self.gravity, state))
        if self.box is not None:
            box = self._at(step, self.box, state)
            if self.current_box is None:  # the first step of this run: the box the state was left in
                times, x, y = self.box
                before = (step - 1) * self.params.dt
                self.current_box = (np.array([np.interp(before, times, x), np.interp(before, times, y)]) if step > 0
                                    else np.array(self.params.box, dtype=np.float64))
            if np.any(box != self.current_box):
                carry_blobs(state, m.offsets, box_map(self.current_box, box, self.current_shear or 0.0))
            self.current_box = box
            params = replace(params, box=(float(box[0]), float(box[1])))
        if self.shear is not None:
            times, values = self.shear
            gamma = float(np.interp(step * self.params.dt, times, values))
            if gamma != self.current_shear:
                carry_blobs(state, m.offsets, np.array([[1.0, gamma - self.current_shear], [0.0, 1.0]]))
                state.awake[:] = 1
                state.still[:] = 0.0
            self.current_shear = gamma
            params = replace(params, shear=gamma)
        return settings(m, params)

    def _at(self, step, keyframes, state) -> np.ndarray:
        """A two-valued schedule's values at t = step × dt; every blob is woken when they change."""
        times, x, y = keyframes
        t, before = step * self.params.dt, (step - 1) * self.params.dt
        now = np.array([np.interp(t, times, x), np.interp(t, times, y)])
        if now[0] != np.interp(before, times, x) or now[1] != np.interp(before, times, y):
            state.awake[:] = 1
            state.still[:] = 0.0
        return now


def target_areas(scene: Scene, steps) -> np.ndarray:
    """(frames, B) m²: each blob's target area at each of these steps, as the scene's schedules set it for the
    step that ended there (step 0: the scene's own): what a recorded frame's area is to be measured against."""
    from .model import build, build_params
    model, state = build(scene)  # a throwaway state: applying a schedule may wake or move its blobs
    schedules = Schedules(scene, model, build_params(scene))
    out = np.empty((len(steps), model.blob_count))
    for k, n in enumerate(steps):
        if n > 0:
            schedules.apply(int(n) - 1, None, state)
        out[k] = np.abs(schedules.arrays.target_area)
    return out


def carry_blobs(state, offsets, F) -> None:
    """Move each blob whole with an affine map of the box: its centre c (vertex average) to F c, F (2, 2)."""
    counts = np.diff(offsets)
    centre = np.add.reduceat(state.pos, offsets[:-1], axis=0) / counts[:, None]
    state.pos[...] += np.repeat(centre @ F.T - centre, counts, axis=0)


def box_map(old, new, gamma) -> np.ndarray:
    """F carrying the old box's vectors e_1 = (L_x, 0), e_2 = (γ L_y, L_y) to the new ones, r = new / old:
    c_x <- r_x c_x + γ (r_y - r_x) c_y, c_y <- r_y c_y (c <- c new / old when γ = 0)."""
    r = new / old
    return np.array([[r[0], gamma * (r[1] - r[0])], [0.0, r[1]]])
