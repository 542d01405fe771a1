"""``psdm diagnose`` end to end: a short synthetic train/validate pair with a hidden spring, written to files."""

from __future__ import annotations

import contextlib
import json
import logging

import numpy as np
import pytest

from identification.data.io import save_recording
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.log_context import install
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


def _write_pair(denso, directory, extras):
    paths = []
    for k, duration in enumerate((8.0, 4.0)):
        rng = np.random.default_rng(40 + k)
        rec, _ = simulate_recording(
            denso,
            sine_experiment(denso, duration=duration, rng=rng).reference(),
            SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1),
            rng,
            extras=extras,
        )
        paths.append(save_recording(rec, directory / f"{'train' if k == 0 else 'validate'}.npz"))
    return paths


@contextlib.contextmanager
def _selection_lines():
    """The selection's progress lines (INFO) of a command run inside, through a handler with the command line's context
    filter (``log_context.install``: what a run says once)."""
    lines = []

    class Keep(logging.Handler):
        def emit(self, record):
            lines.append(record.getMessage())

    keep, logger = Keep(), logging.getLogger("identification.diagnosis.selection")
    install(keep)
    level = logger.level
    logger.addHandler(keep)
    logger.setLevel(logging.INFO)
    try:
        yield lines
    finally:
        logger.removeHandler(keep)
        logger.setLevel(level)


def test_cli_diagnose_json_names_the_hidden_spring(denso, tmp_path, capsys):
    train, validate = _write_pair(denso, tmp_path, [xp.Spring(joint=1, stiffness=40.0, q0=0.1)])
    with _selection_lines() as lines:  # --json shows warnings only: the progress lines as the command's handler sees
        code = main(
            [
                "diagnose",
                str(DENSO_FILE),
                "--train",
                str(train),
                "--validate",
                str(validate),
                "--json",
                "--max-effects",
                "2",
            ]
        )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert {"findings", "rmse_before", "rmse_after"} <= set(out)
    rejected = [line for line in lines if line.startswith("diagnose:   rejected ")]
    assert rejected and len(rejected) == len(set(rejected)), rejected  # each rejection once, not in every round
    assert out["findings"][0]["effect"] == "spring" and out["findings"][0]["joints"] == [2]
    assert out["findings"][0]["parameters"]["k"] == pytest.approx(40.0, rel=0.15)
    assert len(out["rmse_before"]) == 6
    assert out["rmse_after"][1] < 0.5 * out["rmse_before"][1]


def test_cli_diagnose_bad_option_is_a_one_line_error(denso, tmp_path, capsys):
    train, validate = _write_pair(denso, tmp_path, [])
    code = main(
        ["diagnose", str(DENSO_FILE), "--train", str(train), "--validate", str(validate), "--min-improvement", "1.5"]
    )
    assert code == 2
    assert "min_improvement" in capsys.readouterr().err


def test_cli_diagnose_max_samples_reaches_the_diagnosis(denso, tmp_path, monkeypatch, capsys):
    import importlib

    diagnose_module = importlib.import_module("identification.diagnosis.diagnose")  # the module, not the function
    train, validate = _write_pair(denso, tmp_path, [])
    seen = []
    real = diagnose_module.diagnose

    def spy(robot, train_rec, validation, options, model=None, derive=None):
        seen.append(options.max_samples)
        return real(robot, train_rec, validation, options, model=model, derive=derive)

    monkeypatch.setattr(diagnose_module, "diagnose", spy)
    args = ["diagnose", str(DENSO_FILE), "--train", str(train), "--validate", str(validate), "--json"]
    assert main([*args, "--max-samples", "1200", "--max-effects", "0", "--no-sparse"]) == 0
    assert seen == [1200]
    assert json.loads(capsys.readouterr().out)["findings"] == []


def test_cli_diagnose_takes_several_validation_recordings_and_keeps_what_holds_on_each(denso, tmp_path, capsys):
    extras = [xp.Spring(joint=1, stiffness=40.0, q0=0.1)]
    train, validate = _write_pair(denso, tmp_path, extras)
    rng = np.random.default_rng(43)
    rec, _ = simulate_recording(
        denso,
        sine_experiment(denso, duration=4.0, rng=rng).reference(),
        SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1),
        rng,
        extras=extras,
    )
    second = save_recording(rec, tmp_path / "validate_b.npz")
    args = ["diagnose", str(DENSO_FILE), "--train", str(train), "--validate", str(validate), str(second)]
    assert main([*args, "--json", "--max-effects", "2", "--no-sparse"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["second_opinion"] == "validation recordings" and out["unstable"] == []
    assert out["findings"][0]["effect"] == "spring" and out["findings"][0]["parameters"]["k"] == pytest.approx(
        40.0, rel=0.15
    )


def test_a_missing_recording_is_refused_before_the_model_file_is_read(tmp_path, capsys):
    """Cheap errors first: a mistyped --train or --validate path is named before the model is loaded (a new user
    waited for the model file and its model to load before 'recording ... does not exist'). The model file here is
    not a model; the error names the recording, so the recordings were checked before it was read."""
    (tmp_path / "model.json").write_text("{}")
    for given, missing in ((["--train", "nothere.csv"], "nothere.csv"),
                           (["--train", str(DENSO_FILE), "--validate", "gone.csv"], "gone.csv")):  # fmt: skip
        argv = ["diagnose", str(tmp_path / "model.json"), *(str(tmp_path / a) if a.endswith(".csv") else a
                                                             for a in given)]  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"recording '{tmp_path / missing}' does not exist" in err and "model.json" not in err, err
