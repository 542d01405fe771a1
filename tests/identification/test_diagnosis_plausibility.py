"""Plausibility of fitted parameters, the Ipopt refinement of nonlinear terms, and a last link too heavy in the
prior.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis import (
    DelayTerm,
    DiagnosisOptions,
    FrictionDriftTerm,
    JointElasticityTerm,
    LoadDependentFrictionTerm,
    PayloadTerm,
    RotorInertiaTerm,
    SpringTerm,
    TorqueOffsetTerm,
    diagnose,
)
from identification.diagnosis.candidates import MAX_DELAY_S, MAX_LOAD_FRICTION, MIN_DRIFT_TIME_CONSTANT_S
from identification.virtual import effects as xp
from psdm_casadi.robot import LinkInertia
from tests.identification.diagnosis_data import recording_pair


@pytest.mark.parametrize(
    "term, coefficients, accepted",
    [
        (LoadDependentFrictionTerm(joint=0), [0.2], True),
        (LoadDependentFrictionTerm(joint=0), [MAX_LOAD_FRICTION + 0.4], False),  # mu ~ 1 is not gear friction
        (LoadDependentFrictionTerm(joint=0), [-0.1], False),
        (RotorInertiaTerm(joint=0), [0.3], True),
        (RotorInertiaTerm(joint=0), [-0.3], False),
        (DelayTerm(), [0.004], True),
        (DelayTerm(), [-0.004], False),
        (DelayTerm(), [MAX_DELAY_S * 2], False),
        (JointElasticityTerm(joint=0), [-1e-4], False),
        (PayloadTerm(), [2.0, 0.0, 0.0, 0.2], True),
        (PayloadTerm(), [0.1, 0.0, 0.0, 0.2], False),  # centre of mass 2 m away
        (SpringTerm(joint=0), [40.0, 3.0], True),
        (SpringTerm(joint=0), [-40.0, 3.0], False),  # pushes the joint away: not a spring
        (SpringTerm(joint=0, order=3, centre=0.0, q_range=(-1.0, 1.0)), [-5.0, 0.0, -1.0, 0.0], False),
        (SpringTerm(joint=0, order=3, centre=0.0, q_range=(-1.0, 1.0)), [-5.0, 0.0, 30.0, 0.0], True),  # mostly stiff
    ],
)
def test_implausible_parameters_are_named(term, coefficients, accepted):
    reason = term.implausibility(np.array(coefficients))
    assert (reason is None) == accepted
    if not accepted:
        assert isinstance(reason, str) and reason


def _context(tau_rms, gravity_amplitude):
    """A context of one joint with a measured torque of RMS ``tau_rms`` and a nominal gravity torque reaching
    ``gravity_amplitude`` over the recording."""
    t = np.linspace(0.0, 10.0, 1001)
    tau = np.sqrt(2.0) * tau_rms * np.sin(2.0 * np.pi * 0.3 * t)
    gravity = gravity_amplitude * np.cos(2.0 * np.pi * 0.1 * t)
    return SimpleNamespace(tau=tau[:, None], gravity=gravity[:, None], full_t=t, qd=tau[:, None], qdd=tau[:, None])


@pytest.mark.parametrize(
    "term, coefficients, accepted",
    [
        (TorqueOffsetTerm(joint=0), [30.0], True),
        (TorqueOffsetTerm(joint=0), [-2038.0], False),  # the TX40's "offset" of issue 25
        (TorqueOffsetTerm(joint=0), [-90.0], False),  # beyond the gravity amplitude 80 N m and the peak torque 28 N m
        (SpringTerm(joint=0, q_range=(-1.0, 1.0)), [10.0, 5.0], True),
        (SpringTerm(joint=0, q_range=(-1.0, 1.0)), [500.0, 0.0], False),  # 500 N m over the range
        (FrictionDriftTerm(joint=0), [1.0], True),  # 10 N m over 10 s
        (FrictionDriftTerm(joint=0), [10.0], False),  # 100 N m over 10 s
    ],
)
def test_torques_beyond_the_joints_gravity_amplitude_are_not_findings(term, coefficients, accepted):
    reason = term.implausibility(np.array(coefficients), _context(tau_rms=20.0, gravity_amplitude=80.0))
    assert (reason is None) == accepted
    if not accepted:
        assert "80 N m" in reason  # names the bound: the larger of the gravity amplitude and the peak torque


def test_offset_bound_falls_back_to_the_peak_torque_where_gravity_does_not_load_the_joint():
    # a vertical first axis: no gravity torque, the bound is the peak measured torque (sqrt(2) x its RMS of 20 N m)
    context = _context(tau_rms=20.0, gravity_amplitude=0.0)
    assert TorqueOffsetTerm(joint=0).implausibility(np.array([25.0]), context) is None
    reason = TorqueOffsetTerm(joint=0).implausibility(np.array([-30.0]), context)
    assert float(reason.rsplit("(", 1)[1].split(" ")[0]) == pytest.approx(20.0 * np.sqrt(2.0), rel=0.01)


def test_negative_payload_is_reported_as_a_last_link_too_heavy_in_the_prior(denso, denso_model):
    # the robot file says the flange carries 3 kg that the real robot does not have
    links = list(denso.links)
    links[-1] = LinkInertia(mass=3.0, com=np.array([0.0, 0.0, 0.05]), inertia=np.eye(3) * 1e-3)
    prior = denso.with_links(links)
    train, val = recording_pair(denso, [], seed=4)
    lib = PayloadTerm() + TorqueOffsetTerm()
    options = DiagnosisOptions(library=lib, max_effects=1, rigid_body="prior")
    report = diagnose(prior, train, val, options, model=denso_model)
    first = report.findings[0]
    assert first.effect == "last_link_mass_excess" and "lighter" in first.explanation
    assert first.parameters["mass"] == pytest.approx(-3.0, rel=0.1)


def test_a_wrong_prior_mass_is_not_reported_as_missing_physics_by_default(denso, denso_model):
    # the same too-heavy flange: the default ``rigid_body="auto"`` recalibrates the rigid body, which
    # explains the data without any term, so the report blames the robot file instead of naming physics
    links = list(denso.links)
    links[-1] = LinkInertia(mass=3.0, com=np.array([0.0, 0.0, 0.05]), inertia=np.eye(3) * 1e-3)
    prior = denso.with_links(links)
    train, val = recording_pair(denso, [], seed=4)
    lib = PayloadTerm() + TorqueOffsetTerm()
    report = diagnose(prior, train, val, DiagnosisOptions(library=lib, max_effects=1), model=denso_model)
    assert report.findings == ()
    assert any("inertial parameters are off" in note for note in report.rigid_body_notes)


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__()
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@pytest.fixture
def diagnosis_log():
    """The INFO lines of the diagnosis loggers during the test (kept from any handler a CLI test installed)."""
    logger = logging.getLogger("identification.diagnosis")
    handler, level, propagate = _Collect(), logger.level, logger.propagate
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False
    yield handler.messages
    logger.removeHandler(handler)
    logger.setLevel(level)
    logger.propagate = propagate


def test_delay_is_refined_by_ipopt_and_lowers_the_error(denso, denso_model, diagnosis_log):
    train, val = recording_pair(denso, [xp.SignalDelay(samples=6)], seed=5)
    report = diagnose(denso, train, val, DiagnosisOptions(library=DelayTerm() + TorqueOffsetTerm()), model=denso_model)
    messages = diagnosis_log
    assert report.effects[0] == "delay"
    assert any("Ipopt" in m and "Solve_Succeeded" in m for m in messages)
    assert report.findings[0].parameters["delay_s"] == pytest.approx(0.006, abs=0.003)
    assert np.all(np.array(report.rmse_after)[:3] < 0.7 * np.array(report.rmse_before)[:3])


def test_drift_with_a_long_time_constant_tends_to_the_linear_drift():
    class Ctx:  # full rate = grid, exact sign
        n_samples, n_dof = 50, 2
        t = full_t = np.linspace(0.0, 10.0, 50)
        qd = np.column_stack([np.sin(t), np.cos(t)])

        @classmethod
        def friction_sign(cls, joint, factor):
            return factor * np.sign(cls.qd[:, joint])

    linear = FrictionDriftTerm(joint=1).columns(Ctx)
    slow = FrictionDriftTerm(joint=1, time_constant=1e6).columns(Ctx)
    fast = FrictionDriftTerm(joint=1, time_constant=1.0).columns(Ctx)
    np.testing.assert_allclose(slow, linear, rtol=1e-4, atol=1e-9)
    # a short time constant saturates at T: the warm-up is over after a few T
    assert np.max(np.abs(fast)) <= 1.0 + 1e-12 and np.max(np.abs(linear)) > 9.0


def test_a_coefficient_a_later_fit_pushes_out_of_its_bounds_is_not_a_finding(denso, denso_model, diagnosis_log):
    """Load-dependent friction mu = 0.42 on joint 2 (above the 0.4 bound) beside a Coulomb asymmetry of 12 N m that
    hides part of it: screened alone, mu fits 0.37 and qualifies; once the asymmetry is kept, the joint refit takes mu
    to 0.43. The final coefficients are judged by the same rule: the load-dependent friction is rejected with the
    reason ("after the final fit") and the selection runs again without it (issue 25: mu = 0.54 was reported)."""
    from identification.diagnosis import CoulombAsymmetryTerm

    hidden = [xp.LoadDependentFriction(joint=1, coefficient=0.42), xp.CoulombAsymmetry(joint=1, delta=12.0)]
    train, val = recording_pair(denso, hidden, seed=31)
    library = LoadDependentFrictionTerm(joint=1) + CoulombAsymmetryTerm(joint=1)
    # the asymmetry alone lowers joint 2's validation RMSE by 14 % (23 % with one filter period trimmed, where the
    # samples next to the edges weighed more): a gate of 10 % lets the selection run again keep it
    options = DiagnosisOptions(library=library, rigid_body="prior", sparse=False, cv_folds=0, refine=False,
                               min_improvement=0.1)  # fmt: skip
    report = diagnose(denso, train, val, options, model=denso_model)
    assert any("load_dependent_friction[j2] rejected after the final fit" in m for m in diagnosis_log)
    assert "load_dependent_friction" not in report.effects
    (reason,) = [r for label, r in report.rejected if label == "load_dependent_friction[j2]"]
    assert "after the final fit" in reason and "outside (0, 0.4)" in reason
    mu = float(reason.split("mu = ")[1].split(" ")[0])
    assert MAX_LOAD_FRICTION < mu == pytest.approx(0.42, abs=0.03)
    assert report.findings and report.findings[0].label == "coulomb_asymmetry[j2]"


@pytest.mark.parametrize(
    "time_constant, accepted", [(None, True), (0.3, False), (MIN_DRIFT_TIME_CONSTANT_S * 0.9, False), (600.0, True)]
)
def test_a_friction_drift_faster_than_a_thermal_warm_up_is_not_a_drift(time_constant, accepted):
    """Issue 25: the TX40's diagnosis named ``friction_drift[j5]`` with a 0.3 s time constant; heat spreads over
    minutes, so a drift's time constant below the stated bound is rejected, named a start-up transient."""
    term = FrictionDriftTerm(joint=0, time_constant=time_constant)
    reason = term.implausibility(np.array([0.05]), _context(tau_rms=20.0, gravity_amplitude=80.0))
    assert (reason is None) == accepted
    if not accepted:
        assert f"below the {MIN_DRIFT_TIME_CONSTANT_S:g} s of a thermal warm-up" in reason
        assert "start-up transient" in reason


@dataclass(frozen=True)
class StartupFriction(xp.ExtraPhysics):
    """Virtual truth: extra Coulomb friction at the start of each recording, gone with a time constant of
    ``time_constant`` seconds (the first motion after a standstill): ``amplitude exp(-t / T) tanh(qd / v)``."""

    joint: int
    amplitude: float
    time_constant: float
    has_torque = True

    def torque(self, t, q, qd, tau_motor):
        out = np.zeros_like(q)
        out[self.joint] = self.amplitude * np.exp(-t / self.time_constant) * np.tanh(qd[self.joint] / 1e-3)
        return out


def test_a_start_up_friction_transient_is_not_reported_as_a_warm_up_drift(denso, denso_model, diagnosis_log):
    """Truth: joint 2's Coulomb friction 4 N m higher at the start, settling with T = 1 s (not a warm-up). The linear
    screening column ``rate t sign(qd)`` qualifies, the refit's time constant comes out near the truth's, below the
    bound, so the drift is rejected with that reason; a linear drift (the virtual warm-up) keeps a time constant above
    the bound and stays a finding."""
    library = FrictionDriftTerm(joint=1) + TorqueOffsetTerm(joint=1)
    options = DiagnosisOptions(library=library, rigid_body="prior", sparse=False, cv_folds=0)
    train, val = recording_pair(denso, [StartupFriction(joint=1, amplitude=4.0, time_constant=1.0)], seed=7)
    report = diagnose(denso, train, val, options, model=denso_model)
    assert "friction_drift" not in report.effects
    (reason,) = [r for label, r in report.rejected if label == "friction_drift[j2]"]
    settled = float(reason.split("time constant ")[1].split(" s")[0])
    assert settled < MIN_DRIFT_TIME_CONSTANT_S and settled == pytest.approx(1.0, rel=0.5)
    train, val = recording_pair(denso, [xp.FrictionDrift(joint=1, rate=0.4)], seed=7)
    report = diagnose(denso, train, val, options, model=denso_model)
    assert report.effects == ("friction_drift",)
    assert report.findings[0].parameters.get("time_constant_s", np.inf) >= MIN_DRIFT_TIME_CONSTANT_S


def test_the_tx40s_joint_5_friction_change_is_a_start_up_transient_not_a_drift(tx40_benchmark):
    """Issue 25 on the real TX40 recording (skipped without ../shared): beside the wrist coupling, joint 5's friction
    changes by about 7 N m within the first second of the training recording (time constant 0.3 s). With one filter
    period trimmed it was reported as ``friction_drift[j5]`` (a warm-up); now it is rejected with its numbers. With
    identify's three periods trimmed (the default preparation) the transient is gone from the samples and no drift
    qualifies at all."""
    from identification.diagnosis import CouplingTerm

    robot, recording = tx40_benchmark.load_tx40(tx40_benchmark.TX40)
    train, validation = tx40_benchmark.split_two(recording)
    library = CouplingTerm(joint=4, source=5) + CouplingTerm(joint=5, source=4) + FrictionDriftTerm(joint=4)
    options = DiagnosisOptions(cutoff_hz=10.0, library=library, rigid_body="prior", sparse=False, max_effects=3)
    report = diagnose(robot, train, validation, replace(options, edge_periods=1))
    assert "friction_drift" not in report.effects and report.effects == ("coupling", "coupling")
    (reason,) = [r for label, r in report.rejected if label == "friction_drift[j5]"]
    assert float(reason.split("time constant ")[1].split(" s")[0]) < 1.0 and "start-up transient" in reason
    report = diagnose(robot, train, validation, options)
    assert report.effects == ("coupling", "coupling")
