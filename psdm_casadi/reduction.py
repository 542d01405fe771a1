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


def select_independent_rows(rows: np.ndarray, rtol: float = 1e-8, block: int = 512) -> np.ndarray:
    """Indices of the rows that are linearly independent of all earlier rows (greedy, in order).

    Parameters
    ----------
    rows : array, shape (n_rows, n_cols)
    rtol : float
        A row is independent when its component orthogonal to the earlier selected rows is
        larger than ``rtol`` times its norm.
    block : int
        Rows tested together; the result does not depend on it.
    """
    norms = np.linalg.norm(rows, axis=1)
    nonzero = np.nonzero(norms > 0)[0]
    rows, norms = rows[nonzero], norms[nonzero]
    n_rows, n_cols = rows.shape
    basis = np.zeros((0, n_cols))
    selected = []
    start = 0
    while start < n_rows and len(selected) < n_cols:
        chunk = rows[start : start + block]
        residual = chunk - (chunk @ basis.T) @ basis
        residual = residual - (residual @ basis.T) @ basis  # Gram-Schmidt twice is enough
        independent = np.linalg.norm(residual, axis=1) > rtol * norms[start : start + block]
        hits = np.nonzero(independent)[0]
        if hits.size == 0:
            start += block
            continue
        first = int(hits[0])
        vector = residual[first]
        selected.append(start + first)
        basis = np.vstack([basis, vector / np.linalg.norm(vector)])
        start += first + 1
    return nonzero[np.array(selected, dtype=int)]


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
    # rows = P base_map with base_map of full row rank: P = rows base_map^+ (one small pseudo-inverse)
    p_flat = rows @ scipy.linalg.pinv(base_map)
    p_flat[np.abs(p_flat) < clean] = 0.0
    p_flat[selected] = np.eye(len(selected))
    reduction = p_flat.reshape(n_dof, n_functions, len(selected)).transpose(1, 2, 0)
    pairs = np.stack([selected // n_functions, selected % n_functions], axis=1)
    return np.ascontiguousarray(reduction), base_map, pairs
