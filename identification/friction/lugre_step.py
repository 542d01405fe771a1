"""The exact LuGre step over a sample interval: the exponential integrator of the bristle force.

One discretisation of paper eq. 12, shared by the numeric simulation
(:mod:`identification.friction.simulation`), the CasADi expressions
(:mod:`identification.friction.expressions`), the shooting fit
(:mod:`identification.friction.shooting`) and the measurement model
(:mod:`identification.friction.measurement`), so that what is simulated is what is fitted.

Eq. 12 is stiff: the relaxation rate ``a = sigma0 |qd| / g`` reaches 1e5 1/s with the paper's
Denso values (Table 2), so an explicit step at 1 kHz diverges. With the bristle force
``s = sigma0 z`` [N m] (of the order of the Coulomb torque, so well scaled) eq. 12 reads
``sdot = -a(t) (s - y(t))`` with the quasi-steady force ``y = sign(qd) g(qd)``. Over a step of
length h with ``qd`` linear and of one sign (steps are split at zero crossings of the data),
``a`` is frozen at its trapezoidal mean and ``y`` is taken linear, and this linear ODE is
integrated exactly (an exponential integrator)::

    x      = h (a[k] + a[k+1]) / 2
    s[k+1] = exp(-x) s[k] + x (phi1(x) y[k] + phi2(x) (y[k+1] - y[k]))

with ``phi1(x) = (1 - exp(-x)) / x`` and ``phi2(x) = (x - 1 + exp(-x)) / x**2``. The scheme is
unconditionally stable, second order, reproduces steady sliding exactly (so the Stribeck curve is
the steady state of the discrete model) and is the trapezoidal rule in pre-sliding.

This module holds ``phi1, phi2`` (numpy and CasADi, one formula), the layout of the sub-steps of a
sampled velocity (:func:`substep_layout`) and the linear map ``s[k+1] = decay s[k] + gain`` of one
step (:func:`lugre_step_coefficients`) and of a whole sample interval (:func:`sample_interval_maps`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = [
    "phi_functions",
    "phi_function_expressions",
    "SubstepLayout",
    "substep_layout",
    "lugre_step_coefficients",
    "sample_interval_maps",
]

_SERIES_LIMIT = 1e-3  # below this x = h * rate, phi1 and phi2 use their Taylor series


def _phi_functions_with(x, where, expm1):
    """phi1(x) = (1 - e^-x)/x and phi2(x) = (x - 1 + e^-x)/x^2, accurate for all x >= 0.

    ``where`` and ``expm1`` are numpy's or CasADi's, so both evaluations share one formula.
    """
    small = x < _SERIES_LIMIT
    xs = where(small, 1.0, x)
    em1 = expm1(-xs)
    phi1 = where(small, 1 - x / 2 + x * x / 6 - x**3 / 24, -em1 / xs)
    phi2 = where(small, 0.5 - x / 6 + x * x / 24 - x**3 / 120, (xs + em1) / (xs * xs))
    return phi1, phi2


def phi_functions(x):
    """``(phi1(x), phi2(x))`` of the exponential integrator on numpy arrays ``x >= 0`` (module docstring)."""
    return _phi_functions_with(x, np.where, np.expm1)


def phi_function_expressions(x):
    """``(phi1(x), phi2(x))`` as CasADi expressions of ``x >= 0``, the formula of :func:`phi_functions`."""
    return _phi_functions_with(x, ca.if_else, ca.expm1)


@dataclass(frozen=True)
class SubstepLayout:
    """Data-only description of the integration sub-steps of a sampled velocity signal.

    Each sample interval k is split into ``substeps`` equal steps, and an interval in which the
    velocity changes sign is first split at its (linearly interpolated) zero crossing, so that the
    sign of ``qd`` is constant on every sub-step. Part 0 (first axis) holds the sub-steps before the
    crossing (the whole interval when there is none), part 1 those after it, for crossing intervals
    only.

    Attributes
    ----------
    h : ndarray, shape (2, substeps, n_intervals)
        Step lengths [s] of the first and second part; the second part is zero where no crossing.
    qd_a, qd_b : ndarray, shape (2, substeps, n_intervals)
        Velocity at the start and at the end of each sub-step [rad/s].
    sign : ndarray, shape (2, substeps, n_intervals)
        Sign of ``qd`` on the sub-step (-1, 0, 1).
    crossing : ndarray of bool, shape (n_intervals,)
        Whether the velocity changes sign in the sample interval.
    """

    h: np.ndarray
    qd_a: np.ndarray
    qd_b: np.ndarray
    sign: np.ndarray
    crossing: np.ndarray


def substep_layout(t, qd, substeps):
    """The :class:`SubstepLayout` of ``substeps`` steps per sample interval of ``qd`` [rad/s] at times ``t`` [s]."""
    h = np.diff(t)
    q0 = qd[:-1]
    q1 = qd[1:]
    crossing = q0 * q1 < 0
    frac = np.ones_like(h)
    frac[crossing] = q0[crossing] / (q0[crossing] - q1[crossing])
    shape = (2, substeps, h.size)
    f0 = np.empty(shape)
    f1 = np.empty(shape)
    j = np.arange(substeps)[:, None]
    f0[0] = frac * j / substeps
    f1[0] = frac * (j + 1) / substeps
    f0[1] = frac + (1 - frac) * j / substeps
    f1[1] = frac + (1 - frac) * (j + 1) / substeps
    qd_a = q0 + (q1 - q0) * f0
    qd_b = q0 + (q1 - q0) * f1
    # exact zeros at the crossing (no round-off sign flips)
    qd_b[0, -1, crossing] = 0.0
    qd_a[1, 0, crossing] = 0.0
    step = h * (f1 - f0)
    step[1, :, ~crossing] = 0.0
    sign = np.sign(qd_a + qd_b)
    return SubstepLayout(step, qd_a, qd_b, sign, crossing)


def _step_maps(p, h, qd_a, qd_b, sign):
    """Linear map ``s_end = decay s_start + gain`` of one sub-step (numpy; see module docstring)."""
    g_a = p.fc + (p.fs - p.fc) * np.exp(-((qd_a / p.vs) ** 2))
    g_b = p.fc + (p.fs - p.fc) * np.exp(-((qd_b / p.vs) ** 2))
    x = 0.5 * h * p.sigma0 * (np.abs(qd_a) / g_a + np.abs(qd_b) / g_b)
    phi1, phi2 = phi_functions(x)
    y_a = sign * g_a
    y_b = sign * g_b
    return np.exp(-x), x * (phi1 * y_a + phi2 * (y_b - y_a))


def lugre_step_coefficients(parameters, h, qd_start, qd_end):
    """Coefficients of one exponential-integrator step of the bristle force ``s = sigma0 z``.

    ``s_end = decay * s_start + gain``, for ``qd`` linear over the step and of one sign (see the
    module docstring; :func:`substep_layout` splits steps at zero crossings).

    Parameters
    ----------
    parameters : LuGreParameters
    h : float or array
        Step length [s], >= 0.
    qd_start, qd_end : array
        Velocity at the start and end of each step [rad/s], of equal sign or zero.

    Returns
    -------
    decay, gain : ndarray
        ``decay`` in (0, 1], ``gain`` [N m].
    """
    qd_start = np.asarray(qd_start, dtype=float)
    qd_end = np.asarray(qd_end, dtype=float)
    return _step_maps(parameters, h, qd_start, qd_end, np.sign(qd_start + qd_end))


def sample_interval_maps(parameters, layout):
    """Linear maps ``s[k+1] = decay[k] s[k] + gain[k]`` of every sample interval, its sub-steps composed.

    Parameters
    ----------
    parameters : LuGreParameters
    layout : SubstepLayout
        From :func:`substep_layout`.

    Returns
    -------
    decay, gain : ndarray, shape (n_intervals,)
        ``decay`` in (0, 1], ``gain`` [N m].
    """
    decay = np.ones(layout.h.shape[-1])
    gain = np.zeros_like(decay)
    for part in range(2):
        for j in range(layout.h.shape[1]):
            d_j, g_j = _step_maps(
                parameters, layout.h[part, j], layout.qd_a[part, j], layout.qd_b[part, j], layout.sign[part, j]
            )
            decay, gain = d_j * decay, d_j * gain + g_j
    return decay, gain
