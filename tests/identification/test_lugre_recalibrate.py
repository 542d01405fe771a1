"""The discovery loop for a model with LuGre friction: ``psdm diagnose MODEL --apply NEW`` keeps the LuGre friction.

A virtual Denso with known LuGre friction (``lugre_recordings_data``) and a hidden spring on joint 2: ``psdm
identify --friction lugre`` puts the spring into the gravity parameters and into joint 2's friction; the diagnosis
of that model finds the spring, and the recalibration with it (the LuGre identification again, the spring's
columns in every linear fit) recovers the spring, the LuGre truth of every joint and the validation error, in a
version 3 file whose compiled C (inverse dynamics with the spring, plus the LuGre step) gives the reported
validation RMSE.

The same robot with a hidden torque-sensor delay instead: the LuGre model identified from the delayed torque has
taken up part of the delay (its bristle dynamics and Stribeck curve mimic a lag), yet the diagnosis of that model
finds the delay within one sample (the delay is screened at the minimum of its exact profile, ``DelayTerm``), and
``psdm diagnose --apply`` fits the LuGre friction on the corrected recordings and judges the new model with the
bristle state carried along them, as ``psdm validate`` does. The same robot without the delay: the diagnosis of its
LuGre model finds nothing. A load-dependent friction finding, which the LuGre model cannot carry, is refused by the
recalibration and by ``psdm diagnose --apply`` (exit 2, nothing written).
"""

import copy
import importlib
import json
import re
import shutil
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.recalibrate import recalibrate
from identification.diagnosis.candidates import LoadDependentFrictionTerm
from identification.diagnosis.report import DiagnosisReport, Finding
from identification.friction.models import LUGRE_PARAMETER_NAMES
from identification.virtual import effects as xp
from psdm_casadi.errors import ParameterError
from tests.identification.lugre_recordings_data import RATE, TRUTH

SPRING_K, SPRING_Q0 = 40.0, 0.2
#: The hidden torque-sensor delay [samples at RATE] of the delay loop, and its stated tolerance (one sample).
DELAY_SAMPLES, DELAY_TOLERANCE_S = 6, 1.0 / RATE
#: Stated tolerances of the recovered spring: stiffness (relative, beside 3 of its sigma) and rest position [rad].
SPRING_K_TOLERANCE, SPRING_Q0_TOLERANCE = 0.05, 0.02
#: Stated tolerances (relative) of the LuGre parameters after the recalibration, as for the identification alone
#: (``test_lugre_recordings.TOLERANCE``).
TOLERANCE = {"fc": 0.05, "fs": 0.15, "vs": 0.25, "fv": 0.05, "sigma0": 0.15, "sigma1": 0.10}


@pytest.fixture(scope="module")
def spring_loop(denso, tmp_path_factory):
    """``psdm identify --friction lugre`` on the recordings with the spring, then ``psdm diagnose MODEL --apply``
    (the library's terms only: the search beyond it is not what these tests are about)."""
    from psdm_casadi.cli import main
    from tests.conftest import DENSO_FILE
    from tests.identification.lugre_recordings_data import CUTOFF, write_lugre_recordings

    folder = tmp_path_factory.mktemp("lugre_spring")
    spring = xp.Spring(joint=1, stiffness=SPRING_K, q0=SPRING_Q0)
    train, valid = write_lugre_recordings(denso, folder, extras=[spring])
    argv = ["identify", str(DENSO_FILE), "--data", str(train), "--friction", "lugre", "--cutoff", str(CUTOFF),
            "--out", str(folder / "model.json")]  # fmt: skip
    assert main(argv) == 0
    argv = ["diagnose", str(folder / "model.json"), "--train", str(train), "--validate", str(valid), "--cutoff",
            str(CUTOFF), "--no-sparse", "--apply", str(folder / "new.json")]  # fmt: skip
    assert main(argv) == 0
    return folder, valid


def _lugre_errors(calibrated) -> dict:
    """Relative error of each LuGre parameter per joint against the truth."""
    block = calibrated.document["drive"]["lugre"]
    return {name: np.abs(np.array(block[name]) - TRUTH[name]) / TRUTH[name] for name in TOLERANCE}


@pytest.mark.slow
def test_apply_to_a_lugre_model_finds_the_spring_and_recovers_the_friction(spring_loop, capsys):
    from psdm_casadi.cli import main

    folder, valid = spring_loop
    before, after = load_calibrated_model(folder / "model.json"), load_calibrated_model(folder / "new.json")
    assert after.document["version"] == 3 and after.document["drive"]["friction_shape"] == "lugre"
    assert after.lugre_parameters is not None and before.document["findings"] == []
    assert not any(name.startswith(("fc", "fs", "fv")) for name in after.document["drive"]["names"])
    spring = next(e for e in after.document["findings"] if e["label"] == "spring[j2]")
    assert spring["kind"] == "torque"
    k, q0 = spring["parameters"]["k"], spring["parameters"]["q0"]
    assert abs(k - SPRING_K) < 3 * spring["std"][0] + SPRING_K_TOLERANCE * SPRING_K, spring
    assert abs(q0 - SPRING_Q0) < SPRING_Q0_TOLERANCE, spring
    # the spring corrupted joint 2's LuGre friction; with it modelled, every joint's LuGre parameters are right again
    assert any(np.any(e[1] > TOLERANCE[name]) for name, e in _lugre_errors(before).items())
    for name, error in _lugre_errors(after).items():
        assert np.all(error < TOLERANCE[name]), (name, np.round(error, 3))
    block = after.document["recalibration"]
    assert block["after"]["validation_rmse"][1] < 0.5 * block["before"]["validation_rmse"][1], block
    assert block["dropped_findings"] == [] and block["after"]["consistent"]
    assert any(m["name"] == "fc2" for m in block["moved_parameters"])  # the LuGre friction of joint 2 moved
    capsys.readouterr()
    assert main(["validate", str(folder / "new.json"), str(valid), "--json"]) == 0  # judged as psdm validate judges
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(validated, block["after"]["validation_rmse"], rtol=1e-12)


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_exported_c_of_the_recalibrated_lugre_model_gives_the_reported_rmse(spring_loop, tmp_path):
    """``psdm codegen NEW``: the spring in ``psdm_inverse_dynamics``, the LuGre step in ``<lib>_lugre.c``; carried
    along the validation recording they give the report's validation RMSE to 1e-9 relative."""
    from tests.identification.lugre_recordings_data import exported_c_rmse

    folder, valid = spring_loop
    after = load_calibrated_model(folder / "new.json")
    rmse_c, header = exported_c_rmse(folder / "new.json", valid, tmp_path / "c")
    assert "psdm_lugre_step" in header
    assert "spring[j2]" in (tmp_path / "c" / "psdm_dynamics.h").read_text()
    spring = next(e for e in after.document["findings"] if e["label"] == "spring[j2]")
    assert spring["validation_rmse_without"][1] > 10 * rmse_c[1]  # the C holds the spring: without it, far worse
    np.testing.assert_allclose(rmse_c, after.document["recalibration"]["after"]["validation_rmse"], rtol=1e-9)


def _identify_then_diagnose(denso, folder, extras, *diagnose_options):
    """``psdm identify --friction lugre`` on the recordings written with ``extras`` into ``folder``, then ``psdm
    diagnose MODEL`` with ``diagnose_options``; returns the validation recording's path."""
    from psdm_casadi.cli import main
    from tests.conftest import DENSO_FILE
    from tests.identification.lugre_recordings_data import CUTOFF, write_lugre_recordings

    train, valid = write_lugre_recordings(denso, folder, extras=extras)
    argv = ["identify", str(DENSO_FILE), "--data", str(train), "--friction", "lugre", "--cutoff", str(CUTOFF),
            "--out", str(folder / "model.json")]  # fmt: skip
    assert main(argv) == 0
    argv = ["diagnose", str(folder / "model.json"), "--train", str(train), "--validate", str(valid), "--cutoff",
            str(CUTOFF), *diagnose_options]  # fmt: skip
    assert main(argv) == 0
    return valid


@pytest.fixture(scope="module")
def delay_loop(denso, tmp_path_factory):
    """``psdm identify --friction lugre`` on the recordings whose torque lags by ``DELAY_SAMPLES``, then ``psdm
    diagnose MODEL --apply``."""
    folder = tmp_path_factory.mktemp("lugre_delay")
    extras = [xp.SignalDelay(samples=DELAY_SAMPLES)]
    return folder, _identify_then_diagnose(denso, folder, extras, "--apply", str(folder / "new.json"))


@pytest.fixture(scope="module")
def clean_diagnosis(denso, tmp_path_factory):
    """``psdm identify --friction lugre`` on the recordings without hidden physics, then ``psdm diagnose MODEL
    --json``: the report's findings."""
    folder = tmp_path_factory.mktemp("lugre_clean")
    _identify_then_diagnose(denso, folder, (), "--out", str(folder / "report"))
    return json.loads((folder / "report" / "report.json").read_text())


@pytest.mark.slow
def test_apply_of_a_delay_to_a_lugre_model_refits_the_friction_and_validates_as_psdm_validate(delay_loop, capsys):
    """The diagnosis of the LuGre model identified on the delayed torque finds the delay within one sample; it is
    kept (it lowers the validation RMSE of every joint), the LuGre friction fitted on the corrected recordings is the
    truth again where the delayed torque had corrupted it, and ``psdm validate NEW valid.csv`` (the correction
    applied, the bristle state carried along the corrected recording) gives the file's RMSE."""
    from psdm_casadi.cli import main

    folder, valid = delay_loop
    before, after = load_calibrated_model(folder / "model.json"), load_calibrated_model(folder / "new.json")
    assert after.document["version"] == 3 and after.lugre_parameters is not None
    corrections = list(after.corrections.values())
    assert [c["effect"] for c in corrections] == ["delay"], corrections
    assert abs(corrections[0]["delay_s"] - DELAY_SAMPLES / RATE) < DELAY_TOLERANCE_S, corrections
    entry = next(e for e in after.document["findings"] if e["effect"] == "delay")
    assert entry["kind"] == "signal"
    block = after.document["recalibration"]
    # the delay is kept; what --apply drops is only a finding that did not help where it acts once the delay is
    # corrected (since the LuGre fit settles its rounds, lugre_identify: a sparse term on joint 4, 0.1177 -> 0.0745 N m
    # beside the delayed torque, 0.06463 -> 0.0647 N m after the refit without the delay's corruption)
    for dropped in block["dropped_findings"]:
        assert dropped["effect"] != "delay" and dropped["reason"].startswith("taking it out does not raise"), dropped
        assert np.all(np.array(dropped["validation_rmse_with"]) >= np.array(dropped["validation_rmse_without"]))
    joints = [j - 1 for j in entry["joints"]] or list(range(after.n_dof))
    rmse_before, rmse_after = (np.array(block[k]["validation_rmse"])[joints] for k in ("before", "after"))
    assert np.all(rmse_after < rmse_before), (rmse_before, rmse_after)
    assert np.all(np.array(entry["validation_rmse_without"])[joints] > rmse_after)
    assert any(np.any(e > TOLERANCE[name]) for name, e in _lugre_errors(before).items())
    for name, error in _lugre_errors(after).items():
        assert np.all(error < TOLERANCE[name]), (name, np.round(error, 3))
    capsys.readouterr()
    assert main(["validate", str(folder / "new.json"), str(valid), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(validated, block["after"]["validation_rmse"], rtol=1e-9)


@pytest.mark.slow
def test_the_diagnosis_of_a_lugre_model_of_clean_recordings_finds_nothing(clean_diagnosis):
    """The same robot without the delay: the LuGre model identified from its recordings leaves nothing the
    diagnosis reports (no delay, no other finding), though the delay is screened at its profile's minimum."""
    assert clean_diagnosis["findings"] == [], [f["label"] for f in clean_diagnosis["findings"]]


@pytest.mark.slow
def test_a_lugre_models_bristle_state_is_carried_along_the_corrected_positions(delay_loop, denso_model):
    """An encoder before a compliant joint: the model with that correction on the raw recording predicts what the
    model without corrections predicts on the recording corrected beforehand (the friction sees the corrected
    velocity from the raw start on), and the bristle state there differs from the raw positions' one."""
    from identification.calibration.findings import correct_recording
    from identification.calibration.lugre_recordings import bristle_force_at
    from identification.data.io import load_recording

    folder, valid = delay_loop
    document = copy.deepcopy(load_calibrated_model(folder / "new.json").document)
    document["corrections"]["elasticity"] = {"effect": "joint_elasticity", "joint": 2, "compliance_rad_per_Nm": 2e-3}
    corrected_model = CalibratedModel(document)
    plain = CalibratedModel({**copy.deepcopy(document), "corrections": {}})
    recording = load_recording(valid, 6)
    corrected = correct_recording(recording, corrected_model.corrections)
    prepared, predicted = corrected_model.predict_recording(denso_model, recording)
    prepared_ref, reference = plain.predict_recording(denso_model, corrected)
    np.testing.assert_array_equal(prepared.t, prepared_ref.t)
    np.testing.assert_allclose(predicted, reference, rtol=0.0, atol=1e-12)
    cutoff = document["identification"]["cutoff_hz"][0]
    lugre = corrected_model.lugre_parameters
    carried = [bristle_force_at(lugre, r, cutoff, prepared.t[0])[1] for r in (corrected, recording)]
    assert abs(carried[0] - carried[1]) > 0.01 * lugre[1].fc, carried  # the check above can see the difference


@pytest.mark.slow
def test_diagnose_apply_refuses_load_dependent_friction_on_a_lugre_model(delay_loop, monkeypatch, capsys):
    """``psdm diagnose LUGRE.json --apply NEW.json`` with a load-dependent friction finding (the report given by a
    stand-in of the diagnosis): the report printed, then exit 2, one line naming the model file and the fix, no
    traceback, nothing written."""
    from psdm_casadi.cli import main

    folder, valid = delay_loop
    candidate = LoadDependentFrictionTerm(joint=1)
    _stand_in_diagnosis(monkeypatch, candidate, {"coefficient": 0.02})
    out = folder / "refused.json"
    argv = ["diagnose", str(folder / "model.json"), "--train", str(valid), "--validate", str(valid), "--apply",
            str(out)]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 2
    captured = capsys.readouterr()
    error = captured.err
    assert candidate.label in captured.out  # the report says what was found, though it cannot be applied
    assert str(folder / "model.json") in error and candidate.label in error, error
    assert "--friction stribeck" in error and "Nothing was written" in error, error
    assert "Traceback" not in error and not out.exists()


def _lugre_document() -> CalibratedModel:
    """The parts of a LuGre model file the recalibration reads before it fits (two joints)."""
    lugre = {name: [1.0, 1.0] for name in LUGRE_PARAMETER_NAMES}
    return CalibratedModel({"robot": {"joint_names": ["j1", "j2"]}, "findings": [],
                            "drive": {"lugre": lugre, "coulomb_velocity": 0.05}})  # fmt: skip


def _report(candidate, parameters) -> SimpleNamespace:
    """A diagnosis report with one finding of ``candidate`` (the parts the recalibration reads)."""
    value = next(iter(parameters.values()))
    finding = Finding(effect=candidate.key, label=candidate.label, joints=(() if candidate.joint is None else (1,)),
                      parameters=parameters, coefficients=(value,), feature_names=tuple(candidate.feature_names()),
                      explanation="", signature="", rmse_before=(1.0, 1.0), rmse_after=(0.5, 0.5), delta_bic=-10.0,
                      validation_gain=0.5)  # fmt: skip
    return SimpleNamespace(findings=[finding], augmented=SimpleNamespace(terms=(candidate,), coefficients=([value],)))


def _stand_in_diagnosis(patch, candidate, parameters) -> None:
    """``diagnose`` replaced (for ``psdm diagnose``) by one that reports a finding of ``candidate``: in its module
    and where ``psdm diagnose MODEL`` looks it up (``model_file.diagnose_model``, which holds its own name), both
    modules imported before either is patched."""
    modules = [importlib.import_module(m) for m in ("identification.diagnosis.diagnose",
                                                    "identification.diagnosis.model_file")]  # fmt: skip
    parts, n, zeros = _report(candidate, parameters), 2, np.zeros((2, 2))
    report = DiagnosisReport(
        robot_name="stand-in", n_dof=n, friction="lugre", rigid_body="prior", findings=tuple(parts.findings),
        rmse_before=(1.0,) * n, rmse_after=(0.5,) * n, r2_before=(0.9,) * n, r2_after=(0.95,) * n,
        rmse_train_before=(1.0,) * n, rmse_train_after=(0.5,) * n, residual_findings=(), candidates_tried=1,
        augmented=parts.augmented, validation_t=np.arange(2.0), validation_q=zeros, validation_qd=zeros,
        validation_tau=zeros, validation_nominal=zeros, validation_final=zeros,
    )  # fmt: skip
    for module in modules:
        patch.setattr(module, "diagnose", lambda *args, **kwargs: report)


def test_apply_to_a_lugre_model_refuses_load_dependent_friction():
    """A load-dependent friction (a multiple of the model's own torque, whose LuGre part the exported inverse
    dynamics does not hold) is not supported for a LuGre model: the recalibration refuses it by name, before any
    fit, with the way out."""
    candidate = LoadDependentFrictionTerm(joint=1)
    match = rf"drive.lugre. does not take the findings \['{re.escape(candidate.label)}'\]"
    with pytest.raises(ParameterError, match=match) as refused:
        recalibrate(_lugre_document(), None, None, _report(candidate, {"coefficient": 0.02}), [], [])
    assert "--friction stribeck" in str(refused.value)
