"""Starting values of the LuGre fit: the high-speed model of eq. 20 and a data-driven initial guess.

Stage 1 of :mod:`identification.friction.shooting` (and of the paper's method in
:mod:`identification.friction.baseline`): plain arrays ``t, qd, tau_friction`` of one joint's
friction experiment (paper eq. 19) in, :class:`identification.friction.models.CoulombViscous` and
:class:`identification.friction.models.LuGreParameters` out; :func:`check_initial` is the check
both fits apply to a starting point.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from identification.friction.models import CoulombViscous, LuGreParameters, check_friction_data
from identification.friction.simulation import simulated_mse
from psdm_casadi.errors import InsufficientExcitationError, ParameterError

__all__ = ["fit_high_speed", "initial_lugre_guess", "check_initial"]


def _high_speed_mask(qd, threshold):
    if threshold is None:
        threshold = 0.25 * float(np.max(np.abs(qd)))
    if not (np.isfinite(threshold) and threshold > 0):
        raise ParameterError(
            f"fit_high_speed.threshold must be finite and > 0; got {threshold}. Pass a speed well above vs [rad/s]."
        )
    mask = np.abs(qd) > threshold
    if mask.sum() < 10:
        raise ParameterError(
            f"fit_high_speed.threshold leaves {int(mask.sum())} samples with |qd| > {threshold:.3g} rad/s; "
            "need at least 10. Lower it or add fast motion to the experiment."
        )
    counts = (int(np.sum(qd > threshold)), int(np.sum(qd < -threshold)))
    if min(counts) < 5:
        raise InsufficientExcitationError(
            f"fit_high_speed.qd must exceed the threshold {threshold:.3g} rad/s in both directions (at least 5 "
            f"samples each: eq. 20 is odd in qd, one sign alone does not separate fc from a torque offset); got "
            f"{counts[0]} positive and {counts[1]} negative. Record the joint sliding fast both ways."
        )
    return mask


def fit_high_speed(qd, tau_friction, threshold=None):
    """Fit the high-speed model of eq. 20, ``(fc + fv |qd|**dv) sign(qd)``, by trust-region least squares.

    Parameters
    ----------
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    tau_friction : array, shape (n_samples,)
        Friction torque [N m].
    threshold : float, optional
        Only samples with ``|qd| > threshold`` [rad/s] are used; default a quarter of ``max |qd|``
        (pre-sliding and Stribeck effects are negligible there when ``threshold >> vs``).

    Returns
    -------
    CoulombViscous

    Raises
    ------
    ParameterError, ShapeError
        Bad arrays or too few fast samples.
    InsufficientExcitationError
        Fewer than 5 fast samples in one of the two directions.

    Examples
    --------
    >>> qd = np.linspace(-3, 3, 200)
    >>> fit = fit_high_speed(qd, CoulombViscous(fc=5.0, fv=2.0, dv=0.7).torque(qd))
    >>> round(fit.fc, 6), round(fit.fv, 6), round(fit.dv, 6)
    (5.0, 2.0, 0.7)
    """
    _, qd, tau = check_friction_data(np.arange(len(np.ravel(qd))), qd, tau_friction, owner="fit_high_speed")
    mask = _high_speed_mask(qd, threshold)
    v = np.abs(qd[mask])
    sgn = np.sign(qd[mask])
    y = tau[mask]
    # linear start (dv = 1): y sign = fc + fv |qd|
    a = np.column_stack([np.ones_like(v), v])
    fc0, fv0 = np.linalg.lstsq(a, y * sgn, rcond=None)[0]
    x0 = np.array([max(fc0, 1e-3 * abs(y).mean()), max(fv0, 1e-3 * abs(y).mean() / v.mean()), 1.0])
    log_v = np.log(v)

    def residual(x):
        return (x[0] + x[1] * np.exp(x[2] * log_v)) * sgn - y

    def jacobian(x):
        power = np.exp(x[2] * log_v)
        return np.column_stack([sgn, power * sgn, x[1] * power * log_v * sgn])

    sol = least_squares(
        residual,
        x0,
        jac=jacobian,
        bounds=([0.0, 0.0, 0.05], [np.inf, np.inf, 3.0]),
        method="trf",
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    return CoulombViscous(fc=float(sol.x[0]), fv=float(sol.x[1]), dv=float(sol.x[2]))


def _replace(p, **changes):
    values = p.as_dict()
    values.update(changes)
    return LuGreParameters(**values)


def initial_lugre_guess(t, qd, tau_friction, high_speed):
    """Data-driven starting values for the LuGre fit, cheap and deterministic.

    ``fc, fv, dv`` come from ``high_speed`` (eq. 20). ``sigma0`` is the best of a logarithmic grid
    of break-away displacements ``fc / sigma0`` in [1e-6, 1e-2] rad (one LuGre simulation each);
    ``fs`` and ``vs`` are fitted to the steady-sliding samples (displacement since the last
    reversal beyond ten break-away displacements) by least squares on the Stribeck curve, and that
    ``vs`` is kept unless a logarithmic grid ``max|qd| * [1e-4, 0.1]`` simulates better; finally
    ``sigma1`` is picked from a grid ``sigma0 * [1e-5, 1e-2] s``.

    Parameters
    ----------
    t, qd, tau_friction : array, shape (n_samples,)
        Friction experiment [s, rad/s, N m].
    high_speed : CoulombViscous
        Result of :func:`fit_high_speed`.

    Returns
    -------
    LuGreParameters
    """
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="initial_lugre_guess")
    if not isinstance(high_speed, CoulombViscous):
        raise ParameterError(
            f"initial_lugre_guess.high_speed must be a CoulombViscous; got {type(high_speed).__name__}. "
            "Pass fit_high_speed(...)."
        )
    fc = max(high_speed.fc, 1e-6)
    fv = max(high_speed.fv, 1e-9)
    dv = high_speed.dv
    vmax = float(np.max(np.abs(qd)))
    guess = LuGreParameters(fc=fc, fs=1.2 * fc, vs=0.01 * vmax, fv=fv, dv=dv, sigma0=fc / 1e-4, sigma1=1e-4 * fc / 1e-4)
    # sigma0 from a grid of break-away displacements
    candidates = [_replace(guess, sigma0=fc / xb, sigma1=1e-4 * fc / xb) for xb in np.logspace(-6, -2, 17)]
    guess = min(candidates, key=lambda p: simulated_mse(p, t, qd, tau))
    # fs, vs on steady sliding
    q = np.concatenate([[0.0], np.cumsum(0.5 * (qd[1:] + qd[:-1]) * np.diff(t))])
    sgn = np.sign(qd)
    anchor = np.zeros_like(q)
    last = q[0]
    for k in range(1, q.size):  # position at the last sign change
        if sgn[k] != sgn[k - 1]:
            last = q[k]
        anchor[k] = last
    steady = (np.abs(q - anchor) > 10 * guess.fs / guess.sigma0) & (sgn != 0)
    if steady.sum() > 20:
        v = np.abs(qd[steady])
        y = tau[steady] * sgn[steady] - fv * v**dv - fc

        def residual(x):
            return (np.exp(x[0]) - fc) * np.exp(-((v / np.exp(x[1])) ** 2)) - y

        starts = [np.log([1.2 * fc, vs]) for vs in np.quantile(v, [0.05, 0.2, 0.5])]
        best = min((least_squares(residual, x0, method="trf") for x0 in starts), key=lambda s: s.cost)
        fs, vs = np.exp(best.x)
        if np.isfinite(fs) and np.isfinite(vs) and vs > 0:
            guess = _replace(guess, fs=float(fs), vs=float(min(vs, vmax)))
    # vs checked by simulation on a logarithmic grid: with fs close to fc (the Denso's joint 6 has fs < fc)
    # the fit above is ill-conditioned, and a vs far too large can trap the NLP in a local minimum
    candidates = [guess] + [_replace(guess, vs=float(v)) for v in vmax * np.logspace(-4, -1, 7)]
    guess = min(candidates, key=lambda p: simulated_mse(p, t, qd, tau))
    # sigma1 grid
    candidates = [_replace(guess, sigma1=guess.sigma0 * r) for r in np.logspace(-5, -2, 7)]
    return min(candidates, key=lambda p: simulated_mse(p, t, qd, tau))


def check_initial(initial, owner):
    """Check a starting point of the log-scaled LuGre fits; ``owner`` names the caller in the messages.

    Parameters
    ----------
    initial : LuGreParameters
        Starting point; ``fv`` and ``sigma1`` must be > 0 (the fits optimise ``log(p / initial)``).
    owner : str
        Name of the calling function, for the error message.

    Raises
    ------
    ParameterError
        ``initial`` is not a LuGreParameters, or ``fv`` or ``sigma1`` is zero.
    """
    if not isinstance(initial, LuGreParameters):
        raise ParameterError(
            f"{owner}.initial must be a LuGreParameters; got {type(initial).__name__}. "
            "Pass initial_lugre_guess(...) or LuGreParameters(...)."
        )
    for name in ("fv", "sigma1"):
        if getattr(initial, name) <= 0:
            raise ParameterError(
                f"{owner}.initial.{name} must be > 0 for the log-scaled fit; got 0. Pass a small positive guess."
            )
