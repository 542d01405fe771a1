"""A low-harmonic "ripple" as large as the joint's gravity torque is named a counterbalance; motor ripple stays ripple.

Reference: the virtual Denso's hidden truth. A cam counterbalance on joint 2 (``amplitude sin x (1 + lobe cos 2x)``:
one and three periods per revolution) is found by a library of ripples and named a counterbalance with its
amplitude, its period count and its share of the joint's gravity torque (computed here from the PSDM model's own
inverse dynamics at rest); a small ripple of eight periods per revolution keeps the ripple name. The naming rule
itself is checked at its thresholds on a hand-made context.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.diagnosis_prior import carried_findings
from identification.calibration.offset_reading import GRAVITY_SHARE as OFFSET_GRAVITY_SHARE
from identification.calibration.offset_reading import SENSOR_SHARE, oversized_offset
from identification.diagnosis import CandidateLibrary, DiagnosisOptions, TorqueRippleTerm, diagnose
from identification.diagnosis.counterbalance_naming import (
    COUNTERBALANCE,
    GRAVITY_SHARE,
    LOW_HARMONIC,
    name_counterbalances,
)
from identification.diagnosis.report import Finding
from identification.virtual import effects as xp
from tests.identification.diagnosis_data import recording_pair

LIB = CandidateLibrary((TorqueRippleTerm(harmonics=(1, 2, 3, 8)),))


def _gravity_amplitude(model, robot, q) -> float:
    """The largest |gravity torque| on joint 2 over the angles ``q``, from the PSDM model at rest."""
    zero = np.zeros_like(q)
    tau = model.inverse_dynamics(q, zero, zero, model.base_parameters(robot.nominal_dynamic_parameters()))
    return float(np.max(np.abs(tau[:, 1])))


@pytest.mark.slow
def test_a_counterbalance_found_as_a_low_harmonic_is_named_a_counterbalance(denso, denso_model):
    train, val = recording_pair(denso, [], seed=4, train_s=6.0, val_s=4.0)
    gravity = _gravity_amplitude(denso_model, denso, train.q)
    amplitude = 0.6 * gravity  # a balancer sized to most of the shoulder's gravity torque
    cam = xp.CamCounterbalance(joint=1, amplitude=amplitude, q0=0.1, lobe=0.3)
    train, val = recording_pair(denso, [cam], seed=4, train_s=6.0, val_s=4.0)
    report = diagnose(denso, train, val, DiagnosisOptions(library=LIB, rigid_body="prior"), model=denso_model)
    on_2 = [f for f in report.findings if f.joints == (1,)]
    first = on_2[0]
    assert {f.effect for f in on_2} == {COUNTERBALANCE}, [(f.label, f.parameters) for f in on_2]
    # the findings on joint 2 together are the cam's torque over the recorded angles
    q = train.q[:, 1]
    found = sum(f.coefficients[0] * np.sin(f.parameters["harmonic"] * q) + f.coefficients[1]
                * np.cos(f.parameters["harmonic"] * q) for f in on_2)  # fmt: skip
    truth = cam.torque(None, train.q.T, None, None)[1]
    assert np.sqrt(np.mean((found - truth) ** 2)) < 0.1 * np.sqrt(np.mean(truth**2)), [f.label for f in on_2]
    assert first.parameters["gravity_torque"] == pytest.approx(gravity, rel=0.1)
    assert "counterbalance or spring" in first.explanation and "joint 2" in first.explanation
    assert f"{first.parameters['amplitude']:.4g} N m" in first.explanation
    assert "torque_ripple" not in report.effects
    assert report.rmse_after[1] < 0.3 * report.rmse_before[1]
    # the model file holding this term says it carries the counterbalance when diagnosed again
    document = {"findings": [{"kind": "torque", "term": {"effect": "torque_ripple", "joint": 2, "harmonic": 1}}]}
    assert carried_findings(report.findings, document) == tuple(f.label for f in on_2)


@pytest.mark.slow
def test_a_true_motor_ripple_keeps_the_ripple_name(denso, denso_model):
    ripple = xp.TorqueRipple(joint=1, amplitude=1.0, harmonic=8.0, phase=0.4)
    train, val = recording_pair(denso, [ripple], seed=1, train_s=6.0, val_s=4.0)
    report = diagnose(denso, train, val, DiagnosisOptions(library=LIB, rigid_body="prior"), model=denso_model)
    assert [(f.effect, f.label) for f in report.findings] == [("torque_ripple", "torque_ripple[j2,h=8]")]
    assert report.findings[0].parameters["amplitude"] == pytest.approx(1.0, rel=0.1)
    assert "motor cogging" in report.findings[0].explanation


def _ripple(harmonic: int, amplitude: float, joint: int = 1) -> Finding:
    """A ripple finding ``amplitude cos(harmonic q)`` (its peak at q = 0)."""
    parameters = {"amplitude": amplitude, "harmonic": float(harmonic), "phase": np.pi / 2}
    return Finding("torque_ripple", f"torque_ripple[j{joint + 1},h={harmonic}]", (joint,), parameters,
                   (0.0, amplitude), ("s", "c"), "ripple", "sig", (1.0, 1.0), (0.5, 0.5), -10.0, 0.5)  # fmt: skip


@pytest.mark.parametrize(
    ("ripples", "effect"),
    [
        ([(2, 1.01)], COUNTERBALANCE),
        ([(LOW_HARMONIC, 3.0)], COUNTERBALANCE),
        ([(1, 0.6), (2, 0.6)], COUNTERBALANCE),  # one counterbalance fitted as two harmonics: their sum counts
        ([(2, 0.99)], "torque_ripple"),  # small against gravity: ripple
        ([(LOW_HARMONIC + 1, 3.0)], "torque_ripple"),  # more periods per revolution than a load: ripple
        ([(2, 3.0, 0)], "torque_ripple"),  # joint 1 carries no gravity to balance
    ],
)
def test_the_rule_at_its_thresholds(ripples, effect):
    """Amplitudes in units of ``GRAVITY_SHARE`` of joint 2's gravity torque of 100 N m; joint 1 has no gravity torque
    but 100 N m of measured torque (a vertical axis)."""
    q = np.linspace(-1.0, 1.0, 51)
    context = SimpleNamespace(q=np.column_stack([q, q]), gravity=np.column_stack([0 * q, 100.0 * np.cos(q)]),
                              tau=np.full((51, 2), 100.0))  # fmt: skip
    findings = [_ripple(h, a * GRAVITY_SHARE * 100.0, *j) for h, a, *j in ripples]
    named = name_counterbalances(findings, context)
    assert [f.effect for f in named] == [effect] * len(findings)
    assert [(f.label, f.coefficients) for f in named] == [(f.label, f.coefficients) for f in findings]
    if effect == COUNTERBALANCE:
        peak = sum(a for _, a, *_ in ripples) * GRAVITY_SHARE * 100.0
        assert named[0].parameters["peak_torque"] == pytest.approx(peak)
        assert named[0].parameters["gravity_share"] == pytest.approx(peak / 100.0)
    without_gravity = SimpleNamespace(q=context.q, gravity=None, tau=context.tau)
    assert {f.effect for f in name_counterbalances(findings, without_gravity)} == {"torque_ripple"}


def _offset(value: float, joint: int = 1) -> Finding:
    return Finding("torque_offset", f"torque_offset[j{joint + 1}]", (joint,), {"offset": value}, (value,),
                   (f"offset_{joint + 1}",), "bias", "sig", (1.0, 1.0), (0.5, 0.5), -10.0, 0.5)  # fmt: skip


@pytest.mark.parametrize(
    ("offset", "joint", "effect"),
    [
        (-40.0, 1, COUNTERBALANCE),  # 40 % of joint 2's gravity torque, 13 % of its peak: no sensor's zero error
        (0.3, 1, "torque_offset"),  # a sensor's offset (the virtual SCARA's size)
        (SENSOR_SHARE * 300.0 * 0.99, 1, "torque_offset"),  # 30 % of gravity, just under a tenth of the peak
        (60.0, 0, "torque_offset"),  # joint 1 carries no gravity: no balancer
    ],
)
def test_an_offset_no_sensor_has_is_named_a_counterbalance(offset, joint, effect):
    """Reference: the sizes of a sensor's zero error against a balancer's. Joint 2: a gravity torque of 100 N m
    amplitude, a recorded peak of 300 N m; joint 1 a vertical axis (no gravity
    torque, 300 N m recorded). The finding keeps its label and coefficient (its term is applied as found)."""
    q = np.linspace(-0.3, 0.3, 51)
    context = SimpleNamespace(q=np.column_stack([q, q]), gravity=np.column_stack([0 * q, 100.0 * np.cos(q)]),
                              tau=np.full((51, 2), 300.0))  # fmt: skip
    assert OFFSET_GRAVITY_SHARE * 100.0 < SENSOR_SHARE * 300.0  # the sensor's share decides the third case
    (named,) = name_counterbalances([_offset(offset, joint)], context)
    assert named.effect == effect
    assert (named.label, named.coefficients) == (f"torque_offset[j{joint + 1}]", (offset,))
    if effect == COUNTERBALANCE:
        assert named.parameters["gravity_share"] == pytest.approx(abs(offset) / 100.0)
        assert "joint 2" in named.explanation and "zero error is a few percent" in named.explanation


def test_a_carried_file_offset_is_not_named():
    """A model file's carried offset column (``diagnosis.file_offsets``) fits how far the file's offset is off: at the
    size the rule names a counterbalance (-40 N m on joint 2 above), it stays a ``torque_offset`` for ``file_offsets``
    to read, and an offset of the library beside it on another joint is still named."""
    q = np.linspace(-0.3, 0.3, 51)
    gravity = np.column_stack([0 * q, 100.0 * np.cos(q), 100.0 * np.cos(q)])
    context = SimpleNamespace(q=np.column_stack([q, q, q]), gravity=gravity, tau=np.full((51, 3), 300.0))
    found = [_offset(-40.0, 1), _offset(-40.0, 2)]
    carried, library = name_counterbalances(found, context, carried={"torque_offset[j2]"})
    assert (carried.effect, carried.coefficients) == ("torque_offset", (-40.0,))
    assert library.effect == COUNTERBALANCE


@pytest.mark.parametrize(
    ("ripple", "offset", "effect"),
    [
        ((2, 0.5, 1), -40.0, COUNTERBALANCE),  # beside the counterbalance's offset: its shape, below the gravity share
        ((2, 0.5, 1), 0.3, "torque_ripple"),  # beside a sensor's offset: a ripple, small against gravity
        ((LOW_HARMONIC + 1, 0.5, 1), -40.0, "torque_ripple"),  # more periods per revolution than a load: ripple
        ((2, 0.5, 2), -40.0, "torque_ripple"),  # on another joint than the counterbalance's offset
    ],
)
def test_a_low_harmonic_beside_a_counterbalances_offset_is_its_shape(ripple, offset, effect):
    """Reference: the sizes of ``test_an_offset_no_sensor_has_is_named_a_counterbalance`` (joints 2 and 3 with 100
    N m of gravity torque and 300 N m recorded). The ripple is half the gravity share that names a ripple a
    counterbalance alone; beside an offset named a counterbalance on its joint it is that counterbalance's shape."""
    q = np.linspace(-0.3, 0.3, 51)
    gravity = np.column_stack([0 * q, 100.0 * np.cos(q), 100.0 * np.cos(q)])
    context = SimpleNamespace(q=np.column_stack([q, q, q]), gravity=gravity, tau=np.full((51, 3), 300.0))
    harmonic, share, joint = ripple
    found = [_offset(offset, 1), _ripple(harmonic, share * GRAVITY_SHARE * 100.0, joint)]
    named_offset, named = name_counterbalances(found, context)
    assert named.effect == effect and (named.label, named.coefficients) == (found[1].label, found[1].coefficients)
    if effect == COUNTERBALANCE:
        assert named_offset.effect == COUNTERBALANCE
        assert named.explanation.startswith("the shape of joint 2's counterbalance, whose torque the offset")
        assert named.parameters["counterbalance_offset"] == pytest.approx(offset)


def test_the_offset_reading_at_its_thresholds():
    """``oversized_offset`` on its own: the sensor share of the peak, the gravity share, a joint gravity loads."""
    assert oversized_offset(1, 25.0, gravity=100.0, peak=200.0) is not None
    assert oversized_offset(1, 19.0, gravity=100.0, peak=200.0) is None  # 19 % of gravity: < GRAVITY_SHARE
    assert oversized_offset(1, 19.0, gravity=90.0, peak=200.0) is None  # 9.5 % of the peak: < SENSOR_SHARE
    assert oversized_offset(1, 50.0, gravity=10.0, peak=200.0) is None  # gravity 5 % of the peak: not loaded
    reading = oversized_offset(1, -50.0, gravity=100.0, peak=200.0)
    assert (reading.gravity_share, reading.peak_share) == (0.5, 0.25)
    assert "-50 N m on joint 2 is 50% of its gravity torque" in reading.sentence()
