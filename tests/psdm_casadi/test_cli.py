import json

import pytest

from psdm_casadi import load_model
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE


def test_derive_json(capsys):
    assert main(["derive", str(DENSO_FILE), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["p"], out["l"], out["n_gravity"]) == (1318, 32, 9)
    assert out["max_rel_error_vs_pinocchio"] < 1e-9 and out["seconds"] > 0


def test_derive_writes_the_model_and_refuses_to_overwrite(tmp_path, capsys):
    target = tmp_path / "denso.npz"
    assert main(["derive", str(DENSO_FILE), "-o", str(target)]) == 0
    assert load_model(target).n_base == 32
    assert main(["derive", str(DENSO_FILE), "-o", str(target)]) == 2
    assert "--overwrite" in capsys.readouterr().err


def test_bad_robot_file_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[joint]]\na = 1\n")
    assert main(["derive", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "joint[1].alpha is missing" in err[0]


def test_debug_shows_the_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[joint]]\na = 1\n")
    with pytest.raises(Exception, match="alpha is missing"):
        main(["--debug", "derive", str(bad)])


def test_python_dash_m_psdm_casadi_is_the_command_line(tmp_path, monkeypatch, capsys):
    """``.venv/bin/python -m psdm_casadi`` runs ``psdm`` where the entry point is not on the PATH (it said "No module
    named psdm_casadi.__main__"); a bad robot file is its exit 2, as from ``psdm`` (run in this process, as ``-m``
    runs the module: ``runpy``)."""
    import runpy

    monkeypatch.setattr("sys.argv", ["python -m psdm_casadi", "derive", str(tmp_path / "no.toml")])
    with pytest.raises(SystemExit) as stop:
        runpy.run_module("psdm_casadi", run_name="__main__")
    assert stop.value.code == 2 and "psdm derive: error:" in capsys.readouterr().err


def test_help_lists_derive(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "derive" in capsys.readouterr().out
