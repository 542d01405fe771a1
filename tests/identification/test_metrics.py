"""The shared fit metrics against their textbook definitions, on 1-D and 2-D input and edge cases."""

import numpy as np
import pytest

from identification.metrics import is_constant, r2, rms, rmse


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
