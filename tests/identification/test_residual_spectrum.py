"""The residual's spectral peak: its frequency and the share of the residual's power it holds, a fraction <= 1."""

import numpy as np
import pytest

from identification.diagnosis.residual_tests import dominant_frequency


@pytest.mark.parametrize("sine_share", [0.2, 0.4, 0.9])
def test_share_of_a_sinusoid_in_white_noise_is_its_power_fraction(sine_share):
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 20.0, 0.002)
    amplitude = 1.0
    noise_std = np.sqrt(amplitude**2 / 2 * (1 - sine_share) / sine_share)  # sine power A^2/2 is sine_share of all
    residual = amplitude * np.sin(2 * np.pi * 5.0 * t + 0.3) + rng.normal(scale=noise_std, size=t.size) + 0.7
    frequency, share = dominant_frequency(t, residual)
    assert frequency == pytest.approx(5.0, abs=0.05)
    band = 2 * (0.1 * 5.0 + 0.05) / 250.0  # the noise in the +-10 % band: its width over the 250 Hz Nyquist band
    assert share == pytest.approx(sine_share + (1 - sine_share) * band, abs=0.02)


@pytest.mark.parametrize("residual", ["slow sine", "drift", "offset sine"])
def test_a_peak_at_the_lowest_bins_holds_at_most_all_the_power(residual):
    t = np.arange(0.0, 10.0, 0.002)
    signal = {
        "slow sine": np.sin(2 * np.pi * 0.05 * t),  # half a period: the peak sits next to 0 Hz
        "drift": np.cumsum(np.random.default_rng(0).normal(size=t.size)),
        "offset sine": np.sin(2 * np.pi * 0.1 * t) + 0.3,
    }[residual]
    frequency, share = dominant_frequency(t, signal)
    assert frequency == pytest.approx(0.1) and 0.5 < share <= 1.0
