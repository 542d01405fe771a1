"""Logs as controllers write them, read against the truth they were written from.

Logger dropouts (rows of NaN), groups numbered from 0 (UR's RTDE ``actual_q_0..5``), wall-clock time stamps, and
units other than SI stated in ``--columns`` (degrees, mN m, milliseconds): each read back to the SI signals they
were made from, and a two-link virtual arm logged in degrees, mN m and ms identified through the CLI recovers its
link masses when the units are stated, and is refused (exit 2, naming the file and the fix) when they are not.
"""

from __future__ import annotations

import dataclasses
import json
import logging

import numpy as np
import pytest

from identification.data.io import load_recording
from identification.data.layout import ColumnLayout
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.description import DriveParameters, LinkInertia
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.robot import load_robot
from psdm_casadi.robot_writer import write_robot_file
from psdm_casadi.samples import two_link

MASSES = (4.0, 2.5)


def _write(path, header, columns, time_format="%.6f"):
    data = np.column_stack(columns)
    fmt = [time_format] + ["%.12g"] * (data.shape[1] - 1)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    return path


def _signals(n=1000, n_dof=2, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 2e-3
    q = 0.3 * np.sin(np.outer(t, 1.0 + np.arange(n_dof)))
    tau = rng.normal(0.0, 1.0, (n, n_dof))
    return t, q, tau


def test_dropout_rows_are_left_out_and_named(tmp_path, caplog):
    t, q, tau = _signals()
    q, tau = q.copy(), tau.copy()
    q[[100, 500, 501]] = np.nan
    tau[[100, 500, 501]] = np.nan
    path = _write(tmp_path / "log.csv", ["t", "q1", "q2", "tau1", "tau2"], [t, q, tau])
    with caplog.at_level(logging.WARNING):
        rec = load_recording(path, 2)
    assert rec.n_samples == 997 and np.all(np.isfinite(rec.q))
    keep = np.setdiff1d(np.arange(1000), [100, 500, 501])
    np.testing.assert_allclose(rec.t, t[keep], atol=1e-9)
    np.testing.assert_allclose(rec.tau, tau[keep], rtol=1e-11)
    assert "3 of 1000 rows" in caplog.text and "line 102" in caplog.text  # header is line 1, sample 100 line 102


def test_a_nan_of_one_joint_or_many_rows_is_refused(tmp_path):
    t, q, tau = _signals()
    one = q.copy()
    one[200, 1] = np.nan  # one joint only: not a dropout, a broken channel
    path = _write(tmp_path / "one.csv", ["t", "q1", "q2", "tau1", "tau2"], [t, one, tau])
    with pytest.raises(RecordingError, match=r"one.csv: column q2 holds nan at line 202"):
        load_recording(path, 2)
    many = q.copy()
    many[::50] = np.nan  # 20 rows of 1000: beyond 1 %
    path = _write(tmp_path / "many.csv", ["t", "q1", "q2", "tau1", "tau2"], [t, many, tau])
    with pytest.raises(RecordingError, match=r"20 of 1000 rows hold NaN.*up to 1% of the rows"):
        load_recording(path, 2)


def test_zero_based_groups_wall_clock_and_units(tmp_path):
    t, q, tau = _signals(n_dof=3)
    header = ["timestamp"] + [f"actual_q_{j}" for j in range(3)] + [f"actual_current_{j}" for j in range(3)]
    path = _write(tmp_path / "rtde.csv", header, [t + 1733380000.0, q, tau])
    rec = load_recording(path, 3, layout=ColumnLayout.parse("t=timestamp,q=actual_q_,i=actual_current_"))
    np.testing.assert_allclose(rec.q, q, rtol=1e-11)  # actual_q_0 is joint 1, in order
    np.testing.assert_allclose(rec.current, tau, rtol=1e-11)
    np.testing.assert_allclose(rec.t, t, atol=2e-6)  # Unix time: seconds from the first sample
    header = ["Time"] + [f"Pos{j + 1}" for j in range(3)] + [f"Trq{j + 1}" for j in range(3)]
    path = _write(tmp_path / "trace.csv", header, [1000.0 * t, np.degrees(q), 1000.0 * tau], "%.3f")
    rec = load_recording(path, 3, layout=ColumnLayout.parse("t=Time:ms,q=Pos:deg,tau=Trq:mNm"))
    np.testing.assert_allclose(rec.t, t, atol=1e-9)
    np.testing.assert_allclose(rec.q, q, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(rec.tau, tau, rtol=1e-10)
    with pytest.raises(ParameterError, match=r"'deg' is not a unit of tau; use one of Nm, mNm, kNm"):
        ColumnLayout.parse("q=Pos,tau=Trq:deg")


@pytest.fixture(scope="module")
def logged_arm(tmp_path_factory):
    """A two-link arm's 8 s log in ms, degrees and mN m (starting 1 s before it moves), and its robot file."""
    folder = tmp_path_factory.mktemp("two-link-log")
    base = two_link()
    links = tuple(
        LinkInertia(mass=m, com=np.array([-0.5, 0.02, 0.0]), inertia=np.diag([0.02, 0.3, 0.3]) * m / 4) for m in MASSES
    )
    joints = tuple(dataclasses.replace(j, q_min=-2.5, q_max=2.5, qd_max=2.0, qdd_max=8.0) for j in base.joints)
    drives = tuple(DriveParameters(kt=1.0, fc=1.0, fs=1.2, vs=0.05, fv=1.0, sigma0=1e4, sigma1=30.0) for _ in MASSES)
    robot = dataclasses.replace(
        base.with_links(links), joints=joints, name="two-link", rotor_inertia=np.array([0.2, 0.1]), drives=drives
    )
    robot = load_robot(write_robot_file(robot, folder / "arm.toml"))
    t = np.arange(0.0, 8.0, 2e-3)
    moving = np.clip(t - 1.0, 0.0, None)  # the log starts 1 s before the arm moves
    fade = 0.5 * (1.0 - np.cos(np.pi * np.minimum(1.0, np.minimum(moving, 7.0 - moving))))
    q = fade[:, None] * np.column_stack(
        [
            0.5 * np.sin(2.1 * moving) + 0.4 * np.sin(3.7 * moving + 1),
            0.5 * np.sin(2.9 * moving) - 0.3 * np.sin(1.3 * moving),
        ]
    )
    options = SimulationOptions(rate=500.0, record_tau=True, record_current=False, tau_noise_std=0.05)
    rec, _ = simulate_recording(robot, (t, q), options, np.random.default_rng(3))
    header = ["Time", "Pos0", "Pos1", "Trq0", "Trq1"]
    path = _write(folder / "trace.csv", header, [1000.0 * rec.t, np.degrees(rec.q), 1000.0 * rec.tau])
    return folder, path


def test_a_log_in_degrees_mnm_and_ms_identifies_the_arm_once_its_units_are_stated(logged_arm, capsys):
    folder, path = logged_arm
    robot, out = folder / "arm.toml", folder / "model.json"
    code = main(["identify", str(robot), "--data", str(path), "--columns", "t=Time,q=Pos,tau=Trq", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert (
        "trace.csv" in err and err.count("positions in degrees?") == 1 and "--columns t=Time,q=Pos:deg,tau=Trq" in err
    )  # its own names
    columns = "t=Time:ms,q=Pos:deg,tau=Trq:mNm"
    code = main(["-q", "identify", str(robot), "--data", str(path), "--columns", columns, "--out", str(out)])
    assert code == 0
    standard = np.asarray(json.loads(out.read_text())["standard"]["values"], dtype=float).reshape(2, -1)
    np.testing.assert_allclose(standard[:, 0], MASSES, rtol=0.1)  # the truth, not 1000x or the bounds


def test_an_unknown_tool_on_every_recording_is_named_not_separable_and_the_model_written(logged_arm, capsys):
    """A sidecar {"unknown": ...} beside the only recording: the tool cannot be told from the last link (the fit
    leaves it to the arm); identify said so, then crashed writing an infinite condition number into the model."""
    folder, path = logged_arm
    (folder / "trace.payload.json").write_text('{"unknown": "gripper"}')
    out = folder / "tool.json"
    try:
        code = main(["--quiet", "identify", str(folder / "arm.toml"), "--data", str(path), "--columns",
                     "t=Time:ms,q=Pos:deg,tau=Trq:mNm", "--out", str(out)])  # fmt: skip
    finally:
        (folder / "trace.payload.json").unlink()
    assert code == 0 and "gripper" in capsys.readouterr().out
    document = json.loads(out.read_text())
    assert np.isfinite(document["identification"]["condition_number"])
    standard = np.asarray(document["standard"]["values"], dtype=float).reshape(2, -1)
    np.testing.assert_allclose(standard[:, 0], MASSES, rtol=0.1)  # no tool: the arm as it is


def test_a_stored_tool_that_is_not_separable_is_explained_not_called_unidentified():
    from identification.calibration.payload_fit import stated_payload
    from identification.data.configuration import PayloadConfiguration

    stored = [{"name": "gripper", "kind": "unknown", "payload": {"parameters": None}}]
    parameters, note = stated_payload(PayloadConfiguration(name="gripper", unknown=True), stored, "model.json")
    assert parameters is None and "not separable from the arm" in note and "has not identified" not in note
    parameters, note = stated_payload(PayloadConfiguration(name="hammer", unknown=True), stored, "model.json")
    assert parameters is None and "has not identified it" in note


def test_diagnose_names_its_one_training_recording_when_given_identifys_list(tmp_path, capsys):
    """identify takes --data A B; the same list given to diagnose a robot file (no refit to train on the others) was
    argparse's "unrecognized arguments" (a model file's refit takes them: test_refit_training)."""
    code = main(["diagnose", "denso_vs6556g", "--train", str(tmp_path / "a.csv"), str(tmp_path / "b.csv"),
                 "--validate", str(tmp_path / "c.csv")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "--train takes one recording with a robot file; got 2 (a.csv, b.csv)" in err
    assert "Traceback" not in err


def test_torques_in_mnm_left_unstated_are_refused_naming_the_unit_alone(logged_arm, capsys):
    """The torques 1000x the robot file's on every joint: refused before any fit (exit 2), naming the unit and the
    --columns fix, not a wrong torque sign per joint nor a counterbalance pushing each link against its envelope
    (``plausibility.check_torque_magnitude``)."""
    folder, path = logged_arm
    out = folder / "mnm.json"
    code = main(["identify", str(folder / "arm.toml"), "--data", str(path), "--columns", "t=Time:ms,q=Pos:deg,tau=Trq",
                 "--out", str(out), "--no-html"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 2 and not out.exists() and "Traceback" not in captured.err, captured.err
    assert "torques in mN m?" in captured.err and "--columns t=Time:ms,q=Pos:deg,tau=Trq:mNm" in captured.err
    assert "PUSHED" not in captured.out and "Torque sign" not in captured.err and "counterbalance" not in captured.err


def test_a_bag_whose_driver_prefixes_the_joint_names_is_read_by_them(tmp_path, caplog):
    from tests.identification.recording_formats import joint_state_bag, smooth_signals

    robot_names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint"]
    logged = [f"ur/{n}" for n in robot_names] + ["ur/gripper_joint"]
    signals = smooth_signals(logged)
    bag = joint_state_bag(tmp_path / "prefixed", logged, signals, storage="mcap")
    with caplog.at_level(logging.WARNING):
        rec = load_recording(bag, 3, joint_names=robot_names)
    for j, name in enumerate(logged[:3]):  # each joint's own signal, whatever the message's order
        np.testing.assert_allclose(rec.q[:, j], signals[name][0], rtol=1e-12)
        np.testing.assert_allclose(rec.tau[:, j], signals[name][2], rtol=1e-12)
    assert "ur/elbow_joint as elbow_joint" in caplog.text
    twice = ["left_joint1", "right_joint1", "left_joint2"]  # two arms on one topic: joint1 is ambiguous
    bag = joint_state_bag(tmp_path / "two_arms", twice, smooth_signals(twice), storage="mcap")
    with pytest.raises(RecordingError, match=r"joint1, joint2 are missing \(its messages name"):
        load_recording(bag, 2, joint_names=["joint1", "joint2"])


def test_a_sidecar_named_after_the_whole_file_is_read_and_a_near_miss_refused(tmp_path):
    from identification.data.configuration import stated_configuration

    recording = tmp_path / "run1.csv"
    (tmp_path / "run1.csv.payload.json").write_text('{"mass": 2.0, "com": [0, 0, 0.06]}')
    stated = stated_configuration(recording)
    assert stated.payload.mass == 2.0 and stated.stated
    (tmp_path / "run2_payload.json").write_text('{"unknown": "gripper"}')
    with pytest.raises(ParameterError, match=r"run2_payload.json beside recording run2 is not read.*Rename "
                       r"run2_payload.json to run2.payload.json"):  # fmt: skip
        stated_configuration(tmp_path / "run2.csv")
    assert not stated_configuration(tmp_path / "run3.csv").stated  # no sidecar: no payload, as before


def test_a_few_repeated_time_stamps_are_left_out_and_many_refused(tmp_path, caplog):
    t, q, tau = _signals()
    stamps = t.copy()
    stamps[[300, 700]] = stamps[[299, 699]]  # a millisecond clock under jitter: two rows share a stamp
    path = _write(tmp_path / "coarse.csv", ["t", "q1", "q2", "tau1", "tau2"], [stamps, q, tau])
    with caplog.at_level(logging.WARNING):
        rec = load_recording(path, 2)
    keep = np.setdiff1d(np.arange(1000), [300, 700])
    np.testing.assert_allclose(rec.q, q[keep], rtol=1e-11)
    assert "2 of 1000 rows repeat the time stamp" in caplog.text and "line 302" in caplog.text
    stamps[1::40] = stamps[::40]  # 25 rows: beyond 1 %, refused at the first
    path = _write(tmp_path / "many.csv", ["t", "q1", "q2", "tau1", "tau2"], [stamps, q, tau])
    with pytest.raises(RecordingError, match=r"column t must be strictly increasing.*line 3\b"):
        load_recording(path, 2)


def test_a_bag_takes_the_units_of_columns_and_says_its_prefixes_are_not_used(tmp_path, caplog):
    from tests.identification.recording_formats import joint_state_bag, smooth_signals

    names = ["joint1", "joint2"]
    signals = smooth_signals(names)
    bag = joint_state_bag(tmp_path / "deg", names, signals, storage="mcap")
    rec = load_recording(bag, 2, joint_names=names, layout=ColumnLayout.parse("q=q:deg,tau=tau:mNm"))
    np.testing.assert_allclose(rec.q[:, 1], np.radians(signals["joint2"][0]), rtol=1e-12)
    np.testing.assert_allclose(rec.tau[:, 0], 1e-3 * signals["joint1"][2], rtol=1e-12)
    with caplog.at_level(logging.WARNING):
        load_recording(bag, 2, joint_names=names, layout=ColumnLayout.parse("q=Position,tau=Effort"))
    assert "prefixes are not used" in caplog.text


def test_units_stated_in_the_header_and_decimal_commas_are_read_in_si(tmp_path):
    t, q, tau = _signals(n=50)
    header = ["t [ms]", "q1 [deg]", "q2 (deg)", "tau1 [mN m]", "tau2 [Nm]"]
    path = _write(tmp_path / "units.csv", header, [1000.0 * t, np.degrees(q), np.column_stack([1e3 * tau[:, 0],
                                                                                              tau[:, 1]])])  # fmt: skip
    rec = load_recording(path, 2)
    np.testing.assert_allclose(rec.t, t, atol=1e-9)
    np.testing.assert_allclose(rec.q, q, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(rec.tau, tau, rtol=1e-10)
    (tmp_path / "label.csv").write_text("t,q1,tau1 (J1)\n0,0,0\n1,0,0\n2,0,0\n")
    with pytest.raises(RecordingError, match=r"column 'tau1 \(J1\)' states 'J1', which is not a unit"):
        load_recording(tmp_path / "label.csv", 1)
    lines = ["t;q1;q2;tau1;tau2"] + [
        ";".join(f"{v:.9f}".replace(".", ",") for v in row) for row in np.column_stack([t, q, tau])
    ]  # a spreadsheet's export in a European locale
    (tmp_path / "excel.csv").write_text("\n".join(lines) + "\n")
    rec = load_recording(tmp_path / "excel.csv", 2)
    np.testing.assert_allclose(rec.q, q, atol=1e-9)
    np.testing.assert_allclose(rec.tau, tau, atol=1e-9)


def test_a_time_column_of_iso_date_times_named_time_is_read_in_seconds(tmp_path):
    t, q, tau = _signals(n=50)
    start = np.datetime64("2026-12-05T04:13:29.000")
    stamps = [str(start + np.timedelta64(int(round(1e6 * s)), "us")) for s in t]  # pandas' to_csv of a time index
    lines = ["time,q1,q2,tau1,tau2"] + [f"{s},{a:.12g},{b:.12g},{c:.12g},{d:.12g}" for s, (a, b, c, d)
                                         in zip(stamps, np.column_stack([q, tau]))]  # fmt: skip
    (tmp_path / "pandas.csv").write_text("\n".join(lines) + "\n")
    rec = load_recording(tmp_path / "pandas.csv", 2)
    np.testing.assert_allclose(rec.t, t, atol=1e-9)
    np.testing.assert_allclose(rec.q, q, rtol=1e-11)


def test_a_training_log_in_degrees_is_refused_by_name_before_the_model_is_derived(logged_arm, capsys):
    folder, path = logged_arm
    validation = folder / "later.csv"
    validation.write_text(path.read_text())
    code = main(["identify", str(folder / "arm.toml"), "--data", str(path), "--validate", str(validation),
                 "--columns", "t=Time:ms,q=Pos,tau=Trq:mNm", "--out", str(folder / "deg.json")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "Recording trace.csv:" in err and "later.csv" not in err and "deriving" not in err
