"""``--lock JOINT=VALUE``: URDF joints fixed at a position, the same on every command that loads a robot.

The oracle is Pinocchio's rnea of the *full* URDF model with the locked joint held at its value (zero
velocity and acceleration), which the reduced model and the PSDM model derived from it must reproduce.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from psdm_casadi.cli import build_parser, main
from psdm_casadi.cli.checks import load_locked_robot, parse_locks
from psdm_casadi.errors import ParameterError, RobotFileError
from psdm_casadi.model import load_model
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import from_urdf, load_robot
from psdm_casadi.symbolic import build_functions
from tests.catalogue.harness import BadInput, check_refusal
from tests.conftest import example_robot_urdf

UR5 = "ur_description/urdf/ur5_robot.urdf"
PANDA = "panda_description/urdf/panda.urdf"


def full_rnea(urdf, robot, locked: dict, q, qd, qdd) -> np.ndarray:
    """rnea of the whole URDF with the locked joints at their values, on the robot's joints."""
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity.linear = robot.gravity
    data = model.createData()
    keep = [model.joints[model.getJointId(name)].idx_q for name in robot.joint_names]
    out = []
    for x, v, a in zip(q, qd, qdd):
        big_q, big_v, big_a = pin.neutral(model), np.zeros(model.nv), np.zeros(model.nv)
        for name, value in locked.items():
            big_q[model.joints[model.getJointId(name)].idx_q] = value
        big_q[keep], big_v[keep], big_a[keep] = x, v, a
        out.append(pin.rnea(model, data, big_q, big_v, big_a)[keep])
    return np.array(out)


def states(robot, rng, n=20):
    return [rng.uniform(-1, 1, size=(n, robot.n_dof)) for _ in range(3)]


def test_panda_fingers_locked_open(rng):
    urdf = example_robot_urdf(PANDA)
    locks = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
    robot = load_locked_robot(urdf, [f"{name}={value}" for name, value in locks.items()])
    assert robot.n_dof == 7 and robot.locked_joints == tuple(locks.items())
    q, qd, qdd = states(robot, rng)
    expected = full_rnea(urdf, robot, locks, q, qd, qdd)
    np.testing.assert_allclose(PinocchioOracle(robot).rnea(q, qd, qdd), expected, rtol=1e-12, atol=1e-12)
    # the fingers' masses now sit 2 cm off the axis: the reduced model differs from the one locked closed
    closed = PinocchioOracle(from_urdf(urdf, locked_joints=list(locks))).rnea(q, qd, qdd)
    assert np.max(np.abs(closed - expected)) > 1e-6


def test_derive_locks_a_ur5_elbow_at_a_value(tmp_path, capsys, rng):
    urdf = example_robot_urdf(UR5)
    out = tmp_path / "ur5.npz"
    assert main(["derive", str(urdf), "--lock", "elbow_joint=0.7", "-o", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["max_rel_error_vs_pinocchio"] < 1e-9
    robot = load_locked_robot(urdf, ["elbow_joint=0.7"])
    assert robot.joint_names == ("shoulder_pan_joint", "shoulder_lift_joint", "wrist_1_joint", "wrist_2_joint",
                                 "wrist_3_joint")  # fmt: skip
    model = load_model(out)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    fns = build_functions(model)
    q, qd, qdd = states(robot, rng)
    ours = np.array([np.asarray(fns.inverse_dynamics(*x, theta)).ravel() for x in zip(q, qd, qdd)])
    expected = full_rnea(urdf, robot, {"elbow_joint": 0.7}, q, qd, qdd)
    assert np.max(np.abs(ours - expected)) / np.max(np.abs(expected)) < 1e-9


def test_robot_file_with_urdf_table_takes_further_locks(tmp_path):
    urdf = example_robot_urdf(PANDA)
    toml = tmp_path / "panda.toml"
    toml.write_text(f'name = "panda"\n[urdf]\npath = "{urdf}"\nlocked_joints = ["panda_finger_joint1"]\n')
    robot = load_robot(toml, locked_joints={"panda_finger_joint2": 0.01, "panda_joint7": 0.5})
    assert robot.n_dof == 6 and robot.name == "panda"
    assert robot.locked_joints == (("panda_finger_joint1", 0.0), ("panda_finger_joint2", 0.01), ("panda_joint7", 0.5))
    with pytest.raises(RobotFileError, match="joints can be locked only on a robot read from a URDF"):
        load_robot("denso_vs6556g", locked_joints=["J6"])


def test_parse_locks():
    assert parse_locks(["a=0.5", "b", " c = -1e-2 "]) == {"a": 0.5, "b": 0.0, "c": -0.01}
    for items, match in (
        (["=1"], "--lock must be JOINT or JOINT=VALUE"),
        (["a=x"], "--lock a must be locked at a finite number.*'x'"),
        (["a=nan"], "finite number"),
        (["a", "a=1"], "names 'a' twice"),
    ):
        with pytest.raises(ParameterError, match=match):
            parse_locks(items)


COMMANDS = [
    ["derive", "R"],
    ["excite", "R"],
    ["experiment", "gravity", "R"],
    ["simulate", "R", "--experiment", "gravity", "--out", "o"],
    ["identify", "R", "--data", "d", "--out", "o"],
    ["diagnose", "R", "--train", "a", "--validate", "b"],
    ["codegen", "R", "--out", "o"],
]


@pytest.mark.parametrize("argv", COMMANDS, ids=[argv[0] for argv in COMMANDS])
def test_every_command_that_loads_a_robot_takes_lock(argv):
    args = build_parser().parse_args([*argv, "--lock", "j1=0.5", "--lock", "j2"])
    assert args.lock == ["j1=0.5", "j2"]


def refusal(name, argv, *expect, code=2):
    return BadInput(name, tuple(argv), expect=expect, exit_code=code)


def test_lock_refusals(tmp_path, capsys, monkeypatch):
    urdf = str(example_robot_urdf(UR5))
    cases = [
        refusal("unknown joint", ["derive", urdf, "--lock", "elbow=1"], "--lock elbow", "elbow_joint", "spelling"),
        refusal("DH robot", ["derive", "denso_vs6556g", "--lock", "J6=0.1"], "--lock", "dh rows", "urdf"),
        refusal(
            "DH robot, diagnose",
            ["diagnose", "denso_vs6556g", "--train", "a.csv", "--validate", "b.csv", "--lock", "J6"],
            "--lock",
            "dh rows",
        ),  # fmt: skip
        refusal("not a number", ["derive", urdf, "--lock", "elbow_joint=1,5"], "--lock elbow_joint", "'1,5'"),
        refusal("outside limits", ["derive", urdf, "--lock", "elbow_joint=7"], "elbow_joint", "within its limits"),
    ]
    for case in cases:
        check_refusal(case, tmp_path, capsys, monkeypatch)
