"""Base parameters from the regressor's column space at random states: the derivation whose cost is polynomial in n.

The base parameters of a robot are a basis of what its joint torques can see of the standard
parameters: the column space of Pinocchio's regressor stacked over states. A few random states per
free parameter reveal it exactly (the columns are analytic functions of the state, so a
combination that vanishes on generic random states vanishes everywhere), and a second set of fresh
states checks it. Each base parameter is chosen as one joint-frame standard parameter (cheap kinds
first, as in ``psdm_casadi.preimage``): its column of Y_b is Pinocchio's column of that parameter,
and the preimage T (Y_b = Y_std T) has one nonzero per base parameter. The gravity base parameters
are chosen first, from the gravity regressor, and the others are cleared of gravity, so that
``gravity_mask`` counts exactly the rank of the gravity regressor, as the paper's split requires.

Time and memory are polynomial: about 3 n_free / n_dof + 12 states of an O(n^2) regressor, and
dense linear algebra on a (states n_dof) x 11 n_dof matrix.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from psdm_casadi.chain_regressor import N_JOINT, N_LINK, stacked_standard_regressor
from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import DerivationError
from psdm_casadi.oracle import build_kinematic_model, link_to_joint_frame_maps
from psdm_casadi.preimage import JOINT_PARAMETER_NAMES, PREFERENCE
from psdm_casadi.reduction import select_independent_rows
from psdm_casadi.sampling import random_states

logger = logging.getLogger(__name__)

STATES_PER_FREE_PARAMETER = 3.0  # stacked regressor rows per free parameter (oversampling of the column space)
EXTRA_STATES = 12
RANK_RTOL = 1e-10  # singular values of the column-normalised stacked regressor below this are zero
INSIDE_RTOL = 1e-9  # a candidate column farther than this (relative) from the column space is outside it
ZERO_RTOL = 1e-12  # a column this small relative to the largest is round-off of a zero column
RELATION_RTOL = 1e-11  # largest accepted relative residual of the base-parameter relations on fresh states


@dataclass(frozen=True)
class ColumnSpaceBasis:
    """Base parameters of a robot found from its regressor's column space.

    Attributes
    ----------
    preimage : array, shape (11 n_dof, n_base)
        T, joint-frame standard parameters of unit base parameters (Y_b = Y_std T).
    base_map : array, shape (n_base, n_free)
        The base parameters as linear forms in the free standard parameters.
    gravity_mask : array of bool, shape (n_base,)
    relation_error : float
        Largest relative residual of ``Y_std F = Y_b base_map`` on fresh random states.
    n_states : int
        States sampled to find the column space.
    """

    preimage: np.ndarray
    base_map: np.ndarray
    gravity_mask: np.ndarray
    relation_error: float
    n_states: int


def joint_frame_free_basis(robot: RobotDescription, free_basis: np.ndarray) -> np.ndarray:
    """The free parameter basis (link-frame standard parameters) mapped to joint-frame ones, (11 n_dof, n_free)."""
    n = robot.n_dof
    lift = np.eye(N_JOINT * n)
    for i, block in enumerate(link_to_joint_frame_maps(robot)):
        lift[N_JOINT * i : N_JOINT * i + N_LINK, N_JOINT * i : N_JOINT * i + N_LINK] = block
    return lift @ free_basis


def _sample(model, robot: RobotDescription, n_states: int, rng, gravity_only: bool) -> np.ndarray:
    """Stacked joint-frame regressor (n_states n_dof, 11 n_dof) at random states (qd = qdd = 0 for gravity)."""
    q, qd, qdd = random_states(robot, n_states, rng)
    if gravity_only:
        qd, qdd = np.zeros_like(qd), np.zeros_like(qdd)
    stacked = stacked_standard_regressor(model, model.createData(), q, qd, qdd)
    return stacked.reshape(-1, stacked.shape[-1])


def _column_space(matrix: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column space of ``matrix`` (columns normalised first; rank by RANK_RTOL)."""
    norms = np.linalg.norm(_without_roundoff(matrix), axis=0)
    kept = matrix[:, norms > 0] / norms[norms > 0]
    if kept.shape[1] == 0:
        return np.zeros((matrix.shape[0], 0))
    u, s, _ = np.linalg.svd(kept, full_matrices=False)
    return u[:, s > RANK_RTOL * s[0]]


def _inside(columns: np.ndarray, space: np.ndarray) -> np.ndarray:
    """Boolean per nonzero column: it lies in the span of ``space`` (orthonormal)."""
    columns = _without_roundoff(columns)
    norms = np.linalg.norm(columns, axis=0)
    residual = np.linalg.norm(columns - space @ (space.T @ columns), axis=0)
    return (norms > 0) & (residual <= INSIDE_RTOL * norms)


def _without_roundoff(columns: np.ndarray) -> np.ndarray:
    """Columns whose norm is round-off (below ZERO_RTOL times the largest) set to exactly zero."""
    norms = np.linalg.norm(columns, axis=0)
    return np.where(norms > ZERO_RTOL * max(norms.max(initial=0.0), 1e-300), columns, 0.0)


def _select(candidates: np.ndarray, w_full, w_gravity, rank: int, rank_gravity: int):
    """(gravity indices, other indices) of candidate preimage columns, or None when too few are usable."""
    full, gravity = _without_roundoff(w_full @ candidates), _without_roundoff(w_gravity @ candidates)
    gravity_picks = select_independent_rows(gravity.T, rtol=INSIDE_RTOL)[:rank_gravity]
    if gravity_picks.size < rank_gravity:
        return None
    rest = np.setdiff1d(np.arange(candidates.shape[1]), gravity_picks)
    order = np.concatenate([gravity_picks, rest])
    picks = order[select_independent_rows(full[:, order].T, rtol=INSIDE_RTOL)]
    if picks.size < rank or not np.array_equal(picks[:rank_gravity], gravity_picks):
        return None
    return gravity_picks, picks[rank_gravity:rank]


def _preimage(candidates, picks, w_gravity) -> np.ndarray:
    """T with the gravity columns first and the other columns cleared of their gravity part."""
    gravity_picks, other_picks = picks
    t_gravity, t_other = candidates[:, gravity_picks], candidates[:, other_picks]
    if gravity_picks.size and other_picks.size:
        coefficients = np.linalg.lstsq(w_gravity @ t_gravity, w_gravity @ t_other, rcond=None)[0]
        coefficients[np.abs(coefficients) < 1e-13 * max(np.abs(coefficients).max(), 1.0)] = 0.0
        t_other = t_other - t_gravity @ coefficients
    return np.concatenate([t_gravity, t_other], axis=1)


def _preference_order(n_dof: int) -> np.ndarray:
    """Joint-frame parameter indices, cheap kinds first, distal joints first (as the preimage's selection)."""
    return np.array(
        sorted(
            range(N_JOINT * n_dof),
            key=lambda c: (PREFERENCE[JOINT_PARAMETER_NAMES[c % N_JOINT]], -(c // N_JOINT)),
        )
    )


def _solve_relations(y_base: np.ndarray, y_free: np.ndarray) -> np.ndarray:
    """K with y_free = y_base K, by least squares on column-normalised y_base."""
    scale = np.linalg.norm(y_base, axis=0)
    solution = np.linalg.lstsq(y_base / scale, y_free, rcond=None)[0] / scale[:, None]
    solution[np.abs(solution) < 1e-12 * np.abs(solution).max()] = 0.0
    return solution


def column_space_basis(robot: RobotDescription, free_basis: np.ndarray, rng: np.random.Generator) -> ColumnSpaceBasis:
    """Base parameters, their preimage and their relations from the regressor sampled at random states.

    Parameters
    ----------
    robot : RobotDescription
        A serial chain or a tree (URDF); revolute and prismatic joints.
    free_basis : array, shape (11 n_dof, n_free)
        The standard parameters the robot's assumptions leave free (``sampling.free_parameter_basis``).
    rng : numpy.random.Generator

    Returns
    -------
    ColumnSpaceBasis

    Raises
    ------
    DerivationError
        When the relations found do not hold on fresh states (the sampling missed a direction).
    """
    n = robot.n_dof
    model, _ = build_kinematic_model(robot)
    model.gravity.linear = np.asarray(robot.gravity, dtype=float)
    free = joint_frame_free_basis(robot, free_basis)
    n_states = int(np.ceil(STATES_PER_FREE_PARAMETER * free.shape[1] / n)) + EXTRA_STATES
    w_full = _sample(model, robot, n_states, rng, gravity_only=False)
    w_gravity = _sample(model, robot, n_states, rng, gravity_only=True)
    space = _column_space(w_full @ free)
    rank, rank_gravity = space.shape[1], _column_space(w_gravity @ free).shape[1]
    if rank == 0:
        raise DerivationError(f"robot {robot.name!r} produced no dynamics at all: every link is massless.")
    order = _preference_order(n)
    units = np.eye(N_JOINT * n)[:, order]
    units = units[:, _inside(w_full @ units, space)]  # joint-frame parameters the assumptions let through
    picks = _select(units, w_full, w_gravity, rank, rank_gravity)
    candidates = units
    if picks is None:  # assumptions not aligned with joint-frame coordinates: the free directions themselves
        candidates, picks = free, _select(free, w_full, w_gravity, rank, rank_gravity)
    if picks is None:
        raise DerivationError(
            f"no {rank} independent base parameters of robot {robot.name!r} found among its free parameters "
            f"(gravity rank {rank_gravity}). Report this robot file."
        )
    preimage = _preimage(candidates, picks, w_gravity)
    base_map = _solve_relations(w_full @ preimage, w_full @ free)
    check = _sample(model, robot, n_states, rng, gravity_only=False)
    reference = check @ free
    error = float(np.abs(check @ preimage @ base_map - reference).max() / np.abs(reference).max())
    logger.debug("column space of %s: %d states, rank %d (%d gravity)", robot.name, n_states, rank, rank_gravity)
    if not error <= RELATION_RTOL:
        raise DerivationError(
            f"the base parameters of robot {robot.name!r} found on {n_states} random states miss the regressor on "
            f"fresh states by {error:.3g} (relative, above {RELATION_RTOL:g}). Derive again with another seed."
        )
    gravity_mask = np.arange(rank) < rank_gravity
    return ColumnSpaceBasis(preimage, base_map, gravity_mask, error, n_states)
