"""The regressor check: refuse a regression whose identified parameters the recordings do not excite.

Shared by the calibration steps, the refinement and the diagnosis (with the per-joint checks of
:mod:`identification.data.excitation_check`, whose ``ExcitationThresholds.max_condition`` documents the
bound): the weighted regressor, its columns scaled to unit norm, must have full column rank and a
condition number below the bound, else an :class:`~psdm_casadi.errors.InsufficientExcitationError` names
the columns spanning its weak directions and the joints that would excite them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.data.excitation_check import format_fix, joint_labels
from psdm_casadi.errors import InsufficientExcitationError, ParameterError

__all__ = ["RegressorCheck", "check_regressor", "base_parameter_joints"]

_MAX_NAMED = 10  # most columns a message lists
# a column whose norm is below this fraction of the largest column's is not excited: rounding noise (e.g. sin(pi)
# of a still joint) must not pass as a column after scaling; designed experiments give ratios above 1e-4
ZERO_COLUMN = 1e-10


@dataclass(frozen=True)
class RegressorCheck:
    """Rank and condition number (after column scaling) of a regressor that passed :func:`check_regressor`."""

    rank: int
    condition: float


def base_parameter_joints(model) -> tuple:
    """Per base parameter of ``model`` (a PSDMModel), the joints (0-based) whose links' standard parameters it
    holds: the joints whose motion excites it (with the joints before them)."""
    parameter_map = np.asarray(model.parameter_map, dtype=float)
    n_dof = parameter_map.shape[1] // 11
    links = np.abs(parameter_map).reshape(parameter_map.shape[0], n_dof, 11).max(axis=2) > 1e-12
    return tuple(tuple(int(j) for j in np.flatnonzero(row)) for row in links)


def _weak_columns(vt: np.ndarray, singular: np.ndarray, max_condition: float) -> np.ndarray:
    """Columns spanning the directions with singular values below ``s_max / max_condition`` (at least the
    smallest), most involved first."""
    weak = singular < singular[0] / max_condition
    weak[-1] = True
    loading = np.sum(vt[weak] ** 2, axis=0)
    order = np.argsort(-loading, kind="stable")
    return order[loading[order] >= 0.01 * loading[order[0]]]


def check_regressor(
    matrix,
    weights=None,
    *,
    names,
    owner: str,
    source: str,
    fix: str,
    column_joints=None,
    max_condition: float = 1e8,
    robot=None,
) -> RegressorCheck:
    """Raise unless the weighted regressor has full column rank and a condition number <= ``max_condition``.

    The rows with weight > 0 are scaled by ``sqrt(weight)`` and every column to unit norm (as the least
    squares of :mod:`identification.calibration.estimator` solve it), so the condition number measures
    excitation, not units.

    Parameters
    ----------
    matrix : array, shape (n_rows, n_columns)
    weights : array, shape (n_rows,), optional
        Row weights (default all ones; 0 drops a row).
    names : sequence of str, length n_columns
        Parameter names of the columns, for the message.
    owner : str
        The estimator, e.g. ``"InertialIdentifier"``.
    source : str
        The recordings the rows come from, e.g. ``"excitation.csv"``.
    fix : str
        What to record instead; ``{joints}`` and ``{k}`` are replaced by the joints of the unexcited columns.
    column_joints : sequence of sequences of int, optional
        Per column the joints (0-based) whose motion excites it.
    max_condition : float
        See :class:`ExcitationThresholds`.
    robot : RobotDescription, optional
        Joint names for the message.

    Returns
    -------
    RegressorCheck

    Raises
    ------
    InsufficientExcitationError
        Naming the unexcited columns, their joints, the rank and condition number, and ``fix``.

    Examples
    --------
    >>> a = np.column_stack([np.ones(4), np.arange(4.0)])
    >>> check_regressor(a, names=["offset", "slope"], owner="fit", source="x", fix="").rank
    2
    """
    a = np.asarray(matrix, dtype=float)
    names = [str(n) for n in names]
    if a.ndim != 2 or len(names) != a.shape[1]:
        raise ParameterError(
            f"check_regressor.names must name the {a.shape[-1]} columns of a 2-D matrix; got {len(names)} names "
            f"for shape {a.shape}."
        )
    w = np.ones(a.shape[0]) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    keep = w > 0
    aw = a[keep] * np.sqrt(w[keep])[:, None]
    n_cols = a.shape[1]
    scale = np.linalg.norm(aw, axis=0) if aw.size else np.zeros(n_cols)
    zero = ~(scale > ZERO_COLUMN * float(scale.max(initial=0.0))) | (scale == 0)
    if aw.shape[0] < n_cols:
        weak, rank = np.arange(n_cols), int(aw.shape[0])
        got = f"{aw.shape[0]} rows with weight > 0 for {n_cols} columns"
    elif zero.any():
        weak, rank = np.flatnonzero(zero), int(n_cols - zero.sum())
        got = f"columns that are zero on every row with weight > 0 (rank at most {rank} of {n_cols})"
    else:
        singular, vt = np.linalg.svd(aw / scale, full_matrices=False)[1:]
        condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
        rank = int(np.sum(singular > singular[0] * max(aw.shape) * np.finfo(float).eps))
        if condition <= max_condition and rank == n_cols:
            return RegressorCheck(rank, condition)
        weak = _weak_columns(vt, singular, max_condition)
        got = f"rank {rank} of {n_cols}, condition number {condition:.3g}"
    listed = [names[c] for c in weak[:_MAX_NAMED]] + (
        [f"{weak.size - _MAX_NAMED} more"] if weak.size > _MAX_NAMED else []
    )
    joints = sorted({j for c in weak for j in (column_joints[c] if column_joints is not None else ())})
    of_joints = f" (parameters of {joint_labels(joints, robot)})" if joints else ""
    raise InsufficientExcitationError(
        f"{owner}: the regressor of {source} must have full rank and a condition number <= {max_condition:.3g} "
        f"after column scaling (every identified parameter excited); got {got}: {', '.join(listed)}{of_joints} "
        "not excited. " + (format_fix(fix, joints, robot) if joints else fix.format(joints="every joint", k="<k>")),
        joints=joints,
        columns=[names[c] for c in weak],
    )
