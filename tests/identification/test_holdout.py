"""``--holdout FRACTION``: one recording, its last part held out for validation by identify, validate and diagnose.

Reference: the same recording cut by hand into two files (``Recording.slice`` written losslessly, as the documentation
once had users do with numpy): ``identify --holdout 0.3`` on the whole file must give the model of ``identify --data
FIRST --validate LAST``, bit for bit, and validate and diagnose of its model file without ``--validate`` the numbers of
the hand-cut route. The held-out samples never reach the fit: with the data's choices fixed, replacing them by noise
leaves the model unchanged.
"""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import pytest

from identification.calibration.calibrated_model import read_calibrated_model
from identification.data.holdout import HeldOutPart, check_holdout_fraction, cut_recording, stored_parts, train_samples
from identification.data.io import load_recording, save_recording
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, RecordingError
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

N_SAMPLES, CUT = 2501, 1750  # 10 s at 250 Hz; the first 70 % of the samples train
QUICK = ["--no-sparse", "--rigid-body", "prior", "--max-effects", "1", "--json"]  # a short diagnosis


@pytest.fixture(scope="module")
def files(tmp_path_factory, denso):
    """whole.csv (the virtual Denso, 10 s at 250 Hz, torque noise 0.1 N m), its first 70 % and last 30 % cut by hand,
    and model.json: ``identify --holdout 0.3`` on whole.csv."""
    folder = tmp_path_factory.mktemp("holdout")
    robot, rng = denso, np.random.default_rng(3)
    reference = sine_experiment(robot, duration=10.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=250.0)
    recording, _ = simulate_recording(robot, reference, options, rng)
    save_recording(recording, folder / "whole.csv")
    save_recording(recording.slice(0, CUT), folder / "first.csv")
    save_recording(recording.slice(CUT, None), folder / "last.csv")
    argv = ["identify", str(DENSO_FILE), "--data", str(folder / "whole.csv"), "--holdout", "0.3"]
    assert main([*argv, "--out", str(folder / "model.json"), "--json"]) == 0
    return folder


def _values(path) -> dict:
    document = json.loads(path.read_text())
    return {key: np.array(document[key]["values"], dtype=float) for key in ("base", "drive", "standard")}


def test_the_cut_keeps_the_first_samples_for_training_as_the_documentation_cut_them():
    """``int(0.7 n)`` training samples (the benchmarks' and the former numpy recipe's cut) for every length; the parts
    are the recording's own samples, in order, and each needs at least 3."""
    assert [train_samples(n, 0.3) for n in range(3, 5000)] == [int(0.7 * n) for n in range(3, 5000)]
    assert train_samples(20544, 0.3) == 14380 and train_samples(1000, 0.25) == 750
    t = np.arange(1000) / 100.0
    recording = Recording(t=t, q=np.sin(t)[:, None], tau=np.cos(t)[:, None], name="r")
    train, held, part = cut_recording(recording, 0.3, __file__)
    assert (train.n_samples, held.n_samples, part.cut_sample, part.n_samples) == (700, 300, 700, 1000)
    assert part.cut_time_s == 7.0 and np.array_equal(np.concatenate([train.tau, held.tau]), recording.tau)
    assert part.sha256 == hashlib.sha256(open(__file__, "rb").read()).hexdigest()
    with pytest.raises(RecordingError, match="each part needs at least"):
        cut_recording(recording.slice(0, 5), 0.3, __file__)


def test_with_validate_the_held_out_part_joins_the_validation_recordings(files, tmp_path, capsys):
    """--validate and --holdout together: both judge (the report lists the --validate recording, then the held-out
    part, which the model file stores); the four-step route, which validates on its own experiment, refuses it."""
    argv = ["identify", str(DENSO_FILE), "--data", str(files / "whole.csv"), "--holdout", "0.3", "--validate",
            str(files / "last.csv"), "--out", str(tmp_path / "both.json"), "--json"]  # fmt: skip
    assert main(argv) == 0
    entries = json.loads((tmp_path / "both.json").read_text())["validation"]["recordings"]
    assert [e["recording"] for e in entries] == [str(files / "last.csv"), str(files / "whole.csv")]
    assert "held_out" not in entries[0] and entries[1]["held_out"]["cut_sample"] == CUT
    np.testing.assert_allclose(entries[0]["rmse"], entries[1]["rmse"], rtol=1e-9)  # the same samples, cut by hand
    folder = tmp_path / "experiments"
    folder.mkdir()
    (folder / "payload.json").write_text("{}")
    capsys.readouterr()
    assert main(["identify", str(DENSO_FILE), "--data", str(folder), "--holdout", "0.3", "--out", str(tmp_path)]) == 2
    assert "Drop --holdout" in capsys.readouterr().err


@pytest.mark.parametrize("bad", ["0", "0.9", "1.5", "-0.3", "nan", "abc"])
def test_a_fraction_outside_0_to_0_9_is_refused_naming_the_option_and_the_fix(bad, tmp_path, capsys):
    with pytest.raises(ParameterError, match=r"--holdout must be .* between 0 and 0.9"):
        check_holdout_fraction(bad)
    data = tmp_path / "r.csv"
    data.write_text("t,q1\n")  # never read: the option is refused before any work
    argv = ["identify", str(DENSO_FILE), "--data", str(data), "--holdout", bad, "--out", str(tmp_path / "m.json")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--holdout must be" in err and "e.g. --holdout 0.3" in err and "Traceback" not in err
    assert not (tmp_path / "m.json").exists()
    assert main(["diagnose", str(DENSO_FILE), "--train", str(data), "--holdout", bad]) == 2
    assert "--holdout must be" in capsys.readouterr().err


def test_diagnose_of_a_robot_without_a_validation_recording_names_the_holdout(tmp_path, capsys):
    data = tmp_path / "r.csv"
    data.write_text("t,q1\n")
    assert main(["diagnose", str(DENSO_FILE), "--train", str(data)]) == 2
    assert "--holdout 0.3" in capsys.readouterr().err


def test_holdout_gives_the_hand_cut_model_bit_for_bit_and_stores_the_cut(files, capsys):
    """identify --holdout 0.3 on whole.csv = identify --data first.csv --validate last.csv: the same parameters and
    validation RMSE; the model file names the recording (path, content hash), the cut sample and time."""
    capsys.readouterr()
    argv = ["identify", str(DENSO_FILE), "--data", str(files / "first.csv"), "--validate", str(files / "last.csv")]
    assert main([*argv, "--out", str(files / "hand.json"), "--json"]) == 0
    ours, hand = _values(files / "model.json"), _values(files / "hand.json")
    for key in ours:
        np.testing.assert_allclose(ours[key], hand[key], rtol=1e-9, atol=1e-12, err_msg=key)
    document = json.loads((files / "model.json").read_text())
    hand_document = json.loads((files / "hand.json").read_text())
    np.testing.assert_allclose(document["validation"]["recordings"][0]["rmse"],
                               hand_document["validation"]["recordings"][0]["rmse"], rtol=1e-9)  # fmt: skip
    (part,) = stored_parts(read_calibrated_model(files / "model.json").calibrated.document)  # the file reads back
    digest = hashlib.sha256((files / "whole.csv").read_bytes()).hexdigest()
    assert part == HeldOutPart(str(files / "whole.csv"), digest, 0.3, N_SAMPLES, CUT, 7.0)
    assert document["validation"]["recordings"][0]["held_out"]["cut_sample"] == CUT
    assert document["provenance"]["recordings"][0]["n_samples"] == CUT  # trained on the first part only
    assert document["provenance"]["recordings"][0]["sha256"] == digest


def test_no_held_out_sample_reaches_the_fit(files, tmp_path):
    """With the data's choices fixed (columns, smoothing, no counterbalance, the one-way friction fitted and a joint
    worse than the robot file only named: the holds the held-out recordings decide are stated as such), the held-out
    samples only validate:
    replacing them by noise of 50 N m changes the validation, not one bit of the model. (Were the recording cut after
    the zero-phase filter, the noise would reach the last training samples.)"""
    recording = load_recording(files / "whole.csv", 6)
    tau = recording.tau.copy()
    tau[CUT:] = np.random.default_rng(0).normal(0.0, 50.0, tau[CUT:].shape)
    save_recording(recording.with_tau(tau), tmp_path / "noisy.csv")
    fixed = ["--friction", "coulomb-viscous", "--offset", "off", "--drive-inertia", "on", "--drive-loss", "off",
             "--one-way-friction", "fit", "--worse-joint", "report", "--no-counterbalance",
             "--coulomb-velocity", "0.05", "--json"]  # fmt: skip
    for name in ("whole.csv", "noisy.csv"):
        source = files / name if name == "whole.csv" else tmp_path / name
        argv = ["identify", str(DENSO_FILE), "--data", str(source), "--holdout", "0.3", *fixed]
        assert main([*argv, "--out", str(tmp_path / f"{name}.json")]) == 0
    clean, noisy = _values(tmp_path / "whole.csv.json"), _values(tmp_path / "noisy.csv.json")
    for key in clean:
        assert np.array_equal(clean[key], noisy[key]), key
    rmse = [json.loads((tmp_path / f"{n}.json").read_text())["validation"]["recordings"][0]["rmse"]
            for n in ("whole.csv", "noisy.csv")]  # fmt: skip
    assert min(rmse[1]) > 5 * max(rmse[0])  # the noise, filtered at 10 Hz as the model file says


def test_validate_reuses_the_held_out_part(files, capsys):
    """``psdm validate MODEL`` (no recordings) and ``psdm validate MODEL whole.csv`` judge the held-out part only: the
    RMSE of the hand-cut last.csv and of identify's own report, and the output says which part."""
    model = str(files / "model.json")
    capsys.readouterr()
    assert main(["validate", model, str(files / "last.csv"), "--json"]) == 0
    hand = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    for given in ([], [str(files / "whole.csv")]):
        assert main(["validate", model, *given, "--json"]) == 0
        row = json.loads(capsys.readouterr().out)["recordings"][0]
        np.testing.assert_allclose(row["rmse"], hand, rtol=1e-9)
        assert row["held_out"]["cut_sample"] == CUT
    stored = json.loads((files / "model.json").read_text())["validation"]["recordings"][0]["rmse"]
    np.testing.assert_allclose(stored, hand, rtol=1e-9)
    assert main(["validate", model]) == 0
    assert "the last 30 % of whole.csv (samples 1750-2500 of 2501, t >= 7 s), held out" in capsys.readouterr().out


def test_diagnose_of_the_model_without_validate_uses_its_held_out_part(files, capsys):
    """``psdm diagnose MODEL --train whole.csv`` trains on the first 70 % and validates on the stored last 30 %: the
    numbers of ``--train first.csv --validate last.csv``; the report says which part was held out."""
    model = str(files / "model.json")
    capsys.readouterr()
    assert main(["diagnose", model, "--train", str(files / "first.csv"), "--validate", str(files / "last.csv"),
                 *QUICK]) == 0  # fmt: skip
    hand = json.loads(capsys.readouterr().out)
    assert main(["diagnose", model, "--train", str(files / "whole.csv"), *QUICK]) == 0
    ours = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(ours["rmse_before"], hand["rmse_before"], rtol=1e-9)
    np.testing.assert_allclose(ours["rmse_after"], hand["rmse_after"], rtol=1e-9)
    assert ours["held_out"] == [f"training: the first {CUT} samples of {files / 'whole.csv'}",
                                "validation: the last 30 % of whole.csv (samples 1750-2500 of 2501, t >= 7 s), "
                                "held out"]  # fmt: skip
    assert main(["diagnose", model, "--train", str(files / "whole.csv"), "--holdout", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "Drop --holdout" in err and err.count("held out") == 1  # was 'held out the last 30 % ..., held out'
    assert "of 2501, t >= 7 s), held out: another cut" in err


def test_python_diagnose_model_uses_the_stored_held_out_part_as_the_command_does(files, capsys):
    """``diagnose_model(MODEL, whole.csv)`` without a validation recording trains on the first 70 % and validates on
    the stored last 30 %, through the command's own code: the numbers, findings and held-out sentences of ``psdm
    diagnose MODEL --train whole.csv``. A Recording without its path cannot be matched to the stored cut: refused
    naming the fix (not trained on whole, which would fit the held-out samples)."""
    from identification.diagnosis.diagnose import DiagnosisOptions
    from identification.diagnosis.model_file import diagnose_model

    model, whole = str(files / "model.json"), str(files / "whole.csv")
    capsys.readouterr()
    assert main(["diagnose", model, "--train", whole, *QUICK]) == 0
    cli = json.loads(capsys.readouterr().out)
    ours = diagnose_model(model, whole, options=DiagnosisOptions(rigid_body="prior", sparse=False, max_effects=1))
    np.testing.assert_allclose(ours.rmse_before, cli["rmse_before"], rtol=1e-9)
    np.testing.assert_allclose(ours.rmse_after, cli["rmse_after"], rtol=1e-9)
    assert [f.label for f in ours.findings] == [f["label"] for f in cli["findings"]]
    assert list(ours.held_out) == cli["held_out"] and len(ours.held_out) == 2
    with pytest.raises(ParameterError, match="path of the training recording"):
        diagnose_model(model, load_recording(whole, 6))


def test_diagnose_of_the_robot_with_holdout_is_the_hand_cut_diagnosis(files, capsys):
    capsys.readouterr()
    robot = str(DENSO_FILE)
    assert main(["diagnose", robot, "--train", str(files / "first.csv"), "--validate", str(files / "last.csv"),
                 *QUICK]) == 0  # fmt: skip
    hand = json.loads(capsys.readouterr().out)
    assert main(["diagnose", robot, "--train", str(files / "whole.csv"), "--holdout", "0.3", *QUICK[:-1]]) == 0
    text = capsys.readouterr().out
    assert "Held out: training: the first 1750 samples of" in text and "t >= 7 s), held out." in text
    assert main(["diagnose", robot, "--train", str(files / "whole.csv"), "--holdout", "0.3", *QUICK]) == 0
    ours = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(ours["rmse_before"], hand["rmse_before"], rtol=1e-9)
    np.testing.assert_allclose(ours["rmse_after"], hand["rmse_after"], rtol=1e-9)


def test_a_recording_changed_since_identify_is_refused(files, tmp_path, capsys):
    """The held-out part is found by its content hash: a recording edited since identify (one torque sample) is
    refused by validate and diagnose with the recording, the hashes and the fix, not judged on other data."""
    copy = tmp_path / "whole.csv"
    shutil.copy(files / "whole.csv", copy)
    document = json.loads((files / "model.json").read_text())
    document["identification"]["holdout"]["recordings"][0]["path"] = str(copy)
    model = tmp_path / "model.json"
    model.write_text(json.dumps(document))
    capsys.readouterr()
    assert main(["validate", str(model), "--json"]) == 0  # the copy holds the same content
    capsys.readouterr()
    recording = load_recording(copy, 6)
    tau = recording.tau.copy()
    tau[CUT + 10, 0] += 1.0
    save_recording(recording.with_tau(tau), copy, overwrite=True)
    for argv in (["validate", str(model)], ["validate", str(model), str(copy)], ["diagnose", str(model), "--train",
                                                                                  str(copy)]):  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{copy} changed since the model was identified" in err and "Traceback" not in err
    copy.unlink()
    assert main(["validate", str(model)]) == 2
    assert "is not there any more" in capsys.readouterr().err


def test_a_malformed_holdout_block_is_refused_when_the_model_is_read(files, tmp_path, capsys):
    document = json.loads((files / "model.json").read_text())
    document["identification"]["holdout"]["recordings"][0]["cut_sample"] = N_SAMPLES  # nothing left to hold out
    model = tmp_path / "model.json"
    model.write_text(json.dumps(document))
    capsys.readouterr()
    assert main(["validate", str(model)]) == 2
    assert "identification.holdout.recordings[0] must hold" in capsys.readouterr().err


def test_a_recording_moved_or_edited_since_identify_is_named_with_the_command_that_fixes_it(files, tmp_path, capsys):
    """A new user moves the recording after identify, or passes an edited copy under another name. validate says
    that it judged the copy whole (it cannot tell an edited copy from another recording), diagnose that --train is
    not the recording the model cut, and each names its own command to pass the moved recording again."""
    copy = tmp_path / "renamed.csv"
    recording = load_recording(files / "whole.csv", 6)
    tau = recording.tau.copy()
    tau[CUT + 10, 0] += 1.0
    save_recording(recording.with_tau(tau), copy)
    document = json.loads((files / "model.json").read_text())
    model = tmp_path / "model.json"
    model.write_text(json.dumps(document))
    capsys.readouterr()
    assert main(["validate", str(model), str(copy), "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["recordings"][0]["held_out"] is None  # judged whole
    assert f"{copy} is none of the recordings {model} held out a part of" in captured.err
    assert "validated on all its 2501 samples" in captured.err and "trained on its first 70 %" in captured.err
    document["identification"]["holdout"]["recordings"][0]["path"] = str(tmp_path / "gone.csv")
    model.write_text(json.dumps(document))
    assert main(["validate", str(model)]) == 2
    err = capsys.readouterr().err
    assert "not there any more" in err and "psdm validate MODEL NEW/PATH/gone.csv" in err
    assert main(["diagnose", str(model), "--train", str(copy), *QUICK]) == 2
    err = capsys.readouterr().err
    assert f"--train {copy} is not the recording {model} held out a part of (gone.csv" in err
    assert "psdm diagnose MODEL --train NEW/PATH/gone.csv" in err and "psdm validate" not in err
    assert "Traceback" not in err


def test_the_identify_page_names_the_held_out_part(files):
    """identify's page said 'Validation on whole.csv' (the training recording, to a reader)."""
    from identification.report_html.identify_page import identify_page

    page = identify_page(json.loads((files / "model.json").read_text())).to_html()
    assert "Validation on the held-out last 30 % of whole.csv:" in page and "Validation on whole.csv" not in page
