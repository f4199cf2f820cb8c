"""The perimeter stage (core/perimeter.c: bc_solve_perimeter) against its equations written again here, in
Python floats, operation for operation: the stage's loops run on vector registers, and must give the bits of
the scalar equations."""

import math

import numpy as np
import pytest
from conftest import Stage, scene

from blobcli import build, build_params
from blobcli.sim import pipeline

SWEEPS, TOTAL_STEP = 2, 0.4  # core/perimeter.c


def perimeter_twin(x, y, rest, lam, w, alpha, total_rest, total_alpha, total_lam):
    """One ring through the stage: SWEEPS Jacobi sweeps of XPBD edge steps, each from the same positions, then the
    total-length step. Lists x, y, lam are updated in place; returns the total length's λ."""
    n = len(x)
    inv_weight = 1.0 / (w + w + alpha)
    for _ in range(SWEEPS):
        g = []
        for i in range(n):
            j = (i + 1) % n
            dx, dy = x[j] - x[i], y[j] - y[i]
            length = math.sqrt(dx * dx + dy * dy)
            if length == 0.0:  # no direction: moves nothing, keeps its λ
                g.append((0.0, 0.0))
                continue
            dlam = (-(length - rest[i]) - alpha * lam[i]) * inv_weight
            lam[i] += dlam
            scale = dlam / length
            g.append((scale * dx, scale * dy))
        for k in range(n):  # g[-1] is the closing edge's
            x[k] += w * (g[k - 1][0] - g[k][0])
            y[k] += w * (g[k - 1][1] - g[k][1])
    units, lengths = [], []
    for i in range(n):
        j = (i + 1) % n
        dx, dy = x[j] - x[i], y[j] - y[i]
        length = math.sqrt(dx * dx + dy * dy)
        inv = 1.0 / length if length else 1.0
        units.append((dx * inv, dy * inv))
        lengths.append(length)
    C, weight, steepest = -total_rest, 0.0, 0.0
    for i in range(n):
        gx, gy = units[i - 1][0] - units[i][0], units[i - 1][1] - units[i][1]
        C += lengths[i]
        g2 = gx * gx + gy * gy
        weight += w * g2
        steepest = max(steepest, g2)
    steepest = w * math.sqrt(steepest)
    dlam = (-C - total_alpha * total_lam) / (weight + total_alpha)
    most = TOTAL_STEP * total_rest / n
    if abs(dlam) * steepest > most:
        dlam = math.copysign(most / steepest, dlam)
    for i in range(n):
        x[i] += w * dlam * (units[i - 1][0] - units[i][0])
        y[i] += w * dlam * (units[i - 1][1] - units[i][1])
    return total_lam + dlam


@pytest.mark.parametrize("vertices, coincide", [(12, False), (37, False), (37, True), (130, True)])
def test_perimeter_stage_gives_the_bits_of_its_equations(vertices, coincide):
    """A stretched, wobbled ring with multipliers already set (a later iteration's), of lengths that leave
    vector remainders (37, 130); with two vertices at one point where `coincide`: that edge moves nothing and keeps
    its λ in the first sweep, and nothing becomes NaN."""
    sc = scene(f"[[blob]]\ncenter = [0.3, -0.2]\nradius = 1.0\nvertices = {vertices}\n")
    model, state = build(sc)
    rng = np.random.default_rng(vertices)
    state.position[...] = 1.05 * state.position + rng.normal(0.0, 0.01, state.position.shape)
    state.lam[:] = rng.normal(0.0, 1e-3, vertices)
    state.perimeter_lam[:] = 2e-3
    if coincide:
        state.position[:, 5] = state.position[:, 4]
    x, y, lam = list(state.position[0]), list(state.position[1]), list(state.lam)
    h = 1.0 / 240.0
    w, alpha = float(model.inv_mass[0]), float(model.compliance[0]) / (h * h)
    total_lam = perimeter_twin(x, y, list(model.rest_length), lam, w, alpha, float(model.rest_perimeter[0]),
                               float(model.compliance[0]) * vertices / (h * h), 2e-3)
    Stage(model, state, step_settings=pipeline.settings(model, build_params(sc)), scratch=True).call(
        "solve_perimeter", h)
    assert np.isfinite(state.position).all() and np.isfinite(state.lam).all()
    assert np.array_equal(state.position[0], x) and np.array_equal(state.position[1], y)
    assert np.array_equal(state.lam, lam) and state.perimeter_lam[0] == total_lam
