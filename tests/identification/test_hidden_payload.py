"""A tool the free rigid-body recalibration takes into the links is named a payload (``hidden_payload``, issue 25).

Reference: the virtual robot's hidden truth. The Denso, its links' masses, centres of mass and inertias 10-20 % off the
robot file in the truth (CAD values), carries a tool at the flange several times its wrist's mass: the free
recalibration fits it into the links; a rigid body inside its envelope cannot, and needs a body at the flange, named
with the truth's mass and centre of mass. The same arm without the tool gets none. Stated in the identified
diagnosis, the payload leaves the model's prediction as it was and the links without the tool.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.carried_payload import flange_parameter_map
from identification.diagnosis.candidates import PayloadTerm
from identification.diagnosis.envelope_check import EnvelopedFit, EnvelopedRecalibration
from identification.diagnosis.hidden_payload import (
    MIN_JOINTS,
    PAYLOAD_MARGIN,
    carried_estimate,
    flange_carriers,
    hidden_payload,
    name_hidden_payload,
)
from identification.diagnosis.report_assembly import augmented_model_of
from identification.metrics import rmse
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.identification.diagnosis_data import cad_off, identified_diagnosis
from trajopt.experiments import sine_experiment

NOISE = 0.1  # torque sensor noise [N m]
TOOL = xp.Payload(mass=5.0, com=(0.0, 0.0, 0.1))  # the Denso's wrist link weighs 0.8 kg in its robot file


def _identified(robot, model, extras):
    """The CAD-off Denso carrying ``extras`` (12 s, the last 4 s validating): the prior's and the identified diagnosis
    problem, the identified selection and final fit without a candidate (friction and the rigid body identified), its
    options and its enveloped recalibration."""
    rng = np.random.default_rng(7)
    truth = cad_off(robot, rng)
    reference = sine_experiment(robot, duration=12.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=NOISE, friction=False)
    recording, _ = simulate_recording(truth, reference, options, rng, extras=extras)
    problem, recal, selection, final, identified = identified_diagnosis(robot, model, recording)
    enveloped = EnvelopedRecalibration(robot, model, (recal.ctx_t, recal.ctx_v), (problem.base_t, problem.base_v))
    return (problem, recal), (selection, final), identified, enveloped


@pytest.fixture(scope="module")
def with_tool(denso, denso_model):
    return _identified(denso, denso_model, [TOOL])


def test_a_tool_the_free_recalibration_absorbs_is_named_with_its_mass_and_centre_of_mass(denso, denso_model,
                                                                                         with_tool):  # fmt: skip
    (problem, recal), (_, final), _, enveloped = with_tool
    # the free rigid body predicts the tool: its validation error is at the noise on every joint
    assert np.all(rmse(recal.y_v, final.prediction_v) < 3 * NOISE)
    payload = hidden_payload(enveloped, final.terms)
    assert payload is not None and len(payload.joints) >= MIN_JOINTS
    without, body = payload.without.rmse_validation, payload.with_body.rmse_validation
    assert all(body[j] <= (1.0 - PAYLOAD_MARGIN) * without[j] for j in payload.joints)
    # its size: the links that could carry it held at the robot file (a mass at the wrist centre is fixed in link
    # 3's frame), each 10-20 % off: 4.6 kg at 0.116 m (the links inside their envelope kept more: 4.3 kg at 0.131 m)
    assert flange_carriers(denso, denso_model) == (2, 3, 4, 5)
    point = carried_estimate(denso, denso_model, recal, problem.base_t, final.terms)
    assert point[0] == pytest.approx(TOOL.mass, rel=0.15)
    assert point[3] == pytest.approx(TOOL.mass * TOOL.com[2], rel=0.15)
    assert point[3] / point[0] == pytest.approx(TOOL.com[2], abs=0.03) and np.all(np.abs(point[1:3]) < 0.01)


def test_without_a_tool_no_payload_is_named(denso, denso_model):
    problems, fits, options, enveloped = _identified(denso, denso_model, [])
    assert hidden_payload(enveloped, fits[1].terms) is None
    assert name_hidden_payload(denso, denso_model, problems, fits, options, enveloped) is None


def test_the_named_payload_leaves_the_prediction_and_moves_the_tool_out_of_the_links(denso, denso_model, with_tool):
    problems, (selection, final), options, enveloped = with_tool
    named_selection, named, note = name_hidden_payload(denso, denso_model, problems, (selection, final), options,
                                                       enveloped)  # fmt: skip
    assert [s.term.label for s in named_selection.steps] == ["payload"] and named.terms == (PayloadTerm(),)
    payload = named.coefficients[0]
    assert payload[0] == pytest.approx(TOOL.mass, rel=0.15) and f"`payload` named ({payload[0]:.4g} kg" in note
    # on the last joint's axis (the Denso's robot file holds no last link: the links before the flange mimic no part
    # turning with joint 6), where the links took exactly what the payload takes: the prediction is unchanged
    assert payload[1] == payload[2] == 0.0 and payload[3] == pytest.approx(TOOL.mass * TOOL.com[2], rel=0.15)
    for before, after in ((final.prediction_t, named.prediction_t), (final.prediction_v, named.prediction_v)):
        assert np.allclose(after, before, rtol=0.0, atol=1e-9 * np.max(np.abs(before)))
    old, new = (augmented_model_of(denso, denso_model, f, options) for f in (final, named))
    change = PayloadTerm().theta_change(payload, flange_parameter_map(denso, denso_model))
    assert np.allclose(new.theta, old.theta - change)  # the links without the tool
    assert np.allclose(new.theta + change, old.theta, rtol=1e-12)  # the augmented model: links and payload


@pytest.mark.parametrize("point", [(-5.0, 0.0, 0.0, -0.5), (5.0, 0.0, 0.0, 5.0)])
def test_a_body_that_is_no_tool_is_not_named(denso, denso_model, with_tool, monkeypatch, point):
    """A negative mass (the links lighter than the file), a centre of mass 1 m off the flange."""
    import identification.diagnosis.hidden_payload as module

    monkeypatch.setattr(module, "carried_estimate", lambda *args, **kwargs: np.array(point))
    problems, fits, options, enveloped = with_tool
    assert name_hidden_payload(denso, denso_model, problems, fits, options, enveloped) is None


def test_a_payload_is_named_only_where_it_lowers_several_joints_more_than_it_raises():
    def judge(with_body, point=(5.0, 0.0, 0.0, 0.5)):  # the RMSE's verdict alone
        fits = {(): EnvelopedFit(np.ones(4), np.ones(4), ()),
                ("payload[inertia]",): EnvelopedFit(np.ones(4), np.asarray(with_body, float),
                                                    (np.r_[point, np.zeros(6)],))}  # fmt: skip
        enveloped = SimpleNamespace(robot=SimpleNamespace(links=()),
                                    fit=lambda terms: fits[tuple(t.label for t in terms)])  # fmt: skip
        return hidden_payload(enveloped, ())

    assert judge([0.5, 0.7, 1.0, 1.0]).joints == (0, 1)  # the largest drop first
    assert judge([0.5, 0.9, 1.0, 1.0]) is None  # one joint: another effect's
    assert judge([0.5, 0.7, 1.0, 1.3]) is None  # a joint worse beside two lower: over all joints 14 % lower
    assert judge([0.5, 0.7, 0.85, 1.3]).joints == (0, 1)  # two lower, one worse: 21 % lower over all joints
    assert judge([0.1, 0.1, 1.3, 1.3]) is None  # as many joints worse as lower
