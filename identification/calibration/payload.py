"""End-effector torques of a known load (paper eqs. 16-17): the tau_ee term of every calibration step.

The load is an :class:`identification.data.payload.Payload` fixed to the flange (the last link
frame). :func:`payload_static_torque` is the paper's ``J(q)^T f_w`` with the wrench of eq. 17
(flange Jacobian from Pinocchio); :func:`payload_torque` adds the load's inertial torques by the
RNEA of a robot whose only body is the load (used where the robot moves fast).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from identification.data.payload import Payload
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.oracle import build_pinocchio_model, dh_transform
from psdm_casadi.robot import RobotDescription

__all__ = ["flange_placement", "payload_static_torque", "payload_torque"]


def _check(robot, payload, q, owner):
    if not isinstance(robot, RobotDescription):
        raise ParameterError(f"{owner}.robot must be a RobotDescription; got {type(robot).__name__}. Use load_robot().")
    if not isinstance(payload, Payload):
        raise ParameterError(
            f"{owner}.payload must be a Payload; got {type(payload).__name__}. Pass Payload(mass=...)."
        )
    payload.validate(robot.n_dof)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != robot.n_dof:
        raise ShapeError(
            f"{owner}.q must have shape (n_samples, {robot.n_dof}) to match RobotDescription.n_dof; got {q.shape}."
        )
    return q


def flange_placement(robot: RobotDescription) -> pin.SE3:
    """Placement of the last link frame (where a Payload sits) in the last joint frame of Pinocchio."""
    if robot.urdf_path is None and robot.convention == "standard":
        last = robot.joints[-1]
        return dh_transform(robot.convention, last.a, last.alpha, last.d, last.theta)
    return pin.SE3.Identity()


def _payload_only_model(robot, payload):
    parameters = np.zeros((robot.n_dof, 11))
    parameters[-1, :10] = payload.dynamic_parameters()
    return build_pinocchio_model(robot, parameters)


def payload_static_torque(robot: RobotDescription, payload: Payload, q) -> np.ndarray:
    """Joint torques [N m] holding a load against gravity: ``-J(q)^T f_w`` with eq. 17's wrench.

    ``f_w = [m_w g; (R(q) r_w) x (m_w g)]`` is the gravity wrench of the load about the flange origin
    in world axes and ``J`` the flange Jacobian in world-aligned axes, so the result is the torque
    the motors add when the load is attached (the paper's eq. 16 right-hand side).

    Parameters
    ----------
    robot : RobotDescription
    payload : Payload
        Mass [kg] and centre of mass in the flange frame [m].
    q : array, shape (n_samples, n_dof)

    Returns
    -------
    array, shape (n_samples, n_dof)

    Raises
    ------
    ParameterError, ShapeError
    """
    q = _check(robot, payload, q, "payload_static_torque")
    model = build_pinocchio_model(robot, np.zeros((robot.n_dof, 11)))
    frame = model.addFrame(pin.Frame("flange", robot.n_dof, 0, flange_placement(robot), pin.FrameType.OP_FRAME))
    data = model.createData()
    gravity = np.asarray(robot.gravity, dtype=float)
    force = payload.mass * gravity
    com = np.asarray(payload.com, dtype=float)
    out = np.empty_like(q)
    for k, qk in enumerate(q):
        jac = pin.computeFrameJacobian(model, data, qk, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        rotation = data.oMf[frame].rotation
        wrench = np.concatenate([force, np.cross(rotation @ com, force)])
        out[k] = -jac.T @ wrench
    return out


def payload_torque(robot: RobotDescription, payload: Payload, q, qd, qdd) -> np.ndarray:
    """Joint torques [N m] of a load with its inertia: RNEA of a robot whose only body is the load.

    Parameters
    ----------
    robot : RobotDescription
    payload : Payload
    q, qd, qdd : array, shape (n_samples, n_dof)

    Returns
    -------
    array, shape (n_samples, n_dof)
    """
    q = _check(robot, payload, q, "payload_torque")
    qd = np.atleast_2d(np.asarray(qd, dtype=float))
    qdd = np.atleast_2d(np.asarray(qdd, dtype=float))
    if qd.shape != q.shape or qdd.shape != q.shape:
        raise ShapeError(
            f"payload_torque.qd and qdd must have the shape of q {q.shape}; got {qd.shape} and {qdd.shape}."
        )
    model = _payload_only_model(robot, payload)
    data = model.createData()
    return np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])
