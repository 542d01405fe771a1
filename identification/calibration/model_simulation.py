"""simulate_calibrated(): a calibrated model's torques along a reference as a recording (model file -> Recording).

A calibrated-model file is a model of a real robot: its kinematics, identified parameters, friction
(and the torque terms diagnosis added). Simulating it along a reference or an excitation gives the
recording that robot would make if the model were exact: the states of the reference, sampled at a
rate, and the model's joint torques (``CalibratedModel.predict``), with optional Gaussian torque
noise. It is the inverse-dynamics route (the torque the model needs to follow the reference
exactly), the test bed for identification and controllers without hardware: a recording with known
truth whose truth is the model file itself.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, ShapeError

__all__ = ["sample_reference", "simulate_calibrated"]


def sample_reference(reference, t) -> tuple:
    """``(q, qd, qdd)`` at times ``t``, each (n_samples, n_dof), of a reference.

    Parameters
    ----------
    reference : tuple or object with ``sample(t)``
        ``(t, q[, qd[, qdd]])`` arrays (a cubic spline through ``q``; ``qd`` and ``qdd`` from their own
        splines when given, else its derivatives), or a trajectory with ``sample(t) -> (q, qd, qdd)``
        (``trajopt``'s experiments and excitations).
    t : array, shape (n_samples,)
        [s]

    Raises
    ------
    ParameterError
        For a reference of another kind, or times that do not increase.
    """
    t = np.asarray(t, dtype=float)
    if hasattr(reference, "sample"):
        return tuple(np.asarray(a, dtype=float) for a in reference.sample(t))
    if not (isinstance(reference, (tuple, list)) and 2 <= len(reference) <= 4):
        raise ParameterError(
            "simulate_calibrated reference must be a tuple (t, q[, qd[, qdd]]) or have sample(t); got "
            f"{type(reference).__name__}. Pass the arrays of a reference CSV or an experiment."
        )
    t_ref = np.asarray(reference[0], dtype=float)
    if t_ref.ndim != 1 or t_ref.size < 2 or np.any(np.diff(t_ref) <= 0):
        raise ParameterError("simulate_calibrated reference t must be a strictly increasing 1-D array of >= 2 times.")
    splines = [CubicSpline(t_ref, np.asarray(part, dtype=float), axis=0) for part in reference[1:]]
    q = splines[0](t)
    qd = splines[1](t) if len(splines) > 1 else splines[0](t, 1)
    qdd = splines[2](t) if len(splines) > 2 else (splines[1](t, 1) if len(splines) > 1 else splines[0](t, 2))
    return q, qd, qdd


def simulate_calibrated(
    calibrated, model, reference, *, rate: float = 1000.0, duration: float | None = None, tau_noise_std: float = 0.0,
    rng: np.random.Generator | None = None, name: str = "reference",
) -> Recording:  # fmt: skip
    """The recording of a calibrated model along a reference: the reference's states and the model's torques.

    Parameters
    ----------
    calibrated : CalibratedModel
        ``load_calibrated_model("model.json")``.
    model : PSDMModel
        ``derive_psdm(calibrated.load_robot())``.
    reference : tuple or trajectory
        See :func:`sample_reference`.
    rate : float
        [Hz] Sampling rate of the recording.
    duration : float, optional
        [s] Length of the recording from the reference's start (default: the reference's span).
    tau_noise_std : float
        [N m] Standard deviation of white Gaussian noise added to every torque sample (0: the exact model torques).
    rng : numpy.random.Generator, optional
        Source of the noise (required when ``tau_noise_std > 0``, so runs are reproducible).
    name : str
        Name of the recording.

    Returns
    -------
    Recording
        ``t``, ``q``, ``qd``, ``qdd`` of the reference and ``tau = calibrated.predict(model, q, qd, qdd, t=t)``
        (+ noise).

    Raises
    ------
    ParameterError
        For a non-positive rate or duration, a negative noise, noise without ``rng``, or a bad reference.
    ShapeError
        When the reference does not have one column per joint of the model.

    Examples
    --------
    >>> recording = simulate_calibrated(calibrated, model, experiment, rate=500.0)   # doctest: +SKIP
    """
    if not (np.isfinite(rate) and rate > 0):
        raise ParameterError(f"simulate_calibrated rate must be > 0 [Hz]; got {rate!r}.")
    if not (np.isfinite(tau_noise_std) and tau_noise_std >= 0):
        raise ParameterError(f"simulate_calibrated tau_noise_std must be >= 0 [N m]; got {tau_noise_std!r}.")
    if tau_noise_std > 0 and rng is None:
        raise ParameterError("simulate_calibrated tau_noise_std > 0 needs rng; pass np.random.default_rng(seed).")
    t0, span = _span(reference)
    duration = span if duration is None else float(duration)
    if not (np.isfinite(duration) and duration > 0):
        raise ParameterError(f"simulate_calibrated duration must be > 0 [s]; got {duration!r}.")
    t = t0 + np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    q, qd, qdd = sample_reference(reference, t)
    if q.shape != (t.size, calibrated.n_dof) or qd.shape != q.shape or qdd.shape != q.shape:
        raise ShapeError(
            f"simulate_calibrated reference q must have shape (n_samples, {calibrated.n_dof}) to match the model's "
            f"n_dof={calibrated.n_dof}; got {q.shape}. Pass a reference of this robot's joints."
        )
    tau = calibrated.predict(model, q, qd, qdd, t=t)  # a LuGre model carries its bristle state along t
    if tau_noise_std > 0:
        tau = tau + rng.normal(scale=tau_noise_std, size=tau.shape)
    return Recording(t=t, q=q, qd=qd, qdd=qdd, tau=tau, name=name)


def _span(reference) -> tuple:
    if hasattr(reference, "sample"):
        return 0.0, float(reference.duration)
    if isinstance(reference, (tuple, list)) and len(reference) >= 2:
        t_ref = np.asarray(reference[0], dtype=float).reshape(-1)
        return float(t_ref[0]), float(t_ref[-1] - t_ref[0])
    return 0.0, float("nan")
