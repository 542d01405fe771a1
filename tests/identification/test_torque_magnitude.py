"""The recorded torque's scale against the robot file's (``plausibility.check_torque_magnitude``), on the virtual Denso.

A torque constant given without its gear ratio scales every joint's torque by about 1/100; identify then fitted
for many minutes instead of refusing. The truth here is a simulated recording (rigid body, rotors, friction, noise) of
a known robot: scaled by 1/100 it is refused at once, unscaled or recorded by a robot whose link is twice as heavy as
the file says it is not, and one joint's scale alone is a warning naming that joint. A cobot logging motor currents
through its gears (the Denso with a [transmission] table) is refused with its robot file's three usual mistakes, and
passes with the right one; the virtual fleet's health recordings, which the fleet prepares in amperes, pass.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from identification.calibration.trajectory_data import prepare_recording, prepare_recordings
from identification.data.io import load_recording, save_recording
from identification.data.motor_side import to_joint_side
from identification.data.plausibility import PlausibilityThresholds, check_torque_magnitude, torque_magnitude
from identification.data.recording import Recording
from identification.fleet.baseline import build_baseline
from identification.fleet.layout import read_fleet
from identification.fleet.session import SessionTask, read_session
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.robot import load_robot
from psdm_casadi.said_once import SAID
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


def _simulated(truth, seed: int = 3) -> Recording:
    rng = np.random.default_rng(seed)
    reference = sine_experiment(truth, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    return simulate_recording(truth, reference, options, rng)[0]


@pytest.fixture(scope="module")
def recorded(denso) -> Recording:
    return _simulated(denso)


def _scaled(recording: Recording, factors) -> Recording:
    return Recording(t=recording.t, q=recording.q, tau=recording.tau * np.asarray(factors), name="scaled.csv")


def test_the_least_squares_scale_is_the_factor_applied(rng):
    predicted = rng.standard_normal((500, 3))
    found = torque_magnitude(predicted * [0.01, 1.0, 300.0], predicted)
    np.testing.assert_allclose(found.scale, [0.01, 1.0, 300.0], rtol=1e-12)
    np.testing.assert_allclose(found.correlation, 1.0, rtol=1e-12)
    alike = torque_magnitude(predicted * 0.01, predicted)
    assert alike.overall == pytest.approx(0.01, rel=1e-12) and alike.rms_ratio == pytest.approx(0.01, rel=1e-12)


def test_torques_a_hundredth_of_the_truth_are_refused_naming_recording_factor_and_causes(denso, recorded):
    with pytest.raises(RecordingError) as info:
        prepare_recordings(denso, [_scaled(recorded, 0.01)])
    message = str(info.value)
    factor = float(message.split("the recorded torque is about ")[1].split(" times")[0])
    assert factor == pytest.approx(0.01, rel=0.3)  # the rotors and friction are in the truth, not in the factor
    assert "scaled.csv" in message and "torque's unit" in message and "gear ratio" in message


def test_currents_with_the_motors_kt_name_the_forgotten_gear_ratio(denso, recorded):
    current = Recording(t=recorded.t, q=recorded.q, current=recorded.tau / 101.0, name="currents.csv")
    ready, *_ = prepare_recording(current, np.ones(denso.n_dof))  # kt = 1: the motor's kt given for the joint's 101
    with pytest.raises(RecordingError, match=r"currents.csv: .* did you give the motor's kt without the gear ratio"):
        check_torque_magnitude(ready, denso, currents=True)


def test_the_right_scale_and_a_link_twice_as_heavy_as_the_file_pass(denso, recorded):
    ready, *_ = prepare_recording(recorded)
    found = check_torque_magnitude(ready, denso)
    assert 0.5 < found.overall < 2.0 and found.global_factor(PlausibilityThresholds()) is None  # friction, noise
    for link in (1, 2):  # the file says half of link 2's (or link 3's) mass and inertia
        links = list(denso.links)
        links[link] = replace(links[link], mass=2.0 * links[link].mass, inertia=2.0 * np.asarray(links[link].inertia))
        found = check_torque_magnitude(prepare_recording(_simulated(denso.with_links(links), seed=4))[0], denso)
        assert 0.5 < found.overall < 3.0


def test_one_joint_off_is_a_warning_naming_it_not_a_refusal(denso, recorded, caplog):
    SAID.clear()
    factors = np.ones(denso.n_dof)
    factors[1] = 0.01  # joint 2's torque constant given without its gear ratio
    ready, *_ = prepare_recording(_scaled(recorded, factors))
    with caplog.at_level(logging.WARNING):
        check_torque_magnitude(ready, denso)
    (warning,) = [
        r.getMessage() for r in caplog.records if "times the torque the robot file predicts" in r.getMessage()
    ]
    assert "joint 2" in warning and "scaled.csv" in warning and "torque constant" in warning


def test_identify_refuses_a_hundredth_of_the_torque_within_seconds(recorded, tmp_path, capsys):
    path = tmp_path / "scaled.csv"
    save_recording(_scaled(recorded, 0.01), path)
    start = time.perf_counter()
    code = main(["identify", "denso_vs6556g", "--data", str(path), "--out", str(tmp_path / "m.json")])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    assert "scaled.csv" in err and "the recorded torque is about" in err
    assert seconds < 60.0  # before any fit (it ran for many minutes before)


def test_diagnose_refuses_a_hundredth_of_the_torque_before_any_fit(denso, recorded, tmp_path, capsys):
    train, valid = tmp_path / "scaled.csv", tmp_path / "valid.csv"
    save_recording(_scaled(recorded, 0.01), train)
    save_recording(_scaled(_simulated(denso, seed=5), 0.01), valid)
    code = main(["diagnose", "denso_vs6556g", "--train", str(train), "--validate", str(valid)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    assert "scaled.csv" in err and "the recorded torque is about" in err


def test_the_torque_thresholds_are_checked():
    with pytest.raises(ParameterError, match="torque_factor"):
        PlausibilityThresholds(torque_factor=0.0)


# --- a cobot logging motor currents through its gears, and the robot file's usual mistakes ---------------------------
GEARS = np.array([100.0, 100.0, 80.0, 80.0, 50.0, 50.0])
MOTOR_KT = np.array([0.36, 0.40, 0.30, 0.22, 0.29, 0.11])  # the Denso's joint-side kt over the gear ratio, about
TABLES = {
    "right": f"[transmission]\ngear_ratios = {GEARS.tolist()}\nmotor_kt = {MOTOR_KT.tolist()}\n",
    "motor kt": "".join(f"[[drive]]\nkt = {k}\n\n" for k in MOTOR_KT),  # the motor's kt as the joint's
    "inverted gears": f"[transmission]\ngear_ratios = {(1.0 / GEARS).tolist()}\nmotor_kt = {MOTOR_KT.tolist()}\n",
}
LAYOUT = '[recording]\nside = { q = "joint", current = "motor" }\n'


def _cobot_file(tmp_path, mistake: str) -> Path:
    """The built-in Denso's robot file without its [[drive]] tables, its drives stated as ``TABLES[mistake]``."""
    path = tmp_path / f"{mistake.replace(' ', '_')}.toml"
    layout = "" if mistake == "motor kt" else LAYOUT
    path.write_text(DENSO_FILE.read_text().split("\n[[drive]]\n")[0] + "\n" + TABLES[mistake] + "\n" + layout)
    return path


@pytest.fixture(scope="module")
def motor_currents(recorded, tmp_path_factory) -> Path:
    """The simulated recording as its controller logs it: motor currents ``tau / (N kt_m)`` (i1..i6)."""
    path = tmp_path_factory.mktemp("cobot") / "currents.csv"
    current = recorded.tau / (GEARS * MOTOR_KT)
    save_recording(Recording(t=recorded.t, q=recorded.q, current=current, name="currents.csv"), path)
    return path


def test_motor_currents_through_the_right_gears_pass(motor_currents, tmp_path):
    robot = load_robot(_cobot_file(tmp_path, "right"))
    joint_side = to_joint_side(load_recording(motor_currents, robot.n_dof), robot)
    assert joint_side.tau is None  # currents, times the joint-side kt N kt_m
    (ready,) = prepare_recordings(robot, [joint_side], [d.kt for d in robot.drives])[2]
    found = check_torque_magnitude(ready, robot, currents=True)
    assert 0.5 < found.overall < 2.0  # the file's rotors and friction are the truth's (the Denso's), its kt N kt_m


@pytest.mark.parametrize(
    ("mistake", "factor", "fix"),
    [
        ("motor kt", 1.0 / GEARS[:2].mean(), "did you give the motor's kt without the gear ratio"),
        ("inverted gears", 1.0 / GEARS[:2].mean() ** 2, "inverted gear ratios"),
        ("mN m", 1000.0, "torques in mN m?"),
        ("mA", 1000.0, "currents in mA? (A expected; state the log's unit: --columns t=t,q=q,i=i:mA)"),  # its own names
    ],
)
def test_a_cobots_usual_mistakes_are_refused_with_exit_2_naming_recording_factor_and_fix(
    mistake, factor, fix, recorded, motor_currents, tmp_path, capsys
):
    if mistake == "mN m":
        robot, data = str(DENSO_FILE), tmp_path / "torques.csv"
        save_recording(_scaled(recorded, 1000.0), data)
    elif mistake == "mA":  # the right robot file, the currents logged in mA
        robot, data = str(_cobot_file(tmp_path, "right")), tmp_path / "milliamperes.csv"
        current = 1000.0 * recorded.tau / (GEARS * MOTOR_KT)
        save_recording(Recording(t=recorded.t, q=recorded.q, current=current, name=data.name), data)
    else:
        robot, data = str(_cobot_file(tmp_path, mistake)), motor_currents
    code = main(["identify", robot, "--data", str(data), "--out", str(tmp_path / "m.json")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    stated = float(err.split("the recorded torque is about ")[1].split(" times")[0])
    assert stated == pytest.approx(factor, rel=0.3)  # joints 1-2 (gravity's) weigh most in the pooled scale
    assert f"Recording {data.name}" in err and fix in err and "Fix the robot file or the recording" in err
    assert ("mN m?" in err) == (mistake == "mN m")  # currents are not blamed on a torque unit


# --- the fleet: its currents stay in amperes (kt is refitted), judged times the robot file's kt -----------------------
def test_a_fleet_health_recording_passes_as_the_fleet_reads_it(denso_model, tmp_path):
    """The virtual fleet logs ``current = tau / kt`` with each robot's own kt, written into its robot file; the fleet
    prepares the currents with kt = 1 (``session.read_session``: kt is refitted). Judged in amperes the check refused
    every robot-day (a pooled scale of about 1/55: the Denso's kt of 5-40 N m/A); judged times the file's kt, the
    joints without a tracked spring or ripple (1, 3, 5, 6) record the file's rigid body (scale 1)."""
    options = VirtualFleetOptions(n_robots=1, n_days=2, duration=3.0, baseline_days=2, event_robots=0, seed=3)
    write_virtual_fleet(tmp_path / "fleet", options)
    (entry,) = read_fleet(tmp_path / "fleet").robots
    baseline = build_baseline(entry, read_fleet(tmp_path / "fleet").track, lambda robot: denso_model)[0]
    day = entry.days[0]
    prepared, currents = read_session(SessionTask(entry.robot_id, day.day, day.paths, ""), baseline)
    assert currents
    found = check_torque_magnitude(prepared[0], baseline.robot, currents=True, torque_constants=baseline.kt)
    np.testing.assert_allclose(found.scale[[0, 2, 4, 5]], 1.0, rtol=0.05)
    with pytest.raises(RecordingError, match="health.csv: the recorded torque is about"):
        check_torque_magnitude(prepared[0], baseline.robot, currents=True)  # the amperes alone: what was refused
    unknown = check_torque_magnitude(prepared[0], baseline.robot, True, torque_constants=np.full(6, np.nan))
    assert np.isnan(unknown.scale).all()  # a fleet robot file without kt: the current's scale is not judged
