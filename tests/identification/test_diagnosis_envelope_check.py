"""The stand-in rule held to the physical envelope (``envelope_check``, issue 25): a finding the free rigid-body
recalibration makes unnecessary still stands where a rigid body recalibrated inside its envelope needs it.

Reference: the virtual robot's hidden truth. The Denso carries a cam counterbalance on joint 2 (its first harmonic
has the shape of joint 2's gravity, so a free rigid body absorbs it with a link 2 too heavy) and a payload; a spring
on joint 2 is the counterbalance, a torque offset on joint 1 is not there at all.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis.candidates import PayloadTerm, SpringTerm, TorqueOffsetTerm
from identification.diagnosis.diagnose import DiagnosisOptions, DiagnosisProblem, prepare_problem
from identification.diagnosis.envelope_check import EnvelopeCheck, EnvelopedRecalibration, NeededFinding
from identification.diagnosis.rigid_body_choice import Claim, drop_stand_ins, recalibration_parts
from tests.identification.diagnosis_data import CAM, PAYLOAD, held_out_pair


def _selection(*steps):
    """A selection result with ``(term, named joints)`` steps (what the stand-in rule reads)."""
    return SimpleNamespace(steps=tuple(SimpleNamespace(term=t, joints=j) for t, j in steps))


@pytest.fixture(scope="module")
def counterbalanced(denso, denso_model):
    """The diagnosis problem of a Denso with a hidden cam counterbalance on joint 2 and a 1.5 kg payload (8 s
    training, 8 s validation), with the contexts of the recalibrated rigid body."""
    train, validation = held_out_pair(denso, [CAM, PAYLOAD])
    wide = DiagnosisOptions(friction="coulomb_viscous", cutoff_hz=15.0, rate_hz=200.0, samples="diagnosis")
    problem = prepare_problem(denso, denso_model, train, [validation], wide)
    return problem, DiagnosisProblem(**recalibration_parts(problem, denso_model))


def test_the_counterbalance_is_needed_by_an_enveloped_rigid_body_and_a_made_up_offset_is_not(
    denso, denso_model, counterbalanced
):
    problem, recal = counterbalanced
    q = recal.ctx_t.q[:, 1]
    cam = SpringTerm(joint=1, order=3, centre=float(np.mean(q)), q_range=(float(q.min()), float(q.max())))
    selection = _selection((PayloadTerm(), (0, 1, 2)), (cam, (1,)), (TorqueOffsetTerm(joint=0), (0,)))
    judge = EnvelopedRecalibration(denso, denso_model, (recal.ctx_t, recal.ctx_v), (problem.base_t, problem.base_v))
    check = judge.check(selection, (0, 1))
    assert [f.label for f in check.needed] == [cam.label]  # the offset on joint 1 stands in for nothing
    found = check.needed[0]
    assert found.claim == Claim("spring", (1,)) and found.joints == (1,)
    # with the cam's shape the enveloped rigid body predicts joint 2 to a small part of the cam's 12 N m amplitude;
    # without it, it cannot take the counterbalance into link 2 and misses by several times more
    assert found.rmse_with[1] < 0.05 * 12.0
    assert found.rmse_without[1] > 3.0 * found.rmse_with[1]
    assert f"`{cam.label}` kept" in check.notes()[0] and "joint 2:" in check.notes()[0]
    assert len(judge.fits) == 3  # all findings, and all but each tested one: each fit made once
    assert judge.check(selection, (0,)).needed == ()  # the offset alone tested: not needed


def test_drop_stand_ins_keeps_what_the_envelope_needs_and_says_why():
    payload, spring_2, spring_1 = (PayloadTerm(), (0, 1, 2)), (SpringTerm(joint=1), (1,)), (SpringTerm(joint=0), (0,))
    y = np.zeros((10, 3))
    first = (_selection(payload, spring_2, spring_1), SimpleNamespace(prediction_v=np.full((10, 3), 1.0)))
    asked = []

    def envelope(selection, joints):
        asked.append(joints)
        rmse_with = np.array([1.0, 1.0, 1.0])
        return EnvelopeCheck((NeededFinding("spring[j2]", Claim("spring", (1,)), (1,), np.full(3, 9.0), rmse_with),))

    def reselect(instances):
        return _selection(payload, spring_2), first[1]

    instances = (PayloadTerm(), SpringTerm(joint=0), SpringTerm(joint=1))
    # the free recalibration predicts every joint as well as the prior with its springs: both would be stand-ins
    selection, _, notes = drop_stand_ins(reselect, instances, first, _selection(), y, np.ones(3), envelope)
    assert asked[0] == (0, 1)
    assert [s.term.label for s in selection.steps] == ["payload", "spring[j2]"]  # spring[j1] dropped, j2 kept
    assert any("`spring[j2]` kept" in n for n in notes) and any("`spring[j1]` not reported" in n for n in notes)
    # without the envelope check both go
    selection, _, _ = drop_stand_ins(lambda i: (_selection(payload), first[1]), instances, first, _selection(), y,
                                     np.ones(3))  # fmt: skip
    assert [s.term.label for s in selection.steps] == ["payload"]


@pytest.mark.slow
def test_diagnosing_the_heavy_arm_finds_its_cam_counterbalance(benchmark_modules):
    """The issue's case, as ``benchmarks/heavy_arm.py`` runs it (seed 0): a 1 t arm, CAD inertias 10-20 % off in the
    truth, a cam counterbalance on joint 2 and a 145 kg payload, 10 s training and 10 s validation at 250 Hz,
    diagnosed against the robot file on the preparation ``psdm identify`` chooses. The free recalibration absorbs the
    counterbalance into link 2; the enveloped one cannot, so the counterbalance on joint 2 stands beside the payload.
    Written on the old cam, found as a spring kept beside the payload; the physical balancer is nearly constant over
    the recorded range and is named a counterbalance (``counterbalance_naming``) from the offset that takes it."""
    from diagnosis import _scenario
    from heavy_arm import EFFECTS, heavy_industrial_arm

    from identification.calibration.model_preparation import default_preparation
    from identification.diagnosis.diagnose import diagnose
    from psdm_casadi.derive import derive_psdm

    robot = heavy_industrial_arm()
    truth, train, validation = _scenario("heavy", robot, EFFECTS, np.random.default_rng(0), 0)
    assert [key for key, *_ in truth] == ["cam_counterbalance", "payload"]
    preparation = default_preparation(train)
    options = DiagnosisOptions(cutoff_hz=preparation.cutoff_hz, rate_hz=preparation.grid_rate_hz)
    report = diagnose(robot, train, [validation], options, model=derive_psdm(robot))
    found = {(f.effect, f.joints[0] if f.effect != "payload" else None) for f in report.findings}
    assert ("counterbalance", 1) in found
    assert ("payload", None) in found
    payload = next(f for f in report.findings if f.effect == "payload")
    assert abs(payload.parameters["mass"] - truth[1][3]["mass"]) < 0.3 * truth[1][3]["mass"]
