"""The daily update of one robot: its baseline's validation error, then what changes refitted by least squares.

On a day's prepared recordings (``trajectory_data.prepare_recording``: filtered, differentiated, decimated) the
rigid-body torque of the baseline ``Y(q, qd, qdd) theta`` is held and the columns that change from day to day
are refitted: Coulomb and viscous friction per joint (``trajectory_data.drive_columns``), the tracked and carried
terms (``findings.FindingColumns``: springs, ripples, offsets), a payload mass at a flange point
(``payload.payload_torque`` of a unit mass) and, when the recordings hold currents, the torque constant of each
joint where the data determine it (then ``kt_j i_j - D_j f = Y_j theta``; a constant with a relative sigma
above 5 % is held at its nominal value: on a joint whose rigid-body torque is small beside its friction, the
constant and the friction scale together). It is one linear least-squares problem
(``estimator.weighted_least_squares``): ordinary least squares first, then each joint's rows weighted by
``1 / (sigma_j^2 c_j)`` with ``sigma_j`` its residual RMS and ``c_j = (1 + rho_j) / (1 - rho_j)`` the variance
inflation of its residual's lag-one correlation ``rho_j`` (filtered, decimated residuals are not white), so
that the standard deviations are honest ones.

Reported parameters: ``fc<j>``, ``fv<j>``, ``kt<j>``, the terms' features (``spring_k_<j>``, ``bias_<j>``,
...), a ripple's amplitude ``ripple_amp<h>_<j>`` (from its sine and cosine, sigma by linearisation) and
``payload_mass``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.estimator import weighted_least_squares
from identification.calibration.findings import FindingColumns
from identification.calibration.payload import payload_torque
from identification.calibration.trajectory_data import drive_columns
from identification.data.payload import Payload
from identification.fleet.baseline import FRICTION, Baseline

__all__ = ["DayFit", "refit_day"]

MAX_INFLATION = 50.0
KT_MAX_RELATIVE = 0.05  # a torque constant less certain than this is held (see _fit_currents)


@dataclass(frozen=True)
class DayFit:
    """Parameters of one robot-day with standard deviations, and the baseline's and the refit's errors.

    Attributes
    ----------
    names : tuple of str
    joints : tuple of int
        1-based joint of each parameter (0: the robot, e.g. the payload).
    values, sigmas : array, shape (n_parameters,)
    rmse_baseline, rmse_refit : array, shape (n_dof,)
        [N m] per joint: the baseline model's torque error on the day (the cheapest drift signal) and the refit's.
    n_samples : int
        Prepared samples used.
    """

    names: tuple
    joints: tuple
    values: np.ndarray
    sigmas: np.ndarray
    rmse_baseline: np.ndarray
    rmse_refit: np.ndarray
    n_samples: int


def _columns(baseline: Baseline, q, qd, qdd) -> tuple:
    """(names, joints, columns (n_samples, n_dof, k)) of the refitted torque terms."""
    n = baseline.robot.n_dof
    blocks = [drive_columns(qd, qdd, FRICTION, (), baseline.coulomb_velocity)]
    names = [f"{t}{j + 1}" for j in range(n) for t in FRICTION]
    joints = [j + 1 for j in range(n) for _ in FRICTION]
    if baseline.terms:
        extra = FindingColumns(baseline.terms)
        blocks.append(extra.columns(q, qd, qdd))
        names += extra.names
        joints += [term.joint + 1 for term in baseline.terms for _ in term.feature_names()]
    if baseline.payload_com is not None:
        unit = Payload(mass=1.0, com=tuple(baseline.payload_com))
        blocks.append(payload_torque(baseline.robot, unit, q, qd, qdd)[:, :, None])
        names.append("payload_mass")
        joints.append(0)
    return names, joints, np.concatenate(blocks, axis=2)


def _baseline_values(baseline: Baseline) -> np.ndarray:
    values = [baseline.friction.reshape(-1), baseline.term_values]
    if baseline.payload_com is not None:
        values.append(np.zeros(1))
    return np.concatenate(values)


def _inflation(residual: np.ndarray) -> np.ndarray:
    """Per joint ``(1 + rho) / (1 - rho)`` of the lag-one correlation ``rho`` of each column of ``residual``."""
    r = residual - residual.mean(axis=0)
    rho = np.sum(r[1:] * r[:-1], axis=0) / np.maximum(np.sum(r * r, axis=0), 1e-300)
    rho = np.clip(rho, 0.0, 0.99)
    return np.minimum((1.0 + rho) / (1.0 - rho), MAX_INFLATION)


def _solve(matrix, target, n_dof: int, n_samples: int):
    """Two-step weighted least squares on rows ordered (sample, joint): weights from the OLS residuals."""
    first = weighted_least_squares(matrix, target)
    residual = (target - matrix @ first.coefficients).reshape(n_samples, n_dof)
    sigma2 = np.maximum(np.mean(residual**2, axis=0), 1e-300) * _inflation(residual)
    weights = np.tile(1.0 / sigma2, n_samples)
    result = weighted_least_squares(matrix, target, weights)
    # the weights are 1 / variance: the covariance is (A^T W A)^-1, not rescaled by the weighted residual
    covariance = result.covariance / max(result.sigma2, 1e-300)
    return result.coefficients, np.sqrt(np.clip(np.diag(covariance), 0.0, None)), covariance


def _with_amplitudes(names, joints, values, sigmas, covariance) -> tuple:
    """Append each ripple's amplitude ``hypot(sin, cos)`` with its linearised sigma."""
    names, joints, values, sigmas = list(names), list(joints), list(values), list(sigmas)
    for k, name in enumerate(list(names)):
        if name.startswith("ripple_sin"):
            c = k + 1
            amplitude = float(np.hypot(values[k], values[c]))
            grad = np.array([values[k], values[c]]) / max(amplitude, 1e-300)
            block = covariance[np.ix_([k, c], [k, c])]
            names.append(name.replace("ripple_sin", "ripple_amp"))
            joints.append(joints[k])
            values.append(amplitude)
            sigmas.append(float(np.sqrt(max(grad @ block @ grad, 0.0))))
    return tuple(names), tuple(joints), np.asarray(values), np.asarray(sigmas)


def _stack(baseline: Baseline, model, prepared: list) -> tuple:
    """(names, joints, held torque, measured signal, columns) of the day's prepared recordings, stacked."""
    held, measured, columns = [], [], []
    for rec in prepared:
        held.append(model.inverse_dynamics(rec.q, rec.qd, rec.qdd, baseline.theta))
        names, joints, block = _columns(baseline, rec.q, rec.qd, rec.qdd)
        measured.append(rec.tau)
        columns.append(block)
    return names, joints, np.concatenate(held), np.concatenate(measured), np.concatenate(columns)


def _fit_currents(held, current, columns, kt_nominal) -> tuple:
    """(fitted kt joints, x, sigmas, covariance) of ``kt_j i_j - D_j f = Y_j theta``.

    A torque constant whose relative sigma exceeds ``KT_MAX_RELATIVE`` (a joint whose rigid-body torque is small
    beside its friction: the constant and the friction then scale together) is held at the nominal value.
    """
    n_samples, n = current.shape
    fitted = np.arange(n)
    for attempt in range(2):
        diag = np.zeros((n_samples, n, fitted.size))
        diag[:, fitted, np.arange(fitted.size)] = current[:, fitted]
        held_kt = np.setdiff1d(np.arange(n), fitted)
        target = held.copy()
        target[:, held_kt] -= current[:, held_kt] * kt_nominal[held_kt]
        matrix = np.concatenate([diag, -columns], axis=2).reshape(n_samples * n, -1)
        x, s, covariance = _solve(matrix, target.reshape(-1), n, n_samples)
        weak = s[: fitted.size] > KT_MAX_RELATIVE * np.abs(x[: fitted.size])
        if attempt or not weak.any():
            break
        fitted = fitted[~weak]
    return fitted, x, s, covariance


def refit_day(baseline: Baseline, model, prepared: list, currents: bool) -> DayFit:
    """Refit a robot-day (module docstring) on prepared recordings of one kind.

    ``prepared`` recordings hold in ``tau`` the joint torque [N m], or with ``currents`` the motor current [A]
    (the torque constants are then refitted too, where the data determine them).
    """
    n = baseline.robot.n_dof
    names, joints, held, signal, columns = _stack(baseline, model, prepared)
    n_samples = held.shape[0]
    measured = signal * baseline.kt if currents else signal
    rmse_baseline = np.sqrt(np.mean((measured - held - columns @ _baseline_values(baseline)) ** 2, axis=0))
    if currents:
        fitted, x, s, covariance = _fit_currents(held, signal, columns, baseline.kt)
        kt = baseline.kt.copy()
        kt[fitted] = x[: fitted.size]
        names = [f"kt{j + 1}" for j in fitted] + names
        joints = [int(j) + 1 for j in fitted] + joints
        refit = signal * kt - columns @ x[fitted.size :] - held
    else:
        x, s, covariance = _solve(columns.reshape(n_samples * n, -1), (signal - held).reshape(-1), n, n_samples)
        refit = measured - held - columns @ x
    rmse_refit = np.sqrt(np.mean(refit**2, axis=0))
    names, joints, values, sigmas = _with_amplitudes(names, joints, x, s, covariance)
    return DayFit(names, joints, values, sigmas, rmse_baseline, rmse_refit, n_samples)
