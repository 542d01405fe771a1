"""The daily update streams its rows in chunks (bounded memory) and equals the whole least-squares solve to 1e-10:
the reference here builds the whole stacked matrix and solves it with ``weighted_least_squares`` directly."""

from __future__ import annotations

import dataclasses
import tracemalloc

import numpy as np
import pytest

from identification.calibration.estimator import weighted_least_squares
from identification.fleet import update
from identification.fleet.baseline import SharedModels, build_baseline
from identification.fleet.layout import read_fleet
from identification.fleet.plan import plan_run
from identification.fleet.session import read_session
from identification.fleet.streamed import StreamedRows
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet


def _whole_solve(matrix, target, n, m):
    """The two-step weighted least squares on the whole matrix (rows ordered sample, joint)."""
    first = weighted_least_squares(matrix, target)
    r = (target - matrix @ first.coefficients).reshape(m, n)
    r = r - r.mean(axis=0)
    rho = np.clip(np.sum(r[1:] * r[:-1], axis=0) / np.sum(r * r, axis=0), 0.0, 0.99)
    raw = (target - matrix @ first.coefficients).reshape(m, n)
    sigma2 = np.mean(raw**2, axis=0) * np.minimum((1 + rho) / (1 - rho), update.MAX_INFLATION)
    result = weighted_least_squares(matrix, target, np.tile(1.0 / sigma2, m))
    return result.coefficients, np.sqrt(np.diag(result.covariance / result.sigma2))


def _reference(baseline, model, prepared, currents, fitted):
    """(values, sigmas, rmse_baseline) of the whole solve with the torque constants of ``fitted`` joints."""
    n = baseline.robot.n_dof
    held = np.concatenate([model.inverse_dynamics(r.q, r.qd, r.qdd, baseline.theta) for r in prepared])
    cols = np.concatenate([update.refit_columns(baseline, r.q, r.qd, r.qdd)[2] for r in prepared])
    signal = np.concatenate([r.tau for r in prepared])
    m = held.shape[0]
    measured = signal * baseline.kt if currents else signal
    rmse = np.sqrt(np.mean((measured - held - cols @ update.baseline_values(baseline)) ** 2, axis=0))
    diag = np.zeros((m, n, fitted.size))
    diag[:, fitted, np.arange(fitted.size)] = signal[:, fitted]
    target = held.copy()
    held_kt = np.setdiff1d(np.arange(n), fitted)
    target[:, held_kt] -= signal[:, held_kt] * (baseline.kt[held_kt] if currents else 1.0)
    matrix = np.concatenate([diag, -cols], axis=2).reshape(m * n, -1)
    values, sigmas = _whole_solve(matrix, target.reshape(-1), n, m)
    return values, sigmas, rmse


@pytest.fixture(scope="module")
def day(tmp_path_factory, denso_model):
    folder = tmp_path_factory.mktemp("fleet") / "fleet"
    write_virtual_fleet(folder, VirtualFleetOptions(n_robots=2, n_days=2, duration=4.0, baseline_days=2, seed=5))
    fleet = read_fleet(folder)
    baseline, model = build_baseline(fleet.robots[1], fleet.track, SharedModels(lambda robot: denso_model))
    tasks = [t for t in plan_run(fleet).tasks if t.robot_id == fleet.robots[1].robot_id]
    prepared = [p for t in tasks for p in read_session(t, baseline)[0]]  # two days: two recordings
    return baseline, model, prepared


def _close(a, b, rel=1e-10):
    return np.max(np.abs(np.asarray(a) - b) / np.maximum(np.abs(b), 1e-12)) < rel


@pytest.mark.parametrize("currents", [True, False])
def test_streamed_update_equals_the_whole_solve(day, monkeypatch, currents):
    baseline, model, prepared = day
    if not currents:  # the same day as joint torques (the currents times the robot's constants)
        prepared = [dataclasses.replace(r, tau=r.tau * baseline.kt) for r in prepared]
    monkeypatch.setattr(update, "CHUNK", 97)  # many chunks, one across the two recordings' junction
    fit = update.refit_day(baseline, model, prepared, currents)
    fitted = np.array([int(name[2:]) - 1 for name in fit.names if name.startswith("kt")], dtype=int)
    assert (fitted.size > 0) == currents
    values, sigmas, rmse = _reference(baseline, model, prepared, currents, fitted)
    k = values.size
    assert _close(fit.values[:k], values) and _close(fit.sigmas[:k], sigmas) and _close(fit.rmse_baseline, rmse)
    assert fit.n_samples == sum(r.n_samples for r in prepared)


def test_residual_moments_equal_the_residuals_own(rng):
    """Mean square and lag-one correlation of a residual from the factors alone, chunks of any size."""
    rows = rng.standard_normal((500, 3, 4)).cumsum(axis=0)  # correlated rows
    streamed = StreamedRows(3, 4)
    for start in (0, 1, 8, 200, 333):
        stop = {0: 1, 1: 8, 8: 200, 200: 333, 333: 500}[start]
        streamed.add(rows[start:stop])
    c = rng.standard_normal((3, 4))
    r = np.einsum("sjw,jw->sj", rows, c)
    centred = r - r.mean(axis=0)
    rho = np.sum(centred[1:] * centred[:-1], axis=0) / np.sum(centred**2, axis=0)
    mean_square, lag = streamed.residual_moments(c)
    assert np.allclose(mean_square, np.mean(r**2, axis=0), rtol=1e-11) and np.allclose(lag, rho, rtol=1e-9)


def test_memory_of_the_update_does_not_grow_with_the_recording(day, monkeypatch):
    """Eight times the samples: the update's peak allocation stays within 1.3x (the rows are streamed)."""
    baseline, model, prepared = day
    monkeypatch.setattr(update, "CHUNK", 64)
    rec = prepared[0]
    long = dataclasses.replace(rec, **{f: np.tile(getattr(rec, f), (8, 1)) for f in ("q", "qd", "qdd", "tau")},
                               t=np.arange(8 * rec.n_samples) * (rec.t[1] - rec.t[0]))  # fmt: skip
    peaks = []
    for recording in (rec, long):
        tracemalloc.start()
        update.refit_day(baseline, model, [recording], True)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 1.3 * peaks[0], peaks
