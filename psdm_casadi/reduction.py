"""Reduction of the per-joint lumped parameters to one vector of base parameters (paper eqs. 7-9).

Given the coefficient of every function in every joint torque as a linear form in the free
standard parameters, choose base parameters as the first linearly independent forms in
joint-major, function-minor order. Each base parameter is then the lumped coefficient of one
function in one joint torque, every other coefficient is a combination of earlier ones, and
each column of P starts with a 1: the sparse, normalised P of the published model.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg


def select_independent_rows(rows: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """Indices of the rows that are linearly independent of all earlier rows (greedy, in order).

    Parameters
    ----------
    rows : array, shape (n_rows, n_cols)
    rtol : float
        A row is independent when its component orthogonal to the earlier selected rows is
        larger than ``rtol`` times its norm.
    """
    n_cols = rows.shape[1]
    basis = np.zeros((0, n_cols))
    selected = []
    for index, row in enumerate(rows):
        norm = np.linalg.norm(row)
        if norm == 0.0:
            continue
        residual = row - basis.T @ (basis @ row)
        residual = residual - basis.T @ (basis @ residual)  # second pass: Gram-Schmidt twice is enough
        size = np.linalg.norm(residual)
        if size > rtol * norm:
            selected.append(index)
            basis = np.vstack([basis, residual / size])
            if len(selected) == n_cols:
                break
    return np.array(selected, dtype=int)


def reduce_to_base_parameters(coefficients: np.ndarray, rtol: float = 1e-8, clean: float = 1e-10):
    """Reduction matrices and base parameters from the lumped coefficients.

    Parameters
    ----------
    coefficients : array, shape (n_dof, n_functions, n_free)
        ``coefficients[i, f]`` is the coefficient of function f in torque i as a linear form in
        the free standard parameters.
    rtol : float
        Independence tolerance of the greedy selection.
    clean : float
        Entries of P smaller than this are round-off and set to zero.

    Returns
    -------
    reduction : array, shape (n_functions, n_base, n_dof)
        P, with ``coefficients[i] = reduction[:, :, i] @ base_map``.
    base_map : array, shape (n_base, n_free)
        The base parameters as linear forms in the free standard parameters.
    selected : array of (joint, function) pairs, shape (n_base, 2)
    """
    n_dof, n_functions, n_free = coefficients.shape
    rows = coefficients.reshape(n_dof * n_functions, n_free)
    selected = select_independent_rows(rows, rtol)
    base_map = rows[selected]
    solution, *_ = scipy.linalg.lstsq(base_map.T, rows.T, lapack_driver="gelsy")
    p_flat = solution.T
    p_flat[np.abs(p_flat) < clean] = 0.0
    p_flat[selected] = np.eye(len(selected))
    reduction = p_flat.reshape(n_dof, n_functions, len(selected)).transpose(1, 2, 0)
    pairs = np.stack([selected // n_functions, selected % n_functions], axis=1)
    return np.ascontiguousarray(reduction), base_map, pairs
