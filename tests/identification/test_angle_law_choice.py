"""An angle law the free recalibration matches only by moving a link's gravity far from the robot file stands
(``angle_law_choice``, issue 25: the HX-210 gas spring lost to a recalibration with one finding fewer).

Reference: Pinocchio's gravity torque (the oracle's RNEA at rest) of the virtual Denso's robot file and of that file
with link 2's first moment changed, on a sine recording; the "recalibrated" base parameters are those of the changed
file and the spring is fitted by least squares to the gravity torque the change removed from joint 2 (the torque a
balancer would stand for).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.gravity_departure import FILE_GRAVITY_ERROR
from identification.diagnosis.angle_law_choice import gravity_backed_laws
from identification.diagnosis.candidates import SpringTerm
from identification.diagnosis.rigid_body_choice import prior_wins
from psdm_casadi.oracle import PinocchioOracle
from tests.identification.diagnosis_data import cli_json, sine_context


def _moved(robot, factor):
    """``robot`` with link 2's centre of mass (its first moment) times ``factor``."""
    links = list(robot.links)
    links[1] = dataclasses.replace(links[1], com=tuple(np.asarray(links[1].com) * factor))
    return robot.with_links(tuple(links), rotor_inertia=robot.rotor_inertia)


@pytest.fixture(scope="module")
def context(denso, denso_model):
    return sine_context(denso, denso_model, seed=5)


def _judge(denso, denso_model, context, factor, scale=1.0):
    """The rule on a recalibration that made link 2's first moment ``factor`` times the file's, the prior's spring on
    joint 2 fitted to the gravity torque that took away (times ``scale``)."""
    changed = _moved(denso, factor)
    q = context.q
    rest = np.zeros_like(q)
    removed = PinocchioOracle(denso).rnea(q, rest, rest) - PinocchioOracle(changed).rnea(q, rest, rest)
    lo, hi = float(q[:, 1].min()), float(q[:, 1].max())
    spring = SpringTerm(joint=1, q_range=(lo, hi))
    column = np.asarray(spring.columns(context), dtype=float)[:, 1, :]
    coefficients = scale * np.linalg.lstsq(column, -removed[:, 1], rcond=None)[0]
    theta = np.asarray(denso_model.base_parameters(changed.nominal_dynamic_parameters()), dtype=float)
    finding = SimpleNamespace(effect="spring", joints=(1,))
    backed = gravity_backed_laws(denso, denso_model, context, theta, [spring], [coefficients], [finding], context)
    gravity = PinocchioOracle(denso).rnea(q, rest, rest)[:, 1]
    return backed, float(np.sqrt(np.mean(removed[:, 1] ** 2)) / np.sqrt(np.mean(gravity**2))), coefficients


def test_a_spring_the_recalibration_took_into_a_link_far_from_the_file_stands(denso, denso_model, context):
    backed, share, coefficients = _judge(denso, denso_model, context, factor=-1.0)
    assert share > 1.5 * FILE_GRAVITY_ERROR  # the reference: a departure no CAD error explains
    assert coefficients[0] > 0.0  # link 2's moment taken away looks like a restoring spring
    assert [b.label for b in backed] == ["spring[j2]"] and backed[0].joint == 1
    assert backed[0].departure == pytest.approx(share * backed[0].file_gravity, rel=1e-6)
    assert backed[0].remainder < FILE_GRAVITY_ERROR * backed[0].file_gravity
    assert "spring[j2]" in backed[0].note() and "joint 2" in backed[0].note()


def test_a_cad_sized_departure_a_wrong_sign_or_another_torque_does_not(denso, denso_model, context):
    backed, share, _ = _judge(denso, denso_model, context, factor=0.85)  # link 2's moment 15 % off (CAD)
    assert share < FILE_GRAVITY_ERROR and backed == ()
    assert _judge(denso, denso_model, context, factor=-1.0, scale=-1.0)[0] == ()  # negative stiffness: no spring
    assert _judge(denso, denso_model, context, factor=-1.0, scale=0.2)[0] == ()  # the departure is not its torque


def test_the_backed_law_is_not_counted_a_payload_still_is():
    weights = np.ones(3)
    rmse = ([1.5, 2.5, 1.0], [1.0, 2.0, 0.5], [1.0, 1.9, 0.5])  # the prior within the tolerance of the recalibration
    assert not prior_wins(*rmse, weights, ("spring",), ())
    assert prior_wins(*rmse, weights, ("spring",), (), counted=())
    assert not prior_wins(*rmse, weights, ("payload", "spring"), (), counted=("payload",))


@pytest.mark.slow
def test_the_hx210_s_gas_spring_is_named_against_its_datasheet_robot_file(benchmark_modules, tmp_path):
    """The HX-210 case at seed 1 (``heavy_gas_spring_datasheet``: link masses 10-20 % off, a gas spring on joint 2,
    a 150 kg known payload): ``diagnose ROBOT`` names the balancer on joint 2 with a positive stiffness."""
    import unseen_arms

    case = unseen_arms.build("heavy_gas_spring_datasheet", tmp_path, 1)
    found = cli_json(["diagnose", case.robot, "--train", case.train[-1], "--validate", case.validate, "--json"])
    balancers = [f for f in found["findings"] if f["effect"] in ("spring", "gas_spring")]
    assert [f["joints"] for f in balancers] == [[2]]  # 1-based in the JSON
    assert balancers[0]["parameters"].get("k", balancers[0]["parameters"].get("k_ab", 0.0)) > 0.0
    assert found["rigid_body"] == "prior"
    assert any("links were made to carry the balancer" in note for note in found["rigid_body_notes"])
