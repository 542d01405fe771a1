"""Motor currents logged in per cent of each motor's rated current, as industrial controllers trace them.

``--columns i=CurrAct_A:%`` with ``rated_current`` in the robot file's ``[transmission]``: the currents are read in
amperes (``% / 100 x rated``) before the motor side is mapped. Before, ``%`` was refused as no unit of a current and
a controller's trace could not be read at all (a 210 kg-class arm's 12 ms trace, ``benchmarks/unseen_arms.py``
``heavy_trace_percent``); a user who read it as amperes got every link pushed against its envelope and an unstated
load of twice its mass, the warnings naming a payload, never the unit.
"""

import numpy as np
import pytest

from identification.data.io import load_recording
from identification.data.layout import ColumnLayout
from identification.data.robot_recordings import load_robot_recording
from psdm_casadi.errors import ParameterError, RecordingError, RobotFileError
from psdm_casadi.robot import load_robot
from psdm_casadi.robot_writer import write_robot_file

GEARS = np.array([100, -80, 60, 50, -40, 30.0])
MOTOR_KT = np.array([0.3, 0.3, 0.2, 0.1, 0.1, 0.05])
RATED = np.array([12.0, 12.0, 8.0, 4.0, 4.0, 2.5])
TABLES = f"""
[transmission]
gear_ratios = {GEARS.tolist()}
motor_kt = {MOTOR_KT.tolist()}
RATED_LINE
[recording]
side = {{ q = "joint", current = "motor" }}
"""
LAYOUT = "t=TimeStamp:ms,q=AxisAct_A:deg,i=CurrAct_A:%"


def _robot_file(tmp_path, rated=RATED) -> str:
    """The built-in Denso's robot file without its [[drive]] tables, with motor currents stated in [transmission]."""
    from tests.conftest import DENSO_FILE

    line = "" if rated is None else f"rated_current = {[float(x) for x in rated]}\n"
    path = tmp_path / "denso_trace.toml"
    path.write_text(DENSO_FILE.read_text().split("\n[[drive]]\n")[0] + "\n" + TABLES.replace("RATED_LINE\n", line))
    return str(path)


def _trace(tmp_path, rng, header_unit: str = ""):
    """A 12 ms trace: time in ms, axis angles in degrees, motor currents in % of rated; (path, currents in A)."""
    n = 200
    t = np.arange(n) * 12.0 + rng.normal(0.0, 0.3, n).cumsum().clip(-2, 2)
    q = 0.3 * np.sin(np.outer(np.arange(n) * 0.012, [0.5, 0.7, 0.9, 1.1, 1.3, 1.5]))
    amperes = rng.normal(0.0, 1.0, (n, 6)) * RATED * 0.3
    header = [
        "TimeStamp",
        *(f"AxisAct_A{j + 1}" for j in range(6)),
        *(f"CurrAct_A{j + 1}{header_unit}" for j in range(6)),
    ]
    path = tmp_path / "trace_001.csv"
    np.savetxt(path, np.column_stack([t, np.degrees(q), 100.0 * amperes / RATED]), delimiter=",",
               header=",".join(header), comments="", fmt="%.12g")  # fmt: skip
    return path, amperes


def test_currents_in_percent_of_rated_are_read_in_amperes(tmp_path, rng):
    robot = load_robot(_robot_file(tmp_path))
    np.testing.assert_array_equal(robot.transmission.rated_current, RATED)
    path, amperes = _trace(tmp_path, rng)
    read = load_robot_recording(path, robot, columns=ColumnLayout.parse(LAYOUT))
    kt = np.array([d.kt for d in robot.drives])
    np.testing.assert_allclose(read.joint_torque(kt), amperes * MOTOR_KT * GEARS, rtol=1e-9)  # tau_j = N kt_m i_m
    # the robot file keeps its rated currents when written back (a calibrated model keeps its robot file's text)
    again = load_robot(write_robot_file(robot, tmp_path / "again.toml"))
    np.testing.assert_array_equal(again.transmission.rated_current, RATED)


def test_percent_without_rated_currents_is_refused_with_the_fix(tmp_path, rng, capsys):
    from psdm_casadi.cli import main

    robot_file = _robot_file(tmp_path, rated=None)
    path, _ = _trace(tmp_path, rng)
    with pytest.raises(RecordingError, match=r"trace_001.csv: .*% of each motor's rated current.*Add rated_current"):
        load_robot_recording(path, load_robot(robot_file), columns=ColumnLayout.parse(LAYOUT))
    argv = ["identify", robot_file, "--data", str(path), "--columns", LAYOUT, "--out", str(tmp_path / "m.json")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "rated_current = [...]" in err and "[transmission]" in err and "Traceback" not in err, err
    with pytest.raises(RecordingError, match="read with the robot file"):  # no robot, no rated currents
        load_recording(path, 6, layout=ColumnLayout.parse(LAYOUT))


def test_rated_currents_and_percent_units_are_checked_where_they_are_stated(tmp_path, rng):
    with pytest.raises(RobotFileError, match=r"\[transmission\]\.rated_current must be > 0 \[A\]"):
        load_robot(_robot_file(tmp_path, rated=[12.0, 0.0, 8.0, 4.0, 4.0, 2.5]))
    with pytest.raises(ParameterError, match="not a unit of tau"):  # a torque in % of what? refused
        ColumnLayout.parse("q=AxisAct_A,tau=Torque_A:%")
    with pytest.raises(ParameterError, match=r"use one of A, mA, % \(of each motor's rated current"):
        ColumnLayout.parse("q=AxisAct_A,i=CurrAct_A:pct")
    path, _ = _trace(tmp_path, rng, header_unit=" [%]")  # a header cannot say whose rated current: --columns does
    with pytest.raises(RecordingError, match=r"--columns i=PREFIX:% with rated_current"):
        load_robot_recording(path, load_robot(_robot_file(tmp_path)), columns=ColumnLayout.parse("t=TimeStamp:ms"))


def test_currents_in_percent_read_as_amperes_are_refused_naming_the_unit(denso, tmp_path, rng):
    """A trace of the virtual Denso's motor currents in % of rated currents that the robot file states, read without
    ``:%``: the torque comes out 2.5-5 times the file's joint by joint as 100 / rated_current, inside the tenfold the
    unit check refuses. Before, identify fitted it: every link of a 210 kg-class arm against its envelope, a 170 kg
    'unstated load' (truth 85 kg), and warnings that named a payload, never the unit."""
    from identification.calibration.trajectory_data import prepare_recordings
    from identification.virtual.simulation import SimulationOptions, simulate_recording
    from trajopt.experiments import sine_experiment

    rated = np.array([20.0, 25.0, 30.0, 40.0, 25.0, 20.0])
    robot = load_robot(_robot_file(tmp_path, rated=rated))
    reference = sine_experiment(denso, duration=4.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.05)
    truth, _ = simulate_recording(denso, reference, options, rng)
    percent = 100.0 * truth.tau / (GEARS * MOTOR_KT) / rated
    header = ["TimeStamp", *(f"AxisAct_A{j + 1}" for j in range(6)), *(f"CurrAct_A{j + 1}" for j in range(6))]
    path = tmp_path / "trace_002.csv"
    np.savetxt(path, np.column_stack([1000.0 * truth.t, np.degrees(truth.q), percent]), delimiter=",",
               header=",".join(header), comments="", fmt="%.12g")  # fmt: skip
    kt = np.array([d.kt for d in robot.drives])
    as_amperes = load_robot_recording(path, robot, columns=ColumnLayout.parse(LAYOUT.replace(":%", "")))
    with pytest.raises(RecordingError, match=r"trace_002.csv: the currents, read as amperes.*per cent of each "
                       r"motor's rated current.*--columns i=PREFIX:%"):  # fmt: skip
        prepare_recordings(robot, [as_amperes], kt, None)
    stated = load_robot_recording(path, robot, columns=ColumnLayout.parse(LAYOUT))
    prepare_recordings(robot, [stated], kt, None)  # read in % of rated: the file's torque, nothing refused
