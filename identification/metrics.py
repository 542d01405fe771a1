"""Fit metrics shared by calibration, friction and diagnosis: RMSE, R^2 and RMS, per column.

One definition for the whole package, so that every table and report means the same thing:

- ``rms(x)``: root mean square, per column for 2-D input;
- ``rmse(observed, predicted)``: root mean squared error, per column for 2-D input;
- ``r2(observed, predicted)``: coefficient of determination ``1 - SS_res / SS_tot``, per column;
- ``explained_rms(rmse_before, rmse_after)``: the RMS of the residual a model change takes away,
  ``sqrt(before^2 - after^2)`` (0 where the error rises).

Empty input gives NaN. R^2 of a constant observed signal (``SS_tot`` zero to rounding) is undefined
and gives NaN rather than a huge or infinite number; callers that must refuse such data check
:func:`is_constant` and raise with their own message.
"""

from __future__ import annotations

import numpy as np

__all__ = ["explained_rms", "is_constant", "r2", "rms", "rmse"]

#: SS_tot at or below this fraction of sum(y^2) counts as a constant signal.
_CONSTANT_RTOL = 1e-24


def _as_float(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _reduce(values: np.ndarray):
    return float(values) if np.ndim(values) == 0 else values


def rms(x):
    """Root mean square over the first axis (a float for 1-D input, an array per column for 2-D)."""
    x = _as_float(x)
    if x.size == 0:
        return _reduce(np.full(x.shape[1:], np.nan))
    return _reduce(np.sqrt(np.mean(x * x, axis=0)))


def rmse(observed, predicted):
    """Root mean squared error over the first axis (float for 1-D input, per column for 2-D)."""
    return rms(_as_float(observed) - _as_float(predicted))


def explained_rms(rmse_before, rmse_after):
    """The RMS of the residual a model change takes away: ``sqrt(before^2 - after^2)`` of the RMSE without and with it,
    elementwise, 0 where it rises. A change that models an effect exactly explains the effect's own RMS whatever
    noise it leaves; the drop ``before - after`` is that RMS only when the noise left is small against it (an effect
    of RMS e on noise n drops the RMSE by ``sqrt(e^2 + n^2) - n``, about ``e^2 / 2n`` for e < n)."""
    before, after = _as_float(rmse_before), _as_float(rmse_after)
    return _reduce(np.sqrt(np.maximum(before * before - after * after, 0.0)))


def is_constant(observed) -> np.ndarray | bool:
    """True where the observed signal does not vary (its R^2 is undefined)."""
    y = _as_float(observed)
    if y.size == 0:
        return True
    ss_tot = np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    scale = np.sum(y * y, axis=0)
    return ss_tot <= _CONSTANT_RTOL * scale + 1e-300


def r2(observed, predicted):
    """Coefficient of determination ``1 - SS_res / SS_tot`` over the first axis; NaN where undefined."""
    y, p = _as_float(observed), _as_float(predicted)
    if y.size == 0:
        return _reduce(np.full(y.shape[1:], np.nan))
    ss_tot = np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    ss_res = np.sum((y - p) ** 2, axis=0)
    constant = is_constant(y)
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(constant, np.nan, 1.0 - ss_res / np.where(constant, 1.0, ss_tot))
    return _reduce(value)
