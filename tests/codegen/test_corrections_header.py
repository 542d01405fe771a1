"""The C header of a calibrated model with measurement corrections says which signals its functions expect.

A model recalibrated with signal findings (a torque delay, a joint elasticity, a backlash) was fitted on
corrected signals (``findings.correct_recording``), and no exported function applies the corrections: the
header must say to feed the corrected positions (and for a LuGre model, the corrected velocity to
``psdm_lugre_step``) and to compare with the torque advanced by the delay. A model without corrections
gets no such text. Inputs: the SCARA's nominal parameters written as a calibrated model
(``tests.catalogue.model_files``), with the corrections a recalibration stores.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from codegen.calibrated import header_note
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.findings import correct_recording
from identification.data.recording import Recording
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.robot import load_robot
from tests.catalogue.model_files import SCARA_FILE, model_document, nominal_fit

SENTENCE = "the model was fitted on the corrected signals"
CORRECTIONS = {
    "delay": {"effect": "delay", "delay_s": 0.004},
    "elasticity joint 1": {"effect": "joint_elasticity", "joint": 1, "compliance_rad_per_Nm": 2.5e-4,
                           "stiffness_Nm_per_rad": 4000.0},
    "backlash joint 2": {"effect": "backlash", "joint": 2, "backlash_rad": 0.002, "torque_scale_Nm": 0.3},
}  # fmt: skip
LUGRE = {"fc": 1.0, "fs": 1.3, "vs": 0.02, "fv": 0.5, "dv": 1.0, "sigma0": 1.0e4, "sigma1": 10.0}


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # load_robot's copies of the robot texts


@pytest.fixture(scope="module")
def plain():
    return model_document()


@pytest.fixture(scope="module")
def lugre():
    """A LuGre model of the SCARA (no steady-state drive terms; its friction is the bristle model)."""
    robot = load_robot(SCARA_FILE)
    model = derive_psdm(robot)
    document = copy.deepcopy(
        CalibratedModel.from_fit(robot, model, nominal_fit(robot, model, friction=()), robot_source=SCARA_FILE).document
    )
    document["drive"]["lugre"] = {name: [value] * robot.n_dof for name, value in LUGRE.items()}
    document["drive"]["friction_shape"], document["version"] = "lugre", 3
    document["drive"]["friction_shapes"] = ["lugre"] * robot.n_dof  # as identify writes a LuGre model of every joint
    return document


def _flat(comment: str) -> str:
    """A C comment as one line of words (the header wraps at 110 columns)."""
    return " ".join(" ".join(line.strip(" */") for line in comment.splitlines()).split())


def _with(document, corrections) -> CalibratedModel:
    document = copy.deepcopy(document)
    document["corrections"] = copy.deepcopy(corrections)
    return CalibratedModel(document)


def test_the_header_of_a_model_without_corrections_has_no_correction_text(plain, lugre):
    for document in (plain, lugre):
        note = header_note(CalibratedModel(document)).lower()
        assert "measurement corrections" not in note and SENTENCE not in note


def test_the_header_names_each_correction_and_what_to_feed(plain):
    flat = _flat(header_note(_with(plain, CORRECTIONS)))
    assert "MEASUREMENT CORRECTIONS" in flat and SENTENCE in flat.lower()
    assert "torque delay d = delay_s = 0.004 s" in flat and "tau_rec(t + d)" in flat
    assert "q1 = q_rec1 - c tau_rec1, c = compliance_rad_per_Nm = 0.00025 rad/(N m)" in flat
    assert (
        "q2 = q_rec2 - (b / 2) tanh(tau_rec2 / s), b = backlash_rad = 0.002 rad, s = torque_scale_Nm = 0.3 N m" in flat
    )
    assert "Feed psdm_inverse_dynamics the corrected positions q" in flat and "lugre_step" not in flat
    assert "CalibratedModel.predict_recording" in flat and "correct_recording" in flat


def test_the_formulas_in_the_header_are_those_the_python_corrections_apply(plain):
    # the header's q1 = q_rec1 - c tau_rec1 and q2 = q_rec2 - (b/2) tanh(tau_rec2 / s), the delay's tau_rec(t + d)
    t = np.arange(0.0, 0.2, 0.001)
    q, tau = (
        np.column_stack([np.sin(t * k) for k in (1, 2, 3, 4)]),
        np.column_stack([np.cos(t * k) for k in (1, 2, 3, 4)]),
    )
    corrected = correct_recording(Recording(t=t, q=q, tau=tau), _with(plain, CORRECTIONS).corrections)
    advanced = np.column_stack([np.interp(t + 0.004, t, tau[:, j]) for j in range(4)])
    np.testing.assert_allclose(corrected.tau, advanced, rtol=0, atol=1e-15)
    np.testing.assert_allclose(corrected.q[:, 0], q[:, 0] - 2.5e-4 * advanced[:, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(corrected.q[:, 1], q[:, 1] - 0.001 * np.tanh(advanced[:, 1] / 0.3), rtol=0, atol=1e-15)


def test_a_delay_alone_changes_no_position(plain):
    flat = _flat(header_note(_with(plain, {"delay": CORRECTIONS["delay"]})))
    assert "tau_rec(t + d)" in flat and "corrected positions" not in flat


def test_the_lugre_step_is_told_to_take_the_corrected_velocity(lugre):
    flat = _flat(header_note(_with(lugre, CORRECTIONS)))
    assert "Feed psdm_inverse_dynamics and psdm_lugre_step (its qd_prev and qd) the corrected positions q" in flat


def test_psdm_codegen_writes_the_text_into_both_headers_of_a_lugre_model(lugre, tmp_path, capsys):
    for name, corrections in (("plain.json", {}), ("corrected.json", CORRECTIONS)):
        (tmp_path / name).write_text(json.dumps(_with(lugre, corrections).document))
        assert main(["codegen", str(tmp_path / name), "--out", str(tmp_path / name[:-5])]) == 0, capsys.readouterr()
    for header in ("psdm_dynamics.h", "psdm_dynamics_lugre.h", "psdm_dynamics_lugre.c"):
        assert SENTENCE in _flat((tmp_path / "corrected" / header).read_text()).lower()
        assert "MEASUREMENT CORRECTIONS" not in (tmp_path / "plain" / header).read_text()
