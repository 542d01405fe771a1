"""The four calibration steps against known synthetic truth (Pinocchio oracle), plus the estimator contract."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.estimator import Design, weighted_least_squares
from identification.calibration.friction_step import FrictionExperiment, FrictionIdentifier
from identification.calibration.payload import payload_static_torque, payload_torque
from identification.calibration.steps import (
    GravityIdentifier,
    InertialIdentifier,
    MotorExperiment,
    MotorIdentifier,
    fold_out_and_back,
)
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.data.recording import Recording
from identification.friction.models import LuGreParameters
from identification.friction.simulation import simulate_lugre
from identification.virtual.effects import Payload
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import NotFittedError, ParameterError, RecordingError, ShapeError
from psdm_casadi.oracle import PinocchioOracle
from trajopt import experiments

PAYLOAD = Payload(mass=2.0, com=(0.06, 0.04, 0.05))
NOISE_FREE = SimulationOptions(encoder_resolution=None, current_resolution=None, current_noise_std=0.0)


@pytest.fixture(scope="module")
def truth(denso, denso_model):
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    return theta, np.array([d.kt for d in denso.drives]), lugre


def _out_and_back(denso, rng, n=1201, duration=12.0):
    """An out-and-back path through random poses (q[k] == q[n-1-k]) with exact derivatives."""
    t = np.linspace(0.0, duration, n)
    s = 1.0 - np.abs(2.0 * t / duration - 1.0)  # 0 -> 1 -> 0
    a, b = rng.uniform(0.6 * denso.q_min, 0.6 * denso.q_max, (2, denso.n_dof))
    shape = 0.5 * (1 - np.cos(np.pi * s))
    q = a + np.outer(shape, b - a)
    qd = np.gradient(q, t, axis=0)
    return t, q, qd


@pytest.fixture(scope="module")
def motor_experiments(denso):
    out = []
    for j in (1, 4):
        rng = np.random.default_rng(j)
        from trajopt.experiments import choose_motor_pose

        pose = choose_motor_pose(
            denso, j, lambda q: payload_static_torque(denso, PAYLOAD, q), rng, n_candidates=8, range_fraction=0.15
        )
        ref = experiments.motor_experiment(denso, j, speed=0.8, range_fraction=0.15, pose=pose).reference()
        po = PreprocessOptions(cutoff_hz=4.0)
        nominal, _ = simulate_recording(denso, ref, NOISE_FREE)
        loaded, _ = simulate_recording(denso, ref, replace(NOISE_FREE, payload=PAYLOAD))
        out.append(
            MotorExperiment(j, fold_out_and_back(preprocess(nominal, po)), fold_out_and_back(preprocess(loaded, po)))
        )
    return out


@pytest.fixture(scope="module")
def gravity_recording(denso):
    """Folded jog: tau = Pinocchio gravity + Coulomb friction (odd in qd), which folding cancels."""
    t, q, qd = _out_and_back(denso, np.random.default_rng(3))
    tau = PinocchioOracle(denso).gravity(q) + 3.0 * np.sign(qd)
    return fold_out_and_back(Recording(t=t, q=q, tau=tau, qd=qd, qdd=np.zeros_like(q), name="jog"))


@pytest.fixture(scope="module")
def excitation(denso, truth):
    """Sum of sines with exact derivatives; tau = RNEA + LuGre friction of the true drives."""
    t = np.arange(0.0, 8.0, 0.01)
    rng = np.random.default_rng(4)
    n = denso.n_dof
    w = 2 * np.pi * rng.uniform(0.1, 0.6, (3, n))
    a = rng.uniform(0.1, 0.3, (3, n))
    ph = rng.uniform(0, 2 * np.pi, (3, n))
    arg = t[:, None, None] * w[None] + ph[None]
    q = (a * np.sin(arg)).sum(1)
    qd = (a * w * np.cos(arg)).sum(1)
    qdd = (-a * w**2 * np.sin(arg)).sum(1)
    _, _, lugre = truth
    friction = np.column_stack([simulate_lugre(p, t, qd[:, j])[0] for j, p in enumerate(lugre)])
    tau = PinocchioOracle(denso).rnea(q, qd, qdd) + friction
    return Recording(t=t, q=q, tau=tau, qd=qd, qdd=qdd, name="excitation")


def test_payload_static_torque_matches_pinocchio_rnea(denso, rng):
    q = rng.uniform(denso.q_min, denso.q_max, (6, denso.n_dof))
    zero = np.zeros_like(q)
    expected = payload_torque(denso, PAYLOAD, q, zero, zero)  # RNEA of a robot whose only body is the load
    np.testing.assert_allclose(payload_static_torque(denso, PAYLOAD, q), expected, atol=1e-12)
    assert np.abs(expected).max() > 1.0


def test_motor_recovers_kt_noise_free(denso, motor_experiments, truth):
    _, kt, _ = truth
    fit = MotorIdentifier(robot=denso, payload=PAYLOAD).fit(motor_experiments)
    for j in (1, 4):
        assert fit.kt_[j] == pytest.approx(kt[j], rel=2e-3)
    assert np.isnan(fit.kt_[0])
    rmse, _ = fit.evaluate(motor_experiments)
    observed, _, joint = fit.observed_predicted(motor_experiments)
    for j in (1, 4):
        assert rmse[j] < 0.05 * np.abs(observed[joint == j]).max()  # 4 Hz filter edges on a short sweep


def test_motor_dynamic_load_removes_the_velocity_bias(denso, motor_experiments, truth):
    """At 0.8 rad/s the mass's velocity terms survive folding: the static load (eq. 16) is biased, not the dynamic."""
    _, kt, _ = truth
    dynamic = MotorIdentifier(robot=denso, payload=PAYLOAD).fit(motor_experiments)
    static = MotorIdentifier(robot=denso, payload=PAYLOAD, load="static").fit(motor_experiments)
    err_dynamic = np.abs(dynamic.kt_[[1, 4]] / kt[[1, 4]] - 1)
    err_static = np.abs(static.kt_[[1, 4]] / kt[[1, 4]] - 1)
    assert err_dynamic.max() < 2e-4 and err_static.max() > 3 * err_dynamic.max()
    with pytest.raises(ParameterError, match="load"):
        MotorIdentifier(robot=denso, payload=PAYLOAD, load="inertial").fit(motor_experiments)
    first = motor_experiments[0]
    no_rates = MotorExperiment(
        first.joint, first.nominal.with_signals(qd=None, qdd=None), first.loaded.with_signals(qd=None, qdd=None)
    )
    with pytest.raises(ParameterError, match="load='dynamic' needs qd and qdd in the sweeps of joint 2"):
        MotorIdentifier(robot=denso, payload=PAYLOAD).fit([no_rates])


def test_friction_coupling_torque_matches_pinocchio(denso, denso_model, truth):
    """sum_k M_jk(q) qdd_k of the held joints, from the regressor with a given theta, equals Pinocchio's crba row."""
    import pinocchio as pin

    from identification.calibration.friction_step import _coupling_torque
    from psdm_casadi.oracle import build_pinocchio_model

    theta, _, _ = truth
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 0.4, 1e-3)
    q = np.tile(rng.uniform(0.5 * denso.q_min, 0.5 * denso.q_max), (t.size, 1))
    q[:, 1] += 0.3 * np.sin(2 * np.pi * t)  # the moving joint changes M_1k for k < 1
    qdd = rng.normal(0.0, 1.0, q.shape)
    rec = Recording(t=t, q=q, tau=np.zeros_like(q), qd=np.zeros_like(q), qdd=qdd, name="coupling")
    model = build_pinocchio_model(denso, denso.nominal_dynamic_parameters())
    data = model.createData()
    expected = np.empty(t.size)
    for k in range(t.size):
        m = pin.crba(model, data, q[k])
        m = np.triu(m) + np.triu(m, 1).T
        expected[k] = m[1] @ qdd[k] - m[1, 1] * qdd[k, 1]
    got = _coupling_torque(denso_model, theta, rec, 1)
    np.testing.assert_allclose(got, expected, atol=2e-4 * np.abs(expected).max())
    fit = FrictionIdentifier(model=denso_model, kt=None, theta=theta, coupling_theta=theta)
    plain = FrictionIdentifier(model=denso_model, kt=None, theta=theta)
    np.testing.assert_allclose(
        plain.measured_friction(FrictionExperiment(1, rec)) - fit.measured_friction(FrictionExperiment(1, rec)),
        got,
        atol=1e-12,
    )
    with pytest.raises(ParameterError, match="coupling_theta needs qdd"):
        fit.measured_friction(FrictionExperiment(1, rec.with_signals(qdd=None)))


def test_friction_central_difference_needs_full_rate(denso_model, truth):
    from identification.friction.shooting import ShootingOptions

    theta, kt, _ = truth
    rec = Recording(
        t=np.arange(0.0, 0.05, 1e-3),
        q=np.zeros((50, 6)),
        current=np.zeros((50, 6)),
        qd=np.zeros((50, 6)),
        qdd=np.zeros((50, 6)),
        name="x",
    )
    options = ShootingOptions(measurement="central-difference")
    with pytest.raises(ParameterError, match="decimation"):
        FrictionIdentifier(model=denso_model, kt=kt, theta=theta, decimation=2, shooting_options=options).fit(
            FrictionExperiment(0, rec)
        )


def test_gravity_recovers_parameters(denso_model, gravity_recording, truth):
    theta, _, _ = truth
    fit = GravityIdentifier(model=denso_model, kt=None, min_speed=0.0).fit(gravity_recording)
    mask = denso_model.gravity_mask
    np.testing.assert_allclose(fit.theta_gravity_, theta[mask], rtol=1e-6, atol=1e-9)
    assert fit.theta_[~mask].tolist() == [0.0] * int((~mask).sum())


def test_friction_held_set_points_are_averaged(denso_model, truth):
    """A set-point held over the next sample: the torque at t_k is the mean of set-points k-1 and k."""
    theta, _, _ = truth
    t = np.arange(0.0, 0.01, 1e-3)
    q = np.zeros((t.size, 6))
    current = np.zeros((t.size, 6))
    current[:, 2] = np.arange(t.size) % 2  # 0, 1, 0, 1, ...
    rec = Recording(t=t, q=q, current=current, qd=q.copy(), qdd=q.copy(), name="held")
    kt = np.full(6, 2.0)
    gravity = denso_model.gravity_regressor(q)[:, 2, :] @ (theta * denso_model.gravity_mask)
    held = FrictionIdentifier(model=denso_model, kt=kt, theta=theta).measured_friction(FrictionExperiment(2, rec))
    instant = FrictionIdentifier(model=denso_model, kt=kt, theta=theta, held_torque=False).measured_friction(
        FrictionExperiment(2, rec)
    )
    np.testing.assert_allclose(instant + gravity, 2.0 * current[:, 2], atol=1e-12)
    np.testing.assert_allclose(held[1:] + gravity[1:], 1.0, atol=1e-12)


def test_gravity_removes_inertial_torques_with_a_given_model(denso, denso_model, truth):
    """A fast out-and-back jog (inertial torques not negligible): eq. 18 alone is biased, removing
    ``(Y - Y_grav) theta`` of the true model recovers the gravity parameters (Pinocchio RNEA data)."""
    theta, _, _ = truth
    t, q, qd = _out_and_back(denso, np.random.default_rng(5), n=801, duration=4.0)
    qdd = np.gradient(qd, t, axis=0)
    tau = PinocchioOracle(denso).rnea(q, qd, qdd) + 3.0 * np.sign(qd)
    folded = fold_out_and_back(Recording(t=t, q=q, tau=tau, qd=qd, qdd=qdd, name="fast jog"))
    mask = denso_model.gravity_mask
    plain = GravityIdentifier(model=denso_model, min_speed=0.0).fit(folded)
    removed = GravityIdentifier(model=denso_model, min_speed=0.0, theta=theta).fit(folded)
    assert np.abs(plain.theta_gravity_ - theta[mask]).max() > 1e-3
    np.testing.assert_allclose(removed.theta_gravity_, theta[mask], rtol=1e-6, atol=1e-8)
    with pytest.raises(ShapeError, match="theta"):
        GravityIdentifier(model=denso_model, theta=np.ones(3)).fit(folded)


def test_inertial_recovers_parameters(denso_model, excitation, truth):
    theta, _, lugre = truth
    start = theta * denso_model.gravity_mask
    fit = InertialIdentifier(model=denso_model, kt=None, theta=start, lugre=lugre).fit(excitation)
    np.testing.assert_allclose(fit.theta_, theta, rtol=1e-5, atol=1e-6)
    _, r2 = fit.evaluate(excitation)
    assert np.all(r2 > 0.999999)


def test_friction_inertia_and_coulomb_viscous(denso, denso_model, truth):
    """Joint 5 alone: eq. 19 removes gravity, the fitted inertia removes M_55 qdd, LuGre follows."""
    theta, _, lugre = truth
    j = 4
    t, q = experiments.oscillation_experiment(denso, j, amplitudes=(1e-3, 0.05, 0.5), cycles=2).reference()
    t_s = np.arange(0.0, t[-1], 2e-3)
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(t, q, axis=0)
    q, qd, qdd = spline(t_s), spline(t_s, 1), spline(t_s, 2)
    fr = simulate_lugre(lugre[j], t_s, qd[:, j])[0]
    tau = PinocchioOracle(denso).rnea(q, qd, qdd)
    tau[:, j] += fr
    rec = Recording(t=t_s, q=q, tau=tau, qd=qd, qdd=qdd, name="friction")
    # torques at the sample instants (not held set-points)
    fit = FrictionIdentifier(model=denso_model, theta=theta, held_torque=False).fit(FrictionExperiment(j, rec))
    m_jj = PinocchioOracle(denso).crba(q[0])[j, j]
    assert fit.inertia_[j] == pytest.approx(m_jj, rel=0.05)
    err = fit.lugre_[j].relative_error(lugre[j])
    assert err["fc"] < 0.05 and err["fv"] < 0.05
    _, r2 = fit.evaluate(FrictionExperiment(j, rec))
    assert r2[j] > 0.99


# --- contract ---------------------------------------------------------------------------------------
def _cases(denso, denso_model, truth, motor_experiments, gravity_recording, excitation):
    theta, _, lugre = truth
    return [
        (MotorIdentifier(robot=denso, payload=PAYLOAD), motor_experiments, "kt_"),
        (GravityIdentifier(model=denso_model), gravity_recording, "theta_"),
        (
            InertialIdentifier(model=denso_model, theta=theta * denso_model.gravity_mask, lugre=lugre),
            excitation,
            "theta_",
        ),
    ]


def test_contract(denso, denso_model, truth, motor_experiments, gravity_recording, excitation):
    for estimator, data, attribute in _cases(
        denso, denso_model, truth, motor_experiments, gravity_recording, excitation
    ):
        with pytest.raises(NotFittedError, match="fit"):
            estimator.predict(data)
        with pytest.raises(NotFittedError):
            estimator.score(data)
        snapshot = [np.array(r.q) for r in (data if isinstance(data, list) else [data]) if isinstance(r, Recording)]
        assert estimator.fit(data) is estimator
        first = np.array(getattr(estimator, attribute))
        again = type(estimator)(**estimator.get_params()).fit(data)
        np.testing.assert_array_equal(first, getattr(again, attribute))
        after = [np.array(r.q) for r in (data if isinstance(data, list) else [data]) if isinstance(r, Recording)]
        for a, b in zip(snapshot, after):
            np.testing.assert_array_equal(a, b)
        assert np.isfinite(estimator.score(data))


def test_friction_unfitted_predict_raises(denso_model, truth):
    with pytest.raises(NotFittedError):
        FrictionIdentifier(model=denso_model, theta=truth[0]).predict([])


# --- errors ---------------------------------------------------------------------------------------
def test_errors(denso, denso_model, motor_experiments, gravity_recording):
    with pytest.raises(ParameterError, match="payload"):
        MotorIdentifier(robot=denso, payload=None).fit(motor_experiments)
    with pytest.raises(ParameterError, match="min_speed_fraction"):
        MotorIdentifier(robot=denso, payload=PAYLOAD, min_speed_fraction=1.5).fit(motor_experiments)
    with pytest.raises(ShapeError, match="kt"):
        GravityIdentifier(model=denso_model, kt=[1.0, 2.0]).fit(gravity_recording)
    with pytest.raises(ParameterError, match="model"):
        GravityIdentifier(model=None).fit(gravity_recording)
    with pytest.raises(ParameterError, match="lugre"):
        InertialIdentifier(model=denso_model, theta=np.zeros(denso_model.n_base)).fit(gravity_recording)
    with pytest.raises(ParameterError, match="inertia"):
        FrictionIdentifier(model=denso_model, theta=np.zeros(denso_model.n_base), inertia="guess").fit([])
    t = np.linspace(0, 1, 50)
    q = np.column_stack([t] * denso.n_dof)
    with pytest.raises(RecordingError, match="retrace"):
        fold_out_and_back(Recording(t=t, q=q, tau=q, qd=q, qdd=q))
    with pytest.raises(RecordingError, match="preprocess"):
        fold_out_and_back(Recording(t=t, q=q, tau=q))
    with pytest.raises(ShapeError, match="loaded"):
        MotorExperiment(0, motor_experiments[0].nominal, motor_experiments[0].loaded.slice(0, 10))


def test_weighted_least_squares_and_design_errors():
    a = np.column_stack([np.ones(5), np.zeros(5)])
    with pytest.raises(ParameterError, match="not excited"):
        weighted_least_squares(a, np.ones(5))
    with pytest.raises(ParameterError, match="rows"):
        weighted_least_squares(np.ones((5, 2)), np.ones(5), weights=np.r_[1.0, 0, 0, 0, 0])
    with pytest.raises(ParameterError, match="weights"):
        Design(np.ones((3, 1)), np.ones(3), -np.ones(3), np.zeros(3))
    with pytest.raises(ShapeError, match="target"):
        Design(np.ones((3, 1)), np.ones(4), np.ones(3), np.zeros(3))
    rng = np.random.default_rng(0)
    x = rng.standard_normal((200, 3))
    y = x @ [1.0, -2.0, 0.5] + 0.01 * rng.standard_normal(200)
    res = weighted_least_squares(x, y)
    np.testing.assert_allclose(res.coefficients, [1.0, -2.0, 0.5], atol=5e-3)
    assert np.all(res.standard_errors < 2e-3) and np.all(res.standard_errors > 0)
