"""The residual analysis of a short validation recording: a held-out part of 0.7 s (Kinova opti_traj_testing2 at
``--holdout 0.3``) keeps 9 samples on the 100 Hz grid; the cross-correlation's lags of up to 50 samples reached past
it and 'psdm diagnose MODEL --train opti_traj_testing2.csv' ended in a ValueError traceback.

Reference: numpy's full cross-correlation (``np.correlate``), normalised, at the lags the function scans."""

from __future__ import annotations

import numpy as np
import pytest

from identification.diagnosis.residual_tests import cross_correlation


@pytest.mark.parametrize("n", [2, 3, 9, 12, 60, 200])
def test_the_cross_correlation_of_a_short_series_is_numpys_at_every_lag_inside_it(n):
    rng = np.random.default_rng(n)
    signal = rng.normal(size=n + 5)
    residual, signal = signal[:n] + 0.1 * rng.normal(size=n), signal[5 : n + 5]  # shifted by 5 samples
    best, lag = cross_correlation(residual, signal)
    r, s = residual - residual.mean(), signal - signal.mean()
    full = np.correlate(r, s, "full") / np.sqrt((r @ r) * (s @ s))  # index n - 1 + k: sum_i r[i + k] s[i]
    lags = [k for k in range(-50, 51, 5) if abs(k) < n]
    expected = max(lags, key=lambda k: abs(full[n - 1 + k]))
    assert lag == expected and best == pytest.approx(full[n - 1 + expected], rel=1e-12)
    if n >= 60:  # long enough for the true shift to stand out
        assert lag == 5  # the shift found: residual[i + 5] = signal[i]
