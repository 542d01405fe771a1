"""Forward dynamics on the base parameters: solve D(q) qdd = tau - h by a square-root-free Cholesky (LDL^T).

The factorisation is written out on CasADi SX so it code-generates into straight-line C with no
branches and no library calls.
"""

from __future__ import annotations

import casadi as ca


def symmetric_from_columns(columns) -> ca.SX:
    """The symmetric matrix whose column k holds ``columns[k]`` from row k down (the rest mirrored)."""
    n = len(columns)
    matrix = ca.SX(n, n)
    for k, column in enumerate(columns):
        for i in range(k, n):
            matrix[i, k] = column[i]
            matrix[k, i] = column[i]
    return matrix


def ldl_solve(matrix: ca.SX, rhs: ca.SX) -> ca.SX:
    """Solve ``matrix x = rhs`` for a symmetric positive definite SX matrix by LDL^T.

    Parameters
    ----------
    matrix : casadi.SX, shape (n, n)
        Only the lower triangle is read.
    rhs : casadi.SX, shape (n, 1)

    Returns
    -------
    casadi.SX, shape (n, 1)
    """
    n = matrix.shape[0]
    # scaled[i][k] = L_ik d_k is the off-diagonal value before the division by d_k: keeping it makes
    # every update term one product instead of two.
    lower = [[None] * n for _ in range(n)]
    scaled = [[None] * n for _ in range(n)]
    inv_diag = [None] * n  # 1 / d_j: n divisions in all, the solves below only multiply
    for j in range(n):
        d = matrix[j, j]
        for k in range(j):
            d = d - lower[j][k] * scaled[j][k]
        inv_d = 1.0 / d
        inv_diag[j] = inv_d
        for i in range(j + 1, n):
            value = matrix[i, j]
            for k in range(j):
                value = value - lower[i][k] * scaled[j][k]
            scaled[i][j] = value
            lower[i][j] = value * inv_d
    y = [None] * n  # L y = rhs
    for i in range(n):
        value = rhs[i]
        for k in range(i):
            value = value - lower[i][k] * y[k]
        y[i] = value
    x = [None] * n  # D L^T x = y
    for i in reversed(range(n)):
        value = y[i] * inv_diag[i]
        for k in range(i + 1, n):
            value = value - lower[k][i] * x[k]
        x[i] = value
    return ca.vertcat(*x)
