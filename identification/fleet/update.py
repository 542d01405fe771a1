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
that the standard deviations are honest ones. The rows are streamed in chunks of samples into per-joint QR
factors (:mod:`identification.fleet.streamed`), so a day's memory is bounded whatever its length, and the result
equals the whole matrix's solve to rounding.

Reported parameters: ``fc<j>``, ``fv<j>``, ``kt<j>``, the terms' features (``spring_k_<j>``, ``bias_<j>``,
...), a ripple's amplitude ``ripple_amp<h>_<j>`` (from its sine and cosine, sigma by linearisation) and
``payload_mass``.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from identification.calibration.estimator import weighted_least_squares
from identification.calibration.findings import FindingColumns
from identification.calibration.payload import payload_torque
from identification.calibration.trajectory_data import drive_columns
from identification.data.payload import Payload
from identification.fleet.baseline import FRICTION, Baseline
from identification.fleet.streamed import StreamedRows

__all__ = ["CHUNK", "DayFit", "baseline_values", "refit_columns", "refit_day", "uncached"]

MAX_INFLATION = 50.0
KT_MAX_RELATIVE = 0.05  # a torque constant less certain than this is held (see _fit)
CHUNK = 4096  # samples per chunk of rows (bounds the memory of a day, whatever its length)


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


@contextmanager
def uncached(model):
    """The model's memory of evaluated states off while the update runs: each chunk of a day is evaluated once, and
    a Dask worker keeps its model for the whole run, so the memory would grow to the cache's budget."""
    cache = getattr(model, "state_cache", None)
    if cache is None:
        yield
        return
    budget, cache.max_bytes = cache.max_bytes, 0
    try:
        yield
    finally:
        cache.max_bytes = budget


def refit_columns(baseline: Baseline, q, qd, qdd) -> tuple:
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


def baseline_values(baseline: Baseline) -> np.ndarray:
    values = [baseline.friction.reshape(-1), baseline.term_values]
    if baseline.payload_com is not None:
        values.append(np.zeros(1))
    return np.concatenate(values)


def _inflation(rho: np.ndarray) -> np.ndarray:
    """Per joint ``(1 + rho) / (1 - rho)`` of the lag-one correlations ``rho`` of the residuals (clipped)."""
    rho = np.clip(rho, 0.0, 0.99)
    return np.minimum((1.0 + rho) / (1.0 - rho), MAX_INFLATION)


def _solve(rows: StreamedRows, embedding: list, constant: np.ndarray):
    """Two-step weighted least squares: each joint's weight from the OLS residual (module docstring)."""
    first = weighted_least_squares(*rows.system(embedding, constant))
    x = first.coefficients
    mean_square, rho = rows.residual_moments(np.array([e @ x for e in embedding]) + constant)
    sigma2 = np.maximum(mean_square, 1e-300) * _inflation(rho)
    result = weighted_least_squares(*rows.system(embedding, constant, 1.0 / sigma2))
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


def _accumulate(baseline: Baseline, model, prepared: list) -> tuple:
    """(names, joints, rows) of the day's prepared recordings: per joint the augmented rows
    ``[signal_j, D_j, held_j]`` streamed in chunks of ``CHUNK`` samples into their QR factors."""
    rows = names = joints = None
    for rec in prepared:
        for start in range(0, rec.n_samples, CHUNK):
            part = slice(start, start + CHUNK)
            q, qd, qdd = rec.q[part], rec.qd[part], rec.qdd[part]
            held = model.inverse_dynamics(q, qd, qdd, baseline.theta)
            names, joints, block = refit_columns(baseline, q, qd, qdd)
            if rows is None:
                rows = StreamedRows(baseline.robot.n_dof, block.shape[2] + 2)
            rows.add(np.concatenate([rec.tau[part][:, :, None], block, held[:, :, None]], axis=2))
    return names, joints, rows


def _embedding(n: int, k: int, fitted: np.ndarray, signal_scale: np.ndarray) -> tuple:
    """Per joint (E_j, c0_j) of the residual ``s_j signal_j - D_j f - held_j`` with ``x = (kt of fitted, f)``:
    ``s_j`` is the fitted torque constant, else ``signal_scale[j]`` (held)."""
    nf = fitted.size
    embedding, constant = [], np.zeros((n, k + 2))
    for j in range(n):
        e = np.zeros((k + 2, nf + k))
        e[1 : k + 1, nf:] = -np.eye(k)
        where = np.flatnonzero(fitted == j)
        if where.size:
            e[0, where[0]] = 1.0
        else:
            constant[j, 0] = signal_scale[j]
        constant[j, k + 1] = -1.0
        embedding.append(e)
    return embedding, constant


def _fit(rows: StreamedRows, n: int, k: int, kt_nominal, currents: bool) -> tuple:
    """(fitted kt joints, x, sigmas, covariance) of ``kt_j i_j - D_j f = Y_j theta`` (currents) or of
    ``tau_j - D_j f = Y_j theta`` (torques, no constant fitted).

    A torque constant whose relative sigma exceeds ``KT_MAX_RELATIVE`` (a joint whose rigid-body torque is small
    beside its friction: the constant and the friction then scale together) is held at the nominal value.
    """
    fitted = np.arange(n) if currents else np.zeros(0, dtype=int)
    scale = kt_nominal if currents else np.ones(n)
    for attempt in range(2):
        x, s, covariance = _solve(rows, *_embedding(n, k, fitted, scale))
        weak = s[: fitted.size] > KT_MAX_RELATIVE * np.abs(x[: fitted.size])
        if attempt or not weak.any():
            break
        fitted = fitted[~weak]
    return fitted, x, s, covariance


def refit_day(baseline: Baseline, model, prepared: list, currents: bool) -> DayFit:
    """Refit a robot-day (module docstring) on prepared recordings of one kind.

    ``prepared`` recordings hold in ``tau`` the joint torque [N m], or with ``currents`` the motor current [A]
    (the torque constants are then refitted too, where the data determine them). The rows are streamed in chunks
    (:class:`~identification.fleet.streamed.StreamedRows`): the memory does not grow with the recordings' length.
    """
    n = baseline.robot.n_dof
    with uncached(model):
        names, joints, rows = _accumulate(baseline, model, prepared)
    k = rows.width - 2
    scale = baseline.kt if currents else np.ones(n)
    before = np.column_stack([scale, -np.tile(baseline_values(baseline), (n, 1)), -np.ones(n)])
    rmse_baseline = np.sqrt(rows.squares(before) / rows.count)
    fitted, x, s, covariance = _fit(rows, n, k, baseline.kt, currents)
    kt = scale.copy()
    kt[fitted] = x[: fitted.size]
    names = [f"kt{j + 1}" for j in fitted] + list(names)
    joints = [int(j) + 1 for j in fitted] + list(joints)
    after = np.column_stack([kt, -np.tile(x[fitted.size :], (n, 1)), -np.ones(n)])
    rmse_refit = np.sqrt(rows.squares(after) / rows.count)
    names, joints, values, sigmas = _with_amplitudes(names, joints, x, s, covariance)
    return DayFit(names, joints, values, sigmas, rmse_baseline, rmse_refit, rows.count)
