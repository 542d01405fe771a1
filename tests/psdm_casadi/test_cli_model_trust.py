"""What a user of a calibrated model must be told: its stored warnings, and recordings it cannot be judged on.

``psdm identify`` stores in the model file the warnings that point at a wrong recording (here: torques in
mN m, which make link masses an order of magnitude off); ``psdm validate`` and ``psdm codegen`` read the
file later and repeat them (stderr, ``--json``, the C header). Identify now refuses torques in mN m before any fit
(``plausibility.check_torque_magnitude``): the model file identified from them here is one written before that refusal
(the check switched off for it). A validation recording whose joint stands
still is refused naming the joint rather than given an R^2; a recording in degrees is refused once, by the
library the command calls. Inputs: the 3-joint arm of the catalogue on the virtual robot; the recording
in N m is the control (no warning).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration import trajectory_data
from identification.calibration.no_gain import GAIN_SHARE
from identification.calibration.trajectory_checks import check_validation_recording
from identification.calibration.trajectory_fit import identify_trajectories
from identification.data.io import load_recording, save_recording
from identification.diagnosis import motion_checks
from identification.diagnosis.candidates import TorqueOffsetTerm
from identification.diagnosis.report import DiagnosisReport, Finding
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.cli.recalibration_text import better_alone
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import InsufficientExcitationError, RecordingError
from psdm_casadi.robot import load_robot
from tests.catalogue.harness import BadInput, check_refusal
from tests.catalogue.test_implausible_recordings import ARM
from trajopt.experiments import sine_experiment


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # load_robot's copies of the robot texts


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """Folder with arm.toml, train.csv, valid.csv (virtual arm, N m), mNm.csv (train in mN m) and the two models."""
    folder = tmp_path_factory.mktemp("trust")
    (folder / "arm.toml").write_text(ARM)
    robot = load_robot(folder / "arm.toml")
    rng = np.random.default_rng(3)
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.05, friction=True)
    for name in ("train.csv", "valid.csv"):
        recording, _ = simulate_recording(
            robot, sine_experiment(robot, duration=8.0, rng=rng).reference(), options, rng
        )
        save_recording(recording, folder / name)
    train = load_recording(folder / "train.csv")
    save_recording(train.with_signals(tau=1000.0 * train.tau), folder / "mNm.csv")
    for data, model in (("train.csv", "good.json"), ("mNm.csv", "mNm.json")):
        argv = ["identify", str(folder / "arm.toml"), "--data", str(folder / data), "--out", str(folder / model)]
        with pytest.MonkeyPatch.context() as patch:  # a model file of before the torque-scale refusal
            patch.setattr(trajectory_data, "check_torque_magnitude", lambda *args, **kwargs: None)
            assert main(argv) == 0
    return folder


def test_identify_refuses_torques_in_mn_m_before_any_fit(arm, tmp_path, capsys):
    argv = ["identify", arm / "arm.toml", "--data", arm / "mNm.csv", "--out", tmp_path / "m.json"]
    code, _, err = _run(capsys, argv)
    assert code == 2 and "mNm.csv" in err and "mN m" in err and not (tmp_path / "m.json").exists(), err


def _folder(path):
    """A new empty folder for one refusal (the harness checks that nothing appears in it)."""
    path.mkdir()
    return path


def _run(capsys, argv) -> tuple:
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_validate_repeats_the_warnings_stored_in_the_model_file(arm, capsys):
    stored = json.loads((arm / "mNm.json").read_text())["warnings"]
    assert any("rigid-body torques" in w and "mN m?" in w for w in stored)  # identify flagged the mN m torques
    code, out, err = _run(capsys, ["validate", arm / "mNm.json", arm / "valid.csv"])
    assert code == 0 and "R^2" in out
    for warning in stored:
        assert err.count(warning) == 1, err
    assert "psdm validate: warning: mNm.json" in err
    code, out, err = _run(capsys, ["validate", arm / "mNm.json", arm / "valid.csv", "--json"])
    assert code == 0 and json.loads(out)["warnings"] == stored and all(w in err for w in stored)
    # the control: a model identified from torques in N m has no warning, and validate prints none
    assert json.loads((arm / "good.json").read_text())["warnings"] == []
    code, out, err = _run(capsys, ["validate", arm / "good.json", arm / "valid.csv", "--json"])
    assert code == 0 and json.loads(out)["warnings"] == [] and "warning" not in err


def test_codegen_repeats_the_warnings_on_stderr_in_json_and_in_the_header(arm, tmp_path, capsys):
    stored = json.loads((arm / "mNm.json").read_text())["warnings"]
    code, out, err = _run(capsys, ["codegen", arm / "mNm.json", "--out", tmp_path / "c", "--json"])
    assert code == 0 and json.loads(out)["warnings"] == stored
    assert all(err.count(w) == 1 for w in stored) and "psdm codegen: warning: mNm.json" in err
    header = next((tmp_path / "c").glob("*.h")).read_text()
    assert header.startswith("/* WARNINGS of the identification") and "mN m?" in header
    code, out, err = _run(capsys, ["codegen", arm / "good.json", "--out", tmp_path / "g", "--json"])
    assert code == 0 and json.loads(out)["warnings"] == [] and "warning" not in err
    assert "WARNINGS" not in next((tmp_path / "g").glob("*.h")).read_text()


def test_a_model_file_whose_warnings_are_not_strings_is_refused(arm, tmp_path, capsys, monkeypatch):
    document = json.loads((arm / "good.json").read_text())
    document["warnings"] = "masses off"
    files = {"edited.json": json.dumps(document), "valid.csv": (arm / "valid.csv").read_text()}
    case = BadInput("warnings a string", ("validate", "edited.json", "valid.csv"), ("edited.json", "warnings",
                    "a list of strings"), files=files)  # fmt: skip
    check_refusal(case, _folder(tmp_path / "case"), capsys, monkeypatch)


def _still(arm, name="still.csv") -> str:
    """The validation recording with joint 3 held at its first position (its torques as recorded)."""
    valid = load_recording(arm / "valid.csv")
    q = valid.q.copy()
    q[:, 2] = q[0, 2]
    save_recording(valid.with_signals(q=q), arm / name, overwrite=True)
    return (arm / name).read_text()


def test_validate_refuses_a_recording_whose_joint_did_not_move(arm, tmp_path, capsys, monkeypatch):
    text = _still(arm)
    # before the check, this gave exit 0 and an R^2 of joint 3 as if the model had been tested on it
    expect = ("still.csv", "joint 3 (J3) must move", "range 0 rad", "Validate on a recording that moves joint 3")
    files = {"still.csv": text, "model.json": (arm / "good.json").read_text()}
    check_refusal(BadInput("validate still", ("validate", "model.json", "still.csv"), expect, files=files),
                  _folder(tmp_path / "validate"), capsys, monkeypatch)  # fmt: skip
    argv = ("identify", str(arm / "arm.toml"), "--data", "train.csv", "--validate", "still.csv", "--out", "m.json")
    files = {"still.csv": text, "train.csv": (arm / "train.csv").read_text()}
    case = BadInput("identify --validate still", argv, expect, files=files)
    check_refusal(case, _folder(tmp_path / "identify"), capsys, monkeypatch)


def test_identify_refuses_a_recording_in_degrees_once_through_the_library(arm, tmp_path, capsys, monkeypatch):
    train = load_recording(arm / "train.csv")
    degrees = train.with_signals(q=np.degrees(train.q))
    case_folder = _folder(tmp_path / "case")
    save_recording(degrees, case_folder / "deg.csv")
    robot = load_robot(arm / "arm.toml")
    # the Python API refuses it as the command does (identify_trajectories -> prepare_recordings)
    with pytest.raises(RecordingError, match="positions in degrees"):
        identify_trajectories(robot, derive_psdm(robot), [load_recording(case_folder / "deg.csv")])
    argv = ("identify", str(arm / "arm.toml"), "--data", "deg.csv", "--out", "m.json")
    case = BadInput("identify degrees", argv, ("deg.csv", "column q1", "degrees?"))
    err = check_refusal(case, case_folder, capsys, monkeypatch)
    assert err.count("error:") == 1 and err.count("column q1 (joint 1 (J1)) reaches") == 1, err


def test_a_still_validation_joint_is_an_excitation_error_in_the_library(arm):
    robot = load_robot(arm / "arm.toml")
    check_validation_recording(robot, load_recording(arm / "valid.csv"))  # the recording as recorded passes
    _still(arm, "still_lib.csv")
    with pytest.raises(InsufficientExcitationError, match=r"joint 3 \(J3\)") as caught:
        check_validation_recording(robot, load_recording(arm / "still_lib.csv"))
    assert caught.value.joints == (2,)


def test_every_command_reading_the_model_repeats_its_warnings(arm, tmp_path, capsys):
    """``psdm simulate MODEL``, ``psdm export-urdf MODEL`` and ``psdm diagnose MODEL`` show the stored warnings too."""
    stored = json.loads((arm / "mNm.json").read_text())["warnings"]
    runs = {
        "simulate": ["simulate", arm / "mNm.json", "--experiment", "sine", "--duration", "2", "--out", tmp_path / "s"],
        "export-urdf": ["export-urdf", arm / "mNm.json", tmp_path / "arm.urdf"],
        "diagnose": ["diagnose", arm / "mNm.json", "--train", arm / "train.csv", "--validate", arm / "valid.csv",
                     "--max-effects", "0", "--no-sparse"],  # mNm.csv itself is refused now (test above)
    }  # fmt: skip
    for command, argv in runs.items():
        code, _, err = _run(capsys, argv)
        assert code in (0, 1), (command, err)  # export-urdf may refuse an inconsistent model: it still says why
        assert f"psdm {command}: warning: mNm.json" in err and all(err.count(w) == 1 for w in stored), (command, err)
    code, _, err = _run(capsys, ["simulate", arm / "good.json", "--experiment", "sine", "--duration", "2", "--out",
                                 tmp_path / "g2"])  # fmt: skip
    assert code == 0 and "warning" not in err


#: The torque offset [N m] on joint 1 of the recordings a recalibrated model is refitted on.
OFFSET_J1 = 0.5


def test_a_recalibrated_model_keeps_the_warnings_of_its_own_refit(arm, tmp_path, capsys, monkeypatch):
    """``psdm diagnose MODEL --apply NEW`` refits on the same mN m torques: the refit flags the masses again, and
    the new file stores that warning (and the command prints it) instead of starting clean. The recordings carry the
    torque offset on joint 1 the finding names (a finding with no effect behind it gains nothing and is not written:
    ``no_gain``)."""
    candidate = TorqueOffsetTerm(joint=0)
    finding = Finding(effect=candidate.key, label=candidate.label, joints=(1,), parameters={"offset": 1.0},
                      coefficients=(1.0,), feature_names=tuple(candidate.feature_names()), explanation="",
                      signature="", rmse_before=(1.0,) * 3, rmse_after=(0.5,) * 3, delta_bic=-10.0,
                      validation_gain=0.5)  # fmt: skip
    n, zeros = 3, np.zeros((2, 3))
    report = DiagnosisReport(
        robot_name="arm", n_dof=n, friction="coulomb_viscous", rigid_body="prior", findings=(finding,),
        rmse_before=(1.0,) * n, rmse_after=(0.5,) * n, r2_before=(0.9,) * n, r2_after=(0.95,) * n,
        rmse_train_before=(1.0,) * n, rmse_train_after=(0.5,) * n, residual_findings=(), candidates_tried=1,
        augmented=SimpleNamespace(terms=(candidate,), coefficients=([1.0],)), validation_t=np.arange(2.0),
        validation_q=zeros, validation_qd=zeros, validation_tau=zeros, validation_nominal=zeros,
        validation_final=zeros,
    )  # fmt: skip
    # psdm diagnose MODEL runs the diagnosis through diagnose_model: patched where that module looks it up
    model_file = importlib.import_module("identification.diagnosis.model_file")  # the module, not the function
    monkeypatch.setattr(model_file, "diagnose", lambda *a, **k: report)
    for name, target in (("valid.csv", "valid_mNm.csv"), ("train.csv", "mNm.csv")):
        recording = load_recording(arm / name)
        tau = recording.tau + np.array([OFFSET_J1, 0.0, 0.0])  # the offset the finding names, in N m
        save_recording(recording.with_signals(tau=1000.0 * tau), tmp_path / target)
    new = tmp_path / "new.json"
    argv = ["diagnose", arm / "mNm.json", "--train", tmp_path / "mNm.csv", "--validate", tmp_path / "valid_mNm.csv",
            "--apply", new, "--allow-inconsistent"]  # fmt: skip
    code, _, err = _run(capsys, argv)  # today the refit refuses the mN m torques before fitting
    assert code == 2 and "mNm.csv" in err and "mN m" in err and not new.exists(), err
    for module in (trajectory_data, motion_checks):  # a diagnosis and refit of before the refusal
        monkeypatch.setattr(module, "check_torque_magnitude", lambda *args, **kwargs: None)
    code, _, err = _run(capsys, argv)
    assert code == 0, err
    written = json.loads(new.read_text())
    (offset,) = written["findings"]  # it gained: the recordings carry it (in mN m, as they are)
    assert offset["label"] == "torque_offset[j1]" and offset["gain"]["share_lower"][0] >= GAIN_SHARE
    kept = written["warnings"]
    assert any("rigid-body torques" in w and "mN m?" in w for w in kept), kept
    assert "psdm diagnose: warning: new.json" in err and all(w in err for w in kept)


def test_a_refit_on_train_alone_that_beats_the_model_file_is_named_with_its_joints():
    """Nothing to apply, but the refit on --train alone predicts the validation recording better than the model file
    beyond a joint's margin: the joints are named, with their RMSE pairs and the cause to look for (the recordings
    identify averaged disagree, e.g. friction of joints that warmed up); a joint within its margin, or worse, is not."""
    names = ("A1", "A2", "A3", "A4")
    before, after, margin = (0.526, 0.470, 0.367, 0.115), (0.500, 0.274, 0.360, 0.130), (0.037, 0.027, 0.013, 0.004)
    note = better_alone(before, after, margin, names)
    assert "better on joint(s) 2 beyond their margins (A2 0.47 -> 0.274 N m)" in note, note
    assert "A1" not in note and "A3" not in note and "A4" not in note and "warm up" in note
    assert better_alone(before, before, margin, names) == ""


def test_apply_with_only_reported_findings_writes_nothing_and_keeps_the_model_file(arm, tmp_path, capsys, monkeypatch):
    """A diagnosis whose only finding is pre-sliding (reported, no model file holds it): ``--apply`` would write the
    model file identified again on ``--train`` alone, with nothing added. On a virtual 7-joint cobot identified on two
    recordings that refit lost one of them (joint 7 0.0333 -> 0.0391 N m) and was written as 'the model with none
    added'. Now nothing is written and the model file is named as the model to use, as with no finding at all."""
    finding = Finding(effect="presliding", label="presliding[j1]", joints=(0,),
                      parameters={"presliding_coulomb_Nm": 1.0, "presliding_displacement_rad": 1e-4},
                      coefficients=(1.0,), feature_names=("presliding_j1",), explanation="", signature="",
                      rmse_before=(1.0,) * 3, rmse_after=(0.5,) * 3, delta_bic=-10.0, validation_gain=0.5)  # fmt: skip
    n, zeros = 3, np.zeros((2, 3))
    report = DiagnosisReport(
        robot_name="arm", n_dof=n, friction="coulomb_viscous", rigid_body="prior", findings=(finding,),
        rmse_before=(1.0,) * n, rmse_after=(0.5,) * n, r2_before=(0.9,) * n, r2_after=(0.95,) * n,
        rmse_train_before=(1.0,) * n, rmse_train_after=(0.5,) * n, residual_findings=(), candidates_tried=1,
        augmented=SimpleNamespace(terms=(), coefficients=()), validation_t=np.arange(2.0),
        validation_q=zeros, validation_qd=zeros, validation_tau=zeros, validation_nominal=zeros,
        validation_final=zeros,
    )  # fmt: skip
    model_file = importlib.import_module("identification.diagnosis.model_file")
    monkeypatch.setattr(model_file, "diagnose", lambda *a, **k: report)
    new = tmp_path / "new.json"
    model, train, valid = arm / "good.json", arm / "train.csv", arm / "valid.csv"
    argv = ["diagnose", model, "--train", train, "--validate", valid, "--apply", new]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    assert not new.exists()
    assert out.rstrip().endswith(f"{new} was not written; {model} stays the model to use (this table's 'after' row "
                                 "is it identified again on --train alone, with nothing added)")  # fmt: skip
    code, out, err = _run(capsys, [*argv, "--json"])
    assert code == 0 and not new.exists() and json.loads(out)["recalibration"]["model"] is None


def test_validate_and_diagnose_judge_a_loaded_recording_alike(arm, tmp_path, capsys):
    """A held-out recording that carries a known load (its sidecar states it): ``psdm validate MODEL`` and the "before"
    of ``psdm diagnose MODEL`` are one number per joint. The load was added to validate's prediction on the prepared
    positions, while the diagnosis took it off the raw torque, then prepared (a cobot's joint 2: 0.3071 and 0.3053 N m);
    both now take the load's torque as ``payload_check.without_load`` gives it. Unloaded, they agreed already."""
    from identification.calibration.payload_fit import FlangeRegressor

    robot = load_robot(arm / "arm.toml")
    valid = load_recording(arm / "valid.csv")
    qd = np.gradient(valid.q, valid.t, axis=0)
    body = np.array([2.0, 0.0, 0.0, 0.1, 0.012, 0.012, 0.004, 0.0, 0.0, 0.0])  # 2 kg, 5 cm out along the flange z
    load = FlangeRegressor(robot)(valid.q, qd, np.gradient(qd, valid.t, axis=0)) @ body
    save_recording(valid.with_signals(tau=valid.tau + load), tmp_path / "loaded.csv")
    (tmp_path / "loaded.payload.json").write_text(json.dumps({"mass": 2.0, "com": [0.0, 0.0, 0.05]}))
    code, out, err = _run(capsys, ["validate", arm / "good.json", tmp_path / "loaded.csv", "--json"])
    assert code == 0, err
    validated = json.loads(out)["recordings"][0]["rmse"]
    code, out, err = _run(capsys, ["diagnose", arm / "good.json", "--train", arm / "train.csv", "--validate",
                                   tmp_path / "loaded.csv", "--max-effects", "0", "--no-sparse", "--json"])  # fmt: skip
    assert code in (0, 1), err
    before = json.loads(out)["rmse_before"]
    np.testing.assert_allclose(before, validated, rtol=1e-9)


@pytest.fixture(scope="module")
def loaded_model(arm, tmp_path_factory):
    """``(loaded.csv, loaded.json, identify's stdout and stderr)``: the validation recording with a 2 kg load at the
    flange no sidecar states, and the model identify wrote with it held out (and its page, ``loaded.report.html``)."""
    from identification.calibration.payload_fit import FlangeRegressor

    folder = tmp_path_factory.mktemp("loaded")
    robot = load_robot(arm / "arm.toml")
    valid = load_recording(arm / "valid.csv")
    qd = np.gradient(valid.q, valid.t, axis=0)
    body = np.array([2.0, 0.0, 0.0, 0.1, 0.012, 0.012, 0.004, 0.0, 0.0, 0.0])  # 2 kg, 5 cm out along the flange z
    load = FlangeRegressor(robot)(valid.q, qd, np.gradient(qd, valid.t, axis=0)) @ body
    loaded, model = folder / "loaded.csv", folder / "loaded.json"
    save_recording(valid.with_signals(tau=valid.tau + load), loaded)
    argv = ["identify", arm / "arm.toml", "--data", arm / "train.csv", "--validate", loaded, "--out", model]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main([str(a) for a in argv]) == 0
    return loaded, model, out.getvalue(), err.getvalue()


def test_a_load_identify_found_on_a_held_out_recording_is_said_once_by_identify_validate_and_diagnose(
    arm, loaded_model, capsys
):
    """identify said its sentence on a load nothing states on its held-out recording twice, as a warning and as the
    "payload:" line of that recording's validation table; it says it once, in the table (the stored warnings keep it,
    for the commands that read the file). validate and diagnose MODEL repeated the stored sentence beside their own line
    on the same load of the same recording (two lines, one load). Judging that recording again, they say it once, their
    own line; validating another recording, the stored sentence is still repeated (nothing else names that load)."""
    loaded, model, identify_out, identify_err = loaded_model
    (stored,) = [w for w in json.loads(model.read_text())["warnings"] if "carries a load at the flange" in w]
    said = "carries a load at the flange that nothing states"
    assert (identify_out + identify_err).count(said) == 1 and f"  payload: {stored}" in identify_out, identify_err
    said_in_it = ("kg (its mass", "centre of mass", "Taken off before judging", "sidecar: loaded.payload.json")
    assert all(part in stored for part in said_in_it), stored  # the one line holds all it says
    code, out, err = _run(capsys, ["validate", model, loaded])
    assert code == 0 and (out + err).count(said) == 1 and f"payload: {loaded}" in out, err
    code, out, err = _run(capsys, ["validate", model, loaded, "--json"])
    assert code == 0 and stored not in json.loads(out)["warnings"]
    assert json.loads(out)["recordings"][0]["payload"]["taken_off"]
    code, out, err = _run(capsys, ["diagnose", model, "--train", arm / "train.csv", "--validate", loaded,
                                   "--max-effects", "0", "--no-sparse"])  # fmt: skip
    assert code in (0, 1) and (out + err).count(said) == 1 and "## Payload check" in out, err
    code, out, err = _run(capsys, ["validate", model, arm / "valid.csv"])  # another recording: the stored one said
    assert code == 0 and stored in err and out.count(said) == 0, err


def test_identifys_page_plots_the_held_out_torque_as_its_validation_judges_it(loaded_model):
    """The model file's validation RMSE on the loaded recording is the arm's (the load nothing states taken off,
    ``rmse_load_left_in`` beside it); the page plotted the prediction against the torque with the load left in, whose
    residual is the load's torque. Its residual's RMSE is now the file's on every joint, and its title and legend say
    what was taken off."""
    from psdm_casadi.cli.html_report import default_html_path
    from tests.psdm_casadi.html_page import plot_data

    loaded, model, _, _ = loaded_model
    (entry,) = json.loads(model.read_text())["validation"]["recordings"]
    load = entry["unstated_payload"]
    assert load["taken_off"] and max(np.divide(load["rmse_load_left_in"], entry["rmse"])) > 3
    page = default_html_path(model).read_text()
    for j in range(3):
        measured, predicted, residual = plot_data(page, f"joint-{j + 1}-loaded.csv")
        np.testing.assert_allclose(np.subtract(measured["y"], predicted["y"]), residual["y"], atol=1e-9)
        assert np.sqrt(np.mean(np.square(residual["y"]))) == pytest.approx(entry["rmse"][j], rel=1e-6)
        assert measured["name"] == f"measured, the {load['mass']:.3g} kg load nothing states taken off"
        assert f"RMSE {entry['rmse'][j]:.4g} N m (the arm's: the {load['mass']:.3g} kg load nothing states" in page
