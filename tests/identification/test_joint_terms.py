"""The extra terms fitted jointly on the jog and the excitation (``JointGravityIdentifier``), against synthetic truth.

Torques are the derived model's at the Denso's nominal base parameters plus a known spring on joint 4
and white noise of known level: a precise jog over a small range (the spring nearly collinear with the
wrist's gravity torques) and a noisy excitation over a wide one (the spring separated from gravity but
poorly resolved), the regime of the calibration plan. Over repeated noise draws the joint estimate is
compared with the truth and with the route it replaces: the terms from the excitation alone
(``ExcitationTermsIdentifier``), held in the jog's gravity step.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from identification.calibration.extra_passes import (
    ExcitationTermsIdentifier,
    JointGravityIdentifier,
    settle_extra_terms,
)
from identification.calibration.extra_terms import ExtraTerms
from identification.calibration.steps import GravityIdentifier, InertialIdentifier
from identification.data.recording import Recording
from identification.diagnosis.candidates import SpringTerm
from psdm_casadi.errors import ParameterError
from trajopt.experiments import gravity_experiment, sine_experiment

K_TRUE, Q0_TRUE, JOINT = 6.0, 0.4, 3
SPRING = np.array([K_TRUE, -K_TRUE * Q0_TRUE])  # k q + c, c = -k q0
NOISE_JOG, NOISE_EXCITATION = 0.02, 0.5  # [N m] white noise: folded slow jog vs fast excitation
N_DRAWS = 10


def _path(knots, rate):
    """``(t, q, qd, qdd)`` of a trajectory's knots sampled at ``rate`` [Hz] (exact spline derivatives)."""
    t_knots, q_knots = knots
    spline = CubicSpline(t_knots, q_knots, axis=0)
    t = np.arange(0.0, t_knots[-1], 1.0 / rate)
    return t, spline(t), spline(t, 1), spline(t, 2)


@pytest.fixture(scope="module")
def paths(denso, denso_model):
    """Noise-free torques of the jog and the excitation with the spring, and the truth."""
    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    rng = np.random.default_rng(0)
    jog = _path(gravity_experiment(denso, duration=16.0, rng=rng).reference(), 20.0)
    excitation = _path(sine_experiment(denso, duration=16.0, rng=rng).reference(), 20.0)
    out = {}
    for name, (t, q, qd, qdd) in (("jog", jog), ("excitation", excitation)):
        tau = denso_model.regressor(q, qd, qdd) @ theta
        tau[:, JOINT] += K_TRUE * (q[:, JOINT] - Q0_TRUE)
        out[name] = (t, q, qd, qdd, tau)
    return out, theta


def _recording(path, noise, rng, name):
    t, q, qd, qdd, tau = path
    return Recording(t=t, q=q, tau=tau + rng.normal(0.0, noise, tau.shape), qd=qd, qdd=qdd, name=name)


def _estimators(denso_model, theta):
    terms = ExtraTerms((SpringTerm(joint=JOINT),))
    gravity = GravityIdentifier(model=denso_model, min_speed=0.0, theta=theta, extra_terms=terms)
    inertial = InertialIdentifier(
        model=denso_model, theta=theta * denso_model.gravity_mask, lugre=(None,) * 6, extra_terms=terms
    )
    return gravity, inertial


def _scaled(estimate, truth) -> float:
    return float((np.abs(estimate - truth) / np.maximum(np.abs(truth), 0.05 * np.abs(truth).max())).max())


def test_joint_fit_is_closer_to_the_truth_than_the_excitation_alone(denso_model, paths):
    """The joint estimate of the spring is unbiased, its sigma matches its scatter, and it lies closer to the
    truth than the excitation-only estimate by more than that sigma; the gravity parameters it gives are closer
    than those of the jog with the excitation-only spring held."""
    data, theta = paths
    mask = denso_model.gravity_mask
    gravity, inertial = _estimators(denso_model, theta)
    rng = np.random.default_rng(1)
    joint_err, joint_std, alone_err, alone_std, noise = [], [], [], [], []
    gravity_joint, gravity_held = [], []
    for _ in range(N_DRAWS):
        jog = _recording(data["jog"], NOISE_JOG, rng, "jog")
        excitation = _recording(data["excitation"], NOISE_EXCITATION, rng, "excitation")
        alone = ExcitationTermsIdentifier(**inertial.get_params()).fit(excitation).extra_terms_
        held = GravityIdentifier(**dict(gravity.get_params(), extra_terms=alone)).fit(jog)
        joint = JointGravityIdentifier(**gravity.get_params(), inertial=inertial).fit(jog, excitation)
        joint_err.append(joint.extra_terms_.coefficients - SPRING)
        joint_std.append(joint.extra_terms_.std)
        alone_err.append(alone.coefficients - SPRING)
        alone_std.append(alone.std)
        noise.append(joint.noise_rms_)
        gravity_joint.append(_scaled(joint.theta_gravity_, theta[mask]))
        gravity_held.append(_scaled(held.theta_gravity_, theta[mask]))
    joint_err, joint_std, alone_err, alone_std = map(np.array, (joint_err, joint_std, alone_err, alone_std))
    noise = np.mean(noise, axis=0)
    # the weights are each experiment's noise: the residual RMS of each alone recovers the simulated level
    np.testing.assert_allclose(noise[0, :5], NOISE_JOG, rtol=0.15)  # joint 6 has no gravity row
    np.testing.assert_allclose(noise[1], NOISE_EXCITATION, rtol=0.1)
    sigma = joint_std.mean(axis=0)
    rms_joint, rms_alone = np.sqrt((joint_err**2).mean(axis=0)), np.sqrt((alone_err**2).mean(axis=0))
    assert np.all(np.abs(joint_err.mean(axis=0)) < 3 * sigma / np.sqrt(N_DRAWS)), (joint_err.mean(axis=0), sigma)
    assert np.all((rms_joint > 0.6 * sigma) & (rms_joint < 1.5 * sigma)), (rms_joint, sigma)  # honest sigma
    assert np.all(rms_alone - rms_joint > 2 * sigma), (rms_alone, rms_joint, sigma)
    assert np.all(rms_alone > 0.6 * alone_std.mean(axis=0)), (rms_alone, alone_std.mean(axis=0))
    assert np.median(gravity_joint) < 0.5 * np.median(gravity_held), (gravity_joint, gravity_held)


def test_settle_takes_the_gravity_of_the_joint_fit_and_refits_the_inertial_step(denso_model, paths):
    data, theta = paths
    rng = np.random.default_rng(2)
    jog = _recording(data["jog"], NOISE_JOG, rng, "jog")
    excitation = _recording(data["excitation"], NOISE_EXCITATION, rng, "excitation")
    gravity, inertial = settle_extra_terms(*_estimators(denso_model, theta), jog, excitation)
    mask = denso_model.gravity_mask
    assert isinstance(gravity, JointGravityIdentifier)
    np.testing.assert_array_equal(inertial.theta_[mask], gravity.theta_gravity_)  # the gravity is held
    np.testing.assert_allclose(inertial.extra_terms_.coefficients, SPRING, atol=4 * inertial.extra_terms_.std.max())
    # the gravity step's score on the jog predicts with the terms it fitted
    _, r2 = gravity.evaluate(jog)
    assert np.all(r2[:5] > 0.9)


def test_joint_fit_refuses_missing_inputs(denso_model, paths):
    data, theta = paths
    rng = np.random.default_rng(3)
    jog = _recording(data["jog"], NOISE_JOG, rng, "jog")
    gravity, inertial = _estimators(denso_model, theta)
    params = gravity.get_params()
    with pytest.raises(ParameterError, match="excitation_data"):
        JointGravityIdentifier(**params, inertial=inertial).fit(jog)
    with pytest.raises(ParameterError, match="inertial"):
        JointGravityIdentifier(**params).fit(jog, jog)
    fitted = params["extra_terms"].with_fit(SPRING)
    with pytest.raises(ParameterError, match="extra_terms"):
        JointGravityIdentifier(**dict(params, extra_terms=fitted), inertial=inertial).fit(jog, jog)
