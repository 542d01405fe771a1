"""Residual analysis of a model on a recording: where the error lives, per joint, with its evidence in numbers.

For each joint the residual (measured minus model torque) is broken down by time window, by regime
(velocity sign, speed, near reversals, position, acceleration and load terciles), tested for whiteness
(Ljung-Box) and cross-correlated with the joint's position, velocity, acceleration and torque; its
spectrum gives the dominant frequency. ``analyse_residuals`` returns ``ResidualFinding`` values whose
``text`` reads like "joint 2: RMS 3.1 N m, 2.4x larger for qd > 0 than for qd < 0".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.metrics import rms


@dataclass(frozen=True)
class ResidualFinding:
    """One number about a joint's residual: which test, the value, and a sentence."""

    joint: int
    test: str
    value: float
    text: str

    def to_dict(self) -> dict:
        return {"joint": self.joint + 1, "test": self.test, "value": float(self.value), "text": self.text}


def ljung_box(residual, lags: int = 20) -> tuple[float, float]:
    """Ljung-Box Q statistic and p-value of the hypothesis 'white residual' over ``lags`` lags."""
    x = np.asarray(residual, dtype=float) - np.mean(residual)
    n = x.size
    denom = float(x @ x)
    if denom <= 0 or n <= lags + 1:
        return 0.0, 1.0
    acf = np.array([float(x[:-k] @ x[k:]) / denom for k in range(1, lags + 1)])
    q = n * (n + 2) * float(np.sum(acf**2 / (n - np.arange(1, lags + 1))))
    return q, float(stats.chi2.sf(q, lags))


def cross_correlation(residual, signal, max_lag: int = 50) -> tuple[float, int]:
    """Largest normalised cross-correlation between residual and signal over lags -max_lag..max_lag, and its lag."""
    r = np.asarray(residual, dtype=float) - np.mean(residual)
    s = np.asarray(signal, dtype=float) - np.mean(signal)
    norm = np.sqrt(float(r @ r) * float(s @ s))
    if norm <= 0:
        return 0.0, 0
    best, lag_best = 0.0, 0
    n = r.size
    step = max(1, max_lag // 10)
    max_lag = min(max_lag, step * ((n - 1) // step))  # a short recording (a held-out part of 0.7 s): lags inside it
    for lag in range(-max_lag, max_lag + 1, step):
        c = float(r[max(0, lag) : n + min(0, lag)] @ s[max(0, -lag) : n - max(0, lag)]) / norm
        if abs(c) > abs(best):
            best, lag_best = c, lag
    return best, lag_best


def dominant_frequency(t, residual) -> tuple[float, float]:
    """Frequency [Hz] of the largest spectral peak of the residual and the share (0..1) of its power (without the
    0 Hz bin) within +-10 % of the peak and one bin: a fraction of the same bins it is divided by."""
    x = np.asarray(residual, dtype=float) - np.mean(residual)
    dt = float(np.median(np.diff(t)))
    power = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    freq = np.fft.rfftfreq(x.size, dt)
    if power.size < 3 or power[1:].sum() <= 0:
        return 0.0, 0.0
    k = int(np.argmax(power[1:])) + 1
    band = np.abs(freq - freq[k]) <= 0.1 * freq[k] + freq[1]
    band[0] = False  # the 0 Hz bin is left out of the total; a peak at the first bins must not count it
    return float(freq[k]), float(power[band].sum() / power[1:].sum())


def _rms(x) -> float:
    """RMS of a slice of the residual, 0 for an empty slice (a regime the recording never visits)."""
    return float(rms(x)) if x.size else 0.0


def _mean_text(x) -> str:
    """The mean of a regime's residual, or that the recording has no sample in it (not a mean of 0)."""
    return f"{np.mean(x):+.3g} N m" if x.size else "no sample"


def analyse_residuals(context, residual, n_windows: int = 8) -> tuple:
    """Residual findings for every joint (see the module docstring).

    Parameters
    ----------
    context : DiagnosisContext
    residual : array (n_samples, n_dof)
        Measured minus model torque [N m].

    Returns
    -------
    tuple of ResidualFinding
    """
    out = []
    for j in range(context.n_dof):
        out.extend(_joint_findings(context, j, residual[:, j], n_windows))
    return tuple(out)


def _joint_findings(context, j: int, r, n_windows: int) -> list:
    """The findings of joint ``j`` with residual ``r`` (n_samples,): its RMS, then (unless it is zero) where in
    time, in which regime and in which signal the error lives."""
    total = _rms(r)
    out = [ResidualFinding(j, "rms", total, f"joint {j + 1}: residual RMS {total:.3g} N m, mean {np.mean(r):+.3g} N m")]
    if total <= 0:
        return out
    out.append(_worst_window(context.t, j, r, total, n_windows))
    out.extend(_regime_findings(context, j, r, total))
    out.extend(_signal_findings(context, j, r))
    return out


def _worst_window(t, j: int, r, total: float, n_windows: int) -> ResidualFinding:
    """The time window (of ``n_windows`` equal ones) with the largest RMS, relative to the overall RMS."""
    windows = np.array_split(np.arange(r.size), n_windows)
    rms_w = np.array([_rms(r[w]) for w in windows])
    k = int(np.argmax(rms_w))
    return ResidualFinding(
        j,
        "worst_window",
        float(rms_w[k] / total),
        f"joint {j + 1}: largest error in t = {t[windows[k][0]]:.1f}..{t[windows[k][-1]]:.1f} s "
        f"(RMS {rms_w[k]:.3g} N m, {rms_w[k] / total:.2f}x the overall RMS)",
    )


def _regime_findings(context, j: int, r, total: float) -> list:
    """The residual by regime: velocity sign, near reversals, and terciles of position, acceleration, load, speed."""
    qd, q, qdd, tau = context.qd[:, j], context.q[:, j], context.qdd[:, j], context.tau[:, j]
    pos, neg = r[qd > 0], r[qd < 0]
    out = [
        ResidualFinding(
            j,
            "velocity_sign",
            float(np.mean(pos) - np.mean(neg)) if pos.size and neg.size else 0.0,
            f"joint {j + 1}: mean residual {_mean_text(pos)} for qd > 0, {_mean_text(neg)} for qd < 0",
        )
    ]
    slow = np.abs(qd) < 0.1 * np.max(np.abs(qd))
    near = (f"{_rms(r[slow]):.3g} N m vs {_rms(r[~slow]):.3g} N m elsewhere" if slow.any() else
            "none: the joint never slows below a tenth of its top speed here")  # fmt: skip
    out.append(
        ResidualFinding(
            j,
            "near_reversal",
            _rms(r[slow]) / total,
            f"joint {j + 1}: RMS near velocity reversals (|qd| < 10 % of max) {near}",
        )
    )
    for name, signal in (("position", q), ("acceleration", qdd), ("load", np.abs(tau)), ("speed", np.abs(qd))):
        edges = np.quantile(signal, [1 / 3, 2 / 3])
        bins = [r[signal <= edges[0]], r[(signal > edges[0]) & (signal <= edges[1])], r[signal > edges[1]]]
        rms_b = [_rms(b) for b in bins]
        out.append(
            ResidualFinding(
                j,
                f"{name}_terciles",
                max(rms_b) / max(min(rms_b), 1e-12),
                f"joint {j + 1}: RMS by {name} tercile (low/mid/high) "
                + " / ".join(f"{v:.3g}" for v in rms_b)
                + " N m",
            )
        )
    return out


def _signal_findings(context, j: int, r) -> list:
    """The residual as a signal: whiteness (Ljung-Box), correlation with q, qd, qdd, tau, and its spectral peak."""
    qd, q, qdd, tau = context.qd[:, j], context.q[:, j], context.qdd[:, j], context.tau[:, j]
    qstat, pvalue = ljung_box(r)
    out = [
        ResidualFinding(
            j,
            "ljung_box_p",
            pvalue,
            f"joint {j + 1}: Ljung-Box Q = {qstat:.3g} over 20 lags, p = {pvalue:.3g} "
            f"({'white' if pvalue > 0.05 else 'not white'})",
        )
    ]
    for name, signal in (("q", q), ("qd", qd), ("qdd", qdd), ("tau", tau)):
        c, lag = cross_correlation(r, signal)
        out.append(
            ResidualFinding(
                j, f"xcorr_{name}", c, f"joint {j + 1}: correlation with {name}{j + 1} {c:+.2f} at lag {lag} samples"
            )
        )
    f, share = dominant_frequency(context.t, r)
    out.append(
        ResidualFinding(
            j,
            "dominant_frequency_hz",
            f,
            f"joint {j + 1}: spectral peak at {f:.3g} Hz holding {share:.0%} of the power",
        )
    )
    return out
