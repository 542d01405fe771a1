"""`psdm simulate`: writes recordings with truth; bad input gives a one-line error (exit 2)."""

import json

import numpy as np

from identification.data.io import load_recording
from psdm_casadi.cli import main
from tests.conftest import DENSO_FILE


def test_simulate_reference_csv(tmp_path, capsys):
    t = np.linspace(0, 0.5, 51)
    q = 0.2 * np.sin(np.outer(t, np.arange(1, 7)))
    ref = tmp_path / "traj.csv"
    header = "t," + ",".join(f"q{j}" for j in range(1, 7))
    np.savetxt(ref, np.column_stack([t, q]), delimiter=",", header=header, comments="")
    code = main(["simulate", str(DENSO_FILE), "--reference", str(ref), "--out", str(tmp_path / "out"), "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["recordings"][0]["samples"] == 501
    rec = load_recording(tmp_path / "out" / "reference.csv", n_dof=6)
    assert np.abs(rec.q - 0.2 * np.sin(np.outer(rec.t, np.arange(1, 7)))).max() < 5e-3
    assert (tmp_path / "out" / "reference.truth.json").exists()
    # a second run refuses to overwrite
    assert main(["simulate", str(DENSO_FILE), "--reference", str(ref), "--out", str(tmp_path / "out")]) == 2
    assert "overwrite" in capsys.readouterr().err


def test_simulate_experiment(tmp_path):
    code = main(["simulate", str(DENSO_FILE), "--experiment", "sine", "--duration", "1", "--out", str(tmp_path)])
    assert code == 0
    assert load_recording(tmp_path / "sine.csv").n_samples == 1001


def test_simulate_bad_reference(tmp_path, capsys):
    ref = tmp_path / "traj.csv"
    ref.write_text("t,q1,q2\n0,0,0\n1,0,0\n")
    assert main(["simulate", str(DENSO_FILE), "--reference", str(ref), "--out", str(tmp_path / "o")]) == 2
    assert "column q3 is missing" in capsys.readouterr().err
