"""A typo'd path (a new user's 'pandaa.csv') is answered with the close names beside it, by every command that reads
a recording or a model file; exit 2, no traceback, nothing written."""

from __future__ import annotations

import pytest

from psdm_casadi.cli import main
from psdm_casadi.near_names import did_you_mean
from tests.conftest import DENSO_FILE


def test_the_close_names_in_the_folder_are_offered(tmp_path):
    for name in ("panda.csv", "panda.json", "tx40.json", "notes.txt"):
        (tmp_path / name).write_text("")
    assert did_you_mean(tmp_path / "pandaa.csv") == f" Did you mean {str(tmp_path / 'panda.csv')!r}?"
    assert did_you_mean(tmp_path / "zzz.bin") == ""  # nothing close
    assert did_you_mean(tmp_path / "missing" / "panda.csv") == ""  # no such folder


@pytest.mark.parametrize(
    "argv",
    [
        ["identify", str(DENSO_FILE), "--data", "{d}/runn.csv", "--out", "{d}/m.json"],
        ["validate", "{d}/modle.json"],
        ["diagnose", str(DENSO_FILE), "--train", "{d}/runn.csv", "--validate", "{d}/run.csv"],
    ],
)
def test_each_command_names_the_file_meant(argv, tmp_path, capsys):
    (tmp_path / "run.csv").write_text("t,q1\n")
    (tmp_path / "model.json").write_text("{}")
    assert main([a.format(d=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    meant = "run.csv" if "runn.csv" in " ".join(argv) else "model.json"
    assert f"Did you mean {str(tmp_path / meant)!r}?" in err and "Traceback" not in err
    assert not (tmp_path / "m.json").exists()


def test_a_folder_given_as_the_model_names_its_model_files(tmp_path, capsys):
    """'psdm validate /tmp/newuser' said "newuser: not a calibrated-model file ([Errno 21] Is a directory: ...)"."""
    (tmp_path / "panda.json").write_text("{}")
    (tmp_path / "run.csv").write_text("t,q1\n")
    assert main(["validate", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"model file {str(tmp_path)!r} is a folder" in err and "(.json files in it: panda.json)" in err
    assert "Errno" not in err and "Traceback" not in err
