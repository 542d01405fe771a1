"""The direct CasADi SX Newton-Euler peer against Pinocchio's rnea, crba and aba."""

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from codegen.peers.rnea_sx import build_rnea_functions, cholesky_solve_sx
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import build_pinocchio_model
from psdm_casadi.robot import from_urdf
from tests.conftest import example_robot_urdf


def _compare(model, rng, n_states=5):
    peer = build_rnea_functions(model)
    data = model.createData()
    n = model.nv
    for _ in range(n_states):
        q, qd, qdd = rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n)
        tau_ref = pin.rnea(model, data, q, qd, qdd)
        tau = np.array(peer.inverse_dynamics(q, qd, qdd)).ravel()
        np.testing.assert_allclose(tau, tau_ref, rtol=1e-10, atol=1e-10 * np.abs(tau_ref).max())
        mass_ref = pin.crba(model, data, q)
        mass_ref = np.triu(mass_ref) + np.triu(mass_ref, 1).T
        np.testing.assert_allclose(np.array(peer.mass_matrix(q)), mass_ref, rtol=1e-10, atol=1e-12)
        torque = rng.uniform(-20, 20, n)
        qdd_ref = pin.aba(model, data, q, qd, torque)
        qdd_fd = np.array(peer.forward_dynamics(q, qd, torque)).ravel()
        np.testing.assert_allclose(qdd_fd, qdd_ref, rtol=1e-10, atol=1e-10 * np.abs(qdd_ref).max())


def test_rnea_sx_matches_pinocchio_denso(denso, rng):
    model = build_pinocchio_model(denso)
    assert np.any(model.armature > 0) and np.linalg.norm(model.gravity.linear) > 9  # armature and gravity exercised
    _compare(model, rng)


def test_rnea_sx_matches_pinocchio_panda(rng):
    robot = from_urdf(
        example_robot_urdf("panda_description/urdf/panda.urdf"),
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )
    _compare(build_pinocchio_model(robot), rng)


def test_rnea_sx_unaligned_and_prismatic_joints(rng):
    """A branch-free chain mixing RX, PY, revolute-unaligned and prismatic-unaligned joints."""
    model = pin.Model()
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    joints = [
        pin.JointModelRX(),
        pin.JointModelPY(),
        pin.JointModelRevoluteUnaligned(axis),
        pin.JointModelPrismaticUnaligned(axis[::-1].copy()),
    ]
    parent = 0
    for k, joint in enumerate(joints):
        placement = pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-1, 1, 3)), rng.uniform(-0.3, 0.3, 3))
        parent = model.addJoint(parent, joint, placement, f"j{k}")
        model.inertias[parent] = pin.Inertia.Random()
    model.armature = rng.uniform(0.0, 0.1, model.nv)
    model.gravity.linear = np.array([0.3, -1.0, -9.81])
    _compare(model, rng)


def test_rnea_sx_rejects_spherical_joint():
    model = pin.Model()
    model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(ParameterError, match="nq == nv"):
        build_rnea_functions(model)
    model = pin.Model()
    model.addJoint(0, pin.JointModelTranslation(), pin.SE3.Identity(), "slider3")
    with pytest.raises(ParameterError, match="ball|slider3"):
        build_rnea_functions(model)


def test_cholesky_solve_sx_matches_numpy(rng):
    a = rng.normal(size=(5, 5))
    spd = a @ a.T + 5 * np.eye(5)
    b = rng.normal(size=5)
    m, r = ca.SX.sym("m", 5, 5), ca.SX.sym("r", 5)
    f = ca.Function("solve", [m, r], [cholesky_solve_sx(m, r)])
    np.testing.assert_allclose(np.array(f(spd, b)).ravel(), np.linalg.solve(spd, b), rtol=1e-12)
