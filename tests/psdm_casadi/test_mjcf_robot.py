"""MJCF in (issue 28, part 2): a robot read from an MJCF file is MuJoCo's robot.

Oracles: MuJoCo's own inverse dynamics (``mj_inverse`` with its constraints, damping, armature and friction off)
on the same file, against the Pinocchio model psdm builds from it and against the PSDM model derived from it;
and for the Panda, the URDF-derived model of the same robot (the MJCF written from the URDF's numbers).
"""

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest

from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import RobotFileError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import from_urdf, load_robot
from tests.conftest import example_robot_urdf

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

PANDA_LOCKED = ("panda_finger_joint1", "panda_finger_joint2")

# A Menagerie-style arm: degrees, default classes for the axes and ranges, frames by pos/quat/euler/axisangle/
# xyaxes and <frame> elements, a joint off its body's origin, a joint with ref, a slide joint, a welded tool,
# fullinertia and diaginertia + quat, mesh geoms whose files are absent, a contact pair, an actuator's force
# range, a base body.
ARM = """<mujoco model="arm4">
  <compiler angle="degree" meshdir="assets" boundinertia="1e-6"/>
  <option gravity="0 -1.5 -9.7"/>
  <default>
    <default class="arm"><joint axis="0 0 1" range="-170 170"/>
      <default class="wrist"><joint axis="0 1 0" range="-120 120"/></default>
    </default>
  </default>
  <asset><mesh name="link" file="link.stl"/><material name="grey" rgba=".5 .5 .5 1"/></asset>
  <worldbody>
    <body name="base" pos="0.1 0 0.05" euler="0 0 30">
      <geom type="cylinder" size="0.1 0.05" material="grey"/>
      <body name="link1" pos="0 0 0.3">
        <joint name="j1" class="arm"/>
        <inertial pos="0.01 0.02 0.1" mass="3.2" fullinertia="0.05 0.04 0.02 0.001 -0.002 0.003"/>
        <geom name="g1" type="mesh" mesh="link"/>
        <body name="link2" pos="0 0.1 0.2" axisangle="1 0 0 -90">
          <frame><joint name="j2" class="wrist" pos="0 0 0.05" ref="10"/></frame>
          <inertial pos="0.2 0 0.01" quat="0.9 0.1 0.3 0.2" mass="2.1" diaginertia="0.03 0.025 0.01"/>
          <geom type="mesh" mesh="link" material="grey"/>
          <body name="link3" pos="0.4 0 0" xyaxes="0 1 0 -1 0 0">
            <joint name="j3" type="slide" axis="1 0 0" range="-0.1 0.2"/>
            <inertial pos="0.05 0 0" mass="1.1" diaginertia="0.004 0.006 0.005"/>
            <geom name="g3" type="box" size="0.05 0.02 0.02"/>
            <frame pos="0.05 0 0" euler="0 0 20"><body name="link4" pos="0.05 0 0" quat="0.7 0.1 0.7 0.1">
              <joint name="j4" class="arm" axis="0.6 0 0.8"/>
              <inertial pos="0 0.01 0.03" mass="0.6" diaginertia="0.001 0.0012 0.0008"/>
              <body name="tool" pos="0 0 0.08" euler="0 90 0">
                <inertial pos="0 0 0.02" mass="0.4" diaginertia="0.0005 0.0005 0.0002"/>
                <site name="tcp"/>
              </body>
            </body></frame>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <contact><pair geom1="g1" geom2="g3"/></contact>
  <actuator><motor joint="j1" gear="2" forcerange="-40 40" forcelimited="true"/></actuator>
</mujoco>
"""


# The arm with a Menagerie-style gripper in place of its tool: two slide fingers coupled by a fixed tendon and an
# equality constraint, driven through the tendon.
HAND = ARM.replace(
    """<body name="tool" pos="0 0 0.08" euler="0 90 0">
                <inertial pos="0 0 0.02" mass="0.4" diaginertia="0.0005 0.0005 0.0002"/>
                <site name="tcp"/>
              </body>""",
    """<body name="hand" pos="0 0 0.08" euler="0 90 0">
                <inertial pos="0 0 0.02" mass="0.4" diaginertia="0.0005 0.0005 0.0002"/>
                <body name="left" pos="0 0 0.05"><joint name="f1" type="slide" axis="0 1 0" range="0 0.04"/>
                  <inertial pos="0 0.01 0.02" mass="0.05" diaginertia="2e-5 2e-5 1e-5"/></body>
                <body name="right" pos="0 0 0.05" quat="0 0 0 1">
                  <joint name="f2" type="slide" axis="0 1 0" range="0 0.04"/>
                  <inertial pos="0 0.01 0.02" mass="0.05" diaginertia="2e-5 2e-5 1e-5"/></body>
              </body>""",
).replace(
    "<actuator>",
    '<tendon><fixed name="split"><joint joint="f1" coef="0.5"/><joint joint="f2" coef="0.5"/></fixed></tendon>\n'
    '  <equality><joint joint1="f1" joint2="f2"/></equality>\n'
    '  <actuator><general name="grip" tendon="split" ctrlrange="0 255" gainprm="0.01 0 0" biasprm="0 -100 -10" '
    'biastype="affine"/>',
)


def _mujoco_inverse(text, q, qd, qdd):
    """MuJoCo's rigid-body inverse dynamics of the file (constraints, passive forces and armature off)."""
    text = re.sub(r"<asset>.*?</asset>|material=\"grey\"", "", text, flags=re.S)  # no mesh files: spheres
    mj = mujoco.MjModel.from_xml_string(text.replace('type="mesh" mesh="link"', 'type="sphere" size="0.01"'))
    mj.opt.disableflags |= (
        int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        | int(mujoco.mjtDisableBit.mjDSBL_SPRING)
        | int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
    )
    mj.dof_armature[:] = 0.0
    data = mujoco.MjData(mj)
    out = []
    for x in zip(q, qd, qdd):  # joints beyond the arm's (a gripper's fingers) at 0, still
        data.qpos[:], data.qvel[:], data.qacc[:] = (np.r_[v, np.zeros(mj.nv - len(v))] for v in x)
        mujoco.mj_inverse(mj, data)
        out.append(data.qfrc_inverse[: len(x[0])].copy())
    return np.array(out)


def _states(robot, n=40, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max, size=(n, robot.n_dof))
    qd, qdd = rng.normal(size=(2, n, robot.n_dof))
    return q, qd, qdd


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    path = tmp_path_factory.mktemp("mjcf") / "arm4.xml"
    path.write_text(ARM)
    return path


def test_the_arm_is_mujocos_arm_in_pinocchio_and_in_the_derived_model(arm):
    robot = load_robot(arm)
    assert robot.joint_names == ("j1", "j2", "j3", "j4") and [j.kind for j in robot.joints][2] == "prismatic"
    np.testing.assert_array_equal(robot.gravity, [0.0, -1.5, -9.7])
    np.testing.assert_allclose(robot.q_min, np.radians([-170, -120, 0]).tolist()[:2] + [-0.1, np.radians(-170)])
    assert robot.tau_max[0] == 80.0 and np.isinf(robot.tau_max[1])  # forcerange x gear
    q, qd, qdd = _states(robot)
    expected = _mujoco_inverse(ARM, q, qd, qdd)
    ours = PinocchioOracle(robot).rnea(q, qd, qdd)
    assert np.abs(ours - expected).max() <= 1e-12 * np.abs(expected).max()
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    derived = model.inverse_dynamics(q, qd, qdd, theta)
    assert np.abs(derived - expected).max() <= 1e-9 * np.abs(expected).max()


def _broken(tmp_path, old, new, name="bad.xml"):
    path = tmp_path / name
    path.write_text(ARM.replace(old, new, 1))
    return path


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('<body name="link1" pos="0 0 0.3">', '<body name="link1" pos="0 0 0.3"><freejoint/>', "free joint"),
        ('<joint name="j1" class="arm"/>', '<joint name="j1" type="ball"/>', "joint 'j1' is a ball joint"),
        ('<joint name="j1" class="arm"/>', '<joint name="j1" class="arm"/><joint name="j0"/>', "has 2 joints"),
        ("<actuator>", '<tendon><fixed name="t"><joint joint="j1" coef="1"/></fixed></tendon><actuator>',
         "fixed tendon 't'"),
        ("<actuator>", '<equality><joint joint1="j1" joint2="j4"/></equality><actuator>',
         "equality constraint <joint>"),
        ("<worldbody>", '<include file="other.xml"/><worldbody>', "<include>"),
        ('<inertial pos="0.05 0 0" mass="1.1" diaginertia="0.004 0.006 0.005"/>', '<geom type="mesh" mesh="link"/>',
         "give it an <inertial>"),
    ],
)  # fmt: skip
def test_what_a_serial_arm_cannot_hold_is_refused_naming_it(tmp_path, capsys, old, new, message):
    path = _broken(tmp_path, old, new)
    with pytest.raises(RobotFileError, match=re.escape(message)):
        load_robot(path)
    assert main(["derive", str(path)]) == 2
    assert message in capsys.readouterr().err


def menagerie_panda(urdf_text: str) -> str:
    """A Menagerie-style MJCF of the Panda written from its URDF's numbers (exact text): bodies by pos and euler
    (``eulerseq="XYZ"``: URDF's rpy), inertials by pos and fullinertia (the Panda's inertials have rpy 0), the
    fingers welded (locked at 0)."""
    root = ET.fromstring(urdf_text)
    links = {link.get("name"): link for link in root.iter("link")}
    joints = list(root.iter("joint"))
    children = {}
    for joint in joints:
        children.setdefault(joint.find("parent").get("link"), []).append(joint)

    def body(joint, indent):
        origin = joint.find("origin")
        link = links[joint.find("child").get("link")]
        rows = [f'{indent}<body name="{link.get("name")}" pos="{origin.get("xyz")}" euler="{origin.get("rpy")}">']
        if joint.get("type") in ("revolute", "prismatic") and joint.get("name") not in PANDA_LOCKED:
            limit = joint.find("limit")
            kind, axis = "hinge" if joint.get("type") == "revolute" else "slide", joint.find("axis").get("xyz")
            rows.append(f'{indent}  <joint name="{joint.get("name")}" type="{kind}" axis="{axis}" '
                        f'range="{limit.get("lower")} {limit.get("upper")}" actuatorfrcrange="-{limit.get("effort")} '
                        f'{limit.get("effort")}"/>')  # fmt: skip
        inertial = link.find("inertial")
        if inertial is not None and float(inertial.find("mass").get("value")) > 0:  # link8: mass 0, none
            o, i = inertial.find("origin"), inertial.find("inertia").attrib
            assert o.get("rpy") in (None, "0 0 0")
            full = " ".join(i[k] for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz"))
            rows.append(f'{indent}  <inertial pos="{o.get("xyz")}" '
                        f'mass="{inertial.find("mass").get("value")}" fullinertia="{full}"/>')  # fmt: skip
        rows += [body(child, indent + "  ") for child in children.get(link.get("name"), [])]
        return "\n".join(rows + [f"{indent}</body>"])

    chain = "\n".join(body(joint, "    ") for joint in children["panda_link0"])
    return (f'<mujoco model="panda">\n  <compiler angle="radian" eulerseq="XYZ"/>\n'
            f'  <option gravity="0 0 -9.806132"/>\n  <worldbody>\n{chain}\n  </worldbody>\n</mujoco>\n')  # fmt: skip


@pytest.fixture(scope="module")
def panda_files(tmp_path_factory):
    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    path = tmp_path_factory.mktemp("panda") / "panda.xml"
    path.write_text(menagerie_panda(urdf.read_text()))
    return urdf, path


def test_the_panda_from_mjcf_is_the_panda_from_its_urdf(panda_files):
    urdf, path = panda_files
    a, b = from_urdf(urdf, locked_joints=PANDA_LOCKED), load_robot(path)
    assert a.joint_names == b.joint_names
    for field in ("q_min", "q_max", "tau_max", "gravity"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    q, qd, qdd = _states(a)
    expected = PinocchioOracle(a).rnea(q, qd, qdd)
    assert np.abs(PinocchioOracle(b).rnea(q, qd, qdd) - expected).max() <= 1e-12 * np.abs(expected).max()


@pytest.mark.slow  # derives the Panda twice: about 40 s
def test_the_panda_derived_from_mjcf_equals_the_urdf_derived_model(panda_files):
    urdf, path = panda_files
    a, b = from_urdf(urdf, locked_joints=PANDA_LOCKED), load_robot(path)
    model_a, model_b = derive_psdm(a), derive_psdm(b)
    assert model_a.n_base == model_b.n_base
    q, qd, qdd = _states(a)
    tau_a = model_a.inverse_dynamics(q, qd, qdd, model_a.base_parameters(a.nominal_dynamic_parameters()))
    tau_b = model_b.inverse_dynamics(q, qd, qdd, model_b.base_parameters(b.nominal_dynamic_parameters()))
    assert np.abs(tau_b - tau_a).max() <= 1e-9 * np.abs(tau_a).max()


def test_psdm_derive_takes_an_mjcf_file(arm, capsys):
    import json

    assert main(["derive", str(arm), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["robot"] == "arm4" and summary["max_rel_error_vs_pinocchio"] < 1e-12


def test_a_gripper_is_read_with_its_fingers_locked(tmp_path):
    """Menagerie's gripper pattern: refused as it is (tendon), read with --lock f1 f2 as MuJoCo's arm holding it."""
    path = tmp_path / "hand.xml"
    path.write_text(HAND)
    with pytest.raises(RobotFileError, match="fixed tendon 'split'.*lock the joints it couples"):
        load_robot(path)
    robot = load_robot(path, locked_joints=("f1", "f2"))
    assert robot.joint_names == ("j1", "j2", "j3", "j4")
    q, qd, qdd = _states(robot)
    expected = _mujoco_inverse(HAND, q, qd, qdd)
    ours = PinocchioOracle(robot).rnea(q, qd, qdd)
    assert np.abs(ours - expected).max() <= 1e-12 * np.abs(expected).max()
    # without the tendon and the equality the fingers are two free branches: a tree of 6 joints, MuJoCo's too
    free = re.sub(r"<tendon>.*?</equality>", "", HAND, flags=re.S).replace('tendon="split"', 'joint="f1"')
    path.with_name("fingers.xml").write_text(free)
    tree = load_robot(path.with_name("fingers.xml"))
    assert tree.joint_names == ("j1", "j2", "j3", "j4", "f1", "f2")
    q, qd, qdd = _states(tree)
    expected = _mujoco_inverse(free, q, qd, qdd)
    ours = PinocchioOracle(tree).rnea(q, qd, qdd)
    assert np.abs(ours - expected).max() <= 1e-12 * np.abs(expected).max()


def test_a_torso_with_two_arms_is_read_as_a_tree(tmp_path):
    """MuJoCo compiles the example URDF of a torso with two Pandas; its saved MJCF reads as the same 15-joint tree."""
    compiled = mujoco.MjModel.from_xml_path(str(EXAMPLES / "dual_arm_torso.urdf"))
    path = tmp_path / "torso.xml"
    mujoco.mj_saveLastXML(str(path), compiled)
    robot = load_robot(path)
    assert robot.n_dof == 15 and robot.joint_names[:2] == ("torso_joint", "left_panda_joint1")
    q, qd, qdd = _states(robot)
    expected = _mujoco_inverse(path.read_text(), q, qd, qdd)
    ours = PinocchioOracle(robot).rnea(q, qd, qdd)
    assert np.abs(ours - expected).max() <= 1e-12 * np.abs(expected).max()
