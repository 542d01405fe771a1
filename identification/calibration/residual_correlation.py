"""How correlated the residual of a fit on filtered recordings is, and the covariance that accounts for it.

Filtered, decimated samples are not independent: a residual spans several samples. Counting them as
independent would make standard deviations too small (``trajectory_fit``) and an information criterion
too eager to add columns (``column_choice``, which divides the sample count by the factor below).
"""

from __future__ import annotations

import numpy as np

from identification.calibration.trajectory_data import drive_columns

__all__ = ["correlation_time", "residual_correlation_time", "sandwich_covariance"]

CHUNK = 4000


def correlation_time(model, recording, x, options, inertia_joints, extra=None, max_lag: int = 50, *, stribeck=None):
    """Per joint, the integrated autocorrelation time of the residual of the parameters ``x`` (base, drive with
    the terms of ``options``, then ``extra``) on a prepared ``recording`` (:func:`residual_correlation_time`)."""
    residual = np.concatenate(
        [
            recording.tau[sl]
            - np.concatenate(
                [model.regressor(recording.q[sl], recording.qd[sl], recording.qdd[sl]),
                 drive_columns(recording.qd[sl], recording.qdd[sl], options.friction, inertia_joints,
                               options.coulomb_velocity, stribeck, options.viscous_exponent),
                 *([] if extra is None else [extra.columns(recording.q[sl], recording.qd[sl], recording.qdd[sl])])],
                axis=2,
            ) @ x
            for sl in (slice(s, s + CHUNK) for s in range(0, recording.n_samples, CHUNK))
        ]
    )  # fmt: skip
    return residual_correlation_time(residual, max_lag)


def residual_correlation_time(residual, max_lag: int = 50) -> np.ndarray:
    """Per joint, ``1 + 2 sum_k (1 - k/(L+1)) rho_k`` of a residual series (n_samples, n_dof): the factor by which
    the variance of a mean grows over white residuals (Bartlett weights, ``L`` lags; at least 1)."""
    residual = np.asarray(residual, dtype=float)
    measured = np.all(np.isfinite(residual), axis=0)  # a joint without torque (NaN) counts as white
    residual = np.where(measured, residual, 0.0)
    residual = residual - residual.mean(axis=0)
    lags = min(max_lag, residual.shape[0] // 4)
    variance = np.maximum(np.einsum("sn,sn->n", residual, residual), 1e-300)
    factor = np.ones(residual.shape[1])
    for k in range(1, lags + 1):
        rho = np.einsum("sn,sn->n", residual[:-k], residual[k:]) / variance
        factor += 2.0 * (1.0 - k / (lags + 1)) * rho
    return np.maximum(factor, 1.0)


def sandwich_covariance(equations, sigma, inverse, correlation) -> np.ndarray:
    """Covariance of the weighted estimate with each joint's residual variance grown by its correlation time."""
    middle, _, _ = equations.weighted(correlation / sigma**2)
    return inverse @ middle @ inverse
