"""LuGre friction on the recordings route: the bristle parameters fitted along the recorded series.

``psdm identify ROBOT --data A.csv --friction lugre`` first identifies the rigid body, the drive
inertias and the Stribeck steady state exactly as ``--friction stribeck`` does
(``trajectory_fit.identify_trajectories``). The friction torque left in the data,
``tau - Y theta - Ia qdd - offset`` (the rigid body and drive terms of that fit, every friction
term taken out; in a recalibration the findings' torques too, ``split_findings``), is then fitted per
joint by the multiple-shooting LuGre fit of the friction experiments
(:func:`identification.friction.shooting.fit_lugre_multiple_shooting`: bristle state at the nodes, the
exponential integrator of :mod:`identification.friction.lugre_step` between them), started from the
Stribeck fit's ``fc, fs, vs, fv`` and its viscous exponent ``dv`` (1 where its viscous column is linear; identify's
LuGre trial starts from the default model's power law, ``lugre_trial``) and from ``sigma0`` and ``sigma1`` chosen on
grids by simulation (as ``friction.start`` does for the friction experiments). ``dv`` is held there: the shooting fit
does not free it.

All seven parameters are refitted, not only ``sigma0`` and ``sigma1``: the Stribeck shape of the
linear fit rounds the Coulomb step with ``tanh(qd / eps)``, so near zero speed its ``fs`` and ``vs``
absorb what the bristles do there (the pre-sliding spring and damper). In the LuGre model that
rounding is the bristles' own, so the steady-state parameters are fitted again jointly with them.

The standard deviations are those of the linearised (Gauss-Newton) model at the optimum: the
sensitivities of the simulated friction to ``log p`` (central differences of
:func:`identification.friction.simulation.simulate_lugre`), the residual variance grown by its
correlation time. Those describe the noise, not the model's error, and ``sigma0`` is seen only
while the joint reverses or dwells at low speed (over a displacement of about ``fc / sigma0``), where
the low-pass filter of the recording smooths the friction too. So ``sigma0`` is called identifiable
on a joint when both hold: its relative standard deviation is below :data:`IDENTIFIABLE_RELATIVE_SIGMA`,
and the fitted model's pre-sliding transient (:func:`presliding_time`, the time per reversal in which
the bristle force is more than 10 % of ``fc`` away from its steady state) lasts at least
:data:`MIN_PRESLIDING_SAMPLES` samples and the filter's time constant ``1 / (2 pi cutoff)``. A joint
that fails gets a warning that says so, rather than its number returned as if it were measured.

A stiff bristle behind the default filter (the Denso's own sigma0 of 2.5e5 N m/rad at 10 Hz) leaves the shooting fit
with sigma0 and sigma1 free ill-conditioned: on one recording, a friction residual 4e-14 N m apart (round-off of an
equal regressor, 1b7607d) took it from converging in 116 iterations to the iteration limit. Such a joint's fit is
run again with the bristle parameters (:data:`BRISTLE_PARAMETERS`) held at their start (the grids' best, or the
previous round's), which converges in 25 there; its sigma0 is then said not identifiable (``held_message``) instead
of the whole identification failing. Only a fit that fails with them held too is an error.

:func:`lugre_friction` is the one evaluation of the friction along a series: the calibrated-model
file's prediction, ``psdm validate`` and ``psdm simulate MODEL`` all go through it (the exported C
carries the same step, ``codegen.calibrated.build_lugre_step``). The bristle force at the first sample is
an input: relaxed (0) by default, the state of a robot that starts at rest. A prepared recording
starts a filter settling time after its raw start, so :func:`bristle_force_at` carries the state
from a relaxed bristle at the raw start over the trimmed samples (``psdm validate`` does so): in
pre-sliding the state is not forgotten until the joint slides.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass

import numpy as np

from identification.calibration.coulomb_width import joint_width
from identification.calibration.trajectory_data import choose_filter
from identification.data.preprocessing import central_difference, resample_uniform, zero_phase_filter
from identification.friction.models import LUGRE_PARAMETER_NAMES, LuGreParameters
from identification.friction.shooting import ShootingOptions, fit_lugre_multiple_shooting
from identification.friction.simulation import simulate_lugre, simulated_mse
from psdm_casadi.errors import InsufficientExcitationError, ParameterError, ShapeError, SolverError

__all__ = ["IDENTIFIABLE_RELATIVE_SIGMA", "LuGreFit", "LuGreWarning", "fit_lugre_recordings", "friction_residual",
           "held_message", "lugre_friction", "lugre_std", "bristle_force_at", "presliding_time",
           "sigma0_identifiable", "split_findings", "unidentifiable_message", "without_friction"]  # fmt: skip

logger = logging.getLogger(__name__)

#: sigma0 is reported as identified on a joint when its relative standard deviation is below this.
IDENTIFIABLE_RELATIVE_SIGMA = 0.3
#: ... and when its pre-sliding transient after a reversal spans at least this many samples (heuristic).
MIN_PRESLIDING_SAMPLES = 5
FRICTION_DRIVE_TERMS = ("fc", "fs", "fv")
#: Held at their start when a joint's fit with them free does not converge (module docstring).
BRISTLE_PARAMETERS = ("sigma0", "sigma1")


class LuGreWarning(UserWarning):
    """A LuGre parameter the recordings do not determine (the motion never dwells at low speed)."""


@dataclass(frozen=True)
class LuGreFit:
    """What :func:`fit_lugre_recordings` found, per joint.

    Attributes
    ----------
    parameters : tuple of LuGreParameters or None
        One per joint; None on a joint fitted with a steady-state shape instead (``fit_lugre_recordings(joints=)``).
    std : ndarray, shape (n_dof, 7)
        Standard deviations in ``LUGRE_PARAMETER_NAMES`` order (units of the parameters).
    identifiable : tuple of bool
        Whether ``sigma0`` of the joint is determined by the data (module docstring).
    rmse : ndarray, shape (n_dof,)
        [N m] RMSE of the fitted LuGre friction against the friction residual.
    rmse_stribeck : ndarray, shape (n_dof,)
        [N m] Same for the Stribeck steady state of the linear fit.
    status : tuple of str
        Ipopt's return status per joint.
    start_force : ndarray, shape (n_recordings, n_dof), optional
        [N m] The fitted bristle force at the first sample of each prepared recording (the shooting fit's state
        there): a recording starts where the last motion left the bristles, not relaxed.
    """

    parameters: tuple
    std: np.ndarray
    identifiable: tuple
    rmse: np.ndarray
    rmse_stribeck: np.ndarray
    status: tuple
    start_force: np.ndarray | None = None

    def table(self) -> np.ndarray:
        """Parameters as an array (n_dof, 7) in ``LUGRE_PARAMETER_NAMES`` order (NaN on a joint without LuGre)."""
        return np.array([np.full(7, np.nan) if p is None else p.as_array() for p in self.parameters])

    @property
    def joints(self) -> tuple:
        """The joints (0-based) with LuGre friction."""
        return tuple(j for j, p in enumerate(self.parameters) if p is not None)


def lugre_friction(parameters, t, qd, s0=None) -> np.ndarray:
    """LuGre friction torque [N m] of every joint along a sampled series, shape (n_samples, n_dof).

    The one evaluation of a LuGre model along a recording (module docstring): per joint
    :func:`identification.friction.simulation.simulate_lugre` (one exponential-integrator step per
    sample interval, split at zero crossings), from the bristle force ``s0`` at the first sample.

    Parameters
    ----------
    parameters : sequence of LuGreParameters or None
        One per joint; None for a joint of a steady-state shape (no LuGre friction: its column is 0).
    t : array, shape (n_samples,)
        [s] strictly increasing.
    qd : array, shape (n_samples, n_dof)
        [rad/s]
    s0 : array, shape (n_dof,), optional
        [N m] Bristle force ``sigma0 z`` at ``t[0]``; default 0 (relaxed).

    Raises
    ------
    ShapeError
        When ``qd`` does not have one column per parameter set.
    """
    qd = np.atleast_2d(np.asarray(qd, dtype=float))
    if qd.shape[1] != len(parameters) or qd.shape[0] != np.size(t):
        raise ShapeError(
            f"lugre_friction qd must have shape ({np.size(t)}, {len(parameters)}) (one column per joint's LuGre "
            f"parameters, one row per time); got {qd.shape}."
        )
    s0 = np.zeros(qd.shape[1]) if s0 is None else np.asarray(s0, dtype=float).reshape(-1)
    out = np.zeros_like(qd)
    for j, p in enumerate(parameters):  # None: a joint of a steady-state shape (its friction is the drive columns')
        if p is not None:
            out[:, j] = simulate_lugre(p, t, qd[:, j], z0=s0[j] / p.sigma0)[0]
    return out


def bristle_force_at(parameters, recording, cutoff_hz: float, t: float) -> np.ndarray:
    """[N m] Bristle force per joint at time ``t`` of a raw recording, relaxed at its start (module docstring).

    The state is carried at the recording's full rate along the velocity of its positions filtered as
    ``trajectory_data.prepare_recording`` filters them.
    """
    rec = recording if recording.is_uniform(1e-6) else resample_uniform(recording)
    rate = 1.0 / rec.dt
    cutoff, _ = choose_filter(rate, cutoff_hz)
    qd, _ = central_difference(rec.t, zero_phase_filter(rec.q, rate, cutoff))
    stop = int(np.searchsorted(rec.t, t - 1e-9 * rec.dt)) + 1
    out = np.zeros(len(parameters))
    if stop < 2:
        return out
    for j, p in enumerate(parameters):
        out[j] = 0.0 if p is None else p.sigma0 * simulate_lugre(p, rec.t[:stop], qd[:stop, j])[1][-1]
    return out


def without_friction(fit):
    """The ``TrajectoryFit`` with its friction columns (``fc``, ``fs``, ``fv``) taken out: rigid body and drive terms.

    What a LuGre model keeps of the linear fit beside its own friction (drive inertias, offsets).
    """
    keep = [k for k, name in enumerate(fit.drive_names) if name.rstrip("0123456789") not in FRICTION_DRIVE_TERMS]
    return dataclasses.replace(
        fit, drive=fit.drive[keep], drive_names=tuple(fit.drive_names[k] for k in keep),
        drive_ols=fit.drive_ols[keep], drive_std=fit.drive_std[keep],
        covariance=_drive_subset(fit.covariance, fit, keep),
        friction_terms=tuple(t for t in fit.friction_terms if t not in FRICTION_DRIVE_TERMS),
        stribeck_velocity=(), stribeck_velocity_std=(),
    )  # fmt: skip


def split_findings(fit, n_findings: int) -> tuple:
    """The ``TrajectoryFit`` with only its drive parameters, and (values, ols, std) of the ``n_findings`` finding
    features fitted after them (``trajectory_fit.identify_trajectories`` with ``extra`` columns)."""
    n_drive = len(fit.drive_names) - int(n_findings)
    extra = (fit.drive[n_drive:], fit.drive_ols[n_drive:], fit.drive_std[n_drive:])
    plain = dataclasses.replace(
        fit, drive=fit.drive[:n_drive], drive_ols=fit.drive_ols[:n_drive], drive_std=fit.drive_std[:n_drive],
        drive_names=fit.drive_names[:n_drive], covariance=_drive_subset(fit.covariance, fit, range(n_drive)),
    )  # fmt: skip
    return plain, extra


def _drive_subset(covariance, fit, keep):
    """The rows and columns of ``covariance`` (base then drive parameters, ``TrajectoryFit.covariance``) of the base
    parameters and the drive parameters ``keep``; None stays None."""
    if covariance is None:
        return None
    index = [*range(len(fit.theta_std)), *(len(fit.theta_std) + k for k in keep)]
    return covariance[np.ix_(index, index)]


def friction_residual(model, fit, prepared, extra=None) -> np.ndarray:
    """``tau - Y theta - Ia qdd - offset`` of a prepared recording: the friction left by the linear fit's other terms.

    ``fit`` is a ``TrajectoryFit`` of the Stribeck shape; its friction terms (``fc``, ``fs``, ``fv``) are taken out.
    With ``extra`` (``findings.FindingColumns``, the torque findings the fit holds after its drive parameters) the
    findings' torque is taken out too, the ones it holds at given coefficients (``FindingColumns.held``) with them.
    """
    from identification.calibration.trajectory_fit import predict_torque

    q, qd, qdd = prepared.q, prepared.qd, prepared.qdd
    plain, (values, _, _) = split_findings(fit, 0 if extra is None else len(extra.names))
    residual = prepared.tau - predict_torque(model, without_friction(plain), q, qd, qdd)
    residual = residual if extra is None else residual - extra.held_torque(q, qd, qdd)
    return residual - extra.columns(q, qd, qdd) @ values if values.size else residual


def _chained(prepared, residuals) -> tuple:
    """One series of several prepared recordings: times chained one sample period apart, velocities, residuals."""
    times, offset = [], 0.0
    for r in prepared:
        period = float(np.median(np.diff(r.t)))
        times.append(r.t - r.t[0] + offset)
        offset = times[-1][-1] + period
    return np.concatenate(times), np.concatenate([r.qd for r in prepared]), np.concatenate(residuals)


def _steady_state(fit, j: int) -> dict:
    """``fc, fs, vs, fv`` of joint ``j`` from the Stribeck fit, made positive for the log-scaled LuGre fit, and its
    viscous exponent ``dv`` (1: linear): a drive that loses less than linearly with speed keeps that law under LuGre."""
    values = dict(zip(fit.drive_names, fit.drive))
    fc = max(values[f"fc{j + 1}"], 1e-3)
    dv = float(fit.viscous_exponent[j]) if fit.viscous_exponent else 1.0
    return {"fc": fc, "fs": max(values[f"fs{j + 1}"], 1e-3 * fc), "vs": fit.stribeck_velocity[j],
            "fv": max(values[f"fv{j + 1}"], 1e-6), "dv": dv}  # fmt: skip


def _initial(t, qd, tau, steady: dict) -> LuGreParameters:
    """The Stribeck fit's steady state (its viscous exponent too), and sigma0 then sigma1 chosen by simulation on
    grids."""
    fc = steady["fc"]
    candidates = [LuGreParameters(**steady, sigma0=fc / xb, sigma1=1e-4 * fc / xb)
                  for xb in np.logspace(-6, -1, 21)]  # fmt: skip
    guess = _with_hump(min(candidates, key=lambda p: simulated_mse(p, t, qd, tau)), t, qd, tau)
    candidates = [_replace(guess, sigma1=guess.sigma0 * r) for r in np.logspace(-5, -1, 9)]
    return min(candidates, key=lambda p: simulated_mse(p, t, qd, tau))


def _with_hump(guess: LuGreParameters, t, qd, tau) -> LuGreParameters:
    """``guess`` or one with a Stribeck hump from a grid, whichever simulates best.

    The linear fit's tanh rounding can hide the hump (``fs ~ fc``), and a fit that has lost it (``fs -> 0``,
    a dip) does not find it again by itself: the hump is tried from a grid before every shooting fit.
    """
    speed = float(np.max(np.abs(qd)))
    candidates = [guess] + [_replace(guess, fs=ratio * guess.fc, vs=v) for ratio in (1.2, 1.5, 2.0)
                            for v in speed * np.logspace(-3, -0.5, 6)]  # fmt: skip
    return min(candidates, key=lambda p: simulated_mse(p, t, qd, tau))


def _replace(parameters: LuGreParameters, **changes) -> LuGreParameters:
    return LuGreParameters(**{**parameters.as_dict(), **changes})


def _correlation_factor(residual, max_lag: int = 50) -> float:
    """Integrated autocorrelation time of a residual (Bartlett weights): how much its variance of a mean grows."""
    residual = residual - residual.mean()
    variance = max(float(residual @ residual), 1e-300)
    lags = min(max_lag, residual.size // 4)
    factor = 1.0
    for k in range(1, lags + 1):
        factor += 2.0 * (1.0 - k / (lags + 1)) * float(residual[:-k] @ residual[k:]) / variance
    return max(factor, 1.0)


def presliding_time(parameters: LuGreParameters, t, qd) -> float:
    """[s] Mean time per velocity reversal in which the bristle force is more than 10 % of ``fc`` from its steady state.

    The part of a series that shows the bristles (module docstring): a stiff bristle (large ``sigma0``) is
    at its steady state again a moment after each reversal.
    """
    _, z = simulate_lugre(parameters, t, qd)
    g = parameters.fc + (parameters.fs - parameters.fc) * np.exp(-((qd / parameters.vs) ** 2))
    transient = np.abs(parameters.sigma0 * z - np.sign(qd) * g) > 0.1 * parameters.fc
    reversals = max(int(np.sum(qd[1:] * qd[:-1] < 0)), 1)
    return float(transient.sum() * np.median(np.diff(t)) / reversals)


def sigma0_identifiable(parameters: LuGreParameters, t, qd, relative_sigma: float, cutoff_hz: float) -> tuple:
    """(identifiable, pre-sliding time [s], the time it needs [s]) of a joint's sigma0 (module docstring)."""
    time = presliding_time(parameters, t, qd)
    needed = max(MIN_PRESLIDING_SAMPLES * float(np.median(np.diff(t))), 1.0 / (2 * np.pi * cutoff_hz))
    return bool(relative_sigma < IDENTIFIABLE_RELATIVE_SIGMA and time >= needed), time, needed


def lugre_std(parameters: LuGreParameters, t, qd, tau, fixed=(), s0: float = 0.0, step: float = 1e-4) -> np.ndarray:
    """Standard deviations (7,) of the parameters from the linearised model (module docstring).

    ``s0`` [N m] is the bristle force at ``t[0]`` (held). ``fixed`` parameters (held by the fit) get 0; a
    parameter the data do not see (a sensitivity column of zero) gets an infinite standard deviation.
    """
    base = parameters.as_array()

    def simulate(values):
        p = LuGreParameters.from_array(values)
        return simulate_lugre(p, t, qd, z0=s0 / p.sigma0)[0]

    residual = tau - simulate(base)
    columns = np.column_stack([
        (simulate(base * np.exp(step * e)) - simulate(base * np.exp(-step * e))) / (2 * step) for e in np.eye(7)
    ])  # fmt: skip
    variance = float(residual @ residual) / max(residual.size - 7, 1) * _correlation_factor(residual)
    scale = np.linalg.norm(columns, axis=0)
    free = ~np.isin(LUGRE_PARAMETER_NAMES, fixed)
    seen = free & (scale > 1e-12 * max(scale.max(), 1e-300))
    std_log = np.where(free, np.inf, 0.0)
    scaled = columns[:, seen] / scale[seen]
    inverse = np.linalg.pinv(scaled.T @ scaled, rcond=1e-12, hermitian=True)
    std_log[seen] = np.sqrt(np.clip(np.diag(inverse) * variance, 0.0, None)) / scale[seen]
    return base * std_log  # d p = p d(log p)


def fit_lugre_recordings(
    model, fit, prepared, options: ShootingOptions | None = None, initial=None, *, warn=True, extra=None, joints=None
) -> LuGreFit:
    """Fit the LuGre friction of every joint to the friction residual of prepared recordings (module docstring).

    Parameters
    ----------
    model : PSDMModel
    fit : TrajectoryFit
        Of the Stribeck shape (``"fs"`` in its friction terms), on the same prepared recordings.
    prepared : sequence of Recording
        Filtered, differentiated and decimated (``trajectory_data.prepare_recordings``); several are
        chained into one series (the bristle state carried across a join).
    options : ShootingOptions, optional
        Of the shooting fit (default: intervals of 10 samples, acceptable solutions accepted, ``dv`` held at its start).
    initial : sequence of LuGreParameters, optional
        Start of each joint's fit (a previous round of ``lugre_identify``); default: the Stribeck fit's steady
        state and grids of ``sigma0`` and ``sigma1``.
    warn : bool
        Emit a :class:`LuGreWarning` per joint whose ``sigma0`` the data do not determine.
    extra : findings.FindingColumns, optional
        The finding columns ``fit`` was identified with (``recalibrate``): their torque is taken out too.
    joints : sequence of int, optional
        The joints (0-based) whose LuGre friction is fitted; the others keep the steady-state shape of ``fit`` (their
        parameters None, standard deviations and RMSE NaN). Default: every joint.

    Returns
    -------
    LuGreFit

    Raises
    ------
    ParameterError
        For a fit without the Stribeck shape.
    SolverError
        When the shooting fit of a joint does not converge.

    Warns
    -----
    LuGreWarning
        For each joint whose ``sigma0`` the data do not determine.
    """
    if initial is None and "fs" not in fit.friction_terms:
        raise ParameterError(
            f"fit_lugre_recordings fit.friction_terms must hold 'fs' (the Stribeck steady state the LuGre fit "
            f"starts from); got {fit.friction_terms!r}. Identify with TrajectoryOptions(friction=('fc', 'fs', 'fv'))."
        )
    options = ShootingOptions(accept_acceptable=True, fixed=("dv",)) if options is None else options
    t, qd, residual = _chained(prepared, [friction_residual(model, fit, r, extra) for r in prepared])
    n, firsts = qd.shape[1], np.cumsum([0] + [r.n_samples for r in prepared[:-1]])
    joints = tuple(range(n)) if joints is None else tuple(sorted(joints))
    parameters, status, held = [None] * n, [""] * n, [None] * n
    std, rmse, rmse_stribeck = np.full((n, 7), np.nan), np.full(n, np.nan), np.full(n, np.nan)
    start_force = np.zeros((n, len(prepared)))
    for j in joints:
        if initial is None:
            start = _initial(t, qd[:, j], residual[:, j], _steady_state(fit, j))
        else:
            start = _with_hump(initial[j], t, qd[:, j], residual[:, j])
        result, used, held[j] = _fit_joint(t, qd[:, j], residual[:, j], start, options, j)
        parameters[j], status[j], rmse[j] = result.parameters, result.status, np.sqrt(result.objective)
        start_force[j] = result.parameters.sigma0 * result.z[firsts]
        std[j] = lugre_std(result.parameters, t, qd[:, j], residual[:, j], used.fixed, start_force[j, 0])
        if "fs" in fit.friction_terms:
            stribeck = _stribeck_torque(fit, qd[:, j], j)
            rmse_stribeck[j] = float(np.sqrt(np.mean((residual[:, j] - stribeck) ** 2)))
        logger.info("identify: LuGre joint %d: %s", j + 1, np.round(result.parameters.as_array(), 5),
                    extra={"progress": (joints.index(j) + 1, len(joints))})  # fmt: skip
    identifiable = [False] * n
    for j in joints:
        relative = std[j, LUGRE_PARAMETER_NAMES.index("sigma0")] / parameters[j].sigma0
        ok, time, needed = sigma0_identifiable(parameters[j], t, qd[:, j], relative, min(fit.cutoff_hz))
        identifiable[j] = ok and held[j] is None
        if warn and held[j] is not None:
            warnings.warn(held_message(j, parameters[j], held[j]), LuGreWarning, stacklevel=2)
        elif warn and not ok:
            warnings.warn(unidentifiable_message(j, parameters[j], relative, time, needed), LuGreWarning, stacklevel=2)
    return LuGreFit(parameters=tuple(parameters), std=std, identifiable=tuple(identifiable), rmse=rmse,
                    rmse_stribeck=rmse_stribeck, status=tuple(status), start_force=start_force.T)  # fmt: skip


def _fit_joint(t, qd, residual, start, options: ShootingOptions, j: int) -> tuple:
    """(ShootingResult, the ShootingOptions it was fitted with, the Ipopt status of the fit with the bristle parameters
    free when it failed, else None) of joint ``j``'s shooting fit (module docstring: held when free fails)."""
    try:
        return fit_lugre_multiple_shooting(t, qd, residual, start, options), options, None
    except InsufficientExcitationError as exc:
        raise InsufficientExcitationError(
            f"--friction lugre: joint {j + 1} ({exc}). LuGre friction is fitted along the recorded reversals; "
            "record this joint moving both ways, or pass --friction stribeck."
        ) from None
    except SolverError as exc:
        failed = exc
    held = dataclasses.replace(options, fixed=tuple(dict.fromkeys((*options.fixed, *BRISTLE_PARAMETERS))))
    if held.fixed == options.fixed:
        raise SolverError(f"joint {j + 1}: {failed}", failed.status, failed.iterations, joint=j) from None
    try:
        result = fit_lugre_multiple_shooting(t, qd, residual, start, held)
    except SolverError:
        raise SolverError(f"joint {j + 1}: {failed}", failed.status, failed.iterations, joint=j) from None
    logger.info("identify: LuGre joint %d: the fit with sigma0 and sigma1 free stopped (%s); fitted with them held",
                j + 1, failed.status)  # fmt: skip
    return result, held, failed.status


def held_message(j: int, parameters: LuGreParameters, status: str) -> str:
    """The sentence that says a joint's sigma0 was held because its fit with it free did not converge."""
    return (
        f"joint {j + 1}: the bristle stiffness sigma0 is not identifiable from these recordings: the LuGre fit with "
        f"sigma0 and sigma1 free did not converge (Ipopt status {status}), so they are held at their start "
        f"({parameters.sigma0:.3g} N m/rad, {parameters.sigma1:.3g} N m s/rad, chosen on grids by simulating the "
        "recordings) and the other parameters fitted. The model keeps them (they change the friction only near "
        "reversals); record slow reversals of this joint (or run the four-step protocol's friction experiments) to "
        "measure them."
    )


def unidentifiable_message(j: int, parameters: LuGreParameters, relative: float, time: float, needed: float) -> str:
    """The sentence that says a joint's sigma0 is not determined by the recordings, and what would determine it."""
    return (
        f"joint {j + 1}: the bristle stiffness sigma0 is not identifiable from these recordings (fitted "
        f"{parameters.sigma0:.3g} N m/rad, relative sigma {100 * relative:.0f} %; its pre-sliding transient lasts "
        f"{1e3 * time:.3g} ms per reversal, the samples and the filter resolve {1e3 * needed:.3g} ms): the motion "
        f"never dwells at low speed long enough to show the pre-sliding stiffness (about fc/sigma0 after a reversal). "
        "The model keeps the value (it changes the friction only there); record slow reversals of this joint "
        "(or run the four-step protocol's friction experiments) to measure it."
    )


def _stribeck_torque(fit, qd, j: int) -> np.ndarray:
    """The linear fit's own friction of joint ``j`` (its Stribeck shape) at velocities ``qd``."""
    from identification.calibration.trajectory_data import friction_term

    values = dict(zip(fit.drive_names, fit.drive))
    vs, dv = fit.stribeck_velocity[j], float(fit.viscous_exponent[j]) if fit.viscous_exponent else 1.0
    v = joint_width(fit.coulomb_velocity, j)
    return sum(values[f"{term}{j + 1}"] * friction_term(term, qd, v, vs, None if dv == 1.0 else dv)
               for term in FRICTION_DRIVE_TERMS)  # fmt: skip


def lugre_block(lugre) -> dict:
    """The ``drive.lugre`` block: per parameter a list over joints (null on a joint of a steady-state shape), with
    standard deviations and identifiability, and the LuGre ``joints`` (1-based)."""
    table = lugre.table()
    block = {name: _json_floats(table[:, k]) for k, name in enumerate(LUGRE_PARAMETER_NAMES)}
    block["std"] = {name: _json_floats(lugre.std[:, k]) for k, name in enumerate(LUGRE_PARAMETER_NAMES)}
    block.update(joints=[j + 1 for j in lugre.joints], sigma0_identifiable=list(lugre.identifiable),
                 rmse_friction=_json_floats(lugre.rmse),
                 rmse_friction_stribeck=_json_floats(lugre.rmse_stribeck), solver_status=list(lugre.status),
                 start="steady state of the first sample's velocity")  # fmt: skip
    return block


def _json_floats(values) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float).reshape(-1)]
