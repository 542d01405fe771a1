"""One preparation: every command that judges a model prepares the recordings as the model file says.

``psdm validate`` and ``psdm diagnose`` of the same model file on the same recording report the same RMSE of that
model per joint, and the diagnosis names the file it started from and the preparation it used; a file written
before the preparation was stored is judged as before, with a note; a robot file is diagnosed with the preparation
``psdm identify`` would choose.
"""

import copy
import json

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.model_preparation import default_preparation, model_preparation
from identification.calibration.trajectory_data import prepare_recording
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def denso_files(tmp_path_factory, denso, denso_model):
    """A training and a validation recording of the virtual Denso at 500 Hz, and the model identified on the first
    at a cutoff of 8 Hz (neither identify's default 10 Hz nor diagnose's former 15 Hz)."""
    folder = tmp_path_factory.mktemp("one_preparation")
    recordings = []
    for k, name in enumerate(("train.csv", "valid.csv")):
        rng = np.random.default_rng(90 + k)
        reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=500.0)
        recording, _ = simulate_recording(denso, reference, options, rng)
        save_recording(recording, folder / name)
        recordings.append(recording)
    fit = identify_trajectories(denso, denso_model, recordings[:1], TrajectoryOptions(cutoff_hz=8.0))
    CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE).save(folder / "model.json")
    return folder


def test_the_model_file_stores_its_preparation_and_an_older_file_is_judged_as_before(denso_files, denso_model):
    calibrated = load_calibrated_model(denso_files / "model.json")
    block = calibrated.document["identification"]["preparation"]
    assert block["cutoff_hz"] == 8.0 and block["grid_rate_hz"] == 80.0 and block["order"] == 8 and block["version"]
    assert model_preparation(calibrated.document).note == ""
    older = copy.deepcopy(calibrated.document)
    del older["identification"]["preparation"]
    preparation = model_preparation(older)
    assert preparation.cutoff_hz == 8.0 and "written before its preparation was stored" in preparation.note
    from identification.data.io import load_recording

    recording = load_recording(denso_files / "valid.csv", 6)
    ours = calibrated.predict_recording(denso_model, recording)
    theirs = CalibratedModel(older).predict_recording(denso_model, recording)
    ready, _, _ = prepare_recording(recording, None, 8.0)  # the identification's own preparation, independently
    np.testing.assert_array_equal(ours[0].tau, ready.tau)
    # the older file: its cutoff and today's filter, with the one filter period it was judged with (test_edge_trim)
    before, _, _ = prepare_recording(recording, None, 8.0, 1)
    np.testing.assert_array_equal(theirs[0].tau, before.tau)
    np.testing.assert_array_equal(theirs[1], calibrated.predict(denso_model, before.q, before.qd, before.qdd))


def test_validate_states_the_preparation_and_notes_an_older_file(denso_files, tmp_path, capsys):
    document = json.loads((denso_files / "model.json").read_text())
    assert main(["validate", str(denso_files / "model.json"), str(denso_files / "valid.csv"), "--json"]) == 0
    captured = capsys.readouterr()
    new = json.loads(captured.out)
    assert new["preparation"]["cutoff_hz"] == 8.0 and "note:" not in captured.err
    del document["identification"]["preparation"]
    (tmp_path / "old.json").write_text(json.dumps(document))
    assert main(["validate", str(tmp_path / "old.json"), str(denso_files / "valid.csv"), "--json"]) == 0
    captured = capsys.readouterr()
    old = json.loads(captured.out)
    assert old["preparation"]["edge_periods"] == 1 and new["preparation"]["edge_periods"] == 3  # judged as before
    assert "note:" in captured.err and "written before its preparation was stored" in captured.err


def test_a_robot_file_gets_the_preparation_identify_would_choose():
    t = np.arange(0.0, 2.0, 0.02)  # 50 Hz: identify filters at rate / 10 = 5 Hz
    slow = default_preparation(Recording(t=t, q=np.zeros((t.size, 1)), tau=np.zeros((t.size, 1))))
    t = np.arange(0.0, 2.0, 1e-3)  # 1 kHz: at 10 Hz
    fast = default_preparation(Recording(t=t, q=np.zeros((t.size, 1)), tau=np.zeros((t.size, 1))))
    found = (slow.cutoff_hz, slow.grid_rate_hz, fast.cutoff_hz, fast.grid_rate_hz)
    np.testing.assert_allclose(found, (5.0, 50.0, 10.0, 100.0), rtol=1e-12)
    assert "identify's default" in fast.source


@pytest.mark.slow
def test_validate_and_diagnose_report_the_same_before_and_the_report_names_the_file(denso_files, capsys, tmp_path):
    model, valid = str(denso_files / "model.json"), str(denso_files / "valid.csv")
    assert main(["validate", model, valid, "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    argv = ["diagnose", model, "--train", str(denso_files / "train.csv"), "--validate", valid, "--out",
            str(tmp_path / "report"), "--no-sparse", "--rigid-body", "prior", "--max-effects", "1"]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    np.testing.assert_allclose(report["model_file_rmse"], validated, rtol=1e-12)
    # one "before": the diagnosis judged the samples validate judges, so its before is the file's own RMSE
    np.testing.assert_allclose(report["rmse_before"], validated, rtol=1e-9)
    assert report["before_is_model_file"] is True
    assert model in report["nominal_model"] and "calibrated model file" in report["nominal_model"]
    assert "at 8 Hz" in report["preparation"] and "(model file)" in report["preparation"]
    assert f"Nominal model: the calibrated model file {model}" in text and "rigid body from the robot file" not in text
    assert "RMSE before is the model file as it is" in text and f"| 1 | {validated[0]:.4g} |" in text
    assert "RMSE before is the nominal model refitted" not in text


def test_auto_is_identify_s_preparation_and_identify_samples_are_validate_s(denso_files, denso, denso_model):
    """``DiagnosisOptions(cutoff_hz="auto", rate_hz="auto")`` prepares a recording as ``psdm identify`` would (one
    definition, ``filter_choice``), and with ``samples="identify"`` the diagnosis keeps identify's samples: the same
    instants and torques as ``prepare_recording``, for a model file's own cutoff too."""
    from identification.data.io import load_recording
    from identification.diagnosis.diagnose import DiagnosisOptions, prepare_problem

    train, valid = (load_recording(denso_files / name, 6) for name in ("train.csv", "valid.csv"))
    auto = DiagnosisOptions(cutoff_hz="auto", rate_hz="auto").for_recording(train)
    identify = default_preparation(train)
    assert (auto.cutoff_hz, auto.rate_hz) == (identify.cutoff_hz, identify.grid_rate_hz) == (10.0, 100.0)
    for cutoff, rate in (("auto", "auto"), (8.0, 80.0)):
        options = DiagnosisOptions(rigid_body="prior", cutoff_hz=cutoff, rate_hz=rate, samples="identify")
        problem = prepare_problem(denso, denso_model, train, valid, options)
        cutoff = options.for_recording(train).cutoff_hz
        ready, _, _ = prepare_recording(valid, None, cutoff)  # the identification's own preparation
        np.testing.assert_allclose(problem.ctx_v.t, ready.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(problem.ctx_v.tau, ready.tau, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(problem.ctx_v.q, ready.q, rtol=1e-9, atol=1e-12)


def test_the_library_s_defaults_are_identify_s_preparation_and_samples(denso_files, denso, denso_model):
    """``DiagnosisOptions()`` without arguments prepares a robot file's recordings as ``psdm identify`` would (the
    cutoff, grid and samples ``psdm diagnose ROBOT`` uses), and a model file's as the file says."""
    from identification.data.io import load_recording
    from identification.diagnosis.diagnose import DiagnosisOptions, prepare_problem
    from identification.diagnosis.model_file import model_file_options
    from identification.diagnosis.rigid_body_choice import inertial_note, stand_in_note

    train, valid = (load_recording(denso_files / name, 6) for name in ("train.csv", "valid.csv"))
    resolved = DiagnosisOptions().for_recording(train, denso)
    identify = default_preparation(train)  # what the CLI takes for a robot file
    assert (resolved.cutoff_hz, resolved.rate_hz) == (identify.cutoff_hz, identify.grid_rate_hz) == (10.0, 100.0)
    assert resolved.samples == "identify" and resolved.friction == "lugre"
    problem = prepare_problem(denso, denso_model, train, valid, DiagnosisOptions(rigid_body="prior"))
    ready, _, _ = prepare_recording(valid, None, 10.0)  # the identification's own preparation
    np.testing.assert_allclose(problem.ctx_v.t, ready.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(problem.ctx_v.tau, ready.tau, rtol=1e-9, atol=1e-9)
    calibrated = load_calibrated_model(denso_files / "model.json")
    own = model_file_options(calibrated)
    assert (own.cutoff_hz, own.rate_hz, own.samples, own.friction) == (8.0, 80.0, "identify", "coulomb_viscous")
    stated = model_file_options(calibrated, DiagnosisOptions(cutoff_hz=12.0))  # a stated cutoff: identify's grid
    assert stated.for_recording(train).rate_hz == 120.0
    # the report names the nominal inertia it started from: the model file's (identify's), not the robot file's
    assert (own.nominal, resolved.nominal) == ("model file", "robot file")
    note = inertial_note(("payload",), 0.2, 0.1, [("m2", 1.0, 2.0, 1.0)], own.nominal)
    assert note.startswith("the model file's inertial parameters are off")
    stand_in = stand_in_note(["spring[j2]"], [1], [1.0, 1.0], [1.0, 1.0], "kept", own.nominal)
    assert "the model file's inertia is in question" in stand_in


@pytest.mark.slow
def test_python_and_cli_diagnoses_of_a_model_file_and_a_robot_file_give_the_same_numbers(denso_files, capsys, tmp_path):
    """``diagnose_model`` in Python and ``psdm diagnose MODEL`` report the model file's own validation RMSE (``psdm
    validate``'s) as "before", to 1e-9; ``diagnose(robot)`` and ``psdm diagnose ROBOT`` give the same numbers with
    identify's default preparation (10 Hz here)."""
    from identification.data.io import load_recording
    from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
    from identification.diagnosis.model_file import diagnose_model
    from psdm_casadi.robot_file import load_robot

    model, train_csv, valid_csv = (str(denso_files / n) for n in ("model.json", "train.csv", "valid.csv"))
    assert main(["validate", model, valid_csv, "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    train, valid = load_recording(train_csv, 6), load_recording(valid_csv, 6)
    options = DiagnosisOptions(rigid_body="prior", sparse=False, max_effects=1)
    ours = diagnose_model(model, train, valid, options)
    np.testing.assert_allclose(ours.rmse_before, validated, rtol=1e-9)
    assert ours.before_is_model_file and "at 8 Hz" in ours.preparation and model in ours.nominal_model
    flags = ["--no-sparse", "--rigid-body", "prior", "--max-effects", "1", "--json"]
    assert main(["diagnose", model, "--train", train_csv, "--validate", valid_csv, *flags]) == 0
    cli = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(cli["rmse_before"], validated, rtol=1e-9)
    np.testing.assert_allclose(cli["rmse_after"], ours.rmse_after, rtol=1e-9)
    robot = load_robot(str(DENSO_FILE))
    python = diagnose(robot, train, valid, options)
    assert main(["diagnose", str(DENSO_FILE), "--train", train_csv, "--validate", valid_csv, *flags]) == 0
    cli = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(cli["rmse_before"], python.rmse_before, rtol=1e-9)
    np.testing.assert_allclose(cli["rmse_after"], python.rmse_after, rtol=1e-9)
    assert "at 10 Hz" in python.preparation and "identify's default" in python.preparation
    assert "at 10 Hz" in cli["preparation"]


def test_a_diagnosis_without_findings_reports_the_model_file_as_its_after(denso_files, denso_model):
    """The virtual Denso holds nothing the model lacks: a diagnosis of its model file that keeps no finding adds
    nothing, so its "after" is the file as it is, the RMSE ``psdm validate`` gives, not the diagnosis's own refit of
    the nominal friction on its one training recording (which the report once showed as "after", worse on a joint,
    for a model nobody writes)."""
    from identification.calibration.finding_value import validation_rmse
    from identification.data.io import load_recording
    from identification.diagnosis.candidates import CandidateLibrary, TorqueOffsetTerm
    from identification.diagnosis.diagnose import DiagnosisOptions
    from identification.diagnosis.model_file import diagnose_model

    train, valid = (load_recording(denso_files / name, 6) for name in ("train.csv", "valid.csv"))
    options = DiagnosisOptions(
        rigid_body="prior", sparse=False, library=CandidateLibrary((TorqueOffsetTerm(),)), refine=False
    )
    report = diagnose_model(denso_files / "model.json", train, valid, options, derive=lambda robot: denso_model)
    own = validation_rmse(load_calibrated_model(denso_files / "model.json"), denso_model, valid)[0]
    assert not report.findings and report.before_is_model_file
    np.testing.assert_allclose(report.rmse_before, own, rtol=1e-9)
    np.testing.assert_allclose(report.rmse_after, own, rtol=1e-9)
    assert report.joint_notes == ()
