"""``psdm identify ROBOT --train REC``: diagnose names its training recordings ``--train``, identify ``--data``; a user
typing diagnose's name at identify got "required: --data, --out". ``--train`` is an alias of identify's ``--data``:
the same option, documented once in ``--help``."""

from __future__ import annotations

import pytest

from psdm_casadi.cli import build_parser, main

ROBOT = "denso_vs6556g"


def test_train_and_data_give_identify_the_same_recordings():
    parser = build_parser()
    recordings = ["a.csv", "b.csv"]
    by_data = parser.parse_args(["identify", ROBOT, "--data", *recordings, "--out", "m.json"])
    by_train = parser.parse_args(["identify", ROBOT, "--train", *recordings, "--out", "m.json"])
    assert by_train.data == by_data.data == recordings
    assert vars(by_train) == vars(by_data)


def test_identify_help_documents_train_as_the_same_option(capsys):
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    text = capsys.readouterr().out
    assert "--data RECORDING [RECORDING ...], --train RECORDING [RECORDING ...]" in text
    assert text.count("--train RECORDING") == 1  # one option, not a second one


def test_identify_with_train_reads_its_recordings_as_with_data(tmp_path, capsys):
    # the recordings given by --train reach identify's own checks: a missing file is refused (exit 2) by its name
    missing = tmp_path / "nowhere.csv"
    code = main(["identify", ROBOT, "--train", str(missing), "--out", str(tmp_path / "m.json")])
    assert code == 2
    assert f"{str(missing)!r} does not exist" in capsys.readouterr().err
    code = main(["identify", ROBOT, "--out", str(tmp_path / "m.json")])
    assert code == 2
    assert "--data/--train" in capsys.readouterr().err
