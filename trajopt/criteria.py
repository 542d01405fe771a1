"""Excitation criteria on the stacked regressor: the true condition number and smooth surrogates for Ipopt.

The paper (eq. 23) minimises ``cond(Y*)``, the ratio of the extreme singular values of the stacked
regressor. That ratio is not differentiable where the extreme singular values cross, which a
gradient-based solver meets constantly. We minimise instead a smooth function of the eigenvalues
``lambda_i`` of the information matrix ``F = Y*^T Y*`` (``lambda_i = sigma_i^2``):

* ``"cond"``: the log-ratio of the power means of order ``+p`` and ``-p`` of the eigenvalues,
  ``S_p = log M_p(lambda) - log M_-p(lambda)`` (a soft-max of ``log lambda`` minus a soft-min).
  It is smooth for finite ``p``, zero only when all eigenvalues are equal, a lower bound of
  ``2 log cond(Y*)`` and tends to it as ``p`` grows (the gap is at most ``2 log(l) / p``). The
  optimiser continues in ``p`` (4, 16, 64) from the previous solution.
* ``"logdet"``: D-optimal design, ``-log det(F) / l``; invariant to column scaling.

Both are spectral functions, so their gradient with respect to ``F`` is ``V diag(dS/dlambda) V^T``
from one symmetric eigen-decomposition of an ``l x l`` matrix; they enter the CasADi graph as a
Callback with an exact Jacobian (the Hessian is approximated by L-BFGS). The figure reported to the
user is always the true ``cond`` from the singular values of the stacked regressor.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError

CRITERIA = ("cond", "logdet")
_EIG_FLOOR = 1e-300


def condition_number(regressor_stack: np.ndarray) -> float:
    """True condition number ``sigma_max / sigma_min`` of a stacked regressor (inf when rank deficient).

    Parameters
    ----------
    regressor_stack : array, shape (n_rows, n_columns)

    Returns
    -------
    float
    """
    y = np.asarray(regressor_stack, dtype=float)
    if y.ndim != 2 or y.shape[0] < y.shape[1]:
        raise ShapeError(
            f"regressor_stack must be 2-D with at least as many rows as columns; got shape {y.shape}. "
            "Stack more samples."
        )
    sigma = np.linalg.svd(y, compute_uv=False)
    return float(sigma[0] / sigma[-1]) if sigma[-1] > 0 else float("inf")


def check_columns(columns, n_base: int) -> np.ndarray:
    """Validate a column selection (None = all, a bool mask of length n_base, or indices)."""
    if columns is None:
        return np.arange(n_base)
    arr = np.asarray(columns)
    if arr.dtype == bool:
        if arr.shape != (n_base,):
            raise ShapeError(
                f"ExcitationOptions.columns as a mask must have n_base={n_base} entries; got {arr.shape}. "
                "Pass e.g. ~model.gravity_mask."
            )
        arr = np.flatnonzero(arr)
    arr = arr.astype(int).reshape(-1)
    if arr.size == 0 or arr.min() < 0 or arr.max() >= n_base or len(set(arr.tolist())) != arr.size:
        raise ParameterError(
            f"ExcitationOptions.columns must be distinct indices in [0, {n_base}); got {np.asarray(columns).tolist()}. "
            "Pass None for all columns or ~model.gravity_mask for the inertial ones."
        )
    return arr


def stack_regressor(regressor: ca.Function, q, qd, qdd, columns=None) -> np.ndarray:
    """Stack ``Y(q_j, qd_j, qdd_j)[:, columns]`` over the samples, shape (n_samples * n_dof, n_columns)."""
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    n_samples, n_dof = q.shape
    n_base = regressor.size2_out(0)
    cols = check_columns(columns, n_base)
    out = np.asarray(regressor.map(n_samples)(q.T, qd.T, qdd.T))  # (n_dof, n_samples * n_base)
    y = out.reshape(n_dof, n_samples, n_base).transpose(1, 0, 2)  # blocks of n_base columns per sample
    return y[:, :, cols].reshape(n_samples * n_dof, cols.size)


def _spectral_parts(criterion: str, lam: np.ndarray, sharpness: float) -> tuple:
    """Value, d value / d lambda and d value / d sharpness of a criterion for eigenvalues ``lam``."""
    lam = np.maximum(lam, _EIG_FLOOR)
    ell = np.log(lam)
    n = lam.size
    if criterion == "logdet":
        return -ell.mean(), -1.0 / (n * lam), 0.0
    p = sharpness
    upper, lower = p * ell, -p * ell
    mu, ml = upper.max(), lower.max()
    wu, wl = np.exp(upper - mu), np.exp(lower - ml)
    lse_u, lse_l = mu + np.log(wu.sum()), ml + np.log(wl.sum())
    value = (lse_u + lse_l - 2 * np.log(n)) / p
    soft_u, soft_l = wu / wu.sum(), wl / wl.sum()
    grad_lam = (soft_u - soft_l) / lam
    d_p = -value / p + (soft_u @ ell - soft_l @ ell) / p
    return value, grad_lam, d_p


def criterion_value(criterion: str, information: np.ndarray, sharpness: float = 16.0) -> float:
    """Value of a smooth criterion for the information matrix ``F`` (numeric)."""
    _check_criterion(criterion)
    lam = np.linalg.eigvalsh(0.5 * (information + information.T))
    return float(_spectral_parts(criterion, lam, sharpness)[0])


def criterion_gradient(criterion: str, information: np.ndarray, sharpness: float = 16.0) -> np.ndarray:
    """Gradient of ``criterion_value`` with respect to the symmetric ``F``, shape (l, l)."""
    _check_criterion(criterion)
    lam, vec = np.linalg.eigh(0.5 * (information + information.T))
    grad = _spectral_parts(criterion, lam, sharpness)[1]
    return (vec * grad) @ vec.T


def _check_criterion(criterion: str) -> None:
    if criterion not in CRITERIA:
        raise ParameterError(
            f"ExcitationOptions.criterion must be one of {CRITERIA}; got {criterion!r}. "
            "Use 'cond' (smooth condition number) or 'logdet' (D-optimal)."
        )


class _CriterionJacobian(ca.Callback):
    """d criterion / d (F, p): inputs F, p, value; outputs 1 x l^2 and 1 x 1."""

    def __init__(self, name, criterion, size, opts):
        ca.Callback.__init__(self)
        self._criterion, self._size = criterion, size
        self.construct(name, opts)

    def get_n_in(self):
        return 3

    def get_n_out(self):
        return 2

    def get_sparsity_in(self, i):
        return [ca.Sparsity.dense(self._size, self._size), ca.Sparsity.dense(1, 1), ca.Sparsity.dense(1, 1)][i]

    def get_sparsity_out(self, i):
        return [ca.Sparsity.dense(1, self._size**2), ca.Sparsity.dense(1, 1)][i]

    def eval(self, arg):
        info, p = np.asarray(arg[0]), float(arg[1])
        lam, vec = np.linalg.eigh(0.5 * (info + info.T))
        _, grad, d_p = _spectral_parts(self._criterion, lam, p)
        g = (vec * grad) @ vec.T
        return [ca.DM(g.reshape(1, -1, order="F")), ca.DM(d_p)]


class CriterionCallback(ca.Callback):
    """A smooth criterion of the information matrix as a CasADi Function ``(F, p) -> value``.

    Parameters
    ----------
    criterion : {"cond", "logdet"}
    size : int
        Size ``l`` of the information matrix.
    name : str
    """

    def __init__(self, criterion: str, size: int, name: str = "criterion"):
        ca.Callback.__init__(self)
        _check_criterion(criterion)
        self._criterion, self._size = criterion, int(size)
        self._jacobian = None  # keep the Jacobian callback alive as long as this one
        self.construct(name, {"enable_fd": False})

    def get_n_in(self):
        return 2

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ["F", "p"][i]

    def get_name_out(self, i):
        return "value"

    def get_sparsity_in(self, i):
        return [ca.Sparsity.dense(self._size, self._size), ca.Sparsity.dense(1, 1)][i]

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(1, 1)

    def eval(self, arg):
        info, p = np.asarray(arg[0]), float(arg[1])
        return [ca.DM(criterion_value(self._criterion, info, p))]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        self._jacobian = _CriterionJacobian(name, self._criterion, self._size, opts)
        return self._jacobian


def build_information_function(regressor: ca.Function, columns=None, column_scale=None) -> ca.Function:
    """Per-sample information ``q, qd, qdd -> Ys^T Ys`` with ``Ys = Y[:, columns] * column_scale``.

    Parameters
    ----------
    regressor : casadi.Function
        ``q, qd, qdd -> Y`` (n_dof x n_base), e.g. ``build_recursive_functions(model, robot).regressor``.
    columns : array of int or bool mask, optional
        Columns of Y to excite; default all.
    column_scale : array, shape (n_columns,), optional
        Multiplies each selected column (default 1, i.e. raw columns as in the paper).

    Returns
    -------
    casadi.Function
        Named ``information`` (SX), output ``F`` of shape (n_columns, n_columns).
    """
    n_dof, n_base = regressor.size1_out(0), regressor.size2_out(0)
    cols = check_columns(columns, n_base)
    q, qd, qdd = (ca.SX.sym(name, n_dof) for name in ("q", "qd", "qdd"))
    y = regressor(q, qd, qdd)[:, cols.tolist()]
    if column_scale is not None:
        scale = np.asarray(column_scale, dtype=float).reshape(-1)
        if scale.shape != (cols.size,):
            raise ShapeError(f"column_scale must have one entry per selected column ({cols.size}); got {scale.shape}.")
        y = y @ ca.diag(ca.DM(scale))
    return ca.Function("information", [q, qd, qdd], [ca.mtimes(y.T, y)], ["q", "qd", "qdd"], ["F"])


def nominal_column_scale(regressor: ca.Function, q, qd, qdd, columns=None) -> np.ndarray:
    """1 / RMS of each selected column over samples (so scaled columns have unit RMS)."""
    y = stack_regressor(regressor, q, qd, qdd, columns)
    rms = np.sqrt(np.mean(y**2, axis=0))
    return 1.0 / np.where(rms > 0, rms, 1.0)
