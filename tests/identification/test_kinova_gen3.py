"""The shared Kinova Gen3 logs read as shipped (examples/kinova_gen3.toml), checked against the dataset README's facts.

README facts checked: ``TorqueCur`` is exactly ``Cur`` x 9.13 on joints 1-4 and x 5.852 on 5-7 (the
example's torque constants); ``Time`` counts rows at a nominal 1 kHz (opti_traj_testing1: 4741 rows,
4.74 s); the last 21 rows of opti_traj_testing1 hold NaN in reference columns but valid measured
ones; the URDF's shoulder_link and spherical_wrist_1_link inertias break the triangle inequality; the
moving links weigh 5.477 kg in the URDF (6.491 kg with Kinova's published inertials, which the example states in
``[[link]]`` tables, with a 0.6 kg tool on the last link). The slow test identifies the arm from the sensors with
the defaults and checks that every link is plausible and none ends at its mass bound.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from identification.calibration.prior_pull import PRIOR_UNCERTAINTY
from identification.data.io import load_recording
from identification.data.layout import ColumnLayout
from identification.data.robot_recordings import load_robot_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import RecordingError
from psdm_casadi.robot import load_robot
from tests.conftest import DATASETS, ROOT

pytestmark = pytest.mark.real_data

KINOVA = DATASETS / "kinova_gen3_dynid"
ROBOT_FILE = ROOT / "examples" / "kinova_gen3.toml"


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    if not (KINOVA / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {KINOVA}")
    folder = tmp_path_factory.mktemp("kinova")  # the example, with the URDF of this checkout's data folder
    text = ROBOT_FILE.read_text().replace(
        "../../shared/datasets/kinova_gen3_dynid/gen3.urdf", str(KINOVA / "gen3.urdf")
    )
    (folder / "kinova_gen3.toml").write_text(text)
    return load_robot(folder / "kinova_gen3.toml")


def test_the_logs_read_as_shipped_match_the_readme(robot):
    path = KINOVA / "opti_traj_testing1.csv"
    with pytest.raises(RecordingError, match=r"--columns t=Time,q=Position,tau=<one of Torque, TorqueSm, TorqueCur"):
        load_robot_recording(path, robot)
    with pytest.raises(RecordingError, match=r"the time column counts samples \(0, 1, 2, \.\.\., 4740\)"):
        load_recording(path, 7, layout=ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm"))
    with pytest.raises(RecordingError, match=r"column PositionCmptd\d holds nan"):  # the garbage rows' references
        load_robot_recording(path, robot, columns=ColumnLayout.parse("t=Time,q=PositionCmptd,tau=TorqueSm"))
    scaled = load_robot_recording(path, robot, columns=ColumnLayout.parse("t=Time,q=Position,tau=TorqueCur"))
    current = load_robot_recording(path, robot, columns=ColumnLayout.parse("t=Time,q=Position,i=Cur"))
    assert current.n_samples == 4741 and current.t[-1] == pytest.approx(4.74)  # the robot file's 1 kHz
    assert np.all(np.isfinite(current.current[-21:])) and np.all(np.isfinite(current.q[-21:]))
    kt = np.array([drive.kt for drive in robot.drives])
    np.testing.assert_array_equal(kt, [9.13] * 4 + [5.852] * 3)
    np.testing.assert_allclose(scaled.tau, current.current * kt, rtol=1e-5, atol=1e-6)  # to the 6 digits logged
    assert current.tau is None and scaled.current is None


def test_the_urdf_is_read_for_its_kinematics_with_its_unusable_inertias_named(robot):
    urdf = load_robot(KINOVA / "gen3.urdf")
    assert [(r.joint, r.link) for r in urdf.replaced_inertias] == [
        (0, "'shoulder_link'"),
        (4, "'spherical_wrist_1_link'"),
    ]
    assert all("triangle inequality" in r.problem for r in urdf.replaced_inertias)
    assert sum(link.mass for link in urdf.links) == pytest.approx(5.477, abs=1e-3)
    assert robot.joint_names == tuple(f"joint_{k}" for k in range(1, 8))
    assert list(robot.q_min[[0, 2, 4, 6]]) == [-np.pi] * 4  # continuous joints: not limited to the URDF's 0/0
    # the example's [[link]] tables: Kinova's published inertials (6.491 kg moving, README) with the tool on link 7
    assert robot.replaced_inertias == ()
    assert sum(link.mass for link in robot.links) - 0.6 == pytest.approx(6.491, abs=1e-3)
    for joint in range(6):  # the URDF's kinematics and centres of mass are kept
        np.testing.assert_array_equal(robot.links[joint].com, urdf.links[joint].com)


def test_run_trajectory1s_dead_sensor_channel_is_found_and_only_joint_1_is_left_out(robot):
    from identification.data.missing_torque import find_missing_torque

    columns = ColumnLayout.parse("t=Time,q=Position,tau=TorqueSm")
    run = find_missing_torque(load_robot_recording(KINOVA / "RunTrajectory1.csv", robot, columns=columns))
    assert run.missing_torque == ((0, "zero in every sample"),)  # README: TorqueSm1 is zero in RunTrajectory1
    assert np.all(np.isnan(run.tau[:, 0])) and np.all(np.isfinite(run.tau[:, 1:])) and np.ptp(run.tau[:, 1]) > 1
    with pytest.raises(RecordingError, match=r"Trajectory1.csv: no joint's torque is measured \(every column is zero"):
        find_missing_torque(load_robot_recording(KINOVA / "Trajectory1.csv", robot, columns=columns))


def _identify_on_the_currents(robot, out, capsys) -> dict:
    """``psdm identify`` on defaults from the motor currents of the three logs, validated on opti_traj_testing2: its
    --json report (the model file written to ``out``)."""
    argv = ["identify", robot.source, "--data", *(str(KINOVA / n) for n in ("opti_traj_testing1.csv",
            "RunTrajectory1.csv", "Trajectory1.csv")), "--validate", str(KINOVA / "opti_traj_testing2.csv"),
            "--columns", "t=Time,q=Position,i=Cur", "--out", str(out), "--json"]  # fmt: skip
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def _identify_on_the_sensors(robot, folder, capsys) -> tuple:
    """``psdm identify`` on defaults from the joint-torque sensors: (its --json report, the link masses)."""
    out = folder / "sensor.json"
    argv = ["identify", robot.source, "--data", str(KINOVA / "opti_traj_testing1.csv"),
            str(KINOVA / "RunTrajectory1.csv"), "--validate",
            str(KINOVA / "opti_traj_testing2.csv"), "--columns", "t=Time,q=Position,tau=TorqueSm", "--out", str(out),
            "--json"]  # fmt: skip
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["consistent"]
    assert not any("is unusable" in w for w in report["warnings"])  # the example states those inertias
    assert (
        "RunTrajectory1.csv: joint 1 (joint_1) has no torque measurement (zero in every sample)"
        in (report["warnings"][0])
    )
    validation = report["validation"][0]
    rmse, prior = np.array(validation["rmse"]), np.array(validation["rmse_prior"])
    assert np.all(rmse[1:4] < prior[1:4])
    standard = np.array(json.loads(Path(out).read_text())["standard"]["values"]).reshape(7, -1)
    mass = standard[:, 0]
    com = np.linalg.norm(standard[:, 1:4], axis=1) / mass
    assert np.all(com < 0.5), com  # every centre of mass within the arm's 0.42 m longest link plus a margin
    assert not any("mass upper bound" in w for w in report["warnings"])
    return report, mass


def _at_a_mass_bound(robot, mass) -> set:
    stated = np.array([link.mass for link in robot.links])
    return set(np.flatnonzero((mass <= 0.5 * stated * 1.001) | (mass >= 2.0 * stated * 0.999)))


@pytest.mark.slow
def test_identify_on_defaults_from_the_sensors_is_plausible_and_names_every_link_at_a_bound(robot, tmp_path, capsys):
    """Plausible: no link that the data press against a bound, and each link resting on its mass bound is named in
    the envelope report with what it may hold and the bound to revisit (the bound, not the data, set its mass)."""
    report, mass = _identify_on_the_sensors(robot, tmp_path, capsys)
    findings = report["envelope_findings"]
    assert not [f["message"] for f in findings if f["pressed"]]
    named = {f["link"] for f in findings if any(b.startswith("mass") for b in f["bounds"])}
    assert _at_a_mass_bound(robot, mass) <= named, (mass, named)


@pytest.mark.slow
def test_identify_on_defaults_from_the_sensors_leaves_no_link_at_a_mass_bound(robot, tmp_path, capsys):
    """Links 2 and 5, which these recordings hardly fix, stay near the example's masses: the pull towards the robot
    file is a prior weighed against the data's independent samples (``prior_pull``, stated in the report). With the
    per-sample weight of before (1e-4) they rested on their mass bounds (2.33 and 0.34 kg, pressed by 0.8x the
    noise)."""
    report, mass = _identify_on_the_sensors(robot, tmp_path, capsys)
    assert not _at_a_mass_bound(robot, mass), mass
    prior = report["envelope"]["prior"]
    samples = 7 * json.loads((tmp_path / "sensor.json").read_text())["identification"]["n_samples"]
    assert not prior["given"] and prior["uncertainty"] == PRIOR_UNCERTAINTY
    assert 100 < prior["effective_samples"] < 0.5 * samples  # filtered, oversampled: neighbours are not independent


def test_the_robot_file_says_once_which_urdf_inertias_it_replaces(robot, caplog):
    """The URDF's two unusable inertias are named when the example is read (its kinematics used, its [[link]] tables
    state them), as information: nothing is left to do, so no warning."""
    import logging

    with caplog.at_level(logging.INFO, logger="psdm_casadi.robot_file"):
        load_robot(robot.source)
    said = [r for r in caplog.records if "the URDF's inertia of link" in r.getMessage()]
    assert [r.levelno for r in said] == [logging.INFO, logging.INFO]
    assert "'shoulder_link' (joint 1) is unusable (it must satisfy the triangle inequality" in said[0].getMessage()
    assert "'spherical_wrist_1_link' (joint 5)" in said[1].getMessage()
    assert "[[link]] table states the inertia" in said[1].getMessage()


@pytest.fixture(scope="module")
def sensor_check():
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from kinova_gen3 import sensor_check
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    if not (KINOVA / "opti_traj_testing1.csv").exists():
        pytest.skip(f"Kinova Gen3 data absent in {KINOVA}")
    return sensor_check(KINOVA)


def test_the_currents_against_the_sensors_hold_the_rotors_and_a_gear_loss_on_joints_2_and_3(sensor_check):
    """Independent of any arm model: the current torque minus the sensor's is the rotors' inertia (0.4-0.52 kg m^2 on
    the large actuators, 0.09-0.10 on the small ones) and, on joints 2 and 3, a gear efficiency by power-flow
    direction (eta 0.92 and 0.82): its column lowers their residual by 20-26 %; elsewhere it changes nothing."""
    ia, mu = np.array(sensor_check["Ia"]), np.array(sensor_check["mu"])
    assert np.all((ia[:4] > 0.35) & (ia[:4] < 0.6)) and np.all((ia[4:] > 0.07) & (ia[4:] < 0.13)), ia
    assert 0.05 < mu[1] < 0.12 and 0.15 < mu[2] < 0.25, mu
    gain = 1 - np.array(sensor_check["rms_with_mu"]) / np.array(sensor_check["rms_without_mu"])
    assert gain[1] > 0.2 and gain[2] > 0.15 and np.all(gain[[0, 3, 4, 5]] < 0.02), gain
    assert 0.9 < sensor_check["efficiency"][1] < 0.95 and 0.78 < sensor_check["efficiency"][2] < 0.86


@pytest.mark.slow
def test_the_currents_leave_no_link_on_a_mass_bound_and_give_the_sensors_masses(robot, tmp_path, capsys):
    """The joint-torque sensors' fit is the reference (no rotors, no torque constants in it): the currents' fit gives
    every link's mass within 10 % of it and leaves no link on a mass bound or resting there in the envelope report.
    Before the masses were stated as the mass bounds state them (``prior_pull.mass_uncertainty``), link 3, which these
    recordings see only in sums with links 2 and 4, rested on its lower bound (0.58 kg for the file's 1.16; the sensor
    fit 0.67) pressed by 1.5 noise variances over all 761 samples, and links 4 and 6 were 1.26 and 0.71 x the sensor
    fit's: the pull, at twice each mass, was flat across the bounds. The rotors of joints 1 and 2 stay pressed against
    their band (the data ask those joints for more inertia than the sensors see as rotor: the sensors' own least
    squares too want 2 and 1.3 kg m^2 more there than the file's links hold), and the report says so."""
    _, sensor = _identify_on_the_sensors(robot, tmp_path, capsys)
    out = tmp_path / "current.json"
    report = _identify_on_the_currents(robot, out, capsys)
    mass = np.array(json.loads(out.read_text())["standard"]["values"]).reshape(7, -1)[:, 0]
    assert not _at_a_mass_bound(robot, mass) and not _at_a_mass_bound(robot, sensor), (mass, sensor)
    np.testing.assert_allclose(mass, sensor, rtol=0.1)
    findings = report["envelope_findings"]
    assert not [f for f in findings if set(f["bounds"]) & {"envelope", "mass upper", "mass lower"}], findings
    assert sorted(f["link"] for f in findings if f["pressed"]) == [0, 1]  # the rotors of joints 1 and 2
    assert report["envelope"]["prior"]["mass_uncertainty"] == pytest.approx(np.log(4) / 4)


@pytest.mark.slow
def test_identify_on_defaults_from_the_currents_keeps_the_rotors_and_every_link_plausible(robot, tmp_path, capsys):
    """From the currents alone (Trajectory1 has no sensor): the drive inertias are identified (motor currents hold
    them) near the sensor check's, link 5's centre of mass stays on its link (0.209 m before, 2x its length), the
    drive loss is tried and stated. The rotors of joints 1-2 lie inside links 1-2's base parameters (joint 2's axis is
    normal to joint 1's) and the robot file states none: held near joint 4's (same torque constant; joint 3's
    unconstrained drive inertia is negative, so it does not count), they come out
    near the sensor check's 0.52 and 0.48 kg m^2 and links 2 and 4 leave their upper mass bounds (they held them)."""
    out = tmp_path / "current.json"
    report = _identify_on_the_currents(robot, out, capsys)
    assert report["consistent"] and report["columns"]["torque_source"] == "current"
    assert report["columns"]["inertia_joints"] == [3, 4, 5, 6, 7]
    assert len([e for e in report["columns"]["evidence"] if e["term"] == "loss"]) == 7
    ia = np.array([report["drive"][f"Ia{j}"] for j in range(3, 8)])
    assert np.all((ia[:2] > 0.2) & (ia[:2] < 0.6)) and np.all((ia[2:] > 0.04) & (ia[2:] < 0.15)), ia
    standard = np.array(json.loads(Path(out).read_text())["standard"]["values"]).reshape(7, -1)
    com = np.linalg.norm(standard[:, 1:4], axis=1) / standard[:, 0]
    assert com[4] < 0.15, com  # joint 6 sits 0.106 m from joint 5
    reference = report["envelope"]["drive_inertia_reference"]
    assert [r["joint"] for r in reference] == [1, 2] and all(set(r["from_joints"]) <= {3, 4} for r in reference)
    assert np.all((standard[:2, 10] > 0.3) & (standard[:2, 10] < 0.8)), standard[:, 10]
    prior = np.array([link.mass for link in robot.links])
    assert standard[1, 0] < 1.9 * prior[1] and standard[3, 0] < 1.9 * prior[3], standard[:, 0] / prior
    assert not any(w.startswith("link ") and "pushed" in w for w in report["warnings"]), report["warnings"]
