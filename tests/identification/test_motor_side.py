"""Motor-side recordings read as the robot file states them: mapped to the joints once, identified alike."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import read_table
from identification.data.layout import ColumnLayout
from identification.data.motor_side import to_joint_side, to_motor_side
from identification.data.recording import Recording
from identification.data.robot_recordings import load_robot_recording, recording_paths
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import RecordingError, RobotFileError
from psdm_casadi.recording_layout import RecordingLayout
from psdm_casadi.robot import load_robot
from psdm_casadi.transmission import Transmission
from tests.conftest import DATASETS
from trajopt.experiments import sine_experiment

ROOT = Path(__file__).resolve().parents[2]
TX40 = DATASETS / "staubli_tx40_figaroh"


def _random_transmission(rng, n):
    """Gear ratios of either sign between 10 and 120 and a few couplings, with encoder offsets."""
    matrix = np.diag(rng.choice([-1.0, 1.0], n) * rng.uniform(10, 120, n))
    for _ in range(3):
        motor, joint = rng.choice(n, 2, replace=False)
        matrix[motor, joint] = rng.uniform(-40, 40)
    return Transmission(coupling=matrix, joint_offsets=rng.uniform(-3, 3, n))


def _write_without_time(recording: Recording, path: Path) -> None:
    """A controller's log: q1..qn and tau1..taun, no t column."""
    names = [f"q{j + 1}" for j in range(recording.n_dof)] + [f"tau{j + 1}" for j in range(recording.n_dof)]
    np.savetxt(path, np.hstack([recording.q, recording.tau]), delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")  # fmt: skip


def test_a_virtual_recording_logged_on_the_motor_side_identifies_the_same_model(denso, denso_model, tmp_path):
    rng = np.random.default_rng(7)
    reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    joint, _ = simulate_recording(denso, reference, options, rng)
    transmission = _random_transmission(rng, denso.n_dof)
    layout = RecordingLayout(sides=dict.fromkeys(("q", "tau"), "motor"), sample_rate=1.0 / joint.dt)
    robot = dataclasses.replace(denso, transmission=transmission, recording_layout=layout)
    motor = to_motor_side(joint, robot)
    assert np.abs(motor.q - joint.q).max() > 1.0  # really another signal
    _write_without_time(motor, tmp_path / "log.csv")
    read = load_robot_recording(tmp_path / "log.csv", robot)
    np.testing.assert_allclose(read.t, joint.t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(read.q, joint.q, atol=1e-9)
    np.testing.assert_allclose(read.tau, joint.tau, rtol=1e-9, atol=1e-9)
    fit_joint = identify_trajectories(denso, denso_model, [joint], TrajectoryOptions())
    fit_motor = identify_trajectories(robot, denso_model, [read], TrajectoryOptions())
    np.testing.assert_allclose(fit_motor.theta_ols, fit_joint.theta_ols, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(fit_motor.theta, fit_joint.theta, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(fit_motor.drive, fit_joint.drive, rtol=1e-5, atol=1e-6)
    # the same file read without the robot's layout is refused: no time, and the rate is not stated
    with pytest.raises(RecordingError, match=r"column t is missing.*sample_rate = <Hz>"):
        load_robot_recording(tmp_path / "log.csv", denso)


def test_velocities_accelerations_and_currents_cross_the_transmission(rng):
    n = 3
    t = np.arange(5) * 0.01
    q, qd, qdd, current = rng.normal(size=(4, 5, n))
    uncoupled = Transmission(coupling=np.diag([10.0, -20.0, 5.0]))
    layout = RecordingLayout(sides=dict.fromkeys(("q", "qd", "qdd", "current"), "motor"))
    robot = _Robot(uncoupled, layout)
    motor = Recording(t=t, q=q, qd=qd, qdd=qdd, current=current)
    joint = to_joint_side(motor, robot)
    np.testing.assert_allclose(joint.qd * [10.0, -20.0, 5.0], qd, rtol=1e-14)
    np.testing.assert_allclose(joint.qdd * [10.0, -20.0, 5.0], qdd, rtol=1e-14)
    # an uncoupled motor's current stays a current, signed like its joint (kt_joint = |N| kt_motor > 0)
    np.testing.assert_array_equal(joint.current, current * [1.0, -1.0, 1.0])
    np.testing.assert_allclose(to_motor_side(joint, robot).current, current)
    coupling = np.array([[10.0, 0, 0], [0, -20.0, 0], [0, 4.0, 5.0]])
    with pytest.raises(RecordingError, match="motor_kt"):
        to_joint_side(motor, _Robot(Transmission(coupling=coupling), layout))
    kt = np.array([0.1, 0.2, 0.3])
    joint = to_joint_side(motor, _Robot(Transmission(coupling=coupling, motor_kt=kt), layout))
    assert joint.current is None
    np.testing.assert_allclose(joint.tau, (current * kt) @ coupling, rtol=1e-14)  # tau_j = N_q^T (kt i_m)


@dataclasses.dataclass
class _Robot:
    """The fields ``to_joint_side`` reads (a stand-in for a RobotDescription of three joints)."""

    transmission: Transmission
    recording_layout: RecordingLayout
    name: str = "three joints"
    drives: tuple | None = None


@pytest.mark.real_data
def test_the_tx40_as_shipped_equals_the_readme_conversion():
    if not TX40.exists():
        pytest.skip(f"{TX40} is absent")
    robot = load_robot(ROOT / "examples" / "staubli_tx40.toml")
    files = [TX40 / "pos_read_data.csv", TX40 / "curr_data.csv"]
    assert recording_paths(files, robot) == [str(TX40)]  # the two files are one recording
    recording = load_robot_recording(TX40, robot)
    # the README's formulas, written out independently of the transmission code
    theta_m = np.loadtxt(files[0], delimiter=",", skiprows=1)
    tau_m = np.loadtxt(files[1], delimiter=",", skiprows=1)
    ratios = np.array([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
    q = theta_m / ratios
    q[:, 5] = (theta_m[:, 5] - 32.0 * q[:, 4]) / 32.0  # theta_m6 = 32 q5 + 32 q6
    q[:, 1] -= np.pi / 2
    q[:, 2] += np.pi / 2
    tau = tau_m * ratios
    tau[:, 4] += 32.0 * tau_m[:, 5]  # N_tau[4, 5] = 32
    np.testing.assert_allclose(recording.q, q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(recording.tau, tau, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(recording.t, np.arange(45_000) * 0.0002, rtol=1e-12, atol=1e-15)
    assert recording.current is None and recording.n_samples == 45_000


def test_simulate_logs_as_the_controller_and_every_reader_maps_back(tmp_path):
    from psdm_casadi.cli import main
    from tests.conftest import DENSO_FILE

    robot_file = tmp_path / "denso_motors.toml"
    robot_file.write_text(DENSO_FILE.read_text() + """
[transmission]
gear_ratios = [100, -80, 60, 50, -40, 30]
coupling = [{ motor = 6, joint = 5, ratio = 30 }]
joint_offsets = [0.1, 0, -0.2, 0, 0, 0.3]
motor_kt = [0.3, 0.3, 0.2, 0.1, 0.1, 0.05]

[recording]
side = "motor"
""")  # fmt: skip
    assert (
        main(["simulate", str(robot_file), "--experiment", "sine", "--duration", "2", "--out", str(tmp_path / "o")])
        == 0
    )
    robot = load_robot(robot_file)
    table = read_table(tmp_path / "o" / "sine.csv")
    truth = np.load(tmp_path / "o" / "sine.truth.npz")
    theta_m = np.column_stack([table.column(f"q{j + 1}") for j in range(6)])
    # the file holds the motors' angles: theta_m = N_q (q - q_0) (up to the simulated encoders' resolution)
    np.testing.assert_allclose(theta_m, robot.transmission.motor_positions(truth["q"]), atol=1e-3)
    assert np.abs(theta_m - truth["q"]).max() > 1.0
    read = load_robot_recording(tmp_path / "o" / "sine.csv", robot)
    np.testing.assert_allclose(read.q, truth["q"], atol=2e-5)
    assert "i1" in table.names and read.current is None  # the motors' currents (motor_kt) come back as joint torques
    currents = np.column_stack([table.column(f"i{j + 1}") for j in range(6)])
    np.testing.assert_allclose(
        read.tau, (currents * robot.transmission.motor_kt) @ robot.transmission.coupling, rtol=1e-12
    )
    error = np.sqrt(((read.tau - truth["tau_motor"]) ** 2).mean(axis=0))  # the simulated drive torque, up to the
    assert np.all(error < 0.05 * np.sqrt((truth["tau_motor"] ** 2).mean(axis=0)))  # current sensors' noise


def test_a_split_motor_side_log_runs_through_identify_and_validate(denso, tmp_path, capsys):
    """One folder of per-signal files without time (the TX40's layout) on the virtual Denso, end to end."""
    import json

    from psdm_casadi.cli import main
    from tests.conftest import DENSO_FILE

    robot_file = tmp_path / "denso_split.toml"
    robot_file.write_text(DENSO_FILE.read_text() + """
[transmission]
gear_ratios = [100, -80, 60, 50, -40, 30]
coupling = [{ motor = 6, joint = 5, ratio = 30 }]

[recording]
side = "motor"
sample_rate = 1000.0
files = { q = "positions.csv", tau = "torques.csv" }
""")  # fmt: skip
    robot = load_robot(robot_file)
    rng = np.random.default_rng(5)
    for name in ("train", "valid"):
        reference = sine_experiment(denso, duration=6.0, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=1000.0)
        motor = to_motor_side(simulate_recording(denso, reference, options, rng)[0], robot)
        (tmp_path / name).mkdir()
        for signal, file in (("q", "positions.csv"), ("tau", "torques.csv")):
            header = ",".join(f"Joint_{j + 1}" for j in range(6))  # a vendor's header: columns in joint order
            np.savetxt(tmp_path / name / file, getattr(motor, signal), delimiter=",", header=header, comments="")
    out = tmp_path / "model.json"
    argv = ["identify", str(robot_file), "--data", str(tmp_path / "train"), "--out", str(out), "--json"]
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["consistent"]
    # the file states a coupled wrist, the simulated arm has no coupled drive: its training blocks refuse both terms
    assert report["coupled_drives"]["tried"] == ["coupling[j6->j5]", "coupling[j5->j6]"]
    assert report["coupled_drives"]["kept"] == [] and report["coupled_drives"]["route"].startswith("block cross")
    files = [str(tmp_path / "valid" / "positions.csv"), str(tmp_path / "valid" / "torques.csv")]
    assert main(["validate", str(out), *files, "--plots", str(tmp_path / "plots"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"]
    assert len(validated) == 1 and min(validated[0]["r2"]) > 0.95  # the two files are one recording, well predicted
    assert [p.name for p in (tmp_path / "plots").glob("*.png")] == ["valid.png"]


def _denso_without_drives(tmp_path, tables: str) -> Path:
    """The built-in Denso's robot file without its [[drive]] tables, with ``tables`` appended."""
    from tests.conftest import DENSO_FILE

    path = tmp_path / "denso_currents.toml"
    path.write_text(DENSO_FILE.read_text().split("\n[[drive]]\n")[0] + "\n" + tables)
    return path


MOTOR_CURRENTS = """
[transmission]
gear_ratios = [100, -80, 60, 50, -40, 30]
motor_kt = [0.3, 0.3, 0.2, 0.1, 0.1, 0.05]

[recording]
side = { q = "joint", current = "motor" }
"""


def test_motor_currents_through_motor_kt_reach_identify_as_currents(tmp_path, rng):
    """A cobot logging motor currents, its gears and motor torque constants in [transmission] (no [[drive]] tables):
    the currents stay currents (joint-signed) with the joint-side constants |N| kt_m, so identify takes them as
    currents (rotor inertia and gear loss in the torque). Before, they became a torque sensor's ``tau`` and a small
    rotor inertia (a virtual cobot's last joint) was dropped by the column choice."""
    robot = load_robot(_denso_without_drives(tmp_path, MOTOR_CURRENTS))
    gears, motor_kt = np.array([100, -80, 60, 50, -40, 30.0]), np.array([0.3, 0.3, 0.2, 0.1, 0.1, 0.05])
    np.testing.assert_allclose([d.kt for d in robot.drives], np.abs(gears) * motor_kt, rtol=1e-15)
    assert all(d.fc == 0 and d.fv == 0 for d in robot.drives)  # torque constants alone: no friction prior
    current_m = rng.normal(size=(40, 6))
    motor = Recording(t=np.arange(40) * 1e-3, q=rng.normal(size=(40, 6)), current=current_m, name="cobot.csv")
    joint = to_joint_side(motor, robot)
    assert joint.tau is None  # currents, as identify's column choice and every kt user need them
    tau_expected = current_m * motor_kt * gears  # tau_j = N_jj kt_m i_m (the transmission is diagonal)
    np.testing.assert_allclose(joint.joint_torque(np.array([d.kt for d in robot.drives])), tau_expected, rtol=1e-14)
    np.testing.assert_allclose(to_motor_side(joint, robot).current, current_m, rtol=1e-14)


def test_a_drive_kt_that_is_not_the_joint_side_constant_is_refused(tmp_path):
    """[[drive]] kt stated as the motor's own constant beside motor_kt: a 100x torque error, refused with the fix."""
    from tests.conftest import DENSO_FILE

    path = tmp_path / "denso_currents.toml"
    path.write_text(DENSO_FILE.read_text() + MOTOR_CURRENTS)  # the Denso states kt = 36.07, ... (not 30, ...)
    with pytest.raises(RobotFileError, match=r"drive\[1\]\.kt = 36\.07 .* 100 x 0\.3 = 30 N m/A.*set it to 30"):
        load_robot(path)


def test_currents_are_on_the_side_the_file_states_for_the_torques(tmp_path, rng):
    """``side = { q = "joint", tau = "motor" }`` (the docs' per-signal form) with motor_kt, for a log of motor
    currents: the currents are the effort channel the file put on the motor side. Before, they stayed on the joint
    side, the drives got no kt and identify exited 2 asking for [[drive]] kt while motor_kt went unused."""
    robot = load_robot(_denso_without_drives(tmp_path, MOTOR_CURRENTS.replace('current = "motor"', 'tau = "motor"')))
    assert robot.recording_layout.side("current") == "motor"
    assert RecordingLayout(sides={"tau": "motor", "current": "joint"}).side("current") == "joint"  # stated: kept
    assert RecordingLayout(sides={"q": "motor"}).side("current") == "joint"
    current_m = rng.normal(size=(30, 6))
    joint = to_joint_side(Recording(t=np.arange(30) * 1e-3, q=np.zeros((30, 6)), current=current_m), robot)
    gears, motor_kt = np.array([100, -80, 60, 50, -40, 30.0]), np.array([0.3, 0.3, 0.2, 0.1, 0.1, 0.05])
    np.testing.assert_allclose(
        joint.joint_torque(np.array([d.kt for d in robot.drives])), current_m * motor_kt * gears, rtol=1e-14
    )


def test_motor_position_columns_are_named_as_motor_side_and_read_through_the_transmission(denso, tmp_path):
    """A log of ``motor_pos_1..6`` (encoder angles before the gear) and ``joint_torque_1..6``: the refusal names the
    group as motor-side positions with the robot file's ``[recording] side`` that reads it (it was '<position
    group>', matched by a ``pos`` prefix only); read so, the joint positions are the known truth. Beside a joint
    position group, that one is the example and the motor group is named as left unread."""
    rng = np.random.default_rng(11)
    reference = sine_experiment(denso, duration=2.0, rng=rng).reference()
    joint, _ = simulate_recording(denso, reference, SimulationOptions(record_tau=True, record_current=False), rng)
    layout = RecordingLayout(sides={"q": "motor"})
    robot = dataclasses.replace(denso, transmission=_random_transmission(rng, denso.n_dof), recording_layout=layout)
    motor = to_motor_side(joint, robot)
    n = denso.n_dof
    names = ["t", *(f"motor_pos_{j + 1}" for j in range(n)), *(f"joint_torque_{j + 1}" for j in range(n))]
    np.savetxt(tmp_path / "log.csv", np.column_stack([joint.t, motor.q, joint.tau]), delimiter=",",
               header=",".join(names), comments="", fmt="%.17g")  # fmt: skip
    with pytest.raises(RecordingError) as refused:
        load_robot_recording(tmp_path / "log.csv", robot)
    text = str(refused.value)
    assert "--columns q=motor_pos_,tau=joint_torque_" in text and "motor_pos_1.. hold motor-side positions" in text
    assert '[recording] side = { q = "motor" }' in text and "[transmission] gear_ratios" in text
    read = load_robot_recording(tmp_path / "log.csv", robot, None, ColumnLayout.parse("q=motor_pos_,tau=joint_torque_"))
    np.testing.assert_allclose(read.q, joint.q, atol=1e-9)
    np.testing.assert_allclose(read.tau, joint.tau, rtol=1e-12, atol=1e-12)
    names += [f"pos_{j + 1}" for j in range(n)]
    np.savetxt(tmp_path / "both.csv", np.column_stack([joint.t, motor.q, joint.tau, joint.q]), delimiter=",",
               header=",".join(names), comments="", fmt="%.17g")  # fmt: skip
    with pytest.raises(RecordingError, match=r"--columns q=pos_,tau=joint_torque_ .* motor_pos_1\.\. hold motor-side "
                       r"positions \(before the gear\) and are left unread; to read them instead of pos_"):  # fmt: skip
        load_robot_recording(tmp_path / "both.csv", denso)
