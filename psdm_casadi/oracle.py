"""Pinocchio's rnea/crba/aba wrapped as the sampling oracle of the derivation and the reference of tests.

The oracle is an implementation we did not write: the derivation samples it, the tests compare
against it, and the virtual robot integrates its forward dynamics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ShapeError
from psdm_casadi.urdf import load_urdf_model

N_LINK_PARAMETERS = 10  # m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (Pinocchio order, about the frame origin)
N_PARAMETERS_PER_JOINT = 11  # ... plus the rotor inertia Im
LINK_PARAMETER_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def standard_parameter_names(n_dof: int) -> list:
    """Names of the standard parameter vector, joint-major: ``m1, mx1, ..., Izz1, Im1, m2, ...``."""
    return [f"{name}{i + 1}" for i in range(n_dof) for name in (*LINK_PARAMETER_NAMES, "Im")]


def dh_transform(convention: str, a: float, alpha: float, d: float, theta: float) -> pin.SE3:
    """The constant DH placement of one row (standard: Rz Tz Tx Rx; modified: Rx Tx Rz Tz)."""

    def rot(axis, angle):
        c, s = np.cos(angle), np.sin(angle)
        if axis == "z":
            return pin.SE3(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.zeros(3))
        return pin.SE3(np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]]), np.zeros(3))

    def trans(axis, length):
        p = np.zeros(3)
        p["xyz".index(axis)] = length
        return pin.SE3(np.eye(3), p)

    if convention == "standard":
        return rot("z", theta) * trans("z", d) * trans("x", a) * rot("x", alpha)
    return rot("x", alpha) * trans("x", a) * rot("z", theta) * trans("z", d)


def build_kinematic_model(robot: RobotDescription) -> tuple[pin.Model, list]:
    """The robot's kinematic chain as a Pinocchio model with zero inertia (the derivation samples it).

    Parameters
    ----------
    robot : RobotDescription
        DH rows, or a URDF when ``robot.urdf_path`` is set.

    Returns
    -------
    model : pinocchio.Model
        One joint per degree of freedom, every inertia zero.
    link_placements : list of pinocchio.SE3, length n_dof
        Per joint, the placement of the link frame (where the robot's inertial parameters are
        given) in the joint frame: the DH row for the standard convention, identity otherwise.
    """
    if robot.urdf_path is not None:
        model = load_urdf_model(Path(robot.urdf_path), robot.locked_joints)
        for jid in range(1, model.njoints):
            model.inertias[jid] = pin.Inertia.Zero()
        return model, [pin.SE3.Identity()] * robot.n_dof
    model = pin.Model()
    model.name = robot.name
    parent, placement = 0, pin.SE3.Identity()
    link_placements = []
    for joint in robot.joints:
        row = dh_transform(robot.convention, joint.a, joint.alpha, joint.d, joint.theta)
        if robot.convention == "modified":
            joint_placement, link_placement = placement * row, pin.SE3.Identity()
        else:
            joint_placement, link_placement = placement, row
        jmodel = pin.JointModelRZ() if joint.is_revolute else pin.JointModelPZ()
        parent = model.addJoint(parent, jmodel, joint_placement, joint.name)
        link_placements.append(link_placement)
        placement = row if robot.convention == "standard" else pin.SE3.Identity()
    return model, link_placements


def link_to_joint_frame_maps(robot: RobotDescription) -> np.ndarray:
    """Linear maps taking link-frame dynamic parameters to joint-frame ones, shape (n_dof, 10, 10).

    The dynamic parameters (m, m r, I about the origin) transform linearly under a rigid placement;
    the map is recovered column by column from Pinocchio's ``Inertia.se3Action``.
    """
    _, placements = build_kinematic_model(robot)
    base = np.array([1.0, 0, 0, 0, 1.0, 0, 1.0, 0, 0, 1.0])
    maps = np.empty((robot.n_dof, N_LINK_PARAMETERS, N_LINK_PARAMETERS))
    for i, placement in enumerate(placements):
        origin = placement.act(pin.Inertia.FromDynamicParameters(base)).toDynamicParameters()
        for k in range(N_LINK_PARAMETERS):
            moved = placement.act(pin.Inertia.FromDynamicParameters(base + np.eye(N_LINK_PARAMETERS)[k]))
            maps[i, :, k] = moved.toDynamicParameters() - origin
    return maps


def inertia_from_dynamic_parameters(params) -> pin.Inertia:
    """A Pinocchio inertia from (m, m r, I about the origin); a massless body keeps its rotational inertia."""
    params = np.asarray(params, dtype=float)
    if params[0] > 1e-12 * max(1.0, np.abs(params).max()):
        return pin.Inertia.FromDynamicParameters(params)
    _, _, _, _, ixx, ixy, iyy, ixz, iyz, izz = params
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    return pin.Inertia(0.0, np.zeros(3), inertia)


def build_pinocchio_model(robot: RobotDescription, parameters=None) -> pin.Model:
    """A Pinocchio model of the robot with the given (or nominal) inertial parameters.

    Parameters
    ----------
    robot : RobotDescription
    parameters : array, shape (n_dof, 11), optional
        Standard parameters per joint (10 link-frame dynamic parameters, then Im). Defaults to the
        robot's nominal ones.
    """
    params = robot.nominal_dynamic_parameters() if parameters is None else np.asarray(parameters, dtype=float)
    if params.shape != (robot.n_dof, N_PARAMETERS_PER_JOINT):
        raise ShapeError(
            f"parameters must have shape ({robot.n_dof}, {N_PARAMETERS_PER_JOINT}) "
            "(10 link parameters + Im per joint); "
            f"got {params.shape}."
        )
    model, _ = build_kinematic_model(robot)
    maps = link_to_joint_frame_maps(robot)
    for i in range(robot.n_dof):
        joint_frame = maps[i] @ params[i, :N_LINK_PARAMETERS]
        model.inertias[i + 1] = inertia_from_dynamic_parameters(joint_frame)
    model.armature = params[:, N_LINK_PARAMETERS].copy()
    model.gravity.linear = robot.gravity.copy()
    return model


def mass_matrix(model: pin.Model, data, q) -> np.ndarray:
    """The symmetric mass matrix of ``model`` at ``q`` (``pin.crba`` fills the upper triangle only)."""
    m = pin.crba(model, data, q)
    return np.triu(m) + np.triu(m, 1).T


def _batch(x, n_dof, name):
    arr = np.asarray(x, dtype=float)
    single = arr.ndim == 1
    arr = np.atleast_2d(arr)
    if arr.shape[1] != n_dof:
        raise ShapeError(f"{name} must have shape (n_samples, {n_dof}) or ({n_dof},); got {np.shape(x)}.")
    return arr, single


class PinocchioOracle:
    """Rigid-body dynamics of a robot with given inertial parameters, by Pinocchio.

    Parameters
    ----------
    robot : RobotDescription
    parameters : array, shape (n_dof, 11), optional
        Standard parameters (see ``build_pinocchio_model``); nominal ones by default.

    Examples
    --------
    >>> oracle = PinocchioOracle(robot)            # doctest: +SKIP
    >>> tau = oracle.rnea(q, qd, qdd)              # (n_samples, n_dof)
    """

    def __init__(self, robot: RobotDescription, parameters=None):
        self.robot = robot
        self.model = build_pinocchio_model(robot, parameters)
        self.data = self.model.createData()

    def rnea(self, q, qd, qdd) -> np.ndarray:
        """Inverse dynamics tau = M qdd + h [N m], rotor inertia included."""
        n = self.robot.n_dof
        (q, single), (qd, _), (qdd, _) = _batch(q, n, "q"), _batch(qd, n, "qd"), _batch(qdd, n, "qdd")
        out = np.array([pin.rnea(self.model, self.data, a, b, c) for a, b, c in zip(q, qd, qdd)])
        return out[0] if single else out

    def crba(self, q) -> np.ndarray:
        """Mass matrix (symmetric, rotor inertia included), shape (n_dof, n_dof) or (n_samples, n, n)."""
        q, single = _batch(q, self.robot.n_dof, "q")
        out = []
        out = np.array([mass_matrix(self.model, self.data, qi) for qi in q])
        return out[0] if single else out

    def aba(self, q, qd, tau) -> np.ndarray:
        """Forward dynamics qdd [rad/s^2]."""
        n = self.robot.n_dof
        (q, single), (qd, _), (tau, _) = _batch(q, n, "q"), _batch(qd, n, "qd"), _batch(tau, n, "tau")
        out = np.array([pin.aba(self.model, self.data, a, b, c) for a, b, c in zip(q, qd, tau)])
        return out[0] if single else out

    def gravity(self, q) -> np.ndarray:
        """Gravity torque G(q) [N m]."""
        q, single = _batch(q, self.robot.n_dof, "q")
        out = np.array([pin.computeGeneralizedGravity(self.model, self.data, qi) for qi in q])
        return out[0] if single else out
