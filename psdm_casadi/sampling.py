"""Seeded samples for the derivation and its checks: joint states and inertial parameters.

Every function takes a ``numpy.random.Generator``; nothing here touches a global RNG.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.description import (
    PHYSICAL_PARAMETER_NAMES,
    RobotDescription,
    parse_parameter_name,
    physical_to_dynamic,
)
from psdm_casadi.oracle import N_PARAMETERS_PER_JOINT


def random_states(robot: RobotDescription, n_samples: int, rng: np.random.Generator):
    """Random (q, qd, qdd), each (n_samples, n_dof): q over the joint range, qd and qdd over +-limits."""
    n = robot.n_dof
    q = rng.uniform(robot.q_min, robot.q_max, size=(n_samples, n))
    qd = rng.uniform(-1.0, 1.0, size=(n_samples, n)) * robot.qd_max
    qdd = rng.uniform(-1.0, 1.0, size=(n_samples, n)) * robot.qdd_max
    return q, qd, qdd


def zero_parameter_mask(robot: RobotDescription) -> np.ndarray:
    """Boolean (n_dof, 10) mask of the physical parameters (m, r, I_com) forced to zero."""
    mask = np.zeros((robot.n_dof, len(PHYSICAL_PARAMETER_NAMES)), dtype=bool)
    for link in robot.massless_links:
        mask[link - 1, :] = True
    for name in robot.zero_parameters:
        base, link = parse_parameter_name(name, robot.n_dof)
        mask[link - 1, PHYSICAL_PARAMETER_NAMES.index(base)] = True
    return mask


def random_standard_parameters(robot: RobotDescription, rng: np.random.Generator, *, physical=True) -> np.ndarray:
    """Random standard parameters (n_dof, 11) that respect the robot's modelling assumptions.

    Physical parameters (m, r, I about the COM) are drawn with the forced zeros applied, then mapped
    to the linear (m, m r, I about the origin) form. With ``physical=True`` each inertia is positive
    definite about its COM; rotor inertias are drawn only on joints with ``drive_inertia``.
    """
    zero = zero_parameter_mask(robot)
    out = np.zeros((robot.n_dof, N_PARAMETERS_PER_JOINT))
    for i in range(robot.n_dof):
        x = np.empty(len(PHYSICAL_PARAMETER_NAMES))
        x[0] = rng.uniform(0.5, 5.0)
        x[1:4] = rng.uniform(-0.3, 0.3, size=3)
        if physical:
            principal = rng.uniform(0.01, 0.2, size=3)
            principal[2] = min(principal[2], principal[0] + principal[1])  # triangle inequality
            rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            inertia = rotation @ np.diag(principal) @ rotation.T
        else:
            inertia = rng.normal(size=(3, 3)) * 0.1
            inertia = inertia + inertia.T
        x[4:] = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
        x[zero[i]] = 0.0
        ixx, iyy, izz, ixy, ixz, iyz = x[4:]
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        out[i, :10] = physical_to_dynamic(x[0], x[1:4], inertia)
        out[i, 10] = rng.uniform(0.05, 1.0) if robot.drive_inertia[i] else 0.0
    return out


def free_parameter_basis(robot: RobotDescription, rng: np.random.Generator, n_draws=None, rtol=1e-10):
    """Orthonormal basis S (11 n_dof, r) of the standard parameters the assumptions leave free.

    Forcing a COM-frame quantity to zero (e.g. ``Ixz4``) is a nonlinear constraint on the linear
    parameters; the span of many random admissible parameter vectors is what the dynamics can see.
    When that span is coordinate-aligned (the usual case) S is a column selection of the identity.
    """
    n_std = robot.n_dof * N_PARAMETERS_PER_JOINT
    n_draws = n_draws or 3 * n_std
    draws = np.array([random_standard_parameters(robot, rng, physical=False).ravel() for _ in range(n_draws)])
    scale = np.abs(draws).max(axis=0)
    free = scale > rtol * max(scale.max(), 1.0)
    _, sing, vt = np.linalg.svd(draws[:, free], full_matrices=False)
    rank = int(np.sum(sing > rtol * sing[0]))
    if rank == int(free.sum()):
        return np.eye(n_std)[:, free]
    basis = np.zeros((n_std, rank))
    basis[free] = vt[:rank].T
    return basis
