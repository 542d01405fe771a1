"""The fit's least squares from normal equations: each joint weighted by its residual variance, columns scaled.

``identify_trajectories`` solves its unconstrained estimate (and the covariance's inverse normal matrix) here: a first
fit with each joint's rows scaled by its torque RMS gives the residual sigma per joint, the second is weighted by
``1 / sigma^2``; the columns are scaled to a unit diagonal so parameters of very different sizes share one solve.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.consistent_fit import residual_sigma
from identification.calibration.trajectory_data import NormalEquations

__all__ = ["solve_scaled", "weighted_least_squares"]


def solve_scaled(gram, moment, arm=slice(None)):
    """Least squares from normal equations with unit-diagonal scaling; (x, inverse of gram, condition of the ``arm``
    columns: an unknown payload on every recording is not separable from the arm, ``FlangeBodies.separable``)."""
    scale = np.sqrt(np.clip(np.diag(gram), 1e-300, None))
    scaled = gram / np.outer(scale, scale)
    values = np.linalg.eigvalsh(scaled[np.ix_(arm, arm)] if isinstance(arm, np.ndarray) else scaled)
    condition = float(np.sqrt(values[-1] / values[0])) if values[0] > 0 else float("inf")
    inverse = np.linalg.pinv(scaled, rcond=1e-12, hermitian=True) / np.outer(scale, scale)
    return inverse @ moment, inverse, condition


def weighted_least_squares(equations: NormalEquations, free=None, payload=range(0)):
    """Residual sigma per joint (from a torque-RMS-scaled fit), then the weighted estimate and the inverse of its
    normal matrix; only the ``free`` columns are fitted (None: all), the others stay 0 (0 rows in the inverse);
    the condition number is the arm's (every column but the unknown payloads' ``payload``)."""
    free = np.arange(equations.n_columns) if free is None else np.asarray(free, dtype=int)
    subset = equations.subset(free)
    rms = np.sqrt(subset.energy / np.maximum(subset.count, 1))
    first, _, _ = solve_scaled(*subset.weighted(1.0 / np.maximum(rms, 1e-12) ** 2)[:2])
    sigma = residual_sigma(subset, first)
    gram, moment, _ = subset.weighted(1.0 / sigma**2)
    x_free, inverse_free, condition = solve_scaled(gram, moment, np.flatnonzero(~np.isin(free, payload)))
    x, inverse = np.zeros(equations.n_columns), np.zeros((equations.n_columns,) * 2)
    x[free], inverse[np.ix_(free, free)] = x_free, inverse_free
    return sigma, x, inverse, condition
