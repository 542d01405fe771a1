"""A sparse standard-parameter preimage of the base parameters: theta_std = T theta_b with Y_std T = Y_b.

Any base parameter vector is the image K theta_std of many standard ones; picking, for each base
parameter, one standard parameter of the joint frames (columns S of K with K[:, S] invertible)
gives a preimage with only n_base nonzero entries, exact for every theta_b. Evaluating the
rigid-body recursion on that preimage is how the recursive form computes the PSDM model: the
parameters the reduction removed cost nothing. The choice of S prefers parameters that keep the
recursion cheap (rotor and principal inertias first, masses last), as in Khalil's grouping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import DerivationError, ShapeError
from psdm_casadi.model import PSDMModel
from psdm_casadi.oracle import (
    N_LINK_PARAMETERS,
    N_PARAMETERS_PER_JOINT,
    build_pinocchio_model,
    link_to_joint_frame_maps,
)
from psdm_casadi.reduction import select_independent_rows

# Names of the 11 joint-frame parameters, and the order in which the selection prefers them (lower
# first): a rotor or zz inertia adds one product per use, a mass a whole force.
JOINT_PARAMETER_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz", "Im")
PREFERENCE = {"Im": 0, "Izz": 0, "Ixx": 1, "Ixy": 1, "Ixz": 1, "Iyz": 1, "mx": 2, "my": 2, "Iyy": 3, "mz": 4, "m": 5}
_CHECK_STATES = 40
_CHECK_RTOL = 1e-9
_SNAP_RTOL = 1e-13


@dataclass(frozen=True)
class StandardPreimage:
    """Joint-frame standard parameters from base parameters: ``theta_std = matrix @ theta_b``.

    Attributes
    ----------
    matrix : array, shape (11 n_dof, n_base)
        Rows in joint-major order of JOINT_PARAMETER_NAMES (Pinocchio's joint frames, inertia about
        the frame origin, then the rotor inertia).
    support : tuple of int
        The rows that can be nonzero.
    max_rel_error : float
        Largest relative difference of ``Y_std T`` from the model's regressor on the check states.
    """

    matrix: np.ndarray
    support: tuple
    max_rel_error: float

    @property
    def n_dof(self) -> int:
        return self.matrix.shape[0] // N_PARAMETERS_PER_JOINT

    def standard_parameters(self, theta) -> np.ndarray:
        """Joint-frame standard parameters (n_dof, 11) of numeric base parameters."""
        theta = np.asarray(theta, dtype=float).ravel()
        if theta.size != self.matrix.shape[1]:
            raise ShapeError(f"theta must have {self.matrix.shape[1]} base parameters; got {theta.size}.")
        return (self.matrix @ theta).reshape(self.n_dof, N_PARAMETERS_PER_JOINT)

    def support_names(self) -> list:
        """``["Izz5", "mx2", ...]``: the kept standard parameters, 1-based joint numbers."""
        return [
            f"{JOINT_PARAMETER_NAMES[r % N_PARAMETERS_PER_JOINT]}{r // N_PARAMETERS_PER_JOINT + 1}"
            for r in self.support
        ]


def _joint_frame_parameter_map(model: PSDMModel, robot: RobotDescription) -> np.ndarray:
    """K in joint-frame coordinates: theta_b = K_joint theta_joint."""
    n = robot.n_dof
    link_from_joint = np.zeros((N_PARAMETERS_PER_JOINT * n, N_PARAMETERS_PER_JOINT * n))
    for i, joint_from_link in enumerate(link_to_joint_frame_maps(robot)):
        block = slice(N_PARAMETERS_PER_JOINT * i, N_PARAMETERS_PER_JOINT * i + N_LINK_PARAMETERS)
        link_from_joint[block, block] = np.linalg.inv(joint_from_link)
        link_from_joint[
            N_PARAMETERS_PER_JOINT * i + N_LINK_PARAMETERS, N_PARAMETERS_PER_JOINT * i + N_LINK_PARAMETERS
        ] = 1.0
    k_joint = model.parameter_map @ link_from_joint
    k_joint[np.abs(k_joint) < 1e-12 * max(np.abs(k_joint).max(), 1.0)] = 0.0
    return k_joint


def _select_columns(k_joint: np.ndarray) -> list:
    """Greedy independent columns of K_joint in order of preference (cheap kinds first, distal joints first)."""
    order = np.array(
        sorted(
            range(k_joint.shape[1]),
            key=lambda c: (
                PREFERENCE[JOINT_PARAMETER_NAMES[c % N_PARAMETERS_PER_JOINT]],
                -(c // N_PARAMETERS_PER_JOINT),
            ),
        )
    )
    return [int(c) for c in order[select_independent_rows(k_joint[:, order].T, rtol=1e-9)]]


def _regressor_error(model: PSDMModel, robot: RobotDescription, matrix: np.ndarray, rng) -> float:
    """Relative difference of Pinocchio's joint-frame regressor times the preimage from the PSDM regressor."""
    pin_model = build_pinocchio_model(robot, np.zeros((robot.n_dof, N_PARAMETERS_PER_JOINT)))  # kinematics only
    data = pin_model.createData()
    n = robot.n_dof
    worst = 0.0
    for _ in range(_CHECK_STATES):
        q, qd, qdd = (rng.uniform(-np.pi, np.pi, n) for _ in range(3))
        link_columns = pin.computeJointTorqueRegressor(pin_model, data, q, qd, qdd)
        full = np.zeros((n, N_PARAMETERS_PER_JOINT * n))
        for i in range(n):
            full[:, N_PARAMETERS_PER_JOINT * i : N_PARAMETERS_PER_JOINT * i + N_LINK_PARAMETERS] = link_columns[
                :, N_LINK_PARAMETERS * i : N_LINK_PARAMETERS * (i + 1)
            ]
            full[i, N_PARAMETERS_PER_JOINT * i + N_LINK_PARAMETERS] = qdd[i]
        ours = model.regressor(q, qd, qdd)
        worst = max(worst, np.abs(full @ matrix - ours).max() / max(np.abs(ours).max(), 1e-300))
    return worst


def _snap_halves(matrix: np.ndarray) -> np.ndarray:
    """Entries within rounding error of a multiple of 1/2 set to it exactly.

    The inverse of K_joint[:, S] carries a few units of roundoff on entries that are exactly 1, -1 or 1/2
    (sums of inertias, parallel-axis terms); as 1.0000000000000002 each costs the recursion a product.
    """
    halves = np.round(2.0 * matrix) / 2.0
    close = np.abs(matrix - halves) <= _SNAP_RTOL * np.maximum(np.abs(matrix), 1.0)
    return np.where(close, halves, matrix)


def model_preimage(model: PSDMModel) -> StandardPreimage:
    """The preimage a model derived without monomial table carries (``model.chain``), exact by construction.

    Raises
    ------
    DerivationError
        When the model has a monomial table (its preimage needs the robot: :func:`standard_preimage`).
    """
    if model.chain is None:
        raise DerivationError(
            f"model {model.robot_name!r} has a monomial table and no preimage of its own. Call "
            "standard_preimage(model, robot) with the robot it was derived from."
        )
    matrix = np.array(model.chain.preimage)
    support = np.flatnonzero(np.abs(matrix).max(axis=1) > 0)
    error = float(model.metadata.get("relation_error", 0.0))
    return StandardPreimage(matrix=matrix, support=tuple(int(s) for s in support), max_rel_error=error)


def standard_preimage(model: PSDMModel, robot: RobotDescription, *, seed: int = 0) -> StandardPreimage:
    """The sparse joint-frame preimage of a model's base parameters, checked against Pinocchio.

    Parameters
    ----------
    model : PSDMModel
    robot : RobotDescription
        The robot the model was derived from (its kinematics and assumptions).
    seed : int
        Seed of the random states of the check.

    Returns
    -------
    StandardPreimage

    Raises
    ------
    DerivationError
        When no preimage reproduces the model's regressor (the model was derived from another robot).
    """
    if model.n_dof != robot.n_dof:
        raise DerivationError(
            f"robot {robot.name!r} has {robot.n_dof} joints but the model {model.robot_name!r} has {model.n_dof}. "
            "Pass the robot file the model was derived from."
        )
    rng = np.random.default_rng(seed)
    if model.chain is not None:  # derived without monomial table: the model states its own preimage
        preimage = model_preimage(model)
        error = _regressor_error(model, robot, preimage.matrix, rng)
        if not error <= _CHECK_RTOL:
            raise DerivationError(
                f"the model {model.robot_name!r} is not the PSDM model of robot {robot.name!r}: its preimage misses "
                f"the robot's regressor by {error:.2g} (relative). Pass the robot file the model was derived from."
            )
        return StandardPreimage(matrix=preimage.matrix, support=preimage.support, max_rel_error=error)
    k_joint = _joint_frame_parameter_map(model, robot)
    support = _select_columns(k_joint)
    matrix = np.zeros((k_joint.shape[1], model.n_base))
    if len(support) == model.n_base:
        matrix[support] = _snap_halves(np.linalg.inv(k_joint[:, support]))
        error = _regressor_error(model, robot, matrix, rng)
    else:
        error = np.inf
    if not error <= _CHECK_RTOL:  # assumptions not aligned with coordinates: the dense minimum-norm preimage
        matrix = _snap_halves(np.linalg.pinv(k_joint))
        support = [int(r) for r in np.flatnonzero(np.abs(matrix).max(axis=1) > 0)]
        error = _regressor_error(model, robot, matrix, rng)
    if not error <= _CHECK_RTOL:
        raise DerivationError(
            f"the model {model.robot_name!r} is not the PSDM model of robot {robot.name!r}: no standard-parameter "
            f"preimage reproduces its regressor (relative error {error:.2g}). Pass the robot file the model was "
            "derived from, or derive the model again."
        )
    matrix[np.abs(matrix) < 1e-13 * np.abs(matrix).max()] = 0.0
    return StandardPreimage(matrix=matrix, support=tuple(int(s) for s in support), max_rel_error=float(error))
