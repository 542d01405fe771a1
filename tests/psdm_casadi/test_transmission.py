"""The robot file's [transmission] and [recording] tables: the maps they state, and bad values refused with the fix."""

from pathlib import Path

import numpy as np
import pytest

from psdm_casadi.cli import main
from psdm_casadi.errors import RobotFileError
from psdm_casadi.robot import load_robot
from psdm_casadi.transmission import Transmission
from tests.conftest import DENSO_FILE

ROOT = Path(__file__).resolve().parents[2]
TX40_FILE = ROOT / "examples" / "staubli_tx40.toml"
TX40_RATIOS = [32.0, 32.0, 45.0, -48.0, 45.0, 32.0]


def _denso_with(tmp_path, tables: str) -> Path:
    """The built-in Denso's robot file with ``tables`` appended (a DH robot: no third-party file needed)."""
    path = tmp_path / "denso_motors.toml"
    path.write_text(DENSO_FILE.read_text() + "\n" + tables)
    return path


def test_gear_ratios_and_a_coupled_pair_give_the_readmes_matrices(tmp_path):
    robot = load_robot(_denso_with(tmp_path, """
[transmission]
gear_ratios = [32, 32, 45, -48, 45, 32]
coupling = [{ motor = 6, joint = 5, ratio = 32 }]
joint_offsets = [0, "-pi/2", "pi/2", 0, 0, 0]
"""))  # fmt: skip
    transmission = robot.transmission
    # the dataset README (FIGAROH's TX40 config): N_q = diag(N) with N_q[5,4] = 32; N_tau = diag(N) with N_tau[4,5] = 32
    n_q, n_tau = np.diag(TX40_RATIOS), np.diag(TX40_RATIOS)
    n_q[5, 4] = n_tau[4, 5] = 32.0
    np.testing.assert_array_equal(transmission.coupling, n_q)
    np.testing.assert_array_equal(n_tau, n_q.T)  # the README's torque map is the transpose: power-consistent
    rng = np.random.default_rng(0)
    q, qd, tau_m = rng.normal(size=(3, 50, 6))
    theta_m = transmission.motor_positions(q)
    # README: q = N_q^-1 theta_m, then q2 -= pi/2, q3 += pi/2
    readme_q = np.linalg.solve(n_q, theta_m.T).T + np.array([0, -np.pi / 2, np.pi / 2, 0, 0, 0])
    np.testing.assert_allclose(transmission.joint_positions(theta_m), q, atol=1e-14)
    np.testing.assert_allclose(readme_q, q, atol=1e-14)
    np.testing.assert_allclose(transmission.joint_torques(tau_m), tau_m @ n_tau.T, rtol=1e-15)
    # the power the motors deliver is the power the joints receive
    qd_m = transmission.motor_rates(qd)
    tau_j = transmission.joint_torques(tau_m)
    np.testing.assert_allclose((tau_m * qd_m).sum(axis=1), (tau_j * qd).sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(transmission.motor_torques(tau_j), tau_m, rtol=1e-12, atol=1e-13)
    assert transmission.is_coupled and robot.recording_layout is None


def test_a_robot_file_without_the_tables_reads_as_before():
    robot = load_robot(DENSO_FILE)
    assert robot.transmission is None and robot.recording_layout is None


@pytest.mark.parametrize(
    ("tables", "message"),
    [
        ("[transmission]\ngear_ratios = [1, 2, 3]", r"\[transmission\]\.gear_ratios must be a list of 6 numbers"),
        ("[transmission]\ngear_ratios = [1, 2, 0, 4, 5, 6]", r"gear_ratios\[2\] must not be 0"),
        (
            "[transmission]\nmatrix = [[1,0,0,0,0,0],[1,0,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],"
            "[0,0,0,0,0,1]]",
            r"\[transmission\]\.matrix: Transmission\.coupling must be invertible",
        ),
        (
            "[transmission]\ngear_ratios = [1, 1, 1, 1, 1, 1]\ncoupling = [{ motor = 7, joint = 5, ratio = 2 }]",
            r"coupling\[0\]\.motor must be a number 1\.\.6",
        ),  # fmt: skip
        (
            "[transmission]\ngear_ratios = [1, 1, 1, 1, 1, 1]\njoint_offsets = [0, 0]",
            r"joint_offsets must be a list of 6",
        ),
        ("[transmission]\ngear_ratios = [1, 1, 1, 1, 1, 1]\nmotor_kt = [1, 1, 1, 1, 1, -1]", r"motor_kt must be > 0"),
        (
            '[recording]\nside = "motor"',
            r"\[recording\]\.side says signals are recorded on the motor side.*"
            r"Add \[transmission\]",
        ),  # fmt: skip
        ('[recording]\nside = "gear"', r"\[recording\]\.side must be \"joint\", \"motor\""),
        ("[recording]\nsample_rate = 0", r"\[recording\]\.sample_rate must be > 0"),
        ('[recording]\nfiles = { tau = "torques.csv" }', r"must name the positions' file \(q\)"),
    ],
)
def test_bad_values_are_refused_naming_the_field_and_the_fix(tmp_path, capsys, tables, message):
    path = _denso_with(tmp_path, tables)
    with pytest.raises(RobotFileError, match=message):
        load_robot(path)
    assert main(["derive", str(path)]) == 2  # the command line: exit 2, one line
    err = capsys.readouterr().err
    assert "denso_motors.toml" in err and "Traceback" not in err


def test_a_singular_matrix_is_refused_by_the_value_too():
    with pytest.raises(RobotFileError, match="must be invertible"):
        Transmission(coupling=np.array([[1.0, 2.0], [2.0, 4.0]]))
    with pytest.raises(RobotFileError, match="square"):
        Transmission(coupling=np.ones((2, 3)))


def test_the_tx40_robot_file_states_the_readme_conversion():
    if not (ROOT.parent / "shared" / "datasets" / "staubli_tx40_figaroh").exists():
        pytest.skip("the TX40 dataset (its URDF) is absent")
    robot = load_robot(TX40_FILE)
    n_q = np.diag(TX40_RATIOS)
    n_q[5, 4] = 32.0
    np.testing.assert_array_equal(robot.transmission.coupling, n_q)
    # zero offsets: q2 -= pi/2 and q3 += pi/2 after N_q^-1
    np.testing.assert_allclose(
        robot.transmission.joint_positions(np.zeros((1, 6)))[0], [0, -np.pi / 2, np.pi / 2, 0, 0, 0]
    )
    layout = robot.recording_layout
    assert layout.sample_rate == 5000.0 and layout.motor_signals == ("q", "qd", "qdd", "tau", "current")
    assert dict(layout.files) == {"q": "pos_read_data.csv", "tau": "curr_data.csv"}


def test_motor_offsets_state_the_same_zero_as_joint_offsets(tmp_path):
    joint = load_robot(_denso_with(tmp_path, '[transmission]\ngear_ratios = [10, 20, 30, 40, 50, 60]\n'
                                             'joint_offsets = [0.1, 0, 0, 0, 0, "-pi/2"]'))  # fmt: skip
    (tmp_path / "b").mkdir()
    motor = load_robot(_denso_with(tmp_path / "b", '[transmission]\ngear_ratios = [10, 20, 30, 40, 50, 60]\n'
                                                   'motor_offsets = [-1, 0, 0, 0, 0, "30*pi"]'))  # fmt: skip
    np.testing.assert_allclose(motor.transmission.joint_offsets, joint.transmission.joint_offsets, rtol=1e-15)
    np.testing.assert_allclose(joint.transmission.motor_offsets, [-1, 0, 0, 0, 0, 30 * np.pi], rtol=1e-15)
    with pytest.raises(RobotFileError, match="states both joint_offsets and motor_offsets"):
        both = "joint_offsets = [0, 0, 0, 0, 0, 0]\nmotor_offsets = [0, 0, 0, 0, 0, 0]"
        load_robot(_denso_with(tmp_path, f"[transmission]\ngear_ratios = [1, 1, 1, 1, 1, 1]\n{both}"))
