"""Friction models: LuGre numeric simulation against independent references, CasADi against numpy."""

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from identification.friction.expressions import build_lugre_expressions
from identification.friction.lugre_step import lugre_step_coefficients, phi_function_expressions, phi_functions
from identification.friction.models import (
    LUGRE_PARAMETER_NAMES,
    CoulombViscous,
    LuGreParameters,
    Stribeck,
    check_friction_data,
)
from identification.friction.simulation import lugre_torque, simulate_lugre, simulated_mse
from identification.metrics import rms, rmse
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.robot import DriveParameters
from tests.identification.friction_signal import denso_truth, sine_series

TRUTH = dict(fc=9.593, fs=12.51, vs=0.0144, fv=23.67, dv=0.6091, sigma0=288499.0, sigma1=22.79)


@pytest.fixture
def rng():
    return np.random.default_rng(20260522)


# -- parameters -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", LUGRE_PARAMETER_NAMES)
def test_negative_parameter_is_rejected_with_its_name(name):
    values = dict(TRUTH, **{name: -1.0})
    with pytest.raises(ParameterError, match=f"LuGreParameters.{name}"):
        LuGreParameters(**values)


@pytest.mark.parametrize("name", ["fc", "sigma0", "vs"])
def test_nan_parameter_is_rejected(name):
    with pytest.raises(ParameterError, match=name):
        LuGreParameters(**dict(TRUTH, **{name: float("nan")}))


def test_drive_round_trip_and_array_order():
    drive = DriveParameters(kt=36.07, **TRUTH)
    p = LuGreParameters.from_drive(drive)
    assert p.to_drive(36.07) == drive
    np.testing.assert_array_equal(p.as_array(), [TRUTH[n] for n in LUGRE_PARAMETER_NAMES])
    assert LuGreParameters.from_array(p.as_array()) == p
    with pytest.raises(ShapeError, match="values"):
        LuGreParameters.from_array(np.ones(6))
    with pytest.raises(ParameterError, match="drive"):
        LuGreParameters.from_drive(TRUTH)


def test_denso_file_holds_table2_values():
    p, _ = denso_truth(0)
    for name, value in TRUTH.items():
        assert getattr(p, name) == pytest.approx(value, rel=1e-3)


def test_steady_models():
    cv = CoulombViscous(fc=1.0, fv=2.0, dv=0.5)
    np.testing.assert_allclose(cv.torque([-4.0, 0.0, 0.25]), [-5.0, 0.0, 2.0])
    s = Stribeck(fc=1.0, fs=3.0, vs=0.1, fv=2.0, dv=1.0)
    assert s.torque(1e-9) == pytest.approx(3.0)
    assert s.torque(-0.1) == pytest.approx(-(1.0 + 2.0 * np.exp(-1.0) + 0.2))
    assert s.torque(10.0) == pytest.approx(21.0)
    with pytest.raises(ParameterError, match="Stribeck.vs"):
        Stribeck(fc=1.0, fs=3.0, vs=0.0, fv=2.0)
    with pytest.raises(ParameterError, match="CoulombViscous.dv"):
        CoulombViscous(fc=1.0, fv=2.0, dv=0.0)


# -- numeric simulation -------------------------------------------------------------------------
@pytest.mark.parametrize("joint", [0, 3, 5])  # joint 6 has fs < fc
def test_steady_state_equals_stribeck_curve(joint):
    p, _ = denso_truth(joint)
    for v in (-2.0, -0.05, -p.vs, 0.3 * p.vs, p.vs, 3 * p.vs, 1.5):
        t = np.arange(0.0, 3.0, 1e-3)  # slowest relaxation: 40 ms at 0.3 vs on joint 6
        tau, z = simulate_lugre(p, t, np.full(t.size, v))
        assert tau[-1] == pytest.approx(float(p.steady_state(v)), rel=1e-9)
        assert z[-1] == pytest.approx(np.sign(v) * float(p.stribeck().breakaway(v)) / p.sigma0, rel=1e-9)


def _reference_solution(p, qd_fun, t):
    """Continuous LuGre (eq. 12) with the analytic velocity, stiff BDF solver at tight tolerances."""

    def rhs(time, z):
        v = qd_fun(time)
        g = p.fc + (p.fs - p.fc) * np.exp(-((v / p.vs) ** 2))
        return [v - p.sigma0 * abs(v) * z[0] / g]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0], method="Radau", t_eval=t, rtol=1e-10, atol=1e-13, max_step=2e-4)
    return sol.y[0]


def test_simulation_matches_stiff_ode_solver():
    p, _ = denso_truth(0)  # sigma0 = 2.9e5 N m/rad: the stiffest joint
    f, amp = 5.0, 3.0 * p.fc / p.sigma0  # hysteresis loops crossing into sliding
    w = 2 * np.pi * f
    t = np.arange(0.0, 0.6, 1e-3)

    def qd_fun(time):
        return amp * w * np.sin(w * time) + 0.02 * np.sin(2 * np.pi * 3 * time)

    qd = np.array([qd_fun(x) for x in t])
    z_ref = _reference_solution(p, qd_fun, t)
    tau_ref = lugre_torque(p, qd, p.sigma0 * z_ref)
    tau, z = simulate_lugre(p, t, qd)  # one step per 1 ms sample
    assert rmse(tau, tau_ref) < 2e-3 * rms(tau_ref)
    assert np.max(np.abs(z - z_ref)) < 5e-3 * np.max(np.abs(z_ref))


def test_simulation_converges_at_second_order():
    p, qd_max = denso_truth(0)
    t, qd = sine_series(p, qd_max, frequency_scale=4.0)
    ref, _ = simulate_lugre(p, t, qd, substeps=128)
    errors = [rmse(simulate_lugre(p, t, qd, substeps=m)[0], ref) for m in (1, 2, 4)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 3.0), errors  # 4 for a second-order scheme
    assert errors[0] < 1e-2 * rms(ref)  # on a signal 4x faster than the benchmark experiment's


def test_stiff_case_stays_bounded():
    p = LuGreParameters(fc=1.0, fs=1.2, vs=0.01, fv=1.0, dv=1.0, sigma0=3e5, sigma1=10.0)
    t = np.arange(0.0, 2.0, 1e-3)
    qd = 4.0 * np.sin(2 * np.pi * 3 * t)  # rate sigma0 |qd| / g up to 1.2e6 1/s, 1 ms steps
    tau, z = simulate_lugre(p, t, qd)
    assert np.all(np.isfinite(tau))
    assert np.max(np.abs(z)) <= p.fs / p.sigma0 * (1 + 1e-12)


def test_simulation_rejects_bad_inputs():
    p = LuGreParameters(**TRUTH)
    t = np.arange(5) * 1e-3
    with pytest.raises(ParameterError, match="qd"):
        simulate_lugre(p, t, np.array([0.0, np.nan, 0.0, 0.0, 0.0]))
    with pytest.raises(ShapeError, match="qd"):
        simulate_lugre(p, t, np.zeros(4))
    with pytest.raises(ParameterError, match="t must be strictly increasing"):
        simulate_lugre(p, t[::-1], np.zeros(5))
    with pytest.raises(ParameterError, match="substeps"):
        simulate_lugre(p, t, np.zeros(5), substeps=0)
    with pytest.raises(ParameterError, match="parameters"):
        simulate_lugre(TRUTH, t, np.zeros(5))
    with pytest.raises(ShapeError, match="tau"):
        check_friction_data(t, np.zeros(5), np.zeros(6))


def test_inputs_are_not_mutated():
    p = LuGreParameters(**TRUTH)
    t = np.arange(100) * 1e-3
    qd = np.sin(t)
    before = qd.copy()
    simulate_lugre(p, t, qd)
    np.testing.assert_array_equal(qd, before)


def test_simulated_mse_is_the_mean_squared_simulation_error():
    p = LuGreParameters(**TRUTH)
    t = np.arange(200) * 1e-3
    qd = 0.3 * np.sin(2 * np.pi * 4 * t)
    tau = simulate_lugre(p, t, qd)[0] + 0.1
    assert simulated_mse(p, t, qd, tau) == pytest.approx(0.01, rel=1e-12)
    assert simulated_mse(p, t, qd, tau, substeps=4) == np.mean((simulate_lugre(p, t, qd, substeps=4)[0] - tau) ** 2)


# -- the exponential integrator ---------------------------------------------------------------------
def _phi_reference(x, offset):
    """phi1 (offset 1) or phi2 (offset 2) as the power series sum (-x)^k / (k + offset)!, x <= 1."""
    return sum((-x) ** k / math.factorial(k + offset) for k in range(30))


def test_phi_functions_numpy_and_casadi_agree_across_the_series_limit():
    x = np.concatenate([[0.0], np.logspace(-8, 2, 41), [1e-3 * (1 - 1e-12), 1e-3 * (1 + 1e-12)]])
    phi1, phi2 = phi_functions(x)
    small = x <= 1.0
    np.testing.assert_allclose(phi1[small], _phi_reference(x[small], 1), rtol=1e-12)
    np.testing.assert_allclose(phi2[small], _phi_reference(x[small], 2), rtol=1e-11)
    big = x[~small]
    np.testing.assert_allclose(phi1[~small], (1 - np.exp(-big)) / big, rtol=1e-14)
    np.testing.assert_allclose(phi2[~small], (big - 1 + np.exp(-big)) / big**2, rtol=1e-14)
    sym = ca.SX.sym("x")
    f = ca.Function("phi", [sym], list(phi_function_expressions(sym)))
    for value, a, b in zip(x, phi1, phi2):
        assert float(f(value)[0]) == pytest.approx(a, rel=1e-15) and float(f(value)[1]) == pytest.approx(b, rel=1e-15)


# -- CasADi pieces --------------------------------------------------------------------------------
def test_casadi_expressions_equal_numpy(rng):
    p = LuGreParameters(**TRUTH)
    f = build_lugre_expressions()
    pv = p.as_array()
    for _ in range(20):
        qd = rng.choice([-1, 1]) * 10 ** rng.uniform(-4, 0.5)
        z = rng.uniform(-1, 1) * p.fs / p.sigma0
        g = float(p.stribeck().breakaway(qd))
        zdot = qd - p.sigma0 * abs(qd) * z / g
        assert float(f.zdot(z, qd, pv)) == pytest.approx(zdot, rel=1e-12, abs=1e-15)
        assert float(f.torque(z, qd, pv)) == pytest.approx(float(lugre_torque(p, qd, p.sigma0 * z)), rel=1e-12)
        # one integrator step, same sign at both ends
        qd_end = qd * rng.uniform(0.2, 2.0)
        h = 10 ** rng.uniform(-5, -2)
        decay, gain = lugre_step_coefficients(p, h, qd, qd_end)
        s = p.sigma0 * z
        assert float(f.step(s, qd, qd_end, h, pv)) == pytest.approx(float(decay * s + gain), rel=1e-11, abs=1e-12)
    assert float(f.torque(0.0, 0.0, pv)) == 0.0  # viscous term is 0 at rest, no NaN
    mx = build_lugre_expressions(ca.MX)
    assert float(mx.torque(1e-5, 0.3, pv)) == pytest.approx(float(f.torque(1e-5, 0.3, pv)), rel=1e-12)
    with pytest.raises(ParameterError, match="symbol"):
        build_lugre_expressions(float)
