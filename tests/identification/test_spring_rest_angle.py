"""A spring finding states its rest angle: the angle where its torque, with the constant fitted beside it, is zero.

A new user read the demo's spring as "neutral angle q0 = -0.6016" beside an offset of -5.983 N m (the odd law's centre
and its constant), and identify's Denso spring as "centre -0.1024" beside a joint-4 torque offset of -2.986 N m (the
spring's constant absorbed by that offset: one column), while the README promised "rest 0.398 rad". The reference is
the virtual arm's spring (``identification.virtual.effects.Spring``: ``k (q - q0)``, k = 6 N m/rad, q0 = 0.4 rad on
joint 4, the demo's and ``benchmarks/diagnosis.py``'s spring scenario), whose torque both laws fit exactly over the
range the Denso recording covers.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.findings import FindingTerm
from identification.calibration.spring_rest import rest_angle_text, with_rest_angles
from identification.diagnosis.candidates import SpringTerm
from identification.virtual import effects as xp

TRUTH = xp.Spring(joint=3, stiffness=6.0, q0=0.4)
Q = np.linspace(-0.71, 0.505, 200)  # the Denso training recording's joint-4 range (its model file's q_range)


def _fitted(term) -> np.ndarray:
    """``term``'s coefficients fitted (least squares) to the truth's torque over ``Q``."""
    torque = np.array([TRUTH.torque(0.0, np.r_[0.0, 0.0, 0.0, q, 0.0, 0.0], None, None)[3] for q in Q])
    n = len(term.feature_names())
    columns = np.column_stack([term.torque_of_angle(Q, np.eye(n)[i]) for i in range(n)])
    return np.linalg.lstsq(columns, torque, rcond=None)[0]


def test_the_odd_law_states_where_its_torque_is_zero_not_only_its_neutral_angle():
    term = SpringTerm(joint=3, order=5, centre=-0.6016, q_range=(Q[0], Q[-1]), odd=True)  # the demo's neutral angle
    c = _fitted(term)
    parameters = term.physical_parameters(c)
    assert parameters["neutral_angle"] == pytest.approx(-0.6016)
    assert parameters["offset"] == pytest.approx(6.0 * (-0.6016 - 0.4), rel=1e-6)  # its torque at q0: a constant
    assert parameters["rest_angle"] == pytest.approx(TRUTH.q0, abs=1e-6)
    assert "zero torque (its rest angle) at q = 0.4 rad" in term.interpret(c)[1]


def test_a_spring_whose_constant_the_joints_offset_holds_states_the_rest_angle_with_it():
    term = SpringTerm(joint=3, order=3, centre=-0.1024, q_range=(Q[0], Q[-1]))  # identify's cubic about the middle
    *k, constant = _fitted(term)
    entry = {"effect": "spring", "kind": "torque", "joints": [4], "label": term.label, "absorbed": ["c_4"],
             "term": FindingTerm("spring", 3, spec=term.spec()).to_dict(), "coefficients": [*k, None],
             "parameters": {}}  # fmt: skip
    names = [f"{p}{j}" for j in range(1, 7) for p in ("fc", "fv", "offset")]
    drive = {"names": names, "values": [constant if name == "offset4" else 1.0 for name in names]}
    (stated,) = with_rest_angles([entry], drive)
    assert stated["parameters"]["rest_angle"] == pytest.approx(TRUTH.q0, abs=1e-6)
    assert stated["parameters"]["rest_angle_offset"] == pytest.approx(constant)
    assert "zero torque at q = 0.4 rad (with joint 4's torque offset" in rest_angle_text(stated)
    (alone,) = with_rest_angles([entry], None)  # the spring's columns alone: the centre's root, not the rest angle
    assert abs(alone["parameters"]["rest_angle"] - TRUTH.q0) > 0.4
