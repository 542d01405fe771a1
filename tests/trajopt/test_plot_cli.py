"""Plot output and the psdm excite / experiment commands."""

import json

import numpy as np
import pytest

from psdm_casadi import cli
from trajopt.experiments import motor_experiment
from trajopt.plot import plot_trajectory

DENSO = "denso_vs6556g"


def test_plot_writes_png(planar_robot, tmp_path):
    exp = motor_experiment(planar_robot, 1)
    path = plot_trajectory(exp, tmp_path / "p.png", rate=20)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(FileExistsError):
        plot_trajectory(exp, path)


def test_experiment_command(tmp_path, capsys):

    robot = DENSO
    out = tmp_path / "motor.csv"
    code = cli.main(["experiment", "motor", str(robot), "--joint", "2", "--out", str(out), "--json"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["worst_limit_margin"] >= 0 and payload["joints"] == [2]
    data = np.loadtxt(out, delimiter=",", skiprows=2)
    assert np.ptp(data[:, 1]) == 0 and np.ptp(data[:, 2]) > 1.6  # only joint 2 moves, through 40 % of its range
    code = cli.main(["experiment", "motor", str(robot), "--joint", "2", "--out", str(out)])
    assert code == 2 and "overwrite" in capsys.readouterr().err


def test_experiment_command_bad_joint(tmp_path, capsys):

    robot = DENSO
    code = cli.main(["experiment", "friction", str(robot), "--out", str(tmp_path / "f.csv")])
    assert code == 2 and "--joint" in capsys.readouterr().err


def test_excite_command_bad_limit_scale(tmp_path, capsys):

    robot = DENSO
    code = cli.main(["excite", str(robot), "--limit-scale", "0", "--out", str(tmp_path / "x.csv")])
    assert code == 2 and "scale" in capsys.readouterr().err


@pytest.mark.slow
def test_excite_command_denso(tmp_path, capsys):

    robot = DENSO
    out = tmp_path / "traj.csv"
    code = cli.main(
        [
            "excite",
            str(robot),
            "--duration",
            "10",
            "--harmonics",
            "5",
            "--out",
            str(out),
            "--plot",
            str(tmp_path / "t.png"),
            "--starts",
            "1",
            "--json",
        ]
    )
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["worst_limit_margin"] >= 0 and 1 <= payload["cond"] < 10
    assert np.loadtxt(out, delimiter=",", skiprows=2).shape == (1000, 19)
