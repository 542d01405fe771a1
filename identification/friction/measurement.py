"""LuGre friction as the friction step measures it: held commands and central differences of the encoder.

Part of step 3 (:mod:`identification.calibration.friction_step`,
:mod:`identification.friction.shooting`). The friction torque of eq. 19 is formed from held current
set-points and the central second difference of the recorded position,
``y[k] = (tau[k-1] + tau[k]) / 2 - J (q[k+1] - 2 q[k] + q[k-1]) / T^2``. For a command held over
each sample period this equals, exactly, the friction averaged over ``[t[k-1], t[k+1]]`` with the
triangular weight ``1 - |t - t[k]| / T``: ``y`` is not the friction at ``t[k]``. On heavy joints the
bristles ring at tens of hertz after every stick, and comparing that average with the friction at
the sample, along a velocity interpolated between central differences, biases sigma1.

This module's model of ``y`` (``ShootingOptions.measurement="central-difference"``):

- between samples the joint moves at the constant velocity ``v[i] = (q[i+1] - q[i]) / T[i]``, so the
  bristle state follows the encoder's displacement exactly and eq. 12 has the closed-form solution
  ``s(u) = r + (s[i] - r) exp(-x u)``, ``u`` in [0, 1], with ``s = sigma0 z``, ``r = Fss(v) sign(v)``
  and ``x = sigma0 |v| T[i] / Fss(v)`` (``Fss = fc + (fs - fc) exp(-(v/vs)^2)``);
- the friction of eq. 14 on that interval is ``a s(u) + b`` with ``a = 1 - sigma1 |v| / Fss(v)`` and
  ``b = sigma1 v + fv |v|^dv sign(v)``; its weighted means ``L = int (1-u) f du`` and
  ``R = int u f du`` follow from ``phi1``/``phi2`` of :mod:`identification.friction.lugre_step`:
  ``L = a (r/2 + (s[i] - r) phi2(x)) + b/2``, ``R = a (r/2 + (s[i] - r) (phi1(x) - phi2(x))) + b/2``;
- ``y[k] = (2 / (T[k-1] + T[k])) (T[k-1] R[k-1] + T[k] L[k])`` (``R[k-1] + L[k]`` on a uniform grid).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from identification.friction.lugre_step import phi_function_expressions, phi_functions
from identification.friction.models import check_friction_data
from identification.friction.shooting_nlp import build_shooting_interval

__all__ = [
    "simulate_lugre_measured",
    "interval_velocities",
    "measurement_weights",
    "build_measured_interval",
    "measured_layout",
]


def interval_velocities(t, q, owner="interval_velocities") -> tuple[np.ndarray, np.ndarray]:
    """Sample-interval lengths ``T[i]`` [s] and mean velocities ``(q[i+1] - q[i]) / T[i]``, shapes (n - 1,)."""
    t, q = check_friction_data(t, q, owner=owner, signal="q")
    h = np.diff(t)
    return h, np.diff(q) / h


def measurement_weights(h) -> tuple[np.ndarray, np.ndarray]:
    """Weights ``(alpha, beta)`` of ``R[k-1]`` and ``L[k]`` in ``y[k]`` for the interior samples, shapes (n - 2,)."""
    h = np.asarray(h, dtype=float)
    total = h[:-1] + h[1:]
    return 2.0 * h[:-1] / total, 2.0 * h[1:] / total


def _interval_means(p, s, h, v, exp, phi12, absolute, sign, power):
    """``(s_end, L, R)`` of one sample interval at constant velocity ``v`` (numpy or CasADi)."""
    fc, fs, vs, fv, dv, sigma0, sigma1 = p
    gv = fc + (fs - fc) * exp(-((v / vs) ** 2))
    speed = absolute(v)
    x = sigma0 * speed * h / gv
    phi1, phi2 = phi12(x)
    rest = gv * sign
    a = 1.0 - sigma1 * speed / gv
    b = sigma1 * v + fv * power * sign
    d = s - rest
    left = a * (0.5 * rest + d * phi2) + 0.5 * b
    right = a * (0.5 * rest + d * (phi1 - phi2)) + 0.5 * b
    return rest + d * exp(-x), left, right


def simulate_lugre_measured(parameters, t, q, s0=0.0) -> tuple[np.ndarray, np.ndarray]:
    """The friction torque a central-difference measurement sees along recorded positions (module docstring).

    Parameters
    ----------
    parameters : LuGreParameters
    t : array, shape (n_samples,)
        Strictly increasing times [s].
    q : array, shape (n_samples,)
        Recorded joint positions [rad].
    s0 : float
        Bristle force ``sigma0 z`` at ``t[0]`` [N m].

    Returns
    -------
    y : ndarray, shape (n_samples,)
        Triangle-weighted mean friction [N m] around each sample (the end samples use their one
        neighbouring interval: ``2 L[0]`` and ``2 R[-1]``).
    s : ndarray, shape (n_samples,)
        Bristle force ``sigma0 z`` at the samples [N m].
    """
    h, v = interval_velocities(t, q, "simulate_lugre_measured")
    p = parameters.as_array()
    moving = v != 0
    power = np.where(moving, np.abs(v) ** p[4], 0.0)
    sign = np.sign(v)
    # the state recursion s[i+1] = decay s[i] + gain is sequential; L and R are then vectorised
    gv = p[0] + (p[1] - p[0]) * np.exp(-((v / p[2]) ** 2))
    decay = np.exp(-p[5] * np.abs(v) * h / gv)
    rest = gv * sign
    s = np.empty(t.size)
    s[0] = float(s0)
    for i in range(h.size):
        s[i + 1] = rest[i] + (s[i] - rest[i]) * decay[i]
    _, left, right = _interval_means(p, s[:-1], h, v, np.exp, phi_functions, np.abs, sign, power)
    alpha, beta = measurement_weights(h)
    y = np.empty(t.size)
    y[1:-1] = alpha * right[:-1] + beta * left[1:]
    y[0], y[-1] = 2.0 * left[0], 2.0 * right[-1]
    return y, s


def build_measured_interval(p0, s_scale, length):
    """SX Functions of one shooting interval of the central-difference measurement model.

    The interval starts at a node sample ``a`` with the scaled bristle force ``w`` and spans the
    sample intervals ``a .. a + length`` (the last one only for the mean ``L`` of the measurement
    at ``a + length``); it holds the residuals of the measurements ``a + 1 .. a + length``.
    ``steps`` holds per sample interval ``[T, v, sign(v), log|v|]`` (log 0 where v = 0), ``data`` per
    measurement ``[y, weight, alpha, beta]`` (weight 0 pads).

    Returns the pair ``interval(log_p, w, w_next, steps, data) -> (continuity, cost)`` and
    ``hessian(log_p, w, steps, data, lam_f, lam) -> (36,)`` of
    :func:`identification.friction.shooting_nlp.build_shooting_interval`.
    """
    log_p = ca.SX.sym("log_p", 7)
    p = [float(p0[i]) * ca.exp(log_p[i]) for i in range(7)]
    w = ca.SX.sym("w")
    w_next = ca.SX.sym("w_next")
    steps = ca.SX.sym("steps", 4, length + 1)
    data = ca.SX.sym("data", 4, length)
    s = s_scale * w
    cost = 0
    right_prev, con = None, None
    for i in range(length + 1):
        h, v, sign, log_speed = (steps[r, i] for r in range(4))
        s_next, left, right = _interval_means(
            p, s, h, v, ca.exp, phi_function_expressions, ca.fabs, sign, ca.exp(p[4] * log_speed)
        )
        if right_prev is not None:
            y, weight, alpha, beta = (data[r, i - 1] for r in range(4))
            cost = cost + weight * (alpha * right_prev + beta * left - y) ** 2
        if i == length - 1:
            con = s_next / s_scale - w_next
        right_prev, s = right, s_next
    return build_shooting_interval("measured_interval", log_p, w, w_next, steps, data, con, cost)


def measured_layout(t, q, tau, n_nodes, length, mse_scale):
    """Padded per-interval inputs ``(steps, data)`` of :func:`build_measured_interval`, interval-major columns.

    ``steps`` has ``length + 1`` columns per interval (sample intervals ``a .. a + length``), ``data``
    ``length`` columns (measurements ``a + 1 .. a + length``); the residuals are averaged over the
    interior samples and divided by ``mse_scale``.
    """
    n = t.size
    h, v = interval_velocities(t, q, "fit_lugre_multiple_shooting")
    total = n_nodes * length + 1
    steps = np.zeros((4, total))
    moving = v != 0
    steps[:, : n - 1] = np.vstack([h, v, np.sign(v), np.where(moving, np.log(np.abs(v) + ~moving), 0.0)])
    data = np.zeros((4, total))  # column k: measurement at sample k
    alpha, beta = measurement_weights(h)
    data[:, 1 : n - 1] = np.vstack([tau[1:-1], np.full(n - 2, 1.0 / ((n - 2) * mse_scale)), alpha, beta])
    starts = np.arange(n_nodes)[:, None] * length
    step_cols = (starts + np.arange(length + 1)[None, :]).ravel()
    data_cols = (starts + 1 + np.arange(length)[None, :]).ravel()
    return steps[:, step_cols], data[:, data_cols]
