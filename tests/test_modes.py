"""tools/modes: the step linearized about a state at rest (its one-step Jacobian's eigenvalues and modes)."""

import numpy as np
import pytest
from conftest import scene

from blobcli.tools.modes import NEUTRAL, blob_shares, jacobian, leading_modes, main, settle, state_vector, step_map
from blobcli.tools.piles import FLOOR, SMALLEST

RESTING = "[scene]\nsleep = false\n" + SMALLEST["resting"] + FLOOR
FREE = """
[scene]
gravity = [0.0, 0.0]
[[blob]]
name = "free"
center = [0.0, 0.0]
radius = 0.5
vertices = 16
"""


def test_the_jacobian_predicts_how_a_small_disturbance_grows():
    """A disturbance along the leading real mode of J, run through the real step, grows or decays as λ^k (1%; 0.12%
    measured): J's columns are the step's derivatives in the state's own order, each from its own copy of the
    state. (After 3 s the blob has settled from its drop: a step changes the state by 4·10⁻⁵.)"""
    model, state, params = settle(scene(RESTING), 3.0)
    _, values, vectors = leading_modes(jacobian(model, state, params), 8)
    real = [k for k, value in enumerate(values) if abs(value.imag) < 1e-12]
    assert real, values
    value, mode = values[real[0]].real, np.real(vectors[:, real[0]])
    F = step_map(model, state, params)
    base, disturbed = state_vector(state), state_vector(state) + 1e-7 * mode / np.abs(mode).max()
    start = np.linalg.norm(disturbed - base)
    for _ in range(20):
        base, disturbed = F(base), F(disturbed)
    assert np.linalg.norm(disturbed - base) / start == pytest.approx(abs(value) ** 20, rel=0.01)


def test_a_free_blob_has_no_growing_mode():
    """Without gravity or contacts nothing grows: the rigid drift and spin are neutral (λ = 1), and the
    deformation decays (damping) or keeps its size"""
    model, state, params = settle(scene(FREE), 0.0)
    neutral, values, _ = leading_modes(jacobian(model, state, params), 4)
    assert neutral >= 3  # x, y, the turn
    assert np.abs(values).max() <= 1.0 + NEUTRAL


def test_settle_turns_each_blob_and_starts_it_at_rest():
    model, state, params = settle(scene(RESTING), 0.0, turn_deg=90.0)
    original = settle(scene(RESTING), 0.0)[1].pos
    centre = original.mean(axis=0)
    assert np.allclose(state.pos - centre, (original - centre) @ np.array([[0.0, 1.0], [-1.0, 0.0]]), atol=1e-12)
    assert not state.vel.any() and not params.sleep


def test_blob_shares_read_a_rolling_mode():
    """A rigid roll of velocity (-ω R, 0) and spin ω is read back as such, 0% deformed"""
    model, state, params = settle(scene(RESTING), 0.0)
    n = state.pos.shape[0]
    r = state.pos - state.pos.mean(axis=0)
    velocity = np.array([-0.45, 0.0]) + np.stack([-r[:, 1], r[:, 0]], axis=1)
    which, [(ux, uy, spin, deformed, _)] = blob_shares(model, state, np.concatenate([np.zeros(2 * n), velocity.ravel()]),
                                                    params.dt)
    assert which == "v" and (ux, uy, spin) == pytest.approx((-0.45, 0.0, 1.0)) and deformed < 1e-12


def test_the_tool_prints_modes_and_refuses_bad_settings(capsys, tmp_path):
    assert main(["--smallest", "resting", "--settle", "0.5", "--modes", "2"]) == 0
    out = capsys.readouterr().out
    assert "neutral modes" in out and out.count("per second") == 2
    assert "not at rest" in out  # 0.5 s after its drop the blob still sways
    assert main([str(tmp_path / "none.toml")]) == 2
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        main(["--smallest", "resting", "--modes", "0"])
    assert stop.value.code == 2
