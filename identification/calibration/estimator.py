"""The estimator bases of the calibration steps: what every step shares, and the least squares of the linear ones.

:class:`BaseIdentifier` holds what every step estimator shares: its hyper-parameters
(``get_params``, the ``_validate`` hook), :func:`check_is_fitted` and the scores (``predict``,
``evaluate``, ``score``) on the rows a fitted step explains. :class:`LeastSquaresIdentifier` adds
the weighted least squares of the steps that are a linear regression ``b = A x`` on rows built
from recordings (motor, gravity, inertial): such a step overrides ``_design_matrix`` (and
``_solve`` when its estimate is not plain weighted least squares). The friction step is not
linear and derives from :class:`BaseIdentifier` alone.

The estimators follow scikit-learn: ``__init__`` stores hyper-parameters, ``fit`` sets attributes
ending in ``_`` and returns ``self``, ``predict`` and ``score`` call :func:`check_is_fitted` first.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from identification.metrics import r2, rmse
from psdm_casadi.errors import NotFittedError, ParameterError, ShapeError

__all__ = [
    "Design",
    "LeastSquaresResult",
    "BaseIdentifier",
    "LeastSquaresIdentifier",
    "check_is_fitted",
    "weighted_least_squares",
    "rmse_r2",
]


@dataclass(frozen=True, eq=False)
class Design:
    """Rows of a linear regression ``b ~ A x`` with a weight and the joint each row belongs to.

    Parameters
    ----------
    matrix : array, shape (n_rows, n_columns)
        Regressor ``A``.
    target : array, shape (n_rows,)
        Observations ``b`` [N m].
    weights : array, shape (n_rows,)
        Non-negative row weights (0 drops a row).
    joint : array of int, shape (n_rows,)
        Joint (0-based) of each row, for per-joint scores.
    offset : array, shape (n_rows,)
        Known part of the prediction added to ``A x`` (e.g. a fixed friction or payload torque).
    """

    matrix: np.ndarray
    target: np.ndarray
    weights: np.ndarray
    joint: np.ndarray
    offset: np.ndarray | None = None

    def __post_init__(self):
        a = np.asarray(self.matrix, dtype=float)
        if a.ndim != 2:
            raise ShapeError(f"Design.matrix must be 2-D (n_rows, n_columns); got shape {a.shape}.")
        n = a.shape[0]
        for name in ("target", "weights", "joint", "offset"):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=int if name == "joint" else float).reshape(-1)
            if value.shape != (n,):
                raise ShapeError(f"Design.{name} must have shape ({n},) to match Design.matrix; got {value.shape}.")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "matrix", a)
        if np.any(self.weights < 0) or not np.all(np.isfinite(self.weights)):
            raise ParameterError("Design.weights must be finite and >= 0; got a negative or non-finite weight.")
        if self.offset is None:
            object.__setattr__(self, "offset", np.zeros(n))

    @property
    def n_rows(self) -> int:
        return int(self.matrix.shape[0])

    def observed(self) -> np.ndarray:
        """The observations ``b`` [N m]."""
        return self.target

    def predicted(self, coefficients) -> np.ndarray:
        """``A x + offset`` for coefficients ``x``."""
        return self.matrix @ np.asarray(coefficients, dtype=float) + self.offset

    def stack(self, other: Design) -> Design:
        """Rows of ``self`` followed by rows of ``other`` (same columns)."""
        return Design.concatenate([self, other])

    @staticmethod
    def concatenate(designs) -> Design:
        """The rows of every design in ``designs`` (same columns), in order."""
        designs = list(designs)
        return Design(
            np.vstack([d.matrix for d in designs]),
            np.concatenate([d.target for d in designs]),
            np.concatenate([d.weights for d in designs]),
            np.concatenate([d.joint for d in designs]),
            np.concatenate([d.offset for d in designs]),
        )


@dataclass(frozen=True, eq=False)
class LeastSquaresResult:
    """Solution of a weighted least-squares problem.

    Attributes
    ----------
    coefficients : array, shape (n_columns,)
    covariance : array, shape (n_columns, n_columns)
        ``sigma^2 (A^T W A)^-1`` with the weighted residual variance ``sigma^2``.
    sigma2 : float
        Weighted residual variance.
    rank : int
        Numerical rank of the weighted regressor.
    condition : float
        Condition number of the column-scaled weighted regressor.
    """

    coefficients: np.ndarray
    covariance: np.ndarray
    sigma2: float
    rank: int
    condition: float

    @property
    def standard_errors(self) -> np.ndarray:
        """Square roots of the covariance diagonal."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))


def weighted_least_squares(matrix, target, weights=None, offset=None) -> LeastSquaresResult:
    """Solve ``min sum w (A x + offset - b)^2`` with column scaling, and return the covariance.

    Parameters
    ----------
    matrix : array, shape (n_rows, n_columns)
    target : array, shape (n_rows,)
    weights : array, shape (n_rows,), optional
        Non-negative weights (default all ones).
    offset : array, shape (n_rows,), optional
        Known part subtracted from the target.

    Returns
    -------
    LeastSquaresResult

    Raises
    ------
    ParameterError
        When fewer weighted rows than columns remain or a column is identically zero (unidentifiable).

    Examples
    --------
    >>> a = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    >>> weighted_least_squares(a, a @ [2.0, -1.0]).coefficients.round(6).tolist()
    [2.0, -1.0]
    """
    a = np.asarray(matrix, dtype=float)
    b = np.asarray(target, dtype=float).reshape(-1)
    w = np.ones(b.size) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    if offset is not None:
        b = b - np.asarray(offset, dtype=float).reshape(-1)
    keep = w > 0
    n_cols = a.shape[1]
    if keep.sum() < n_cols:
        raise ParameterError(
            f"weighted_least_squares needs at least n_columns={n_cols} rows with weight > 0; got {int(keep.sum())}. "
            "Record more data or lower the thresholds that drop rows."
        )
    sw = np.sqrt(w[keep])
    aw, bw = a[keep] * sw[:, None], b[keep] * sw
    scale = np.linalg.norm(aw, axis=0)
    if np.any(scale == 0):
        bad = int(np.flatnonzero(scale == 0)[0])
        raise ParameterError(
            f"weighted_least_squares column {bad} is zero on every weighted row: the parameter is not excited. "
            "Excite the joint or remove the column."
        )
    an = aw / scale
    x_n, _, rank, sv = np.linalg.lstsq(an, bw, rcond=None)
    x = x_n / scale
    residual = bw - aw @ x
    dof = max(int(keep.sum()) - n_cols, 1)
    sigma2 = float(residual @ residual / dof)
    pinv = np.linalg.pinv(an.T @ an)
    covariance = sigma2 * pinv / np.outer(scale, scale)
    condition = float(sv[0] / sv[-1]) if sv.size and sv[-1] > 0 else float("inf")
    return LeastSquaresResult(x, covariance, sigma2, int(rank), condition)


def rmse_r2(observed, predicted, joint, n_dof: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint RMSE and R^2 (:mod:`identification.metrics`) of rows labelled by ``joint``; NaN without rows.

    Parameters
    ----------
    observed, predicted : array, shape (n_rows,)
    joint : array of int, shape (n_rows,)
        Joint (0-based) of each row.
    n_dof : int

    Returns
    -------
    (array, array), each shape (n_dof,)
    """
    joint = np.asarray(joint, dtype=int)
    out_rmse, out_r2 = np.full(n_dof, np.nan), np.full(n_dof, np.nan)
    for j in range(n_dof):
        rows = joint == j
        if rows.any():
            out_rmse[j] = rmse(observed[rows], predicted[rows])
            out_r2[j] = r2(observed[rows], predicted[rows])
    return out_rmse, out_r2


def check_is_fitted(estimator, attribute: str = "coef_") -> None:
    """Raise :class:`NotFittedError` unless ``estimator`` has the fitted attribute ``attribute``.

    Raises
    ------
    NotFittedError
        ``<Class>.<attribute> is missing: the estimator is not fitted. Call fit(...) first.``
    """
    if not hasattr(estimator, attribute):
        name = type(estimator).__name__
        raise NotFittedError(
            f"{name}.{attribute} must exist, but {name} is not fitted; got an unfitted estimator. Call fit(...) first."
        )


class BaseIdentifier:
    """What every calibration step shares: hyper-parameters, the fitted check and the scores.

    A subclass stores its keyword hyper-parameters in ``__init__``, checks them in ``_validate``,
    sets ``n_dof_`` and its learned attributes in ``fit`` (``_fitted_attribute`` names the one
    :func:`check_is_fitted` looks for) and returns, in ``_scored_rows(data)``, the observed and
    predicted torques of the rows it explains; ``predict``, ``evaluate``, ``observed_predicted``
    and ``score`` are built on them.
    """

    _fitted_attribute = "coef_"

    def _validate(self) -> None:
        """Hook: raise :class:`ParameterError` for a bad hyper-parameter."""

    def _scored_rows(self, data):  # pragma: no cover - abstract
        """``(observed, predicted, joint)`` of the rows of ``data`` the fitted step explains."""
        raise NotImplementedError

    def get_params(self) -> dict:
        """The hyper-parameters given to ``__init__``."""
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {name: getattr(self, name) for name in names}

    def observed_predicted(self, data):
        """``(observed, predicted, joint)`` rows of ``data`` (those with weight > 0), for plots."""
        check_is_fitted(self, self._fitted_attribute)
        return self._scored_rows(data)

    def predict(self, data) -> np.ndarray:
        """Predicted torques [N m] of the rows of ``data`` (weight > 0), shape (n_rows,)."""
        return self.observed_predicted(data)[1]

    def evaluate(self, data) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint RMSE [N m] and R^2 on ``data`` (rows with weight > 0), each shape (n_dof,)."""
        observed, predicted, joint = self.observed_predicted(data)
        return rmse_r2(observed, predicted, joint, self.n_dof_)

    def score(self, data) -> float:
        """Mean over joints of the R^2 on ``data`` (joints without a defined R^2 are skipped)."""
        _, scores = self.evaluate(data)
        return float(np.nanmean(scores))


class LeastSquaresIdentifier(BaseIdentifier):
    """A calibration step that is a weighted linear regression ``b ~ A x + offset`` (motor, gravity, inertial).

    Subclasses implement ``_design_matrix(data) -> Design`` and ``_n_dof(data)``; ``fit`` checks the
    excitation (``_check_excitation``), solves the weighted least squares (override ``_solve`` for
    another estimator) and sets ``coef_``, ``covariance_``, ``sigma2_``, ``condition_``, ``n_rows_``
    and ``n_dof_``; ``_after_fit`` derives the step's named attributes from them.

    Attributes
    ----------
    coef_ : array, shape (n_columns,)
        Estimated coefficients.
    covariance_ : array, shape (n_columns, n_columns)
    sigma2_ : float
    condition_ : float
    n_rows_ : int
    n_dof_ : int
    """

    def fit(self, data):
        """Fit the step on ``data`` (see the subclass) and return ``self``."""
        design = self._design_matrix(data)
        self._check_excitation(data, design)
        result = self._solve(design)
        self.coef_ = np.asarray(result.coefficients, dtype=float)
        self.covariance_ = result.covariance
        self.sigma2_ = result.sigma2
        self.condition_ = result.condition
        self.n_rows_ = design.n_rows
        self.n_dof_ = self._n_dof(data)
        self._after_fit(design)
        return self

    def _after_fit(self, design: Design) -> None:
        """Hook: derive named attributes from ``coef_``."""

    def _check_excitation(self, data, design: Design) -> None:
        """Hook: raise :class:`~psdm_casadi.errors.InsufficientExcitationError` when ``data`` does not excite the
        step's parameters (:mod:`identification.calibration.excitation`); called by ``fit`` before the solve."""

    def _solve(self, design: Design) -> LeastSquaresResult:
        return weighted_least_squares(design.matrix, design.target, design.weights, design.offset)

    def _design_matrix(self, data) -> Design:  # pragma: no cover - abstract
        raise NotImplementedError

    def _n_dof(self, data) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _scored_rows(self, data):
        design = self._design_matrix(data)
        keep = design.weights > 0
        return design.target[keep], design.predicted(self.coef_)[keep], design.joint[keep]
