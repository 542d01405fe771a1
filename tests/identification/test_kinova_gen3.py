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


@pytest.mark.slow
def test_identify_on_defaults_from_the_sensors_is_plausible_and_no_link_is_at_a_mass_bound(robot, tmp_path, capsys):
    out = tmp_path / "sensor.json"
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
    mass, stated = standard[:, 0], np.array([link.mass for link in robot.links])
    com = np.linalg.norm(standard[:, 1:4], axis=1) / mass
    assert np.all((mass > 0.5 * stated * 1.001) & (mass < 2.0 * stated * 0.999)), mass  # none at a mass bound
    assert np.all(com < 0.5), com  # every centre of mass within the arm's 0.42 m longest link plus a margin
    assert not any("mass upper bound" in w for w in report["warnings"])
