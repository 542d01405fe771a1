"""Joint refinement and the mass-matrix consistency check."""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.consistency import check_consistency, mass_matrices
from identification.calibration.refinement import RefinementBlock, RefinementOptions, refine_parameters
from identification.data.recording import Recording
from identification.friction.models import LuGreParameters
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.oracle import PinocchioOracle


def test_mass_matrices_match_crba(denso, denso_model, rng):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    q = rng.uniform(denso.q_min, denso.q_max, (5, denso.n_dof))
    np.testing.assert_allclose(mass_matrices(denso_model, theta, q), PinocchioOracle(denso).crba(q), atol=1e-9)


def test_consistency_check(denso, denso_model):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    good = check_consistency(denso_model, theta, denso.q_min, denso.q_max, n_samples=50)
    assert good.consistent and good.min_eigenvalue > 0
    standard = denso.nominal_dynamic_parameters().copy()
    standard[5, 10] = -0.5  # negative rotor inertia of joint 6: D66 < 0
    bad = check_consistency(denso_model, denso_model.base_parameters(standard), denso.q_min, denso.q_max, n_samples=50)
    assert not bad.consistent and bad.n_violations == 50
    with pytest.raises(ShapeError, match="theta"):
        check_consistency(denso_model, theta[:3], denso.q_min, denso.q_max)
    with pytest.raises(ParameterError, match="n_samples"):
        check_consistency(denso_model, theta, denso.q_min, denso.q_max, n_samples=0)


def _synthetic_block(denso, lugre, seed):
    """Sliding-only motion with exact derivatives; tau = RNEA + steady-state (Stribeck) friction."""
    t = np.arange(0.0, 6.0, 0.02)
    rng = np.random.default_rng(seed)
    n = denso.n_dof
    w = 2 * np.pi * rng.uniform(0.2, 0.6, n)
    a = rng.uniform(0.2, 0.4, n)
    q = a * np.sin(np.outer(t, w))
    qd = a * w * np.cos(np.outer(t, w))
    qdd = -a * w**2 * np.sin(np.outer(t, w))
    friction = np.column_stack([p.steady_state(qd[:, j]) for j, p in enumerate(lugre)])
    tau = PinocchioOracle(denso).rnea(q, qd, qdd) + friction
    return RefinementBlock(Recording(t=t, q=q, tau=tau, qd=qd, qdd=qdd, name=f"block{seed}"))


def test_refinement_recovers_perturbed_parameters(denso, denso_model):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    blocks = [_synthetic_block(denso, lugre, s) for s in (1, 2)]
    rng = np.random.default_rng(7)
    start_theta = theta * (1 + 0.05 * rng.standard_normal(theta.size))
    start_lugre = tuple(LuGreParameters(**{**p.as_dict(), "fc": 1.1 * p.fc, "fv": 0.9 * p.fv}) for p in lugre)
    kt = np.ones(denso.n_dof)
    result = refine_parameters(
        denso_model,
        blocks,
        start_theta,
        kt,
        start_lugre,
        RefinementOptions(min_speed=0.05, refine_friction=True, refine_gravity=True),
    )
    assert result.status == "Solve_Succeeded"
    assert result.objective_final < 1e-8 * max(result.objective_initial, 1.0)
    for p, t in zip(result.lugre, lugre):
        assert p.fc == pytest.approx(t.fc, rel=1e-3) and p.fv == pytest.approx(t.fv, rel=1e-3)
    predicted = [
        denso_model.inverse_dynamics(b.recording.q, b.recording.qd, b.recording.qdd, result.theta) for b in blocks
    ]
    expected = [denso_model.inverse_dynamics(b.recording.q, b.recording.qd, b.recording.qdd, theta) for b in blocks]
    np.testing.assert_allclose(np.vstack(predicted), np.vstack(expected), atol=1e-4)


def test_refinement_holds_gravity_friction_and_kt_by_default(denso, denso_model):
    """Default: only the inertial base parameters move; gravity part, Kt and friction stay at the step values."""
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    blocks = [_synthetic_block(denso, lugre, s) for s in (1, 2)]
    mask = denso_model.gravity_mask
    start_theta = theta * np.where(mask, 1.0, 1 + 0.05 * np.random.default_rng(3).standard_normal(theta.size))
    result = refine_parameters(
        denso_model, blocks, start_theta, np.ones(denso.n_dof), lugre, RefinementOptions(min_speed=0.05)
    )
    np.testing.assert_array_equal(result.theta[mask], start_theta[mask])
    assert result.lugre == lugre and np.all(result.kt == 1.0)
    np.testing.assert_allclose(result.theta[~mask], theta[~mask], rtol=1e-3, atol=1e-5)


def test_refinement_errors(denso, denso_model):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    with pytest.raises(ParameterError, match="blocks"):
        refine_parameters(denso_model, [], theta, np.ones(6), lugre)
    block = _synthetic_block(denso, lugre, 1)
    with pytest.raises(ShapeError, match="theta"):
        refine_parameters(denso_model, [block], theta[:4], np.ones(6), lugre)
    with pytest.raises(ParameterError, match="lugre"):
        refine_parameters(denso_model, [block], theta, np.ones(6), lugre[:2])
    with pytest.raises(ParameterError, match="consistency"):
        RefinementOptions(consistency="maybe")


def test_a_parameter_the_refinement_rows_do_not_touch_is_held_not_refused(caplog):
    from identification.calibration import refinement

    class _Model:
        n_dof, gravity_mask, base_names = 1, np.array([False, False]), ("theta1", "theta2")
        parameter_map = np.ones((2, 11))

    class _Rows:
        weight = np.ones(50)
        y = np.column_stack([np.sin(np.linspace(0, 6, 50)), np.zeros(50)])  # theta2 never appears
        current = np.zeros(50)
        direct = np.ones(50)

    options = refinement.RefinementOptions(refine_kt=False)
    with caplog.at_level("INFO", logger="identification.calibration.refinement"):
        refinement._check_excited(_Model(), [_Rows()], np.ones(1), options, refinement.thresholds_of("t", None))
    assert "theta2 not in the refinement's rows" in caplog.text
