"""The refit of ``diagnose MODEL --apply`` (and the report's "after") trains on the model file's own training
recordings and ``--train`` (``refit_training``), not on ``--train`` alone.

Known truth: the virtual Denso with a spring on joint 2 (k = 40 N m/rad, rest angle 0.2 rad). The model file was
identified (without the spring) on two recordings: ``a.csv`` moves every joint, ``b.csv`` moves joint 6 over a tenth
of its swing only. Diagnosed with ``--train b.csv``, a refit on ``b.csv`` alone loses joint 6 (its validation RMSE
0.18 -> 1.1 N m, and the never-worse gate refuses every subset of the findings); with ``a.csv`` found again beside
the model file, the model written keeps joint 6 and carries the spring at its true stiffness.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.payload_check import without_load
from identification.calibration.recording_provenance import recording_provenance
from identification.calibration.refit_training import refit_training
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import load_recording, save_recording
from identification.data.payload import Payload
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from tests.conftest import DENSO_FILE
from tests.identification.diagnosis_data import SPRING_K, SPRING_Q0, cli_json
from trajopt.experiments import sine_experiment

#: The joint ``b.csv`` hardly moves (0-based), and the share of its swing it keeps.
SMALL_JOINT, SMALL_SHARE = 5, 0.1
#: ``diagnose`` options that keep the runs short (no sparse search, no second rigid-body diagnosis).
QUICK = ("--no-sparse", "--rigid-body", "prior")


@pytest.fixture(scope="module")
def files(tmp_path_factory, denso, denso_model):
    """``a.csv``, ``b.csv`` (joint 6 at a tenth of its swing), ``valid.csv`` (6 s at 200 Hz, seeds 40-42, the spring,
    0.1 N m torque noise) and ``model.json``, identified on ``a.csv`` and ``b.csv`` without the spring."""
    folder = tmp_path_factory.mktemp("refit")
    for k, name in enumerate(("a.csv", "b.csv", "valid.csv")):
        rng = np.random.default_rng(40 + k)
        t, q = sine_experiment(denso, duration=6.0, rng=rng).reference()
        if name == "b.csv":
            q = q.copy()
            q[:, SMALL_JOINT] = q[0, SMALL_JOINT] + SMALL_SHARE * (q[:, SMALL_JOINT] - q[0, SMALL_JOINT])
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=200.0)
        spring = xp.Spring(joint=1, stiffness=SPRING_K, q0=SPRING_Q0)
        recording, _ = simulate_recording(denso, (t, q), options, rng, extras=[spring])
        save_recording(recording, folder / name)
    paths = [folder / "a.csv", folder / "b.csv"]
    recordings = [load_recording(path, denso.n_dof) for path in paths]
    fit = identify_trajectories(denso, denso_model, recordings, TrajectoryOptions())
    provenance = [recording_provenance(r, p) for r, p in zip(recordings, paths)]
    CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE, recordings=provenance).save(
        folder / "model.json"
    )
    return folder


@pytest.fixture(scope="module")
def applied(files):
    """``diagnose model.json --train b.csv --apply new.json --json``, and validate's RMSE of the two files."""
    folder = files
    payload = cli_json(["diagnose", folder / "model.json", "--train", folder / "b.csv", "--validate",
                        folder / "valid.csv", "--apply", folder / "new.json", *QUICK, "--json"])  # fmt: skip
    rmse = [
        np.array(cli_json(["validate", folder / name, folder / "valid.csv", "--json"])["recordings"][0]["rmse"])
        for name in ("new.json", "model.json")
    ]
    return payload, *rmse


def test_the_refit_trains_on_the_model_s_recordings_and_keeps_what_they_taught(applied, files):
    payload, written, before = applied
    refit = payload["refit_training"]
    assert refit["not_found"] == []
    assert refit["recordings"] == [f"{files / 'b.csv'} (--train)", str(files / "a.csv")]  # b.csv once, a.csv found
    # joint 6, which only a.csv moves over its swing, stays as the model file predicts it (a refit on b.csv alone:
    # 0.18 -> 1.1 N m, refused), and the spring the model lacked is in the model written at its true stiffness
    assert written[SMALL_JOINT] <= 1.1 * before[SMALL_JOINT], (before, written)
    assert written[1] < 0.2 * before[1], (before, written)
    document = json.loads((files / "new.json").read_text())
    spring = next(e for e in document["findings"] if e["label"] == "spring[j2]")
    assert spring["parameters"]["k"] == pytest.approx(SPRING_K, rel=0.1)
    assert spring["parameters"]["q0"] == pytest.approx(SPRING_Q0, abs=0.05)
    # the report's "after" is the model written, as validate judges it
    np.testing.assert_allclose(payload["rmse_after"], written, rtol=0.01)
    np.testing.assert_allclose(payload["recalibration"]["after"]["validation_rmse"], written, rtol=0.01)
    # the new file lists the recordings it was trained on, so that its own refit finds them again
    names = [entry["name"] for entry in document["provenance"]["recordings"]]
    assert sorted(names) == ["a.csv", "b.csv"] and all("sha256" in e for e in document["provenance"]["recordings"])


def test_a_training_recording_that_is_gone_is_named_and_the_diagnosis_goes_on(files, tmp_path):
    """The model file in another folder, its ``a.csv`` neither at the path identify read it from nor beside it: the
    report names it, where it was looked for and the fix, and the "after" is the refit on ``b.csv`` alone (joint 6
    lost: the case the model's own recordings are there for)."""
    document = json.loads((files / "model.json").read_text())
    for entry in document["provenance"]["recordings"]:
        entry["path"] = str(tmp_path / "gone" / entry["name"]) if entry["name"] == "a.csv" else entry["path"]
    (tmp_path / "model.json").write_text(json.dumps(document))
    for name in ("b.csv", "valid.csv"):
        shutil.copy(files / name, tmp_path / name)
    payload = cli_json(["diagnose", tmp_path / "model.json", "--train", tmp_path / "b.csv", "--validate",
                        tmp_path / "valid.csv", *QUICK, "--json"])  # fmt: skip
    refit = payload["refit_training"]
    assert refit["recordings"] == [f"{tmp_path / 'b.csv'} (--train)"]
    (missing,) = refit["not_found"]
    assert missing["name"] == "a.csv" and str(tmp_path / "gone" / "a.csv") in missing["looked"]
    assert str(tmp_path / "a.csv") in missing["looked"]  # beside the model file
    assert "give it as --train" in missing["sentence"] and "not there" in missing["reason"]
    before, after = np.array(payload["rmse_before"]), np.array(payload["rmse_after"])
    assert after[SMALL_JOINT] > 2.0 * before[SMALL_JOINT], (before, after)  # what a.csv taught is lost


def test_the_model_s_recordings_are_found_by_content_read_once_and_their_loads_taken_off(files, tmp_path, denso):
    """``refit_training`` directly: the ``--train`` counted once when it is a training recording under another name
    (same content) or the same samples in another file, a recording found beside a moved model file, one whose content
    changed named as such, the file's recordings left out where identify moved their torques for a friction drift and
    the file does not record how (written before it did), and the load the model's ``configurations`` block lists for
    a recording taken off its torque (the same torque ``without_load`` leaves)."""
    document = json.loads((files / "model.json").read_text())
    for entry in document["provenance"]["recordings"]:
        entry.pop("path")  # a file written before the paths were stored: found beside the model file
    shutil.copy(files / "a.csv", tmp_path / "a.csv")
    shutil.copy(files / "b.csv", tmp_path / "renamed_b.csv")

    def load(path):
        return load_recording(path, denso.n_dof)

    train = load(tmp_path / "renamed_b.csv")
    found = refit_training(document, tmp_path / "model.json", train, tmp_path / "renamed_b.csv", load, denso, 10.0)
    assert found.missing == () and len(found.recordings) == 2 and found.recordings[0] is train
    assert found.sources[1] == str(tmp_path / "a.csv")
    assert [e["name"] for e in found.entries] == ["b.csv", "a.csv"]  # the file's own entry for the --train
    np.testing.assert_array_equal(found.recordings[1].tau, load(files / "a.csv").tau)
    shutil.copy(files / "b.csv", tmp_path / "b.csv")
    save_recording(load(files / "b.csv"), tmp_path / "b_again.npz")  # the same samples, another file and content
    again = refit_training(document, tmp_path / "model.json", load(tmp_path / "b_again.npz"), tmp_path / "b_again.npz",
                           load, denso, 10.0)  # fmt: skip
    assert len(again.recordings) == 2 and again.entries[0]["name"] == "b.csv" and again.missing == ()

    document["identification"]["friction_drift"] = {"named": [3], "corrected": True}  # identify moved joint 3's
    drifted = refit_training(document, tmp_path / "model.json", train, tmp_path / "renamed_b.csv", load, denso, 10.0)
    assert drifted.recordings == (train,) and "friction drift (3)" in drifted.note and "--train alone" in drifted.note
    document["identification"]["friction_drift"]["corrected"] = False  # named only: the files hold what it fitted
    assert (
        len(refit_training(document, tmp_path / "model.json", train, tmp_path / "b.csv", load, denso, 10.0).recordings)
        == 2
    )

    load_ = {"mass": 2.0, "com": [0.0, 0.0, 0.05], "inertia": None}
    document["configurations"] = [{"name": "2 kg", "kind": "known", "recordings": ["a.csv"], "payload": load_}]
    carried = refit_training(document, tmp_path / "model.json", train, tmp_path / "renamed_b.csv", load, denso, 10.0)
    body = Payload(2.0, (0.0, 0.0, 0.05)).dynamic_parameters()
    expected = without_load(denso, load(files / "a.csv"), body, None, 10.0).tau
    np.testing.assert_allclose(carried.recordings[1].tau, expected, rtol=1e-12)
    assert not np.allclose(carried.recordings[1].tau, found.recordings[1].tau)

    with open(tmp_path / "a.csv", "a") as handle:
        handle.write("\n")  # another content under the same name
    changed = refit_training(document, tmp_path / "model.json", train, tmp_path / "renamed_b.csv", load, denso, 10.0)
    (missing,) = changed.missing
    assert missing.name == "a.csv" and "changed since the model was identified" in missing.reason
    assert len(changed.recordings) == 1 and "not found: a.csv" in changed.sentence()


def _recordings_moved(files, tmp_path):
    """The model file copied to ``tmp_path``, its recordings neither where identify read them nor beside it but in
    ``tmp_path / "moved"`` (returned)."""
    document = json.loads((files / "model.json").read_text())
    for entry in document["provenance"]["recordings"]:
        entry["path"] = str(tmp_path / "gone" / entry["name"])
    (tmp_path / "model.json").write_text(json.dumps(document))
    (tmp_path / "moved").mkdir()
    for name in ("a.csv", "b.csv"):
        shutil.copy(files / name, tmp_path / "moved" / name)
    return tmp_path / "moved"


def test_recordings_that_moved_are_handed_back_as_further_train_recordings(files, tmp_path):
    """``diagnose MODEL --train b.csv a.csv``: the model file in another folder, its recordings neither where identify
    read them nor beside it but in ``moved/``; handed back, each stands for the file's recording of the same content,
    so the refit trains on both and keeps joint 6 (alone on ``b.csv`` it is lost: the test above), the spring at its
    true stiffness; the written model lists them where they are now, for its own refit."""
    moved = _recordings_moved(files, tmp_path)
    payload = cli_json(["diagnose", tmp_path / "model.json", "--train", moved / "b.csv", moved / "a.csv", "--validate",
                        files / "valid.csv", "--apply", tmp_path / "new.json", *QUICK, "--json"])  # fmt: skip
    refit = payload["refit_training"]
    assert refit["not_found"] == [] and refit["recordings"] == [f"{moved / n} (--train)" for n in ("b.csv", "a.csv")]
    written, before = (
        np.array(cli_json(["validate", path, files / "valid.csv", "--json"])["recordings"][0]["rmse"])
        for path in (tmp_path / "new.json", files / "model.json")
    )
    assert written[SMALL_JOINT] <= 1.1 * before[SMALL_JOINT], (before, written)
    assert written[1] < 0.2 * before[1], (before, written)
    entries = json.loads((tmp_path / "new.json").read_text())["provenance"]["recordings"]
    assert sorted((e["name"], e["path"]) for e in entries) == [(n, str(moved / n)) for n in ("a.csv", "b.csv")]


def test_further_train_recordings_stand_for_the_file_s_are_added_or_counted_once(files, tmp_path, denso):
    """``refit_training`` with other ``--train`` recordings: one with a training recording's content under another
    name stands for it (not looked for on disk, not named missing), a recording the file does not list is added with
    an entry of its own (name, path, content hash), one given twice counts once and the note says so."""
    document = json.loads((files / "model.json").read_text())
    for entry in document["provenance"]["recordings"]:
        entry["path"] = str(tmp_path / "gone" / entry["name"])
    shutil.copy(files / "a.csv", tmp_path / "renamed_a.csv")

    def load(path):
        return load_recording(path, denso.n_dof)

    train = load(files / "b.csv")
    more = [(str(p), load(p)) for p in (tmp_path / "renamed_a.csv", files / "valid.csv", files / "b.csv")]
    refit = refit_training(document, tmp_path / "model.json", train, str(files / "b.csv"), load, denso, 10.0, more)
    assert refit.missing == () and refit.recordings[0] is train and len(refit.recordings) == 3
    np.testing.assert_array_equal(refit.recordings[1].tau, more[0][1].tau)
    assert refit.sources[1:] == (f"{tmp_path / 'renamed_a.csv'} (--train)", f"{files / 'valid.csv'} (--train)")
    assert [e["name"] for e in refit.entries] == ["b.csv", "a.csv", "valid.csv"]
    assert refit.entries[1]["path"] == str(tmp_path / "renamed_a.csv")
    assert refit.entries[2] == recording_provenance(more[1][1], files / "valid.csv")
    assert f"{files / 'b.csv'} is the same recording as --train the first: counted once" in refit.note
    assert refit.short() == "the 3 --train recordings alone"


def test_bad_further_train_recordings_are_refused_naming_the_file(files, tmp_path, capsys, denso):
    """A missing file, a recording of another joint count and one in degrees among the ``--train`` recordings: exit 2
    before any fit, naming the file and the fix; several with a robot file (no refit to train them) name identify's
    route."""
    from identification.data.recording import Recording
    from psdm_casadi.cli import main

    five = load_recording(files / "valid.csv", denso.n_dof)
    save_recording(Recording(t=five.t, q=five.q[:, :5], tau=five.tau[:, :5], name="five.csv"), tmp_path / "five.csv")
    save_recording(Recording(t=five.t, q=np.degrees(five.q), tau=five.tau, name="deg.csv"), tmp_path / "deg.csv")
    for bad, expected in (("gone.csv", "does not exist"), ("five.csv", "give 5 joints but the robot has n_dof=6"),
                          ("deg.csv", "degrees")):  # fmt: skip
        code = main([str(a) for a in ("diagnose", files / "model.json", "--train", files / "b.csv", tmp_path / bad,
                                      "--validate", files / "valid.csv", *QUICK)])  # fmt: skip
        err = capsys.readouterr().err
        assert code == 2 and bad in err and expected in err and "Traceback" not in err, err
    code = main([str(a) for a in ("diagnose", DENSO_FILE, "--train", files / "a.csv", files / "b.csv", "--validate",
                                  files / "valid.csv")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "--train takes one recording with a robot file; got 2 (a.csv, b.csv)" in err
    assert "psdm identify" in err and "psdm diagnose model.json --train" in err


def test_diagnose_model_takes_the_train_recordings_as_the_command_does(files, tmp_path, denso):
    """``diagnose_model(MODEL, [b.csv, a.csv])`` from Python: the recordings moved, handed back as a list, and the
    refit (the report's "after") trains on both, as ``psdm diagnose MODEL --train b.csv a.csv``; a ``LoadedModel``
    (no file to refit) with several is refused naming the fix."""
    from identification.calibration.calibrated_model import read_calibrated_model
    from identification.diagnosis.diagnose import DiagnosisOptions
    from identification.diagnosis.model_file import diagnose_model
    from psdm_casadi.errors import ParameterError

    moved = _recordings_moved(files, tmp_path)
    trains = [moved / "b.csv", moved / "a.csv"]
    valid = load_recording(files / "valid.csv", denso.n_dof)
    options = DiagnosisOptions(sparse=False, rigid_body="prior")
    report = diagnose_model(tmp_path / "model.json", trains, [valid], options)
    assert report.refit_training.missing == ()
    assert report.refit_training.sources == tuple(f"{p} (--train)" for p in trains)
    with pytest.raises(ParameterError, match="several train paths need source as the model file's path"):
        diagnose_model(read_calibrated_model(tmp_path / "model.json"), trains, [valid], options)


def test_holdout_cuts_every_train_recording_each_part_a_validation_recording(files, tmp_path, denso):
    """``diagnose MODEL --train b.csv a.csv --holdout 0.3``: both recordings are cut, not the first only (before, a.csv
    trained whole in the refit and none of it was judged): the report names the training part of each and both held-out
    parts, which are its validation recordings, each of its own."""
    from identification.data.holdout import train_samples

    payload = cli_json(["diagnose", files / "model.json", "--train", files / "b.csv", files / "a.csv", "--holdout",
                        "0.3", *QUICK, "--max-effects", "1", "--json"])  # fmt: skip
    n = load_recording(files / "a.csv", denso.n_dof).n_samples
    cut = train_samples(n, 0.3)
    held = payload["held_out"]
    assert held[:2] == [f"training: the first {cut} samples of {files / name}" for name in ("b.csv", "a.csv")], held
    assert [line.split(" (samples")[0] for line in held[2:]] == [
        f"validation: the last 30 % of {name}" for name in ("b.csv", "a.csv")
    ], held
    assert len(payload["validation_recordings"]) == 2, payload["validation_recordings"]


def test_other_train_recordings_are_cut_as_the_first_and_the_refit_trains_on_their_first_part(files, tmp_path, denso):
    """``holdout.other_training_parts`` and ``refit_training``: a further ``--train`` the model trained on whole, cut at
    ``--holdout`` 0.3, gives its first 70 % to the refit (standing for the file's recording, its entry now of the
    samples trained on, for the written model's own refit) and its last 30 % as a validation part of its own; where the
    model file cut a recording itself, its own cut is kept (given raw: the refit cuts it as identify did), another
    ``--holdout`` is refused, and its part is listed once."""
    from identification.data.holdout import cut_recording, holdout_block, other_training_parts
    from psdm_casadi.errors import ParameterError

    def load(path):
        return load_recording(path, denso.n_dof)

    document = json.loads((files / "model.json").read_text())
    a = load(files / "a.csv")
    more, held = other_training_parts([(str(files / "a.csv"), a)], document, 0.3, True, "model.json")
    (path, first, cut), ((held_path, last, part),) = more[0], held
    assert path == held_path == str(files / "a.csv") and part is cut and cut.fraction == 0.3
    assert first.n_samples == cut.cut_sample and first.n_samples + last.n_samples == a.n_samples
    np.testing.assert_array_equal(np.vstack([first.q, last.q]), a.q)
    train = load(files / "b.csv")
    refit = refit_training(document, files / "model.json", train, str(files / "b.csv"), load, denso, 10.0, more)
    assert refit.missing == () and len(refit.recordings) == 2
    np.testing.assert_array_equal(refit.recordings[1].q, first.q)
    assert refit.sources[1] == f"{files / 'a.csv'}, its first {cut.cut_sample} samples (--train)"
    assert refit.entries[1]["n_samples"] == cut.cut_sample and refit.entries[1]["name"] == "a.csv"
    assert other_training_parts([(str(files / "a.csv"), a)], document, None, True, "model.json") == (
        [(str(files / "a.csv"), a)], [])  # fmt: skip
    own = dict(document, identification=dict(document["identification"], holdout=holdout_block([cut])))
    kept, listed = other_training_parts([(str(files / "a.csv"), a)], own, 0.3, True, "model.json")
    assert kept == [(str(files / "a.csv"), a)] and len(listed) == 1
    np.testing.assert_array_equal(listed[0][1].q, cut_recording(a, 0.3, files / "a.csv")[1].q)
    assert other_training_parts([(str(files / "a.csv"), a)], own, None, False, "model.json")[1] == []
    with pytest.raises(ParameterError, match=r"--holdout 0.25: model.json was identified on the first 70 %"):
        other_training_parts([(str(files / "a.csv"), a)], own, 0.25, True, "model.json")


@pytest.mark.slow  # about 25 s: an identify and two diagnoses
def test_with_validate_each_train_recording_the_model_cut_adds_its_held_out_part(files, tmp_path):
    """A model identified with ``--holdout 0.3`` on a.csv and b.csv, diagnosed with ``--train a.csv b.csv --validate
    valid.csv``: the model's cut of each ``--train`` is kept and each held-out part joins the validation recordings
    (before, b.csv's was left out: only the first ``--train``'s joined ``--validate``), from the command and from
    Python's ``diagnose_model`` alike."""
    from identification.diagnosis.diagnose import DiagnosisOptions
    from identification.diagnosis.model_file import diagnose_model

    cli_json(["identify", DENSO_FILE, "--data", files / "a.csv", files / "b.csv", "--holdout", "0.3", "--out",
              tmp_path / "cut.json", "--json"])  # fmt: skip
    trains = [files / "a.csv", files / "b.csv"]
    payload = cli_json(["diagnose", tmp_path / "cut.json", "--train", *trains, "--validate", files / "valid.csv",
                        *QUICK, "--max-effects", "1", "--json"])  # fmt: skip
    parts = [line.split(" (samples")[0] for line in payload["held_out"] if line.startswith("validation")]
    assert parts == [f"validation: the last 30 % of {name}" for name in ("a.csv", "b.csv")], payload["held_out"]
    assert len(payload["validation_recordings"]) == 3
    options = DiagnosisOptions(rigid_body="prior", sparse=False, max_effects=1)
    report = diagnose_model(tmp_path / "cut.json", [str(p) for p in trains], validation=[load_recording(
        files / "valid.csv", 6)], options=options)  # fmt: skip
    assert [line.split(" (samples")[0] for line in report.held_out if line.startswith("validation")] == parts
    assert len(report.recordings) == 3


def test_the_refit_sentence_says_how_many_samples_each_recording_gave():
    """TX40 (new user, identify --holdout 0.3 then diagnose MODEL --apply): 'Refit: ... trained on 1 recording(s):
    staubli_tx40_figaroh (--train)' read as the whole recording beside 'Held out: training: the first 31499 samples';
    the sentence gives each recording's samples (the cut part's), once."""
    from identification.calibration.refit_training import RefitTraining, training_alone
    from identification.data.recording import Recording

    t = np.arange(120) * 0.01
    part = Recording(t=t, q=np.zeros((120, 2)), tau=np.zeros((120, 2)), name="run")
    assert "run.csv (--train; 120 samples)" in training_alone(part, "run.csv").sentence()
    cut = RefitTraining((part, part), ("run.csv, its first 120 samples (--train)", "other.csv"), ({}, {}))
    text = cut.sentence()
    assert "run.csv, its first 120 samples (--train), other.csv (120 samples)" in text
