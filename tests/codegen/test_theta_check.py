"""``psdm codegen --theta``: a theta whose mass matrix is not positive definite is refused or loudly marked.

The oracle is Pinocchio's crba of the robot file's nominal parameters: the model's mass matrix of the nominal
theta is it, and that of the negated theta is its negative.
"""

import numpy as np
import pytest

from codegen.theta_check import check_theta
from identification.calibration.consistency import mass_matrices
from psdm_casadi.cli import main
from psdm_casadi.cli.codegen import read_theta
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot

SCARA_FILE = BUILTIN_ROBOTS_DIR / "scara.toml"


@pytest.fixture(scope="module")
def scara():
    robot = load_robot(SCARA_FILE)
    model = derive_psdm(robot)
    return robot, model, model.base_parameters(robot.nominal_dynamic_parameters())


def test_the_nominal_theta_passes_with_pinocchios_smallest_eigenvalue(scara):
    robot, model, theta = scara
    check = check_theta(model, theta, robot, n_samples=200)
    assert check.consistent and check.problem("theta.txt") is None and check.blamed == ()
    assert np.all(check.report.worst_q >= robot.q_min) and np.all(check.report.worst_q <= robot.q_max)
    crba = PinocchioOracle(robot).crba(check.report.worst_q[None, :])[0]
    assert check.report.min_eigenvalue == pytest.approx(np.linalg.eigvalsh(crba)[0], rel=1e-9)


def test_the_negated_theta_fails_everywhere_and_names_the_parameters(scara):
    robot, model, theta = scara
    check = check_theta(model, -theta, robot, n_samples=200)
    assert not check.consistent and check.report.n_violations == 200
    crba = PinocchioOracle(robot).crba(check.report.worst_q[None, :])[0]
    assert check.report.min_eigenvalue == pytest.approx(-np.linalg.eigvalsh(crba)[-1], rel=1e-9)
    # the named terms are the most negative of theta_k v^T D_k v, whose sum over k is the eigenvalue
    assert 1 <= len(check.blamed) <= 3 and all(share < 0 for _, _, share in check.blamed)
    names = [name for name, _, _ in check.blamed]
    assert all(value == -theta[model.base_names.index(name)] for name, value, _ in check.blamed)
    shares = [share for _, _, share in check.blamed]
    assert shares == sorted(shares)
    values, vectors = np.linalg.eigh(-crba)
    v = vectors[:, 0]
    every = [-theta[k] * v @ mass_matrices(model, np.eye(model.n_base)[k], check.report.worst_q)[0] @ v
             for k in range(model.n_base)]  # fmt: skip
    assert sum(every) == pytest.approx(values[0], rel=1e-9)  # D(q) is linear in theta: the terms sum to it
    np.testing.assert_allclose(shares, sorted(every)[: len(shares)], rtol=1e-9)
    assert all(share < -1e-9 * max(map(abs, every)) for share in shares)
    problem = check.problem("neg.txt")
    assert "neg.txt" in problem and f"{check.report.min_eigenvalue:.4g}" in problem and names[0] in problem


def test_without_a_robot_revolute_joints_are_sampled_over_a_turn(scara):
    robot, model, theta = scara
    check = check_theta(model, theta, None, n_samples=200)
    assert check.consistent and "no robot file" in check.ranges
    assert np.any(np.abs(check.report.worst_q[model.revolute]) > 0)


def test_codegen_refuses_a_negated_theta_unless_allowed_and_then_marks_it(scara, tmp_path, capsys):
    robot, model, theta = scara
    np.savetxt(tmp_path / "neg.txt", -theta)
    np.savetxt(tmp_path / "nominal.txt", theta)
    out = tmp_path / "cg"
    assert main(["codegen", str(SCARA_FILE), "--theta", str(tmp_path / "neg.txt"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "neg.txt are not physically consistent" in err and "smallest eigenvalue" in err
    assert "--allow-inconsistent" in err and "theta" in err and not out.exists()
    argv = ["codegen", str(SCARA_FILE), "--theta", str(tmp_path / "neg.txt"), "--out", str(out), "--allow-inconsistent"]
    assert main(argv) == 0
    assert "warning: exporting it although" in capsys.readouterr().err
    for name in ("psdm_dynamics.h", "psdm_dynamics.c"):
        assert (out / name).read_text().startswith("/* WARNING: the base parameters of neg.txt are not physically")
    good = tmp_path / "good"
    assert main(["codegen", str(SCARA_FILE), "--theta", str(tmp_path / "nominal.txt"), "--out", str(good)]) == 0
    assert "WARNING" not in (good / "psdm_dynamics.h").read_text() and "warning" not in capsys.readouterr().err


def test_read_theta_refuses_non_finite_values(tmp_path):
    (tmp_path / "nan.txt").write_text("1.0\nnan\n2.0\n")
    with pytest.raises(ParameterError, match="--theta must hold finite numbers; got nan at value 2 of nan.txt"):
        read_theta(tmp_path / "nan.txt")
