"""Numeric LuGre simulation of one joint along a sampled velocity (paper eqs. 12-14), stiff-safe.

Turns :class:`identification.friction.models.LuGreParameters` and a velocity record into the
friction torque, with the exponential integrator of :mod:`identification.friction.lugre_step`
(the discretisation the shooting fit uses). The start values (:mod:`identification.friction.start`),
the fits and the calibration steps simulate friction through :func:`simulate_lugre`.

A long series is simulated in pieces of ``LUGRE_CHUNK`` samples, each starting from the bristle force the
previous one ended with: the same recursion (the interval maps are local to each sample interval), several
times faster on an hour of samples because the simulator's temporaries then stay in the processor's cache.
"""

from __future__ import annotations

import numpy as np

from identification.friction.lugre_step import sample_interval_maps, substep_layout
from identification.friction.models import LuGreParameters, check_friction_data
from psdm_casadi.errors import ParameterError

__all__ = ["LUGRE_CHUNK", "lugre_torque", "simulate_lugre", "simulated_mse"]

#: Sample intervals per piece of a long series (module docstring).
LUGRE_CHUNK = 50_000


def lugre_torque(parameters, qd, s):
    """LuGre friction torque (eq. 14) [N m] from velocity ``qd`` and bristle force ``s = sigma0 z`` [N m]."""
    p = parameters
    qd = np.asarray(qd, dtype=float)
    g = p.fc + (p.fs - p.fc) * np.exp(-((qd / p.vs) ** 2))
    zdot = qd - np.abs(qd) * s / g
    return s + p.sigma1 * zdot + p.fv * np.abs(qd) ** p.dv * np.sign(qd)


def simulate_lugre(parameters, t, qd, z0=0.0, substeps=1, *, chunk=None):
    """Simulate the LuGre model along a sampled velocity signal (stiff-safe, any sigma0).

    The velocity is taken as linear between samples. Each sample interval is split at a zero
    crossing of ``qd`` and into ``substeps`` exponential-integrator steps
    (:mod:`identification.friction.lugre_step`); their linear maps are composed, so the sequential
    loop costs one multiply-add per sample whatever ``substeps``.

    Parameters
    ----------
    parameters : LuGreParameters
    t : array, shape (n_samples,)
        Strictly increasing times [s].
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    z0 : float
        Bristle deflection at ``t[0]`` [rad].
    substeps : int
        Integration steps per sample interval, >= 1. The scheme is second order; one step suffices
        at 1 kHz (tests/identification/test_friction.py checks it against a stiff ODE solver), 32 or
        more give a reference solution.
    chunk : int, optional
        Sample intervals per piece of a long series (module docstring), >= 1; default ``LUGRE_CHUNK``. The
        result does not depend on it.

    Returns
    -------
    tau : ndarray, shape (n_samples,)
        Friction torque [N m] (eq. 14).
    z : ndarray, shape (n_samples,)
        Bristle deflection [rad].

    Raises
    ------
    ParameterError, ShapeError
        Bad parameters or arrays; the message names the field.

    Examples
    --------
    >>> p = LuGreParameters(fc=1.0, fs=1.5, vs=0.01, fv=0.5, dv=1.0, sigma0=1e5, sigma1=10.0)
    >>> t = np.arange(0.0, 1.0, 1e-3)
    >>> tau, z = simulate_lugre(p, t, np.full_like(t, 0.2))
    >>> round(float(tau[-1]), 6)  # steady sliding: fc + fv * 0.2
    1.1
    """
    if not isinstance(parameters, LuGreParameters):
        raise ParameterError(
            f"simulate_lugre.parameters must be a LuGreParameters; got {type(parameters).__name__}. "
            "Build one with LuGreParameters(...)."
        )
    t, qd = check_friction_data(t, qd, owner="simulate_lugre")
    if not (isinstance(substeps, (int, np.integer)) and not isinstance(substeps, bool) and substeps >= 1):
        raise ParameterError(f"simulate_lugre.substeps must be an integer >= 1; got {substeps!r}. Pass e.g. 1 or 8.")
    if not np.isfinite(z0):
        raise ParameterError(f"simulate_lugre.z0 must be finite; got {z0}. Pass 0.0 for a relaxed bristle.")
    chunk = LUGRE_CHUNK if chunk is None else chunk
    if not (isinstance(chunk, (int, np.integer)) and not isinstance(chunk, bool) and chunk >= 1):
        raise ParameterError(f"simulate_lugre.chunk must be an integer >= 1; got {chunk!r}. Pass e.g. 50000.")
    s, tau = np.empty(t.size), np.empty(t.size)
    s[0], start = parameters.sigma0 * float(z0), 0
    while start < t.size - 1:  # pieces of ``chunk`` intervals, each from the bristle force the last one ended with
        stop = min(t.size, start + int(chunk) + 1)
        piece = substep_layout(t[start:stop], qd[start:stop], int(substeps))
        decay, gain = sample_interval_maps(parameters, piece)
        s[start:stop] = _run_recursion(decay, gain, s[start])
        tau[start:stop] = lugre_torque(parameters, qd[start:stop], s[start:stop])
        start = stop - 1
    return tau, s / parameters.sigma0


def _run_recursion(decay, gain, s0):
    """Evaluate the first-order linear recursion sequentially (plain floats are fastest here)."""
    s = [s0]
    value = s0
    for d, g in zip(decay.tolist(), gain.tolist()):
        value = d * value + g
        s.append(value)
    return np.asarray(s)


def simulated_mse(parameters, t, qd, tau, substeps=1):
    """Mean squared error [N^2 m^2] of :func:`simulate_lugre` (from a relaxed bristle) against ``tau``.

    The cost the start values (:mod:`identification.friction.start`) and the paper's Nelder-Mead
    fit (:mod:`identification.friction.baseline`) minimise.

    Parameters
    ----------
    parameters : LuGreParameters
    t, qd, tau : array, shape (n_samples,)
        Friction experiment [s, rad/s, N m].
    substeps : int
        Integrator sub-steps per sample interval.

    Returns
    -------
    float
    """
    pred, _ = simulate_lugre(parameters, t, qd, substeps=substeps)
    return float(np.mean((pred - tau) ** 2))
