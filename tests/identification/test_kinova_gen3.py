"""The shared Kinova Gen3 logs read as shipped (examples/kinova_gen3.toml), checked against the dataset README's facts.

README facts checked: ``TorqueCur`` is exactly ``Cur`` x 9.13 on joints 1-4 and x 5.852 on 5-7 (the
example's torque constants); ``Time`` counts rows at a nominal 1 kHz (opti_traj_testing1: 4741 rows,
4.74 s); the last 21 rows of opti_traj_testing1 hold NaN in reference columns but valid measured
ones; the URDF's shoulder_link and spherical_wrist_1_link inertias break the triangle inequality; the
moving links weigh 5.477 kg in the URDF. The slow test identifies the arm from the sensors with the
defaults and checks that every link is plausible and that the tool at the flange is named (0.6-0.8 kg
over Kinova's published masses by the README; the diagnosis of the robot file weighs it in the benchmark).
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
    assert [(r.joint, r.link) for r in robot.replaced_inertias] == [
        (0, "'shoulder_link'"),
        (4, "'spherical_wrist_1_link'"),
    ]
    assert all("triangle inequality" in r.problem for r in robot.replaced_inertias)
    assert sum(link.mass for link in robot.links) == pytest.approx(5.477, abs=1e-3)
    assert robot.joint_names == tuple(f"joint_{k}" for k in range(1, 8))
    assert list(robot.q_min[[0, 2, 4, 6]]) == [-np.pi] * 4  # continuous joints: not limited to the URDF's 0/0


@pytest.mark.slow
def test_identify_on_defaults_from_the_sensors_is_plausible_and_finds_the_tool(robot, tmp_path, capsys):
    out = tmp_path / "sensor.json"
    argv = ["identify", robot.source, "--data", str(KINOVA / "opti_traj_testing1.csv"), "--validate",
            str(KINOVA / "opti_traj_testing2.csv"), "--columns", "t=Time,q=Position,tau=TorqueSm", "--out", str(out),
            "--json"]  # fmt: skip
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["consistent"]
    assert any("'spherical_wrist_1_link' (joint 5) is unusable" in w for w in report["warnings"])
    validation = report["validation"][0]
    rmse, prior = np.array(validation["rmse"]), np.array(validation["rmse_prior"])
    assert np.all(rmse[1:4] < prior[1:4]) and rmse[1] < 0.5 * prior[1]  # the URDF's gravity is far off on J2
    standard = np.array(json.loads(Path(out).read_text())["standard"]["values"]).reshape(7, -1)
    mass, urdf = standard[:, 0], np.array([link.mass for link in robot.links])
    com = np.linalg.norm(standard[:, 1:4], axis=1) / mass
    assert np.all((mass > urdf / 5) & (mass < urdf * 5)), mass
    assert np.all(com < 0.5), com  # every centre of mass within the arm's 0.42 m longest link plus a margin
    assert mass[-1] > 1.5 * urdf[-1]  # the tool, carried by the last link, named as such
    (tool,) = [w for w in report["warnings"] if w.startswith("link 7 ") and "tool at the flange" in w]
    assert "--columns t=Time,q=Position,tau=TorqueSm'" in tool  # the diagnose it suggests reads the logs too
