"""``psdm derive``, ``codegen`` and ``identify`` on robots beyond the sum form: a 12-joint arm and a 2 x 7 + 1 tree.

References: Pinocchio's rnea with the robot file's parameters (the compiled C), and a recording whose
torques are Pinocchio's rnea plus known Coulomb and viscous friction (the identified friction).
"""

import json
import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from psdm_casadi import load_model, load_robot
from psdm_casadi.cli import main
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.sampling import random_states

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SERIAL = EXAMPLES / "serial_arm_12.toml"
TREE = EXAMPLES / "dual_arm_torso.toml"


def _recording(robot, path: Path, duration: float, seed: int = 0) -> None:
    """t, q, tau of ``benchmarks/identify_speed.py``'s ``mid_range_sines``: tau = rnea + FC tanh(qd / 0.01) + FV qd."""
    from identify_speed import mid_range_sines

    rec = mid_range_sines(robot, duration, seed)
    names = ["t", *(f"q{j + 1}" for j in range(robot.n_dof)), *(f"tau{j + 1}" for j in range(robot.n_dof))]
    np.savetxt(path, np.column_stack([rec.t, rec.q, rec.tau]), delimiter=",", header=",".join(names), comments="")


def test_derive_json_of_the_tree(tmp_path, capsys):
    target = tmp_path / "tree.npz"
    assert main(["derive", str(TREE), "--json", "-o", str(target)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["n_dof"], out["form"], out["p"]) == (15, "recursive", None)
    assert out["max_rel_error_vs_pinocchio"] < 1e-12
    model = load_model(target)
    assert (model.n_base, model.n_gravity) == (out["l"], out["n_gravity"]) and not model.has_monomials


def test_derive_text_names_the_form(capsys):
    assert main(["derive", str(SERIAL)]) == 0
    assert "12 joints, recursive form" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.needs_cc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_codegen_of_a_saved_tree_model_without_the_robot(tmp_path, capsys, rng):
    model_file = tmp_path / "tree.npz"
    assert main(["derive", str(TREE), "-o", str(model_file)]) == 0
    capsys.readouterr()
    robot = load_robot(TREE)
    theta = load_model(model_file).base_parameters(robot.nominal_dynamic_parameters())
    np.savetxt(tmp_path / "theta.txt", theta)
    out = tmp_path / "c"
    args = ["codegen", str(model_file), "--out", str(out), "--theta", str(tmp_path / "theta.txt"), "--compile"]
    assert main([*args, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["form"] == "recursive"
    inverse_dynamics = ca.external("psdm_inverse_dynamics", str(out / "libpsdm_dynamics.so"))
    q, qd, qdd = random_states(robot, 5, rng)
    reference = PinocchioOracle(robot).rnea(q, qd, qdd)
    ours = np.array([np.array(inverse_dynamics(q[k], qd[k], qdd[k])).ravel() for k in range(5)])
    assert np.abs(ours - reference).max() <= 1e-12 * np.abs(reference).max()


@pytest.mark.slow
@pytest.mark.parametrize("robot_file", [SERIAL, TREE], ids=["serial12", "tree"])
def test_identify_validate_and_codegen_beyond_eight_joints(robot_file, tmp_path, capsys, benchmark_modules):
    from identify_speed import FC, FV

    robot = load_robot(robot_file)
    _recording(robot, tmp_path / "run.csv", duration=40.0)
    _recording(robot, tmp_path / "held_out.csv", duration=15.0, seed=1)
    args = ["identify", str(robot_file), "--data", str(tmp_path / "run.csv"), "--out", str(tmp_path / "m.json")]
    assert main([*args, "--friction", "coulomb-viscous", "--no-html", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["consistent"]
    joints = range(1, robot.n_dof + 1)
    assert np.median([abs(out["drive"][f"fc{j}"] / FC - 1) for j in joints]) < 0.1
    assert np.median([abs(out["drive"][f"fv{j}"] / FV - 1) for j in joints]) < 0.1
    assert main(["validate", str(tmp_path / "m.json"), str(tmp_path / "held_out.csv"), "--json"]) == 0
    assert min(json.loads(capsys.readouterr().out)["recordings"][0]["r2"]) > 0.97
    assert main(["codegen", str(tmp_path / "m.json"), "--out", str(tmp_path / "c"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["form"] == "recursive"
