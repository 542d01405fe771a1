"""The shared fit metrics against their textbook definitions, on 1-D and 2-D input and edge cases."""

import numpy as np
import pytest

from identification.metrics import explained_rms, is_constant, r2, rms, rmse


def test_rmse_and_r2_match_definitions_per_column():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(200, 3))
    p = y + 0.1 * rng.normal(size=y.shape)
    for j in range(3):
        e = y[:, j] - p[:, j]
        assert rmse(y[:, j], p[:, j]) == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-14)
        ss_tot = np.sum((y[:, j] - y[:, j].mean()) ** 2)
        assert r2(y[:, j], p[:, j]) == pytest.approx(1 - np.sum(e**2) / ss_tot, rel=1e-14)
    np.testing.assert_allclose(rmse(y, p), [rmse(y[:, j], p[:, j]) for j in range(3)], rtol=1e-14)
    np.testing.assert_allclose(r2(y, p), [r2(y[:, j], p[:, j]) for j in range(3)], rtol=1e-14)
    assert rms(y[:, 0]) == pytest.approx(np.sqrt(np.mean(y[:, 0] ** 2)), rel=1e-14)


def test_constant_and_empty_signals_give_nan_not_infinity():
    y = np.full(50, 3.0)
    assert is_constant(y)
    assert np.isnan(r2(y, y + 0.1))
    assert rmse(y, y + 0.1) == pytest.approx(0.1)
    assert np.isnan(rmse([], [])) and np.isnan(r2([], []))
    both = np.column_stack([y, np.arange(50.0)])
    values = r2(both, both)
    assert np.isnan(values[0]) and values[1] == 1.0
    assert list(is_constant(both)) == [True, False]


def test_explained_rms_is_the_size_of_an_effect_a_model_takes_out_whatever_noise_it_leaves():
    # known truth: a residual of an effect of RMS e = 0.02 (a sine) plus noise of RMS n = 0.015, uncorrelated; the model
    # that takes the effect out leaves the noise. The RMSE drops by sqrt(e^2 + n^2) - n = 0.010 only, half the effect,
    # while the torque the model explains is the effect's RMS; a model that makes the residual worse explains nothing
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 100.0, 200_001)
    effect = 0.02 * np.sqrt(2.0) * np.sin(2.0 * np.pi * 0.37 * t)
    noise = 0.015 * rng.standard_normal(t.size)
    before, after = rms(effect + noise), rms(noise)
    assert before - after == pytest.approx(np.sqrt(0.02**2 + 0.015**2) - 0.015, abs=3e-4)  # 0.010, half the effect
    assert explained_rms(before, after) == pytest.approx(0.02, rel=0.02)
    np.testing.assert_allclose(explained_rms([before, 0.1], [after, 0.2]), [explained_rms(before, after), 0.0])
    assert explained_rms(0.05, 0.05) == 0.0
