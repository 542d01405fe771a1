"""write_robot_file: the file reads back to the same robot (kinematics, inertias, drives, limits, assumptions), and
Pinocchio's torques of the robot read back equal those of the robot written."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from psdm_casadi.errors import RobotFileError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import DriveParameters, LinkInertia, load_robot
from psdm_casadi.robot_writer import write_robot_file
from tests.conftest import example_robot_urdf


def _random_robot(rng):
    """The Denso with every number redrawn (masses, centres of mass, inertias, rotors, drives, limits), the modified
    convention, an odd gravity and one joint without a torque limit: nothing a writer could get right by copying
    the defaults."""
    denso = load_robot("denso_vs6556g")
    joints = tuple(
        dataclasses.replace(
            j,
            a=float(rng.uniform(-0.4, 0.4)),
            d=float(rng.uniform(-0.4, 0.4)),
            theta=float(rng.uniform(-1, 1)) / 3.0,
            qd_max=float(rng.uniform(1, 5)),
            tau_max=math.inf if k == 2 else float(rng.uniform(10, 300)),
        )
        for k, j in enumerate(denso.joints)
    )
    links = []
    for _ in range(denso.n_dof):
        r, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # a random orientation of a solid ellipsoid's inertia
        s = rng.uniform(0.01, 0.04, 3)
        moments = np.array([s[1] + s[2], s[0] + s[2], s[0] + s[1]])
        links.append(
            LinkInertia(mass=float(rng.uniform(0.5, 9)), com=rng.normal(0, 0.1, 3), inertia=r @ np.diag(moments) @ r.T)
        )
    drives = tuple(
        DriveParameters(kt=float(rng.uniform(1, 40)), fc=float(rng.uniform(0, 9)), fv=float(rng.uniform(0, 20)))
        for _ in range(denso.n_dof)
    )
    return dataclasses.replace(
        denso,
        name='random "arm" \\ with quotes',
        joints=joints,
        convention="modified",
        gravity=rng.normal(0, 5, 3),
        links=tuple(links),
        rotor_inertia=rng.uniform(0, 1, denso.n_dof),
        drives=drives,
        drive_inertia=(True, False, True, True, False, True),
        massless_links=(),
        zero_parameters=("rx5",),
        source=None,
    )


def _assert_same_robot(robot, back):
    assert back.name == robot.name and back.convention == robot.convention and back.n_dof == robot.n_dof
    assert back.joints == robot.joints  # DH rows, joint types, names and every limit, exactly
    assert np.array_equal(back.gravity, robot.gravity)
    assert back.drives == robot.drives
    assert np.array_equal(back.rotor_inertia, robot.rotor_inertia)
    assert (back.drive_inertia, back.massless_links, back.zero_parameters) == (
        robot.drive_inertia,
        robot.massless_links,
        robot.zero_parameters,
    )
    for a, b in zip(robot.links, back.links):
        assert a.mass == b.mass and np.array_equal(a.com, b.com) and np.array_equal(a.inertia, b.inertia)


@pytest.mark.parametrize("name", ["denso_vs6556g", "scara", "random"])
def test_a_written_robot_file_reads_back_to_the_same_robot(name, tmp_path, rng):
    robot = _random_robot(rng) if name == "random" else load_robot(name)
    path = write_robot_file(robot, tmp_path / "robot.toml")
    back = load_robot(path)
    _assert_same_robot(robot, back)
    # Pinocchio (built from each description independently) gives the same torques on random states
    q, qd, qdd = (rng.uniform(-1.5, 1.5, (50, robot.n_dof)) for _ in range(3))
    tau, tau_back = PinocchioOracle(robot).rnea(q, qd, qdd), PinocchioOracle(back).rnea(q, qd, qdd)
    assert np.max(np.abs(tau_back - tau)) <= 1e-9 * max(1.0, float(np.max(np.abs(tau))))


def test_the_writer_refuses_to_overwrite_a_file_without_overwrite(tmp_path):
    robot = load_robot("scara")
    path = tmp_path / "robot.toml"
    path.write_text("user's file\n")
    with pytest.raises(RobotFileError, match="exists; pass overwrite=True"):
        write_robot_file(robot, path)
    assert path.read_text() == "user's file\n"
    write_robot_file(robot, path, overwrite=True)
    assert load_robot(path).joints == robot.joints


def test_the_writer_refuses_a_path_that_is_no_toml_file(tmp_path):
    with pytest.raises(RobotFileError, match=r"path must end in \.toml"):
        write_robot_file(load_robot("scara"), tmp_path / "robot.urdf")


def test_the_writer_refuses_a_urdf_robot_naming_the_fix(tmp_path):
    robot = load_robot(example_robot_urdf("ur_description/urdf/ur5_robot.urdf"))
    with pytest.raises(RobotFileError, match=r"read from a URDF.*\[urdf\] table"):
        write_robot_file(robot, tmp_path / "ur5.toml")
    assert not (tmp_path / "ur5.toml").exists()


def test_the_writer_refuses_rotor_inertia_without_link_inertias(tmp_path):
    robot = dataclasses.replace(load_robot("scara"), links=None, rotor_inertia=np.full(4, 0.1))
    with pytest.raises(RobotFileError, match="rotor inertia but RobotDescription.links is None"):
        write_robot_file(robot, tmp_path / "robot.toml")


def test_a_transmission_and_a_recording_layout_are_written_and_read_back(tmp_path, rng):
    from psdm_casadi.recording_layout import RecordingLayout
    from psdm_casadi.transmission import Transmission

    coupling = np.diag(rng.uniform(10, 100, 6) * rng.choice([-1, 1], 6))
    coupling[5, 4] = rng.uniform(-50, 50)
    transmission = Transmission(coupling=coupling, joint_offsets=rng.normal(size=6), motor_kt=rng.uniform(0.1, 1, 6))
    layout = RecordingLayout(sides={"q": "motor", "tau": "joint"}, sample_rate=2500.0,
                             files=(("q", "p.csv"), ("tau", "t.csv")))  # fmt: skip
    robot = dataclasses.replace(load_robot("denso_vs6556g"), transmission=transmission, recording_layout=layout)
    back = load_robot(write_robot_file(robot, tmp_path / "robot.toml"))
    _assert_same_robot(robot, back)
    for key in ("coupling", "joint_offsets", "motor_kt"):
        assert np.array_equal(getattr(back.transmission, key), getattr(transmission, key)), key
    assert back.recording_layout == layout
