"""A model file's carried finding whose size changed is written at the data's size (``diagnosis.carried_sizes``,
``calibration.resized_findings``); one whose size holds is kept, and nothing is refitted or written.

Reference: the virtual Denso's hidden truth, torque sensors with 0.1 N m noise and no friction. The model file is the
one ``diagnose --apply`` writes (``applied_model``'s ``finding_terms`` and ``joint_fit``) from a recording whose joint 2
carries a torque ripple 1.5 sin(6 q2 + 0.4) N m. New recordings of the same motion: (a) the ripple grown to 2.5 N m
(a worn gear), (b) the same 1.5 N m. Before, the ripple was carried and fitted again to 2.5 N m, reported, and
``--apply`` wrote nothing (no new label: ``adds_nothing``), so the file kept 1.5 N m for ever.
"""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.applied_model import finding_terms, joint_fit
from identification.calibration.calibrated_model import CalibratedModel, read_calibrated_model
from identification.calibration.recalibrate import recalibrate
from identification.calibration.refit_training import RefitTraining
from identification.calibration.resized_findings import RESIZED_KEY, resized_labels
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.diagnosis.applied_after import with_applied_after, with_written_after
from identification.diagnosis.candidates import CandidateLibrary, CouplingTerm, TorqueRippleTerm
from identification.diagnosis.carried_sizes import HOLDS, RESIZED
from identification.diagnosis.diagnose import DiagnosisOptions
from identification.diagnosis.model_file import diagnose_model, diagnose_model_prior
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli.recalibration_text import adds_nothing
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import cli_json
from trajopt.experiments import sine_experiment

FILE_AMPLITUDE, WORN_AMPLITUDE, HARMONIC, PHASE, RATE = 1.5, 2.5, 6, 0.4, 500.0
RIPPLE = TorqueRippleTerm(joint=1, harmonic=HARMONIC)


def _recording(robot, amplitude, seed, coupling=0.0, seconds=(9.0, 6.0)):
    """(training part, held-out part) of ``seconds[0]`` s of the same sine motion, cut at ``seconds[1]``, with a ripple
    of ``amplitude`` on joint 2 (and a viscous coupling ``coupling`` qd5 on joint 6)."""
    reference = sine_experiment(robot, duration=seconds[0], rng=np.random.default_rng(3)).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False, rate=RATE)
    extras = [xp.TorqueRipple(joint=1, amplitude=amplitude, harmonic=float(HARMONIC), phase=PHASE)]
    if coupling:
        matrix = np.zeros((6, 6))
        matrix[5, 4] = coupling
        extras.append(xp.JointCoupling(matrix=matrix))
    recording, _ = simulate_recording(robot, reference, options, np.random.default_rng(seed), extras=extras)
    return recording.time_slice(-np.inf, seconds[1]), recording.time_slice(seconds[1], np.inf)


def _model_file(denso, denso_model, folder, coupling=0.0, seconds=(9.0, 6.0)):
    """(model file, its training recording): the ripple as ``--apply`` writes it, identified on a recording with the
    file's size."""
    train, _ = _recording(denso, FILE_AMPLITUDE, 11, coupling, seconds)
    fit = identify_trajectories(denso, denso_model, [train], TrajectoryOptions())
    before = CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)
    coefficients = tuple(FILE_AMPLITUDE * np.array([np.cos(PHASE), np.sin(PHASE)]))
    finding = SimpleNamespace(effect=RIPPLE.key, label=RIPPLE.label, joints=RIPPLE.joints, coefficients=coefficients,
                              parameters={}, feature_names=tuple(RIPPLE.feature_names()), rmse_before=(),
                              rmse_after=())  # fmt: skip
    augmented = SimpleNamespace(terms=(RIPPLE,), coefficients=[coefficients])
    report = SimpleNamespace(findings=(finding,), augmented=augmented)
    after, _ = joint_fit(before, denso, denso_model, [train], finding_terms(before, report), DENSO_FILE)
    path = folder / "model.json"
    after.save(path)
    return read_calibrated_model(path, derive=lambda robot: denso_model), train


@pytest.fixture(scope="module")
def model_file(denso, denso_model, tmp_path_factory):
    """The model file with the ripple as ``--apply`` writes it, identified on a recording with the file's size."""
    return _model_file(denso, denso_model, tmp_path_factory.mktemp("carried_sizes"))[0]


def _diagnosed(loaded, recordings):
    train, validation = recordings
    options = DiagnosisOptions(library=CandidateLibrary((TorqueRippleTerm(harmonics=(3, 6)),)), rigid_body="prior",
                               sparse=False, cv_folds=0)  # fmt: skip
    return diagnose_model(loaded, train, [validation], options)


@pytest.fixture(scope="module")
def worn(denso, model_file):
    """(recordings, report) of the new recordings whose ripple grew."""
    recordings = _recording(denso, WORN_AMPLITUDE, 12)
    return recordings, _diagnosed(model_file, recordings)


def test_the_file_holds_the_ripple_at_its_size(model_file):
    (entry,) = model_file.calibrated.document["findings"]
    assert entry["label"] == RIPPLE.label
    assert entry["parameters"]["amplitude"] == pytest.approx(FILE_AMPLITUDE, rel=0.05)


def test_a_grown_ripple_is_read_as_the_file_being_off(worn):
    _, report = worn
    (size,) = report.carried_sizes
    assert size.verdict == RESIZED and size.label == RIPPLE.label
    assert size.data == pytest.approx(WORN_AMPLITUDE, rel=0.05)  # the truth's new size
    assert size.file == pytest.approx(FILE_AMPLITUDE, rel=0.05) and size.sigmas > 3.0
    assert size.better == (1,) and size.worse == ()
    (finding,) = report.findings  # one finding: the file's own label, a correction of its size (not a new effect)
    assert finding.label == RIPPLE.label and f"the model file's `{RIPPLE.label}` is off by +" in finding.correction
    assert f"writes amplitude as {size.written:.4g}" in finding.correction
    assert size.written == pytest.approx(WORN_AMPLITUDE, rel=0.05)


def test_apply_writes_the_new_size_in_place_and_validation_is_better(denso, denso_model, model_file, worn):
    """The CLI's --apply path (``recalibrate`` on the report's model, then ``adds_nothing``): main wrote nothing."""
    (train, validation), report = worn
    assert report.applied is not None and report.applied.fit is None  # the file resized, nothing refitted
    calibrated = model_file.calibrated
    result = recalibrate(calibrated, denso, denso_model, report, train, [validation], applied=report.applied)
    assert result.refused is None and not adds_nothing(calibrated.document, result.after.document)
    (entry,) = result.after.document["findings"]  # the same label, no duplicate
    assert entry["label"] == RIPPLE.label and resized_labels(calibrated.document, result.after.document) == (
        RIPPLE.label,
    )
    assert entry["parameters"]["amplitude"] == pytest.approx(WORN_AMPLITUDE, rel=0.05)
    assert entry[RESIZED_KEY]["parameters"]["amplitude"] == pytest.approx(FILE_AMPLITUDE, rel=0.05)
    assert result.rmse_after[1] < 0.5 * result.rmse_before[1]  # joint 2: the grown ripple's 1 N m mostly gone
    np.testing.assert_allclose(report.rmse_after, result.rmse_after, rtol=1e-6)  # the report's "after" is it


def test_a_ripple_of_the_file_size_holds_and_nothing_is_refitted(denso, model_file):
    recordings = _recording(denso, FILE_AMPLITUDE, 13)
    report = _diagnosed(model_file, recordings)
    (size,) = report.carried_sizes
    assert size.verdict == HOLDS and size.data == pytest.approx(FILE_AMPLITUDE, rel=0.05)
    assert any(f"the model file's `{RIPPLE.label}` holds at its size" in n for n in report.rigid_body_notes)
    assert report.nothing_applied and report.applied is None and report.refit_training is None  # no refit run
    np.testing.assert_allclose(report.rmse_after, report.rmse_before)  # the "after" is the file as it is
    assert "nothing to apply" in report.after_source


def test_a_record_an_older_apply_left_is_not_a_new_size():
    """``resized_labels`` names only the sizes written over this file's own (a refit carrying an older file's record,
    its coefficients fitted again, adds nothing: main's ``adds_nothing`` holds for it)."""
    before = {"findings": [{"label": "r", "kind": "torque", "coefficients": [1.0, 0.0], RESIZED_KEY: {"coefficients": [
        0.5, 0.0]}}]}  # fmt: skip
    refitted = {"findings": [dict(before["findings"][0], coefficients=[1.01, 0.0])]}
    resized = {"findings": [dict(before["findings"][0], coefficients=[2.0, 0.0], **{RESIZED_KEY: {
        "coefficients": [1.0, 0.0]}})]}  # fmt: skip
    assert resized_labels(before, refitted) == () and adds_nothing(before, refitted)
    assert resized_labels(before, resized) == ("r",) and not adds_nothing(before, resized)


@pytest.mark.slow  # two 'psdm diagnose MODEL --apply' runs with the default library: 1-3 min
def test_the_command_writes_the_grown_ripple_and_nothing_for_the_same(denso, model_file, worn, tmp_path):
    """``psdm diagnose model.json --train --validate --apply``: the grown ripple is written in place (one entry, the
    truth's size), the same ripple writes no file and runs no refit."""
    model = tmp_path / "model.json"
    model_file.calibrated.save(model)
    for name, (train, validation) in (("worn", worn[0]), ("same", _recording(denso, FILE_AMPLITUDE, 13))):
        paths = [tmp_path / f"{name}_{part}.npz" for part in ("train", "valid")]
        save_recording(train, paths[0])
        save_recording(validation, paths[1])
        out = tmp_path / f"{name}_applied.json"
        payload = cli_json(["diagnose", model, "--train", paths[0], "--validate", paths[1], "--apply", out, "--json"])
        if name == "worn":
            (entry,) = json.loads(out.read_text())["findings"]
            assert entry["label"] == RIPPLE.label and payload["recalibration"]["model"] == str(out)
            assert entry["parameters"]["amplitude"] == pytest.approx(WORN_AMPLITUDE, rel=0.05)
        else:
            assert not out.exists() and "recalibration" not in payload and payload["nothing_applied"]
            assert payload["rmse_after"] == payload["rmse_before"]


def test_a_new_finding_the_refit_drops_leaves_the_resize_written_alone(denso, denso_model, model_file, worn):
    """Beside the grown ripple, a ripple on joint 6 the recordings do not hold (truth: none; put into the report as a
    new finding): the refit drops it (no help on validation) and the model is the file with the ripple resized
    alone, nothing refitted, which --apply writes (before, the refit without it added no label: nothing written)."""
    (train, validation), report = worn
    ghost = TorqueRippleTerm(joint=5, harmonic=3)
    finding = replace(report.findings[0], effect=ghost.key, label=ghost.label, joints=ghost.joints,
                      coefficients=(0.3, 0.0), parameters={}, feature_names=tuple(ghost.feature_names()),
                      correction="")  # fmt: skip
    augmented = SimpleNamespace(terms=(*report.augmented.terms, ghost),
                                coefficients=[*report.augmented.coefficients, (0.3, 0.0)])  # fmt: skip
    both = with_applied_after(replace(report, findings=(*report.findings, finding), augmented=augmented,
                                      applied=None), model_file, train, validation)  # fmt: skip
    applied = both.applied
    assert [d["label"] for d in applied.dropped] == [ghost.label] and applied.fit is None  # nothing refitted
    result = recalibrate(model_file.calibrated, denso, denso_model, both, train, [validation], applied=applied)
    assert result.refused is None and not adds_nothing(model_file.calibrated.document, result.after.document)
    (entry,) = result.after.document["findings"]
    assert entry["label"] == RIPPLE.label
    assert entry["parameters"]["amplitude"] == pytest.approx(WORN_AMPLITUDE, rel=0.05)
    assert result.after.document["recalibration"]["resized_alone"] == [RIPPLE.label]
    np.testing.assert_allclose(both.rmse_after, result.rmse_after, rtol=1e-6)  # the report's "after" is it


#: The coupled arm's recordings: 12 s, 8 s of training (the gate's refits without each training block can run).
COUPLED_SECONDS, COUPLING = (12.0, 8.0), 0.5


@pytest.fixture(scope="module")
def coupled_file(denso, denso_model, tmp_path_factory):
    """(model file, its training recording) of an arm with a viscous coupling 0.5 qd5 on joint 6 the file lacks."""
    return _model_file(denso, denso_model, tmp_path_factory.mktemp("coupled"), COUPLING, COUPLED_SECONDS)


def _coupled_apply(denso, denso_model, coupled_file, seed):
    """(report, recalibration, validation) of the new recordings ``seed`` of the coupled arm, its ripple grown to
    2.5 N m, diagnosed and applied as ``diagnose --apply`` does, the refit training on the new recording and the
    file's own (found again, as ``refit_training`` does)."""
    loaded, old = coupled_file
    train, validation = _recording(denso, WORN_AMPLITUDE, seed, COUPLING, COUPLED_SECONDS)
    options = DiagnosisOptions(library=CandidateLibrary((TorqueRippleTerm(harmonics=(3, 6)), CouplingTerm(
        joint=5, source=4))), rigid_body="prior", sparse=False, cv_folds=0)  # fmt: skip
    refit = lambda: RefitTraining((train, old), ("new.npz (--train)", "old.npz"), ({}, {}))  # noqa: E731
    report, _ = diagnose_model_prior(loaded, train, [validation], options, refit=refit)
    (size,) = report.carried_sizes
    assert size.verdict == RESIZED and size.data == pytest.approx(WORN_AMPLITUDE, rel=0.05)
    entries = {e["label"]: e for e in report.applied.after.document["findings"]}
    assert entries[RIPPLE.label]["parameters"]["amplitude"] == pytest.approx(size.data, rel=1e-9)  # held, no blend
    (coupling,) = [label for label in entries if label.startswith("coupling")]
    assert entries[coupling]["parameters"]["viscous"] == pytest.approx(COUPLING, rel=0.05)  # the truth, on both
    assert report.applied.train[1] is not old  # the file's recording put at the new size (``at_data_size``)
    result = recalibrate(loaded.calibrated, denso, denso_model, report, train, [validation], applied=report.applied)
    assert result.refused is None and not adds_nothing(loaded.calibrated.document, result.after.document)
    margin = np.asarray(result.after.document["recalibration"]["never_worse"]["margin"])
    assert np.all(result.rmse_after <= result.rmse_before + margin)  # never worse, joint by joint
    written = {e["label"]: e for e in result.after.document["findings"]}
    assert written[RIPPLE.label]["parameters"]["amplitude"] == pytest.approx(size.data, rel=1e-9)
    assert result.rmse_after[1] < 0.1 * result.rmse_before[1]  # joint 2: the grown ripple's torque gone
    shown = with_written_after(report, result, denso_model, validation, None, True)
    np.testing.assert_allclose(shown.rmse_after, result.rmse_after, rtol=1e-6)  # the report's "after" is the written
    return shown, result, coupling


@pytest.mark.slow  # a model file, a diagnosis, its refit on both recordings, the never-worse gate: about a minute
def test_a_resize_beside_a_new_finding_is_written_at_the_data_size(denso, denso_model, coupled_file):
    """The coupling is in every recording, the file's and the new ones; the ripple grew in the new ones. Both are
    written: the ripple at the size the diagnosis fitted on --train (held in the refit on both recordings, where main
    fitted it on both and wrote the blend 2.012 N m: joint 2 0.692 -> 0.314 N m, now 0.050), the coupling at its
    truth, no joint worse than the file."""
    report, result, coupling = _coupled_apply(denso, denso_model, coupled_file, 14)
    written = {e["label"]: e for e in result.after.document["findings"]}
    assert set(written) == {RIPPLE.label, coupling} and "resized_alone" not in result.after.document["recalibration"]
    assert written[coupling]["parameters"]["viscous"] == pytest.approx(COUPLING, rel=0.05)
    assert result.rmse_after[5] < 0.1 * result.rmse_before[5]  # joint 6: the coupling's torque gone


@pytest.mark.slow  # as above
def test_a_resize_survives_the_gate_dropping_the_new_finding(denso, denso_model, coupled_file):
    """Other new recordings of the same arm: the never-worse gate finds joint 5 worse with the coupling (over its
    margin, and its refits without each training block agree), which no subset of the new findings avoids; the model
    written is the file with the ripple resized alone, nothing refitted (main wrote the blend 2.016 N m with the
    coupling: its refits cleared joint 5, the ripple free in them)."""
    report, result, coupling = _coupled_apply(denso, denso_model, coupled_file, 12)
    block = result.after.document["recalibration"]
    (dropped,) = block["never_worse"]["dropped"]
    assert dropped["label"] == coupling and dropped["joint"] == 5  # what the gate saw
    (entry,) = result.after.document["findings"]
    assert entry["label"] == RIPPLE.label and block["resized_alone"] == [RIPPLE.label]
    assert "no new finding left" in report.after_source
