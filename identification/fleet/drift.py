"""Drift and wear tests on a robot's parameter history, using each day's standard deviation.

Per robot and parameter (``fc3``, ``kt2``, ``spring_k_2``, ``ripple_amp12_4``, ``payload_mass``, ...) the first
``baseline_days`` recording days are its baseline window: their mean ``mu0`` and an over-dispersion factor
``phi^2 >= 1`` (the window's scatter over its own sigmas, taken at an upper confidence bound: day-to-day changes the
least-squares sigma does not see, such as temperature) scale every later day's standardised change
``z_t = (x_t - mu0) / sqrt(phi^2 s_t^2 + var(mu0))``. Two tests:

- **shift**: ``|z_t|`` above the threshold on ``persistence`` consecutive days (a step: a tool change, a broken
  spring);
- **CUSUM** (two-sided, allowance ``k``, decision interval ``h``) for a slow drift (wear).

The baseline model's validation RMSE per joint (the cheapest drift signal, :func:`validation_parameters`) is
tested the same way: a rise says the model no longer explains the robot and names the diagnosis to run.

False alarms are the enemy: both thresholds are family-wise over every series and day tested (Bonferroni at
``alpha``: the shift threshold is ``Phi^-1(1 - alpha / (2 M))``; ``h`` gives an in-control average run length
above ``days M / alpha`` by Siegmund's approximation), and the CUSUM allowance covers the baseline mean's own
error at the same level (it is shared by every later day of a series). A series that alarms is then explained:
the onset day and the size at the last day come from the best of a step and a hinged ramp fitted after the
baseline window (weighted least squares over the onset day), the size's sigma from that fit and the baseline's.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from identification.fleet.history import ParameterRow
from identification.fleet.phrases import describe, meaning

__all__ = ["DriftFinding", "DriftOptions", "cusum_interval", "detect_drift", "series_of", "validation_parameters"]

#: relative sigma of a day's validation RMSE (a floor: changes of a few % are not news; a wider scatter of the
#: baseline window raises it through ``phi``)
VALIDATION_SIGMA = 0.05


@dataclass(frozen=True)
class DriftOptions:
    """Options of the drift tests (module docstring): family-wise false-alarm rate ``alpha``, ``persistence``
    days of the shift test, the CUSUM allowance ``k`` (in sigma, before the baseline-error margin), the upper
    confidence level of the over-dispersion factor and the baseline window (None: the fleet's)."""

    alpha: float = 0.01
    persistence: int = 2
    k: float = 0.5
    dispersion_confidence: float = 0.8
    baseline_days: int | None = None


@dataclass(frozen=True)
class DriftFinding:
    """A change found in one parameter of one robot; ``test`` is ``shift``, ``cusum`` or ``fleet``."""

    robot_id: str
    joint: int
    parameter: str
    test: str
    onset: dt.date | None
    size: float
    size_sigma: float
    relative_percent: float | None
    z: float
    text: str


@dataclass(frozen=True)
class Series:
    """One parameter of one robot over its recording days."""

    robot_id: str
    parameter: str
    joint: int
    days: tuple
    values: np.ndarray
    sigmas: np.ndarray


def validation_parameters(validation_rows) -> list:
    """The baseline model's validation RMSE of each joint (``History.validation_rows()``) as parameters
    ``rmse_<j>``, so that the same tests flag a day whose torque the baseline no longer explains."""
    return [ParameterRow(robot_id, day, f"rmse_{joint}", joint, float(rmse), VALIDATION_SIGMA * max(float(rmse), 1e-12))
            for robot_id, day, joint, rmse, _ in validation_rows]  # fmt: skip


def series_of(rows) -> list:
    """Group ``history.ParameterRow`` rows into :class:`Series` of the tracked parameters (named in ``phrases``)."""
    groups: dict = {}
    for row in rows:
        if meaning(row.name) is not None:
            groups.setdefault((row.robot_id, row.name, row.joint), []).append(row)
    out = []
    for (robot_id, name, joint), items in sorted(groups.items()):
        items.sort(key=lambda r: r.day)
        out.append(Series(robot_id, name, joint, tuple(r.day for r in items),
                          np.array([r.value for r in items]), np.array([r.sigma for r in items])))  # fmt: skip
    return out


def cusum_interval(arl: float, k: float) -> float:
    """Decision interval ``h`` of a one-sided CUSUM with allowance ``k`` whose in-control ARL is ``arl``
    (Siegmund: ``ARL = (exp(2 k b) - 2 k b - 1) / (2 k^2)``, ``b = h + 1.166``)."""

    def excess(b):
        return (np.expm1(2 * k * b) - 2 * k * b) / (2 * k * k) - arl

    high = 1.0
    while excess(high) < 0:
        high *= 2.0
    return float(optimize.brentq(excess, 1e-9, high)) - 1.166


def _standardise(s: Series, window: int, confidence: float) -> tuple:
    """(mu0, var(mu0), per-day scale) of a series from its baseline window."""
    w, sw = s.values[:window], s.sigmas[:window]
    m2 = max(float(np.mean(sw**2)), 1e-300)
    upper = np.var(w, ddof=1) * (window - 1) / stats.chi2.ppf(1.0 - confidence, window - 1)
    phi2 = max(1.0, upper / m2)
    var_mu0 = phi2 * m2 / window
    return float(np.mean(w)), var_mu0, np.sqrt(phi2 * s.sigmas**2 + var_mu0)


def _first_shift(z: np.ndarray, threshold: float, persistence: int) -> int | None:
    run = 0
    for t in range(z.size):
        same = run and np.sign(z[t]) == np.sign(z[t - 1])
        run = (run + 1 if same else 1) if abs(z[t]) > threshold else 0
        if run >= persistence:
            return t
    return None


def _first_cusum(z: np.ndarray, k: float, h: float) -> int | None:
    high = low = 0.0
    for t, value in enumerate(z):
        high, low = max(0.0, high + value - k), max(0.0, low - value - k)
        if high > h or low > h:
            return t
    return None


def _explain(s: Series, window: int, mu0: float, var_mu0: float, scale: np.ndarray) -> tuple:
    """(onset index, size at the last day, its sigma) of the best step or hinged ramp after the window."""
    x, w = s.values - mu0, 1.0 / scale**2
    n, best = x.size, None
    for tau in range(window, n):
        after = np.arange(tau, n)
        step_var = 1.0 / w[after].sum()
        step = float(np.sum(w[after] * x[after]) * step_var)
        ramp_x = (after - tau + 1).astype(float)
        ramp_var = 1.0 / np.sum(w[after] * ramp_x**2)
        slope = float(np.sum(w[after] * ramp_x * x[after]) * ramp_var)
        for fitted, size, var in ((step * np.ones(after.size), step, step_var),
                                  (slope * ramp_x, slope * ramp_x[-1], ramp_var * ramp_x[-1] ** 2)):  # fmt: skip
            sse = float(np.sum(w[window:tau] * x[window:tau] ** 2) + np.sum(w[after] * (x[after] - fitted) ** 2))
            if best is None or sse < best[0]:
                best = (sse, tau, size, np.sqrt(var + var_mu0))
    return best[1], best[2], best[3]


def _test_series(s: Series, window: int, threshold: float, k: float, h: float, options: DriftOptions):
    mu0, var_mu0, scale = _standardise(s, window, options.dispersion_confidence)
    z = (s.values[window:] - mu0) / scale[window:]
    shift = _first_shift(z, threshold, options.persistence)
    cusum = _first_cusum(z, k, h)
    if shift is None and cusum is None:
        return None
    test = "shift" if cusum is None or (shift is not None and shift <= cusum) else "cusum"
    onset, size, sigma = _explain(s, window, mu0, var_mu0, scale)
    sig_mu0 = np.sqrt(var_mu0)
    relative = 100.0 * size / abs(mu0) if abs(mu0) > 3 * sig_mu0 and s.parameter != "payload_mass" else None
    since = s.days[onset]
    text = describe(s.parameter, s.joint, size, sigma, relative, str(since), test)
    return DriftFinding(s.robot_id, s.joint, s.parameter, test, since, size, sigma, relative, size / sigma, text)


def detect_drift(rows, options: DriftOptions | None = None, baseline_days: int = 7) -> list:
    """Drift findings of a history (``History.parameter_rows()``), the shift and CUSUM tests (module docstring).

    Series with no more days than the baseline window are not tested.
    """
    options = options or DriftOptions()
    window = options.baseline_days or baseline_days
    series = [s for s in series_of(rows) if s.values.size > window]
    if not series:
        return []
    n_tests = sum(s.values.size - window for s in series)
    threshold = float(stats.norm.isf(options.alpha / (2 * n_tests)))
    # the baseline mean's error is shared by every later day: the allowance covers it at the family-wise level
    margin = float(stats.norm.isf(options.alpha / (2 * len(series)))) / np.sqrt(window + 1)
    k = options.k + margin
    h = cusum_interval(2 * n_tests / options.alpha, k)
    findings = [_test_series(s, window, threshold, k, h, options) for s in series]
    return [f for f in findings if f is not None]
