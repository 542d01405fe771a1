"""A spring ``diagnose --apply`` finds on a joint whose torque offset the model file holds as the counterbalance's
stand-in (``counterbalance_record``) takes the offset's place: its constant is the offset's column
(``findings.offsets_left_to_findings``), so ``offset_split`` does not judge it, and neither does its ``REPLACE_GAIN``
(the gain one of two shapes splitting one torque needs to replace the other). The spring holds the offset and its
slope, as ``counterbalance[jJ]`` holds the offset and its bend (``counterbalance_finding``): a model that contains the
offset's. So it is judged as that finding is, by the gates of every new finding: no joint worse beyond its paired
margin on the held-out recording (``never_worse``), and a model below the one without it (the offset again) on each
held-out recording (``no_gain``).

Reference: the virtual Denso with a hidden torque on joint 2 and a model file carrying an offset there named a
counterbalance. A linear spring far from its rest angle (a balancer's constant and slope) truly replaces the offset:
written, its stiffness and rest angle the truth's, joint 2 better. A cam whose held-out swing reaches where the
cam's own best line over the training swing predicts worse than its mean there (the heavy arm's case) is not: the
spring the training data give makes joint 2 worse, and the model keeps its offset.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.counterbalance_column import BY_OFFSET
from identification.calibration.recalibrate import recalibrate
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.diagnosis.candidates.torque import SpringTerm
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


def _report(term) -> SimpleNamespace:
    """A diagnosis report holding one torque finding of ``term`` (what ``recalibrate`` reads of it)."""
    finding = SimpleNamespace(label=term.label, effect=term.key, joints=(term.joint,), feature_names=(),
                              coefficients=(), parameters={}, rmse_before=[], rmse_after=[])  # fmt: skip
    return SimpleNamespace(findings=[finding], augmented=SimpleNamespace(terms=[term], coefficients=[np.zeros(2)]))


def _offset_model(denso, denso_model, hidden, fractions):
    """(training and held-out recordings of the virtual Denso with ``hidden`` on joint 2, swinging ``fractions`` of
    its limits; the model file fitted on the training one with a torque offset on joint 2 chosen from the data and
    named a counterbalance, as identify writes it where the spring it tried was not kept)."""
    recordings = []
    for k, fraction in enumerate(fractions):
        rng = np.random.default_rng(40 + k)
        reference = sine_experiment(denso, duration=6.0, rng=rng, fraction=fraction).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=500.0)
        recordings.append(simulate_recording(denso, reference, options, rng, extras=[hidden])[0])
    options = TrajectoryOptions(friction=("fc", "fv", "offset"), offset_joints=(1,))
    fit = identify_trajectories(denso, denso_model, recordings[:1], options)
    calibrated = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    identification = calibrated.document["identification"]
    identification["column_choice"] = {"request": {"offset": "auto"}, "offset_joints": [2]}
    identification["counterbalance"] = {"joints": [2], "named_by": {"2": BY_OFFSET}, "kept": False}
    return recordings, calibrated


def _offset2(calibrated) -> float:
    return dict(zip(calibrated.document["drive"]["names"], calibrated.document["drive"]["values"])).get("offset2", 0.0)


@pytest.mark.slow  # two simulations, a fit and diagnose --apply's gates on the Denso: ~25 s under load
def test_a_spring_that_is_the_balancer_replaces_the_offset(denso, denso_model):
    spring = xp.Spring(joint=1, stiffness=40.0, q0=-1.2)  # its constant is the offset the file holds
    (train, validation), calibrated = _offset_model(denso, denso_model, spring, (0.5, 0.5))
    assert _offset2(calibrated) == pytest.approx(-spring.stiffness * spring.q0, rel=0.5)  # the balancer's constant
    result = recalibrate(calibrated, denso, denso_model, _report(SpringTerm(joint=1)), train, validation)
    assert result.refused is None
    (written,) = result.after.document["findings"]
    assert written["label"] == "spring[j2]" and _offset2(result.after) == 0.0  # in the offset's place, not beside it
    assert written["parameters"]["k"] == pytest.approx(spring.stiffness, rel=0.05)
    assert written["parameters"]["q0"] == pytest.approx(spring.q0, abs=0.1)
    assert result.rmse_after[1] < 0.2 * result.rmse_before[1]
    assert np.all(result.rmse_after <= result.rmse_before * 1.01)


@pytest.mark.slow  # two simulations, a fit and diagnose --apply's gates with their refits on the Denso: ~50 s
def test_a_spring_the_held_out_swing_refuses_leaves_the_offset(denso, denso_model):
    cam = xp.CamCounterbalance(joint=1, amplitude=30.0, q0=-1.0, lobe=0.5)
    (train, validation), calibrated = _offset_model(denso, denso_model, cam, (0.15, 0.6))
    # the truth: the cam's own best line over the training swing predicts the held-out swing worse than its mean
    torque = [np.asarray([cam.torque(0.0, row, 0.0 * row, None)[1] for row in r.q]) for r in (train, validation)]
    line = np.polyfit(train.q[:, 1], torque[0], 1)
    errors = [np.sqrt(np.mean((torque[1] - x) ** 2)) for x in (np.polyval(line, validation.q[:, 1]), torque[0].mean())]
    assert errors[0] > 1.5 * errors[1]
    result = recalibrate(calibrated, denso, denso_model, _report(SpringTerm(joint=1)), train, validation)
    written = result.after.document
    assert not written["findings"] and _offset2(result.after) == pytest.approx(_offset2(calibrated), rel=1e-9)
    (gate,) = written["recalibration"]["never_worse"]["dropped"]
    assert gate["label"] == "spring[j2]" and "joint 2" in gate["reason"]
    assert result.rmse_after == pytest.approx(result.rmse_before, rel=1e-9)
