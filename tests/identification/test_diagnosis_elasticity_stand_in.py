"""A joint elasticity does not stand in for pre-sliding that does not hold (issue 25).

A compliance shifts the velocity the friction sees by ``c dtau/dt``: its fitted torque lives at the velocity reversals,
where a LuGre bristle's pre-sliding lives too (on the benchmark's true wrist elasticity, scenario 12, 0.089 of its
0.090 N m come from that shift, 0.31 N m RMS near the reversals against 0.02 elsewhere; on the unseen UR5-like arm's
friction-dominated joint 5, with no elasticity, 0.09 against 0.01). Where a friction shape on the joint explained the
validation recording better but did not hold on the second opinion, the elasticity chosen after it is not named
(``FrictionRival.stand_in``); where it beats them but not pre-sliding alone on every held-out training block, the pair
is reported (``presliding_or_elasticity``, tested in ``test_presliding_or_elasticity.py``). Known truth: the unseen
UR5-like arm (LuGre drives, no elasticity) from ``benchmarks/unseen_cases.py``, and the virtual Denso with a wrist
elasticity beside the pre-sliding candidates."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.candidates import CandidateLibrary, JointElasticityTerm
from identification.diagnosis.candidates.deflection import BacklashTerm
from identification.diagnosis.candidates.friction import lacking_friction_shapes
from identification.diagnosis.friction_rival import FrictionRival
from identification.diagnosis.second_opinion import UnstableFinding
from identification.virtual.transmission_effects import JointElasticity
from tests.identification.diagnosis_data import sine_recording


def _unstable(effect, label, joint):
    return UnstableFinding(effect=effect, label=label, joints=(joint,), route="block cross-validation", opinions=())


def test_an_elasticity_after_a_friction_shape_refused_on_its_joint_is_a_stand_in():
    rival = FrictionRival(None, [])
    elastic = JointElasticityTerm(joint=4)
    presliding = _unstable("presliding", "presliding[j5]", 4)
    sentence = rival.stand_in(elastic, [presliding])
    assert sentence.startswith("joint_elasticity[j5] not named: presliding[j5]") and rival.sentences == [sentence]
    assert rival.stand_in(elastic, [_unstable("presliding", "presliding[j4]", 3)]) is None  # another joint
    assert rival.stand_in(elastic, [_unstable("delay", "delay", 4)]) is None  # not a friction shape
    assert rival.stand_in(BacklashTerm(joint=4), [presliding]) is None  # the rule is the elasticity's


def _wrist_case(denso, denso_model, joint):
    """(report, true stiffness): the Denso's LuGre friction diagnosed with a Coulomb-viscous nominal, 4 s of training,
    a torsion of 0.2 deg at ``joint``'s RMS torque; the library the elasticity and the friction shapes it lacks."""
    train, _ = sine_recording(denso, 0, 4.0, ())
    k = float(np.sqrt(np.mean(train.tau[:, joint] ** 2))) / np.radians(0.2)
    extras = (JointElasticity(joint=joint, stiffness=k),)
    train, _ = sine_recording(denso, 0, 4.0, extras)
    validation, _ = sine_recording(denso, 1, 3.0, extras)
    library = JointElasticityTerm() + CandidateLibrary(lacking_friction_shapes())
    options = DiagnosisOptions(rigid_body="prior", sparse=False, library=library, friction="coulomb_viscous")
    return diagnose(denso, train, validation, options, model=denso_model), k


def test_a_true_elasticity_beside_the_pre_sliding_a_nominal_model_lacks_is_reported_as_the_pair(denso, denso_model):
    # the Denso's LuGre friction diagnosed with a Coulomb-viscous nominal: its bristles' pre-sliding and the elasticity
    # on joint 5 are both in the data. On 4 s of training the elasticity fits the validation recording a little better
    # than pre-sliding alone but does not hold on the training blocks held out in turn: the pair is reported on the
    # elasticity's joint (``presliding_or_elasticity``), and only pre-sliding, there too, is named
    joint = 4
    report, _ = _wrist_case(denso, denso_model, joint)
    assert not [f for f in report.findings if f.effect == "joint_elasticity"], report.summary()
    (pair,) = [s for s in report.dropped if s.startswith(f"pre-sliding or elasticity on joint {joint + 1}: ")]
    assert "the data cannot tell them apart" in pair and "to tell them apart, record" in pair
    assert any(f.effect == "presliding" and f.joints == (joint,) for f in report.findings), report.summary()


def test_a_true_wrist_elasticity_that_holds_where_the_joint_moves_is_named(denso, denso_model):
    # the same on joint 6: with its standstill samples in the training blocks (the friction holds whatever the
    # controller asks there, which neither rival explains) the elasticity won one block of four and the pair was
    # reported; on the samples where the joint moves (``standstill``) it wins, and the true elasticity is named
    report, k = _wrist_case(denso, denso_model, 5)
    (found,) = [f for f in report.findings if f.effect == "joint_elasticity"]
    assert found.joints == (5,) and 0.5 < found.parameters["stiffness_Nm_per_rad"] / k < 2.0, report.summary()
    assert not [s for s in report.dropped if s.startswith("pre-sliding or elasticity on joint 6: ")]


@pytest.mark.slow
def test_the_unseen_ur5_s_friction_dominated_wrist_gets_no_elasticity(tmp_path):
    # the UR5-like arm on motor currents (500 Hz, LuGre drives, no elasticity): identify, then diagnose as
    # benchmarks/unseen_arms.py runs them; joint 5's reversals are what an elasticity could stand in for
    # (3900-4600 N m/rad, 0.02 deg at the joint's RMS torque), and it is not named
    bench = str(Path(__file__).resolve().parents[2] / "benchmarks")
    sys.path.insert(0, bench)
    try:
        import unseen_arms

        case = unseen_arms.build("cobot_currents_payload", tmp_path, 0)
        model, layout = tmp_path / "model.json", list(case.extra)
        code, _, text, _ = unseen_arms._cli(["identify", case.robot, "--data", *case.train, "--validate",
                                             case.validate, *layout, "--out", model, "--json"])  # fmt: skip
        assert code == 0, text
        code, report, text, _ = unseen_arms._cli(["diagnose", model, "--train", case.train[-1], "--validate",
                                                  case.validate, *layout, "--json"])  # fmt: skip
    finally:
        sys.path.remove(bench)
    assert code == 0, text
    assert not [f for f in report["findings"] if f["effect"] == "joint_elasticity"], json.dumps(report["findings"])
    # they are taken by the pre-sliding the truth's LuGre drive has: since diagnose MODEL fits the file's drive
    # inertias again beside its findings (475add4), pre-sliding on joint 5 holds on the blocks and is found, more than
    # halving the joint's validation error (before, it did not hold, and the elasticity tried after it was unstable)
    presliding = [f for f in report["findings"] if f["effect"] == "presliding" and f["joints"] == [5]]
    assert presliding, json.dumps(report["findings"])
    assert presliding[0]["rmse_after"][4] < 0.5 * presliding[0]["rmse_before"][4]
