"""Trajectory families: numpy against CasADi, derivatives against finite differences, paper eq. 22, rest-to-rest."""

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.errors import ParameterError, ShapeError
from trajopt.parametrization import FourierTrajectory, SumOfSinesTrajectory

FAMILIES = [
    FourierTrajectory(n_dof=3, n_harmonics=4, period=6.0),
    FourierTrajectory(n_dof=2, n_harmonics=3, period=5.0, rest_to_rest=True),
    SumOfSinesTrajectory(n_dof=3, n_terms=3, duration=6.0, frequency_min=0.3, frequency_max=3.0),
    SumOfSinesTrajectory(n_dof=2, n_terms=2, duration=5.0, rest_to_rest=True, ramp=1.0),
]


def _params(family, rng):
    return family.random_parameters(rng, center=np.linspace(-0.2, 0.3, family.n_dof))


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f"{type(f).__name__}-{f.rest_to_rest}")
def test_numpy_matches_casadi(family, rng):
    x = _params(family, rng)
    t = np.linspace(0, family.duration, 37)
    xs = ca.MX.sym("x", family.n_parameters)
    fn = ca.Function("f", [xs], list(family.symbolic(xs, t)))
    for numeric, symbolic in zip(family.evaluate(t, x), fn(x)):
        np.testing.assert_allclose(numeric, np.asarray(symbolic), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f"{type(f).__name__}-{f.rest_to_rest}")
def test_derivatives_match_finite_differences(family, rng):
    x = _params(family, rng)
    t = np.linspace(0.3, family.duration - 0.3, 25)
    h = 1e-5
    q_plus, qd_plus, _ = family.evaluate(t + h, x)
    q_minus, qd_minus, _ = family.evaluate(t - h, x)
    _, qd, qdd = family.evaluate(t, x)
    np.testing.assert_allclose((q_plus - q_minus) / (2 * h), qd, atol=1e-6)
    np.testing.assert_allclose((qd_plus - qd_minus) / (2 * h), qdd, atol=1e-5)


def test_fourier_is_periodic(rng):
    family = FourierTrajectory(n_dof=2, n_harmonics=5, period=4.0)
    x = _params(family, rng)
    start = family.evaluate([0.0, 4.0], x)
    for arr in start:
        np.testing.assert_allclose(arr[0], arr[1], atol=1e-12)


def test_fourier_rest_to_rest_constraints_vanish(rng):
    family = FourierTrajectory(n_dof=3, n_harmonics=4, period=8.0, rest_to_rest=True)
    x = _params(family, rng)
    _, qd, qdd = family.evaluate([0.0, 8.0], x)
    np.testing.assert_allclose(qd, 0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(family.equality(ca.DM(x))), 0, atol=1e-12)
    assert family.equality(ca.DM(x)).shape[0] == 2 * 3


def test_fourier_mean_is_offset(rng):
    family = FourierTrajectory(n_dof=2, n_harmonics=3, period=2.0)
    x = _params(family, rng)
    q, _, _ = family.evaluate(family.default_grid(400), x)
    np.testing.assert_allclose(q.mean(axis=0), family.offsets(x), atol=1e-12)


def test_sum_of_sines_is_paper_eq22(rng):
    family = SumOfSinesTrajectory(n_dof=2, n_terms=3, duration=5.0, offset=False)
    x = _params(family, rng)
    c = x.reshape(2, 9)
    t = np.linspace(0, 5, 11)
    expected = np.stack([sum(c[i, k] * np.sin(c[i, 3 + k] * t + c[i, 6 + k]) for k in range(3)) for i in range(2)], 1)
    np.testing.assert_allclose(family.evaluate(t, x)[0], expected, atol=1e-14)


def test_sum_of_sines_rest_to_rest_ends_at_rest(rng):
    family = SumOfSinesTrajectory(n_dof=2, n_terms=3, duration=6.0, rest_to_rest=True)
    x = _params(family, rng)
    q, qd, qdd = family.evaluate([0.0, 6.0], x)
    np.testing.assert_allclose(q, np.tile(family.offsets(x), (2, 1)), atol=1e-12)
    np.testing.assert_allclose(qd, 0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0, atol=1e-12)


def test_scale_joints_scales_motion_exactly(rng):
    for family in FAMILIES:
        x = _params(family, rng)
        scales = np.linspace(0.3, 0.9, family.n_dof)
        t = np.linspace(0, family.duration, 17)
        q, qd, qdd = family.evaluate(t, x)
        q2, qd2, qdd2 = family.evaluate(t, family.scale_joints(x, scales))
        offsets = family.offsets(x)
        np.testing.assert_allclose(q2 - offsets, (q - offsets) * scales, atol=1e-12)
        np.testing.assert_allclose(qd2, qd * scales, atol=1e-12)
        np.testing.assert_allclose(qdd2, qdd * scales, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(n_dof=0), "n_dof"),
        (dict(n_dof=2, n_harmonics=0), "n_harmonics"),
        (dict(n_dof=2, period=-1.0), "period"),
        (dict(n_dof=2, period=float("nan")), "period"),
    ],
)
def test_fourier_errors(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        FourierTrajectory(**kwargs)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(n_dof=2, n_terms=0), "n_terms"),
        (dict(n_dof=2, duration=0.0), "duration"),
        (dict(n_dof=2, frequency_min=2.0, frequency_max=1.0), "frequency_min"),
        (dict(n_dof=2, duration=4.0, ramp=3.0), "ramp"),
    ],
)
def test_sum_of_sines_errors(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        SumOfSinesTrajectory(**kwargs)


def test_wrong_parameter_length_names_layout():
    family = FourierTrajectory(n_dof=2, n_harmonics=2)
    with pytest.raises(ShapeError, match="n_parameters"):
        family.evaluate([0.0], np.zeros(3))
    assert len(family.parameter_names()) == family.n_parameters
