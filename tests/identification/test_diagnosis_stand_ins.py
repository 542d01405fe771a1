"""Findings that only stand in for a wrong prior (``rigid_body_choice.stand_ins``): when the prior model needed an
inertial finding, its other findings are judged against the diagnosis with the rigid body identified."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from identification.diagnosis.candidates import GravityTiltTerm, PayloadTerm, SpringTerm, TorqueRippleTerm
from identification.diagnosis.rigid_body_choice import drop_stand_ins, stand_ins, without_stand_ins


def _selection(*steps):
    """A selection result with ``(term, named joints)`` steps (what ``stand_ins`` reads)."""
    return SimpleNamespace(steps=tuple(SimpleNamespace(term=t, joints=j) for t, j in steps))


PAYLOAD = (PayloadTerm(), (0, 1, 2))
SPRING_1, SPRING_2 = (SpringTerm(joint=0), (0,)), (SpringTerm(joint=1), (1,))
TILT = (GravityTiltTerm(), (0, 1))


def test_a_finding_the_identified_rigid_body_does_not_need_is_a_stand_in():
    prior = _selection(PAYLOAD, SPRING_2, SPRING_1)
    identified = _selection((TorqueRippleTerm(joint=1, harmonic=2), (1,)))  # joint 2 needs a term there too
    # joint 1: the prior with its spring predicts no better than the recalibrated rigid body (66 vs 64 N m)
    assert stand_ins(prior, identified, np.array([66.0, 90.0, 5.0]), np.array([64.0, 200.0, 5.0])) == ((0,), ())
    # the same spring stands when the prior model with it predicts joint 1 clearly better (40 < 0.8 x 64)
    assert stand_ins(prior, identified, np.array([40.0, 90.0, 5.0]), np.array([64.0, 200.0, 5.0])) == ((), ())


def test_without_an_inertial_finding_the_prior_is_trusted():
    prior = _selection(SPRING_2, SPRING_1)
    assert stand_ins(prior, _selection(), np.array([66.0, 90.0]), np.array([10.0, 10.0])) == ((), ())


def test_a_robot_wide_stand_in_is_named_by_its_effect_and_left_out_of_the_candidates():
    prior = _selection(PAYLOAD, TILT)
    joints, keys = stand_ins(prior, _selection(), np.array([60.0, 70.0, 5.0]), np.array([61.0, 69.0, 5.0]))
    assert (joints, keys) == ((), ("gravity_tilt",))
    # a term the identified diagnosis keeps on one of the tilt's joints does not support a tilt
    ripple = _selection((TorqueRippleTerm(joint=1, harmonic=2), (1,)))
    assert stand_ins(prior, ripple, np.array([60.0, 70.0, 5.0]), np.array([61.0, 69.0, 5.0])) == ((), ("gravity_tilt",))
    instances = (PayloadTerm(), GravityTiltTerm(), SpringTerm(joint=0), SpringTerm(joint=1), TorqueRippleTerm(joint=0))
    kept = without_stand_ins(instances, (0,), keys)
    assert [t.label for t in kept] == ["payload", "spring[j2]"]


def test_drop_stand_ins_repeats_the_selection_without_them_and_says_why():
    y = np.zeros((10, 3))
    fits = []

    def reselect(instances):
        fits.append([t.label for t in instances])
        return _selection(PAYLOAD, SPRING_2), SimpleNamespace(prediction_v=np.full((10, 3), 1.0))

    first = (_selection(PAYLOAD, SPRING_2, SPRING_1), SimpleNamespace(prediction_v=np.full((10, 3), 1.0)))
    identified = _selection((SpringTerm(joint=1), (1,)))
    instances = (PayloadTerm(), SpringTerm(joint=0), SpringTerm(joint=1))
    selection, _, notes = drop_stand_ins(reselect, instances, first, identified, y, np.array([1.0, 9.0, 1.0]))
    assert fits == [["payload", "spring[j2]"]]  # the spring on joint 1 is no candidate any more
    assert [s.term.label for s in selection.steps] == ["payload", "spring[j2]"]
    assert len(notes) == 1 and "`spring[j1]` not reported as missing physics" in notes[0]
