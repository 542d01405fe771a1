"""A URDF whose link inertias are not physical is read for its kinematics: the inertias are reported, not refused.

Vendor URDFs edited by hand carry inertias that break the triangle inequality or are not positive
semi-definite (the shared Kinova Gen3 file has two). The reader keeps the kinematics, masses and centres
of mass, replaces each such inertia by a solid sphere of the link's mass and size, and says which link
and which condition; non-finite or negative numbers are still refused. Checked against Pinocchio's own
model of the same file.
"""

from __future__ import annotations

import logging

import numpy as np
import pinocchio as pin
import pytest

from psdm_casadi import load_robot
from psdm_casadi.cli import main
from psdm_casadi.errors import RobotFileError
from psdm_casadi.urdf import MIN_STAND_IN_RADIUS


def two_links(ixx1="0.01", ixx2="0.01", mass1="2.0"):
    """Two revolute joints; link 1's COM 0.05 m from its joint, joint 2 0.3 m beyond joint 1."""
    return (
        '<robot name="r"><link name="base"/>'
        f'<link name="l1"><inertial><origin xyz="0 0 0.05"/><mass value="{mass1}"/>'
        f'<inertia ixx="{ixx1}" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="1.0"/>'
        f'<inertia ixx="{ixx2}" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
        '<limit lower="-2" upper="2" velocity="2" effort="10"/></joint>'
        '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/>'
        '<axis xyz="0 1 0"/><limit effort="10" velocity="2"/></joint></robot>'
    )


def write(tmp_path, text, name="arm.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "ixx1, ixx2, condition",
    [("0.05", "0.01", "triangle inequality"), ("0.01", "-0.02", "positive semi-definite")],
    ids=["triangle", "not psd"],
)
def test_an_impossible_urdf_inertia_is_replaced_and_reported(tmp_path, caplog, ixx1, ixx2, condition):
    path = write(tmp_path, two_links(ixx1, ixx2))
    with caplog.at_level(logging.WARNING, logger="psdm_casadi"):
        robot = load_robot(path)
    reference = pin.buildModelFromUrdf(str(path))
    bad = 0 if ixx1 != "0.01" else 1
    (replaced,) = robot.replaced_inertias
    assert replaced.joint == bad and replaced.link == f"'l{bad + 1}'" and condition in replaced.problem
    for j in range(2):  # kinematics, masses and centres of mass are the file's
        inertia = reference.inertias[j + 1]
        assert robot.links[j].mass == pytest.approx(inertia.mass)
        np.testing.assert_allclose(robot.links[j].com, inertia.lever)
        if j != bad:
            np.testing.assert_allclose(robot.links[j].inertia, inertia.inertia)
    # link 1: half the 0.3 m to joint 2 (0.15) beats its COM distance 0.05; link 2: its COM distance 0.2
    radius = 0.15 if bad == 0 else 0.2
    assert replaced.radius == pytest.approx(radius) and radius > MIN_STAND_IN_RADIUS
    mass = reference.inertias[bad + 1].mass
    np.testing.assert_allclose(robot.links[bad].inertia, 0.4 * mass * radius**2 * np.eye(3))
    assert robot.q_min[1] == -np.pi and robot.q_max[1] == np.pi  # no limits in the file: the default range
    text = " ".join(r.getMessage() for r in caplog.records)
    assert f"link 'l{bad + 1}' (joint {bad + 1}) is unusable" in text and condition in text
    assert "correct it in the URDF" in text


def test_derive_goes_on_with_a_warning_and_non_finite_or_negative_numbers_are_still_refused(tmp_path, capsys):
    path = write(tmp_path, two_links("0.05"))
    assert main(["derive", str(path), "--out", str(tmp_path / "model.npz")]) == 0
    err = capsys.readouterr().err
    assert "arm.urdf: the inertia of link 'l1' (joint 1) is unusable" in err and "triangle inequality" in err
    with pytest.raises(RobotFileError, match=r"arm\.urdf joint 'j1' \(link 'l1'\): LinkInertia.mass must be"):
        load_robot(write(tmp_path, two_links("0.05", mass1="-1.0")))
    assert main(["derive", str(write(tmp_path, two_links(mass1="nan"), "nan.urdf"))]) == 2
    assert "mass [nan] is not a float" in capsys.readouterr().err


def test_right_angles_written_with_few_digits_are_taken_as_exact(tmp_path):
    """rpy="1.5708 0 0" (the Kinova file's spelling of pi/2) gives the exact right angle, so the derivation holds."""
    from psdm_casadi.derive import derive_psdm
    from psdm_casadi.urdf import load_urdf_model

    rounded = two_links().replace('<origin xyz="0 0 0.3"/>', '<origin xyz="0 0 0.3" rpy="1.5708 0 3.1416"/>')
    exact = two_links().replace('<origin xyz="0 0 0.3"/>', f'<origin xyz="0 0 0.3" rpy="{np.pi / 2!r} 0 {np.pi!r}"/>')
    model = load_urdf_model(write(tmp_path, rounded))
    reference = pin.buildModelFromUrdf(str(write(tmp_path, exact, "exact.urdf")))
    np.testing.assert_allclose(model.jointPlacements[2].rotation, reference.jointPlacements[2].rotation, atol=1e-15)
    assert np.count_nonzero(model.jointPlacements[2].rotation) == 3
    derive_psdm(load_robot(tmp_path / "arm.urdf"))  # checks itself against Pinocchio's rnea (raises otherwise)
    tilted = two_links().replace('<origin xyz="0 0 0.3"/>', '<origin xyz="0 0 0.3" rpy="1.56 0 0"/>')
    assert load_urdf_model(write(tmp_path, tilted, "tilted.urdf")).jointPlacements[2].rotation[1, 1] != 0.0


def test_each_command_says_an_unusable_inertia_once(tmp_path, capsys):
    """The Kinova's vendor URDF: identify, validate and the exports printed each unusable inertia twice, once when
    the robot was loaded and once as a warning stored in the model file."""
    import numpy as np

    from identification.data.io import save_recording
    from identification.data.recording import Recording
    from psdm_casadi import derive_psdm
    from psdm_casadi.cli import main
    from psdm_casadi.recursive import build_recursive_functions
    from psdm_casadi.robot import load_robot

    path = write(tmp_path, two_links(ixx1="0.05"))  # link l1 breaks the triangle inequality
    robot = load_robot(path)
    model = derive_psdm(robot)
    fast = build_recursive_functions(model, robot, model.base_parameters(robot.nominal_dynamic_parameters()))
    t = np.arange(1600) / 200.0
    w = 2 * np.pi * np.array([0.3, 0.5])
    q, qd, qdd = np.sin(w * t[:, None]), w * np.cos(w * t[:, None]), -(w**2) * np.sin(w * t[:, None])
    tau = np.array([np.asarray(fast.inverse_dynamics(a, b, c)).ravel() for a, b, c in zip(q, qd, qdd)])
    save_recording(Recording(t=t, q=q, tau=tau + 0.2 * np.tanh(qd / 0.05)), tmp_path / "run.csv")
    capsys.readouterr()
    out = tmp_path / "model.json"
    argv = ["identify", str(path), "--data", str(tmp_path / "run.csv"), "--holdout", "0.3", "--out", str(out)]
    for command in ([*argv, "--no-html"], ["validate", str(out)], ["export-mjcf", str(out), str(tmp_path / "a.xml")]):
        assert main(command) == 0
        err = capsys.readouterr().err
        assert err.count("the inertia of link 'l1' (joint 1) is unusable") == 1, (command[0], err)
