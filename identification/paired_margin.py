"""The noise margin of a paired RMSE comparison: how far two models' RMSE on the same samples may differ by chance.

Two models' residuals on the same samples (row k of both at the same instant) -> per column the RMSE of each and the
standard error of their difference, from a circular block bootstrap (``BOOTSTRAP_SAMPLES`` draws, fixed seed) whose
block length is where the autocorrelation of the difference of the squared residuals first drops below 1/e (twice
that lag; at least ``n**(1/3)``): the RMSE change a different stretch of the same motion would give. The blocks wrap
around the recording's end (Politis and Romano's circular bootstrap): a plain moving-block bootstrap draws the first
and last samples in fewer blocks than the others, which on a short recording with long blocks (a fifth of it) centres
the draws away from the measured difference when the difference sits near an end, and understates their spread. The
never-worse gate of a refit (``calibration.never_worse``) asks ``MARGIN_SIGMAS`` of those standard errors, at least
``MARGIN_FLOOR`` of the RMSE before; the diagnosis asks the same of an elasticity against pre-sliding
(``diagnosis.presliding_or_elasticity``).

Where one model's error sits in a few bursts (a friction reversal the other model follows), the draws are skewed and
their standard error overstates the doubt of a large difference; the share of the draws in which one model is lower
(``share_lower``) does not. That share is what a finding must win by: an elasticity against pre-sliding on a held-out
training block (``presliding_or_elasticity``), a finding of the model ``diagnose --apply`` writes against the refit
without it (``calibration.no_gain``).
"""

from __future__ import annotations

import numpy as np

#: Standard errors of the paired RMSE difference a joint may rise by.
MARGIN_SIGMAS = 2.0
#: Smallest margin, as a fraction of the joint's validation RMSE before.
MARGIN_FLOOR = 0.01
#: Moving-block bootstrap draws of the paired RMSE difference (fixed seed: the same margin every run).
BOOTSTRAP_SAMPLES = 300


def noise_margin(before, standard_error) -> np.ndarray:
    """The never-worse margin [N m] per joint: ``MARGIN_SIGMAS`` standard errors of the paired RMSE difference, never
    below ``MARGIN_FLOOR`` of the RMSE ``before`` (the gate's, ``calibration.never_worse.MARGIN_RULE``, and the
    diagnosis report's rises, ``diagnosis.joint_changes``)."""
    return np.maximum(MARGIN_SIGMAS * np.asarray(standard_error, dtype=float), MARGIN_FLOOR * np.asarray(before))


def block_length(series: np.ndarray) -> int:
    """Block length [samples] of the (circular) block bootstrap of ``series`` (n_samples,): twice the first lag at
    which its autocorrelation drops below 1/e, at least ``n**(1/3)``, at most n / 5."""
    x = np.asarray(series, dtype=float) - np.mean(series)
    n = x.size
    floor = max(1, int(np.ceil(n ** (1.0 / 3.0))))
    if n < 10 or not np.any(x):
        return floor
    spectrum = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
    acf = acf / acf[0]
    below = np.flatnonzero(acf < np.exp(-1.0))
    lag = int(below[0]) if below.size else n
    return int(min(max(2 * lag, floor), max(1, n // 5)))


def paired_rmse_margin(before: np.ndarray, after: np.ndarray, seed: int = 0) -> tuple:
    """(RMSE before, RMSE after, standard error of their difference) per joint from residuals on the same samples.

    ``before``, ``after``: residuals [N m], shape (n_samples, n_dof), row k of both at the same instant. The
    standard error is of ``RMSE_after - RMSE_before`` over ``BOOTSTRAP_SAMPLES`` circular block resamples (the same
    blocks for both models: the difference is paired; ``paired_rmse_draws``; circular: every sample equally often).
    """
    rmse_before, rmse_after, draws = paired_rmse_draws(before, after, seed)
    return rmse_before, rmse_after, np.std(draws, axis=0, ddof=1)


def paired_rmse_draws(before: np.ndarray, after: np.ndarray, seed: int = 0) -> tuple:
    """(RMSE before, RMSE after, the circular block bootstrap draws of ``RMSE_after - RMSE_before``
    (``BOOTSTRAP_SAMPLES``, n_dof)) per joint from residuals on the same samples (``paired_rmse_margin``). Where one
    model's error sits in a few bursts (a friction reversal the other model follows), the draws are skewed and their
    standard error overstates the doubt of a large difference; the share of draws below zero does not."""
    before, after = np.atleast_2d(before), np.atleast_2d(after)
    n = min(len(before), len(after))
    e_b, e_a = before[:n] ** 2, after[:n] ** 2
    rng = np.random.default_rng(seed)
    draws = np.zeros((BOOTSTRAP_SAMPLES, e_b.shape[1]))
    for j in range(e_b.shape[1]):
        length = block_length(e_a[:, j] - e_b[:, j])
        starts = rng.integers(0, n, size=(BOOTSTRAP_SAMPLES, -(-n // length)))
        rows = ((starts[:, :, None] + np.arange(length)) % n).reshape(BOOTSTRAP_SAMPLES, -1)[:, :n]
        draws[:, j] = np.sqrt(e_a[rows, j].mean(axis=1)) - np.sqrt(e_b[rows, j].mean(axis=1))
    return np.sqrt(e_b.mean(axis=0)), np.sqrt(e_a.mean(axis=0)), draws


def share_lower(before: np.ndarray, after: np.ndarray, seed: int = 0) -> np.ndarray:
    """Per column, the share of the circular block bootstrap draws (``paired_rmse_draws``) in which ``after``'s RMSE
    is below ``before``'s, strictly: 0 where the two residuals are the same."""
    return np.mean(paired_rmse_draws(before, after, seed)[2] < 0.0, axis=0)
