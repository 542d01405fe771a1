"""Known extra torques (a diagnosis finding) inside the four-step calibration: a hidden spring on the virtual Denso.

The reference is the virtual robot's truth: its Kt, inertias and LuGre parameters are the robot
file's, and the hidden spring's stiffness and rest angle are the ones simulated.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.extra_passes import ExcitationTermsIdentifier, settle_extra_terms
from identification.calibration.extra_terms import ExtraTerms
from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
from identification.calibration.preparation import decimation_step, excitation_split, gravity_split
from identification.calibration.steps import GravityIdentifier, InertialIdentifier
from identification.diagnosis.candidates import BacklashTerm, DelayTerm, RotorInertiaTerm, SpringTerm
from identification.friction.models import LuGreParameters
from psdm_casadi.errors import ParameterError

K_TRUE, Q0_TRUE, JOINT = 6.0, 0.4, 3


def _scaled_error(estimate, truth) -> float:
    """Worst error scaled by max(|truth|, 5 % of the largest parameter) (small parameters carry noise-level torques)."""
    return float((np.abs(estimate - truth) / np.maximum(np.abs(truth), 0.05 * np.abs(truth).max())).max())


def _excitation(robot, model):
    """Two periods of the quick demo's optimised excitation (inertial columns), sampled at 1 kHz."""
    from psdm_casadi.recursive import build_recursive_functions
    from trajopt.optimize import ExcitationOptions, optimize_excitation

    excitation = optimize_excitation(
        robot,
        build_recursive_functions(model, robot).regressor,
        ExcitationOptions(
            duration=6.0, harmonics=3, columns=tuple(np.nonzero(~model.gravity_mask)[0]), n_starts=1, quiet=True
        ),
        seed=0,
    )
    t = excitation.time_grid(1000.0, periods=2)
    return (t, *excitation.sample(t))


@pytest.fixture(scope="module")
def jog_and_excitation(denso, denso_model):
    """The gravity jog and one excitation of the virtual Denso, with the spring hidden and without it."""
    from identification.virtual.effects import Spring
    from identification.virtual.simulation import SimulationOptions, simulate_recording
    from trajopt.calibration_plan import CalibrationPlan

    jog = CalibrationPlan(gravity_duration=16.0).gravity_reference(denso, np.random.default_rng(0))
    out = {}
    for name, extras in (("spring", (Spring(joint=JOINT, stiffness=K_TRUE, q0=Q0_TRUE),)), ("clean", ())):
        rng = np.random.default_rng(1)
        recordings = [
            simulate_recording(denso, reference, SimulationOptions(), rng, extras=extras)[0].with_signals(name=label)
            for label, reference in (("gravity", jog), ("excitation", _excitation(denso, denso_model)))
        ]
        out[name] = SimpleNamespace(gravity=(recordings[0],), excitation=(recordings[1],))
    return out


def _gravity_and_inertial(denso, model, data, extra):
    """Steps 2 and 4 with the true Kt and LuGre (the friction removed before folding), the spring settled."""
    options = PipelineOptions()
    kt = np.array([d.kt for d in denso.drives])
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    theta_nominal = model.base_parameters(denso.nominal_dynamic_parameters())
    jog = gravity_split(data, options, lugre=lugre, kt=kt).train
    excitation = excitation_split(data, options).train
    step = decimation_step(data.excitation[0], options.inertial_rate_hz)
    gravity = GravityIdentifier(model=model, kt=kt, robot=denso, theta=theta_nominal, extra_terms=extra).fit(jog)
    inertial = InertialIdentifier(
        model=model, kt=kt, theta=gravity.theta_, lugre=lugre, robot=denso, decimation=step, extra_terms=extra
    )
    if extra is None:
        return gravity, inertial.fit(excitation)
    return settle_extra_terms(gravity, inertial, jog, excitation)


@pytest.mark.slow
def test_gravity_and_inertial_steps_recover_the_parameters_with_a_known_spring(denso, denso_model, jog_and_excitation):
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    mask = denso_model.gravity_mask
    errors = {}
    for name, extra in (
        ("clean", None),
        ("hidden", None),
        ("known", ExtraTerms((SpringTerm(joint=JOINT),))),
    ):
        data = jog_and_excitation["clean" if name == "clean" else "spring"]
        gravity, inertial = _gravity_and_inertial(denso, denso_model, data, extra)
        errors[name] = (_scaled_error(gravity.theta_gravity_, truth[mask]), _scaled_error(inertial.theta_, truth))
        if extra is not None:
            k, c = inertial.extra_terms_.coefficients
            assert abs(k / K_TRUE - 1) < 0.02
            assert abs(-c / k - Q0_TRUE) < 0.01
            assert np.all(inertial.extra_terms_.std > 0) and np.all(inertial.extra_terms_.std < 0.1)
    clean, hidden, known = errors["clean"], errors["hidden"], errors["known"]
    # the unknown spring corrupts the parameters; the known one costs the gravity step some precision (the
    # jog's small range makes k q + c nearly collinear with the wrist's gravity torques), not accuracy
    assert hidden[0] > 30 * max(clean[0], 0.01) and hidden[1] > 5 * clean[1], errors
    assert known[0] <= 6 * max(clean[0], 0.01) and known[0] < hidden[0] / 10, errors
    assert known[1] <= 2 * clean[1], errors  # issue 16: after the loop within twice the clean-data errors


@pytest.mark.slow
def test_the_terms_are_estimated_on_the_excitation_with_every_base_parameter_free(
    denso, denso_model, jog_and_excitation
):
    """The spring's estimate owes nothing to a gravity estimate (issue 16: the alternation's fixed point let the
    jog's collinearity and the inertial step's held gravity feed each other's errors)."""
    data, options = jog_and_excitation["spring"], PipelineOptions()
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    wrong = truth.copy()
    wrong[denso_model.gravity_mask] *= 1.05  # a gravity estimate 5 % off
    common = dict(
        model=denso_model,
        kt=np.array([d.kt for d in denso.drives]),
        lugre=tuple(LuGreParameters.from_drive(d) for d in denso.drives),
        robot=denso,
        decimation=decimation_step(data.excitation[0], options.inertial_rate_hz),
        extra_terms=ExtraTerms((SpringTerm(joint=JOINT),)),
    )
    excitation = excitation_split(data, options).train
    free = [ExcitationTermsIdentifier(**common, theta=theta).fit(excitation) for theta in (truth, wrong)]
    held = InertialIdentifier(**common, theta=wrong).fit(excitation)
    k, c = free[0].extra_terms_.coefficients
    assert abs(k / K_TRUE - 1) < 0.01 and abs(-c / k - Q0_TRUE) < 0.005
    np.testing.assert_array_equal(free[1].coef_, free[0].coef_)  # no parameter is held
    assert _scaled_error(free[0].theta_, truth) < 1.0  # every base parameter fitted, none left at zero
    k_held, c_held = held.extra_terms_.coefficients
    assert abs(c_held - c) > 3 * free[0].extra_terms_.std[1], (c_held, c)  # a held gravity error moves the spring


def test_extra_terms_take_torques_of_the_joint_state_only(denso, denso_model):
    extra = ExtraTerms((SpringTerm(joint=JOINT),))
    assert extra.feature_names == ("k_q4", "c_4") and not extra.fitted
    with pytest.raises(ParameterError, match="no coefficients"):
        extra.torque(np.zeros((3, 6)))
    for term, reason in (
        (DelayTerm(), "signal correction"),
        (BacklashTerm(joint=1), "signal correction"),
        (RotorInertiaTerm(joint=1), "base parameters"),
        (SpringTerm(), "joint is not set"),
    ):
        with pytest.raises(ParameterError, match=reason):
            ExtraTerms((term,))
    with pytest.raises(ParameterError, match="joint 7"):
        IdentificationPipeline(denso, denso_model, extra_terms=(SpringTerm(joint=6),))._extra_terms()


def test_model_with_a_spring_predicts_saves_and_exports_its_whole_torque(denso, denso_model, tmp_path):
    """predict_torque, the saved model and the CasADi feed-forward all carry the spring (reference: the formula)."""
    from identification.calibration.report import StepScore, ValidationReport
    from identification.calibration.result import IdentifiedModel, load_identified

    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    spring = ExtraTerms((SpringTerm(joint=JOINT),), [K_TRUE, -K_TRUE * Q0_TRUE], [0.01, 0.02])
    report = ValidationReport((StepScore("all", np.zeros(6), np.ones(6)),), tuple(denso.joint_names))
    model = IdentifiedModel(
        denso.name, denso_model, theta, [d.kt for d in denso.drives], lugre, report, None, {}, spring
    )
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.uniform(-1, 1, size=(3, 5, 6))
    qd[:, 0] = 0.0
    expected = np.array([denso_model.inverse_dynamics(*x, theta) for x in zip(q, qd, qdd)])
    expected += np.array([[p.steady_state(v) for p, v in zip(lugre, row)] for row in qd])
    expected[:, JOINT] += K_TRUE * (q[:, JOINT] - Q0_TRUE)
    feedforward = model.build_feedforward(denso)
    got = np.array([feedforward(*x).full().ravel() for x in zip(q, qd, qdd)])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9)
    back = load_identified(model.save(tmp_path / "m"))
    np.testing.assert_array_equal(back.extra_terms.coefficients, spring.coefficients)
    np.testing.assert_array_equal(back.extra_terms.std, spring.std)
    t = np.linspace(0.0, 0.004, 5)
    difference = back.predict_torque(t, q, qd, qdd) - IdentifiedModel(
        denso.name, denso_model, theta, back.kt, lugre, report
    ).predict_torque(t, q, qd, qdd)
    np.testing.assert_allclose(difference[:, JOINT], K_TRUE * (q[:, JOINT] - Q0_TRUE), atol=1e-12)
    np.testing.assert_allclose(np.delete(difference, JOINT, axis=1), 0.0, atol=1e-12)


def test_motor_step_is_not_misled_by_the_start_up_transient_of_a_hidden_spring(denso):
    """The spring yanks joint 4 at the start of each sweep (a controller switched on at the first sample,
    ``settled_start=False``); Kt comes from the steady sweep (truth: the robot file)."""
    from dataclasses import replace
    from functools import partial

    from identification.calibration.payload import payload_static_torque
    from identification.calibration.preparation import motor_split
    from identification.calibration.steps import MotorIdentifier
    from identification.virtual.calibration import VirtualCalibrationOptions
    from identification.virtual.effects import Spring
    from identification.virtual.simulation import simulate_recording
    from trajopt.calibration_plan import CalibrationPlan

    rng = np.random.default_rng(0)
    options = VirtualCalibrationOptions()
    spring = (Spring(joint=JOINT, stiffness=K_TRUE, q0=Q0_TRUE),)
    reference = CalibrationPlan().motor_reference(
        denso, JOINT, partial(payload_static_torque, denso, options.payload), rng
    )
    nominal, loaded = (
        simulate_recording(
            denso, reference, replace(options.simulation, payload=payload, settled_start=False), rng, extras=spring
        )[0]
        for payload in (None, options.payload)
    )
    split = motor_split(SimpleNamespace(motor=((JOINT, nominal, loaded),)), PipelineOptions())
    speed = np.abs(split.train[0].nominal.qd[:, JOINT])
    assert speed.max() > 1.2 * np.percentile(speed, 90)  # the transient is there
    kt = MotorIdentifier(robot=denso, payload=options.payload).fit(split.train).kt_[JOINT]
    assert abs(kt / denso.drives[JOINT].kt - 1) < 0.005
