"""Diagnosis on short synthetic recordings: a hidden spring and offset are found, a clean robot gives no finding."""

from __future__ import annotations

import json

import numpy as np
import pytest

from identification.data.recording import Recording
from identification.diagnosis import (
    NO_FINDING,
    DiagnosisOptions,
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
    diagnose,
)
from identification.virtual import effects as xp
from identification.virtual.transmission_effects import Backlash, JointElasticity
from psdm_casadi.errors import ParameterError, RecordingError, ShapeError
from tests.identification.diagnosis_data import recording_pair

LIB = SpringTerm() + TorqueOffsetTerm() + TorqueRippleTerm(harmonics=(4, 8))


def test_hidden_spring_is_found_with_its_stiffness(denso, denso_model):
    train, val = recording_pair(denso, [xp.Spring(joint=1, stiffness=35.0, q0=0.15)], seed=1)
    report = diagnose(denso, train, val, DiagnosisOptions(library=LIB), model=denso_model)
    first = report.findings[0]
    assert first.effect == "spring" and first.joints == (1,)
    assert first.parameters["k"] == pytest.approx(35.0, rel=0.1)
    assert first.parameters["q0"] == pytest.approx(0.15, abs=0.05)
    assert report.rmse_after[1] < 0.5 * report.rmse_before[1]


def test_hidden_offset_is_found(denso, denso_model):
    offset = np.zeros(6)
    offset[2] = -2.5
    train, val = recording_pair(denso, [xp.TorqueOffset(offset=tuple(offset))], seed=2)
    report = diagnose(denso, train, val, DiagnosisOptions(library=LIB), model=denso_model)
    assert report.effects[0] == "torque_offset" and report.findings[0].joints == (2,)
    assert report.findings[0].parameters["offset"] == pytest.approx(-2.5, abs=0.25)


@pytest.mark.slow
def test_clean_recording_gives_no_finding_and_same_seed_same_result(denso, denso_model):
    train, val = recording_pair(denso, [], seed=3)
    a = diagnose(denso, train, val, DiagnosisOptions(), model=denso_model)
    b = diagnose(denso, train, val, DiagnosisOptions(), model=denso_model)
    assert a.findings == () and a.summary() == NO_FINDING
    assert a.to_json() == b.to_json()
    data = json.loads(a.to_json())
    assert data["findings"] == [] and len(data["rmse_before"]) == 6


@pytest.mark.slow
def test_report_and_augmented_model_files(denso, denso_model, tmp_path):
    train, val = recording_pair(denso, [xp.Spring(joint=1, stiffness=35.0, q0=0.15)], seed=1)
    report = diagnose(denso, train, val, DiagnosisOptions(library=LIB), model=denso_model)
    paths = report.save(tmp_path, plots=False)
    assert "spring" in paths["markdown"].read_text()
    import casadi as ca

    f = ca.Function.load(str(paths["augmented_function"]))
    q = np.full(6, 0.3)
    tau = np.array(f(q, np.zeros(6), np.zeros(6), 0.0)).ravel()
    spring = report.findings[0].parameters
    # the augmented function minus the nominal rigid body equals spring + friction at rest (zero with qd = 0)
    from psdm_casadi.oracle import PinocchioOracle

    tau_rigid = PinocchioOracle(denso).rnea(q, np.zeros(6), np.zeros(6))
    assert tau[1] - tau_rigid[1] == pytest.approx(spring["k"] * (0.3 - spring["q0"]), rel=1e-6)
    with pytest.raises(FileExistsError, match="overwrite"):
        report.save(tmp_path, plots=False)


def test_hidden_effects_validate_and_measure():
    q, tau = np.zeros((4, 2)), np.array([[1.0, 0], [-1.0, 0], [2.0, 0], [0.0, 0]])
    qb, _ = Backlash(joint=0, width=0.02, torque_scale=1e-6).measure(None, q, tau)
    np.testing.assert_allclose(qb[:, 0], [0.01, -0.01, 0.01, 0.0])
    qe, _ = JointElasticity(joint=0, stiffness=100.0).measure(None, q, tau)
    np.testing.assert_allclose(qe[:, 0], tau[:, 0] / 100.0)
    assert np.all(q == 0)  # input unmutated
    with pytest.raises(ParameterError, match="Backlash.joint"):
        Backlash(joint=5, width=0.01).validate(2)
    with pytest.raises(ParameterError, match="JointElasticity.stiffness"):
        JointElasticity(joint=0, stiffness=-1.0).validate(2)


def test_errors_name_the_field(denso, denso_model):
    t = np.linspace(0, 1, 200)
    rec3 = Recording(t=t, q=np.zeros((200, 3)), tau=np.zeros((200, 3)))
    with pytest.raises(ShapeError, match="Recording.q"):
        diagnose(denso, rec3, rec3, model=denso_model)
    with pytest.raises(ParameterError, match="DiagnosisOptions.friction"):
        DiagnosisOptions(friction="magic")
    with pytest.raises(ParameterError, match="DiagnosisOptions.rigid_body"):
        DiagnosisOptions(rigid_body="guess")
    with pytest.raises(ParameterError, match="DiagnosisOptions.min_improvement"):
        DiagnosisOptions(min_improvement=1.5)
    with pytest.raises(ParameterError, match="DiagnosisOptions.max_effects"):
        DiagnosisOptions(max_effects=-1)
    with pytest.raises(ParameterError, match="DiagnosisOptions.library"):
        DiagnosisOptions(library=[SpringTerm()])
    rec6 = Recording(t=t, q=np.zeros((200, 6)), tau=np.zeros((200, 6)))
    with pytest.raises(RecordingError, match="qd and qdd"):
        diagnose(denso, rec6, rec6, DiagnosisOptions(preprocess=False), model=denso_model)
