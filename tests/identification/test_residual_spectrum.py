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


def test_a_regime_the_recording_never_visits_is_named_not_given_a_zero():
    """The Kinova's 4.7 s validation log moves six of its joints one way only: their residual has no sample with
    qd < 0 and none near a reversal, which the report said as '+0 N m' and '0 N m'."""
    from types import SimpleNamespace

    from identification.diagnosis.residual_tests import analyse_residuals

    t = np.linspace(0.0, 4.0, 400)
    qd = np.column_stack([0.5 + 0.2 * np.sin(t), np.cos(2.0 * t)])  # joint 1 one way, joint 2 reversing
    q, qdd = np.cumsum(qd, axis=0) * (t[1] - t[0]), np.gradient(qd, t, axis=0)
    context = SimpleNamespace(n_dof=2, t=t, q=q, qd=qd, qdd=qdd, tau=np.ones_like(qd))
    residual = np.column_stack([1.0 + 0.1 * np.sin(3.0 * t), 0.2 * np.sign(qd[:, 1])])
    text = {(f.joint, f.test): f.text for f in analyse_residuals(context, residual)}
    assert text[(0, "velocity_sign")].endswith("+1 N m for qd > 0, no sample for qd < 0")
    assert text[(0, "near_reversal")].endswith("none: the joint never slows below a tenth of its top speed here")
    assert text[(1, "velocity_sign")].endswith("+0.2 N m for qd > 0, -0.2 N m for qd < 0")
    assert "N m elsewhere" in text[(1, "near_reversal")]
