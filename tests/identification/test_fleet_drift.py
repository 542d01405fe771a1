"""The drift tests: quiet on healthy histories (family-wise), a step and a ramp found with onset and size."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from identification.fleet.drift import DriftOptions, cusum_interval, detect_drift
from identification.fleet.history import ParameterRow
from identification.fleet.phrases import describe

START = dt.date(2026, 10, 1)


def _rows(robot_id, name, joint, values, sigmas):
    return [ParameterRow(robot_id, START + dt.timedelta(days=d), name, joint, float(v), float(s))
            for d, (v, s) in enumerate(zip(values, sigmas))]  # fmt: skip


def _healthy(rng, n_series=300, n_days=30, jitter=0.5):
    """Series whose day-to-day scatter exceeds their least-squares sigma (``jitter``: over-dispersion)."""
    rows = []
    for k in range(n_series):
        sigma = rng.uniform(0.05, 0.2) * np.ones(n_days)
        values = 10.0 + sigma * rng.standard_normal(n_days) + jitter * sigma[0] * rng.standard_normal(n_days)
        rows += _rows(f"r{k // 30:02d}", f"fc{k % 30 % 6 + 1}" if k % 30 < 6 else f"fv{k % 30}", 1, values, sigma)
    return rows


def test_healthy_histories_give_no_alarm(rng):
    assert detect_drift(_healthy(rng), DriftOptions(), baseline_days=7) == []


def test_a_step_is_found_with_its_onset_and_size(rng):
    sigma = np.full(30, 0.1)
    values = 5.0 + 0.1 * rng.standard_normal(30)
    values[18:] += 1.0  # +20 %, 10 sigma, from day 18
    rows = _healthy(rng) + _rows("r99", "fc3", 3, values, sigma)
    findings = detect_drift(rows, baseline_days=7)
    assert [(f.robot_id, f.parameter) for f in findings] == [("r99", "fc3")]
    f = findings[0]
    assert f.test in ("shift", "cusum") and f.onset == START + dt.timedelta(days=18)
    assert abs(f.size - 1.0) < 2 * f.size_sigma and f.relative_percent == pytest.approx(20, abs=3)
    assert f.text.startswith("joint 3 Coulomb friction +2") and "gearbox wear or lubrication" in f.text


def test_a_slow_drift_is_found_by_the_cusum_near_its_start(rng):
    sigma = np.full(40, 0.1)
    values = 5.0 + 0.1 * rng.standard_normal(40)
    values[15:] += 0.08 * np.arange(1, 26)  # 0.8 sigma a day from day 15
    findings = detect_drift(_rows("r01", "kt2", 2, 40.0 - (values - 5.0), sigma), baseline_days=7)
    assert len(findings) == 1
    f = findings[0]
    assert abs((f.onset - START).days - 15) <= 3 and f.size < 0
    assert abs(f.size + 2.0) < 2 * f.size_sigma
    assert "torque constant" in f.text and "drive degrading" in f.text


def test_cusum_interval_matches_siegmund():
    # k = 0.5, h = 4: ARL = (exp(2 k b) - 2 k b - 1) / (2 k^2), b = 5.166 -> 338 (Montgomery's table: 336)
    assert cusum_interval(338.0, 0.5) == pytest.approx(4.0, abs=0.06)
    assert cusum_interval(1e6, 0.5) > cusum_interval(1e4, 0.5) > cusum_interval(1e2, 0.5)


def test_describe_names_the_effect():
    text = describe("spring_k_2", 2, -40.0, 4.0, -30.0, "2026-10-12", "cusum")
    assert text == (
        "joint 2 spring (counterbalance) stiffness -30 % since 2026-10-12 (-40 +- 4 N m/rad, 10 sigma): "
        "counterbalance losing pressure or a weakened spring"
    )


def test_a_rising_validation_error_names_the_diagnosis(rng):
    """The baseline's validation RMSE as a series: a 40 % rise alarms, a few-% wander does not."""
    from identification.fleet.drift import validation_parameters

    days = [START + dt.timedelta(days=d) for d in range(30)]
    quiet = 2.0 * (1 + 0.02 * rng.standard_normal(30))
    rising = 2.0 * (1 + 0.02 * rng.standard_normal(30))
    rising[20:] *= 1.4
    rows = [("r01", d, 1, q, q) for d, q in zip(days, quiet)] + [("r02", d, 3, r, r) for d, r in zip(days, rising)]
    findings = detect_drift(validation_parameters(rows), baseline_days=7)
    assert [(f.robot_id, f.parameter, f.onset) for f in findings] == [("r02", "rmse_3", days[20])]
    assert "the fleet diagnoses the days its refit does not explain" in findings[0].text
