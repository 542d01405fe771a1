"""Reading a controller's log as shipped: ``--columns`` names the signals' column groups, ``--rate`` the time base.

The file written here has the Kinova Gen3 logs' layout (a sample-index ``Time``, ``Position``, a model
``Torque``, sensor ``TorqueSm``, ``Cur``, and reference columns holding NaN and 1e297 in rows the
controller left unset); the expected values are the columns themselves.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.data.io import load_recording
from identification.data.layout import ColumnLayout
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, RecordingError

N = 50


def vendor_log(tmp_path, time=None, name="log.csv", joints=2):
    rng = np.random.default_rng(0)
    columns = {"Time": np.arange(N, dtype=float) if time is None else time}
    for group in ("Position", "Velocity", "Torque", "TorqueSm", "Cur", "PositionCmptd"):
        for k in range(1, joints + 1):
            columns[f"{group}{k}"] = rng.normal(size=N)
    columns["PositionCmptd2"][-5:] = [np.nan, 1e297, -1e297, 4e-320, np.nan]  # garbage rows of unset references
    path = tmp_path / name
    header = ",".join(columns)
    np.savetxt(path, np.column_stack(list(columns.values())), delimiter=",", header=header, comments="", fmt="%.17g")
    return path, columns


def test_a_log_is_read_by_its_column_groups_and_rate(tmp_path):
    path, columns = vendor_log(tmp_path)
    sensor = load_recording(path, 2, layout=ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm", 1000.0))
    np.testing.assert_array_equal(sensor.t, np.arange(N) / 1000.0)
    np.testing.assert_array_equal(sensor.q, np.column_stack([columns["Position1"], columns["Position2"]]))
    np.testing.assert_array_equal(sensor.tau, np.column_stack([columns["TorqueSm1"], columns["TorqueSm2"]]))
    assert sensor.current is None and sensor.qd is None
    currents = load_recording(path, 2, layout=ColumnLayout.parse("q=Position,qd=Velocity,i=Cur", 500.0))
    np.testing.assert_array_equal(currents.current[:, 1], columns["Cur2"])
    np.testing.assert_array_equal(currents.qd[:, 0], columns["Velocity1"])
    np.testing.assert_allclose(currents.t, np.arange(N) / 500.0, rtol=1e-15)  # no time column named: the rate
    assert currents.tau is None


def test_a_layout_naming_only_the_signal_groups_reads_the_files_own_clock(tmp_path):
    """``--columns q=...,i=...`` without ``t=``: the file's one time-like column is its clock, as without --columns
    (before, the stated groups dropped it and the log was refused as having no time column)."""
    stamps = 1765000000.0 + np.cumsum(np.random.default_rng(1).uniform(1.5e-3, 2.5e-3, N))  # a jittered wall clock
    path, columns = vendor_log(tmp_path, time=stamps)
    recording = load_recording(path, 2, layout=ColumnLayout.parse("q=Position,i=Cur"))
    np.testing.assert_allclose(recording.t, stamps - stamps[0], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(recording.current[:, 0], columns["Cur1"])


def test_a_log_without_a_layout_or_rate_is_refused_with_the_fix(tmp_path):
    path, _ = vendor_log(tmp_path)
    with pytest.raises(
        RecordingError, match=r"log\.csv: the columns are not t, q1\.\.qn.*Position1\.\.2.*TorqueSm1\.\.2"
    ):
        load_recording(path, 2)
    with pytest.raises(
        RecordingError,
        match=r"--columns t=Time,q=Position,tau=<one of Torque, TorqueSm> \(the torque group that is measured",
    ):
        load_recording(path, 2)
    with pytest.raises(RecordingError, match=r"time column counts samples \(0, 1, 2, \.\.\., 49\).*--rate HZ"):
        load_recording(path, 2, layout=ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm"))
    with pytest.raises(RecordingError, match=r"--columns tau=Torq names no column.*TorqueSm1\.\.2"):
        load_recording(path, 2, layout=ColumnLayout.parse("t=Time,q=Position,tau=Torq", 1000.0))
    with pytest.raises(RecordingError, match=r"column PositionCmptd2 holds nan"):  # a column that is read is checked
        load_recording(path, 2, layout=ColumnLayout.parse("t=Time,q=PositionCmptd,tau=TorqueSm", 1000.0))
    seconds, _ = vendor_log(tmp_path, time=np.arange(N) * 0.001 + 0.0005, name="seconds.csv")
    for rate in (None, 1000.0):  # a column of times is kept as it is, whatever the rate
        layout = ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm", rate)
        np.testing.assert_allclose(load_recording(seconds, 2, layout=layout).t[:2], [5e-4, 1.5e-3])


@pytest.mark.parametrize(
    "text, rate, match",
    [
        ("q=Position,torque=TorqueSm", None, r"--columns names signal 'torque'"),
        ("q=Position,tau", None, r"--columns items must be SIGNAL=PREFIX; got 'tau'"),
        ("q=Position,q=Pos", None, r"names a signal twice"),
        ("q=Position", -5.0, r"--rate must be a sample rate > 0"),
    ],
)
def test_bad_layout_options_are_refused(text, rate, match):
    with pytest.raises(ParameterError, match=match):
        ColumnLayout.parse(text, rate)


@pytest.mark.parametrize(
    "options, message",
    [
        ((), "the columns are not t, q1..qn"),
        (("--columns", "t=Time,q=Position,tau=Torq", "--rate", "1000"), "--columns tau=torq names no column"),
        (("--columns", "t=Time,q=Position,tau=TorqueSm"), "the time column counts samples"),
    ],
    ids=["no layout", "wrong prefix", "no rate"],
)
def test_the_commands_take_the_layout_and_refuse_a_log_without_it(tmp_path, capsys, options, message):
    path, _ = vendor_log(tmp_path, joints=6)
    for command in (["identify", "denso_vs6556g", "--data", str(path), "--out", str(tmp_path / "m.json")],
                    ["diagnose", "denso_vs6556g", "--train", str(path), "--validate", str(path)]):  # fmt: skip
        assert main([*command, *options]) == 2
        assert message in capsys.readouterr().err.lower()


def test_the_refusal_names_where_the_robot_file_states_its_torque_constants(tmp_path, capsys):
    """A log of motor currents refused for its own column names: the fix names the torque constants' section the
    robot file uses (a cobot's file with [transmission] motor_kt was told about [[drive]] tables it does not have)."""
    from tests.conftest import DENSO_FILE

    path, _ = vendor_log(tmp_path, joints=6)
    without_drives = DENSO_FILE.read_text().split("\n[[drive]]\n")[0]
    files = {
        "motor_kt": without_drives + "\n[transmission]\ngear_ratios = [100, 80, 60, 50, 40, 30]\n"
        "motor_kt = [0.3, 0.3, 0.2, 0.1, 0.1, 0.05]\n",
        "drive": DENSO_FILE.read_text(),
        "none": without_drives,
    }
    expected = {
        "motor_kt": ("read through the robot file's [transmission] motor_kt", "[[drive]]"),
        "drive": ("the torque constants kt of the robot file's [[drive]] tables", "motor_kt"),
        "none": ("add motor_kt and gear_ratios to [transmission], or kt (N m/A at the joint) to [[drive]]", None),
    }
    for name, text in files.items():
        robot_file = tmp_path / f"{name}.toml"
        robot_file.write_text(text)
        assert main(["identify", str(robot_file), "--data", str(path), "--out", str(tmp_path / "m.json")]) == 2
        err = capsys.readouterr().err
        said, unsaid = expected[name]
        assert "the columns are not t, q1..qn" in err and said in err, err
        assert unsaid is None or unsaid not in err, err
    with pytest.raises(RecordingError, match=r"\[\[drive\]\] kt at the joint, or \[transmission\] motor_kt"):
        load_recording(path, 6)  # no robot: both places


def test_a_log_read_with_a_rate_alone_is_refused_naming_all_its_groups(tmp_path):
    """``--rate`` without ``--columns`` on a controller's log: the refusal lists the file's groups (before, the rate's
    layout kept only the standard names first, and the Kinova log was said to have only 'Temp1..7 and Time')."""
    path, _ = vendor_log(tmp_path)
    with pytest.raises(RecordingError, match=r"the file has Position1\.\.2, Velocity1\.\.2, Torque1\.\.2, TorqueSm1"):
        load_recording(path, 2, layout=ColumnLayout.parse(None, 1000.0))


def test_currents_on_a_urdf_robot_are_refused_naming_the_robot_file_that_holds_the_torque_constants(tmp_path, capsys):
    """A URDF has no place for torque constants: the refusal of its currents says to write a TOML robot file naming
    it, and that file, written as said, is read with its kt."""
    from psdm_casadi import load_robot
    from tests.identification.test_envelope import ARM_URDF

    (tmp_path / "arm.urdf").write_text(ARM_URDF.format(l1="", l2="", tip=""))
    t = np.arange(2000) * 1e-3
    path = tmp_path / "currents.csv"
    table = np.column_stack([np.arange(t.size), 0.5 * np.sin(t), 0.3 * np.cos(2 * t), np.sin(3 * t), np.cos(t)])
    np.savetxt(path, table, delimiter=",", header="Time,Position1,Position2,Cur1,Cur2", comments="")
    command = ["identify", str(tmp_path / "arm.urdf"), "--data", str(path), "--out", str(tmp_path / "m.json")]
    assert main([*command, "--columns", "t=Time,q=Position,i=Cur", "--rate", "1000"]) == 2
    err = capsys.readouterr().err
    said = 'arm.urdf cannot hold these tables: write a robot file robot.toml beside it with [urdf] path = "arm.urdf"'
    assert said in err, err
    (tmp_path / "robot.toml").write_text('format = "psdm-robot/1"\nname = "arm"\n[urdf]\npath = "arm.urdf"\n'
                                         "[[drive]]\nkt = 2.0\n[[drive]]\nkt = 3.0\n")  # fmt: skip
    assert [d.kt for d in load_robot(tmp_path / "robot.toml").drives] == [2.0, 3.0]
