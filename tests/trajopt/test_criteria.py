"""Criteria: true cond against numpy, stacked regressor against an analytic regressor, gradients against FD."""

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.errors import ParameterError, ShapeError
from tests.trajopt.conftest import planar_regressor_numpy
from trajopt.criteria import (
    CriterionCallback,
    build_information_function,
    check_columns,
    condition_number,
    criterion_gradient,
    criterion_value,
    stack_regressor,
)


def _spd(rng, n=5, spread=3.0):
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (q * np.logspace(0, spread, n)) @ q.T


def test_condition_number_matches_numpy(rng):
    y = rng.standard_normal((40, 6)) * np.logspace(0, 2, 6)
    assert condition_number(y) == pytest.approx(np.linalg.cond(y), rel=1e-12)


def test_condition_number_rank_deficient_is_inf(rng):
    y = rng.standard_normal((10, 3))
    y[:, 2] = 0
    assert condition_number(y) == float("inf")
    with pytest.raises(ShapeError, match="regressor_stack"):
        condition_number(np.ones((2, 3)))


def test_stack_regressor_matches_analytic(planar_regressor, rng):
    q, qd, qdd = (rng.standard_normal((7, 2)) for _ in range(3))
    expected = planar_regressor_numpy(q, qd, qdd)
    np.testing.assert_allclose(stack_regressor(planar_regressor, q, qd, qdd), expected.reshape(14, 5), atol=1e-12)
    np.testing.assert_allclose(
        stack_regressor(planar_regressor, q, qd, qdd, columns=[0, 2]), expected[:, :, [0, 2]].reshape(14, 2), atol=1e-12
    )


def test_information_function_is_gram_of_columns(planar_regressor, rng):
    q, qd, qdd = (rng.standard_normal(2) for _ in range(3))
    scale = np.array([2.0, 0.5, 3.0])
    info = build_information_function(planar_regressor, [0, 1, 2], scale)
    y = planar_regressor_numpy(q, qd, qdd)[0][:, :3] * scale
    np.testing.assert_allclose(np.asarray(info(q, qd, qdd)), y.T @ y, atol=1e-12)


@pytest.mark.parametrize("criterion", ["cond", "logdet"])
def test_gradient_matches_finite_differences(criterion, rng):
    f = _spd(rng)
    grad = criterion_gradient(criterion, f, 8.0)
    direction = _spd(rng, spread=0.5)
    h = 1e-6
    plus, minus = (criterion_value(criterion, f + s * h * direction, 8.0) for s in (1, -1))
    fd = (plus - minus) / (2 * h)
    assert np.sum(grad * direction) == pytest.approx(fd, rel=1e-5)


def test_cond_surrogate_bounds_and_limit(rng):
    f = _spd(rng, n=6, spread=4.0)
    log_cond2 = np.log(np.linalg.cond(f))  # = 2 log cond(Y) for F = Y^T Y
    values = [criterion_value("cond", f, p) for p in (2.0, 8.0, 32.0, 128.0)]
    assert all(0 <= v <= log_cond2 + 1e-12 for v in values)
    assert values == sorted(values)
    assert log_cond2 - values[-1] <= 2 * np.log(6) / 128 + 1e-12
    assert criterion_value("cond", np.eye(4) * 3.0, 16.0) == pytest.approx(0.0, abs=1e-12)


def test_callback_jacobian_matches_gradient(rng):
    f = _spd(rng, n=4)
    cb = CriterionCallback("cond", 4)
    fs = ca.MX.sym("F", 4, 4)
    jac = ca.Function("j", [fs], [ca.jacobian(cb(fs, 16.0), fs)])
    got = np.asarray(jac(f)).reshape(4, 4, order="F")
    np.testing.assert_allclose(got, criterion_gradient("cond", f, 16.0), rtol=1e-10, atol=1e-14)
    assert float(cb(f, 16.0)) == pytest.approx(criterion_value("cond", f, 16.0))


def test_column_and_criterion_errors():
    with pytest.raises(ParameterError, match="columns"):
        check_columns([0, 7], 5)
    with pytest.raises(ParameterError, match="columns"):
        check_columns([1, 1], 5)
    with pytest.raises(ShapeError, match="columns"):
        check_columns(np.array([True, False]), 5)
    np.testing.assert_array_equal(check_columns(np.array([True, False, True]), 3), [0, 2])
    with pytest.raises(ParameterError, match="criterion"):
        criterion_value("aopt", np.eye(2))


def test_stack_regressor_matches_psdm_model_numpy(planar_robot, rng):
    derive = pytest.importorskip("psdm_casadi.derive")
    symbolic = pytest.importorskip("psdm_casadi.symbolic")
    model = derive.derive_psdm(planar_robot, seed=0)
    regressor = symbolic.build_functions(model).regressor
    q, qd, qdd = (rng.standard_normal((9, 2)) for _ in range(3))
    columns = np.flatnonzero(~model.gravity_mask)
    expected = model.regressor(q, qd, qdd)[:, :, columns].reshape(-1, columns.size)
    np.testing.assert_allclose(
        stack_regressor(regressor, q, qd, qdd, ~model.gravity_mask), expected, rtol=1e-10, atol=1e-10
    )
