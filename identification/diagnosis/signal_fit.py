"""Exact fit of the signal-level terms (delay, backlash, joint elasticity) by variable projection, ahead of
``refine_fit``.

The selection screens a delay and a backlash through columns linear in one coefficient (a first-order
expansion in the delay, in the play at a fixed flank smoothing). Their exact torques are not linear
in the parameters, and not smooth enough for a derivative-based solver: the delayed torque is an
interpolated signal, and backlash moves the friction's sign changes, which needs a LuGre simulation
per value. ``fit_signal_terms`` therefore fits them by Nelder-Mead on their few parameters (log scale),
with everything else (nominal friction, the other kept terms' linear columns) solved by weighted
least squares at every trial (variable projection), on the training recording:

- ``delay``: ``tau_rec(t) - tau_rec(t + d)`` (``DelayTerm.exact_contribution``), parameter d [s];
- ``backlash``: deflection ``h tanh(tau_raw / tau_s)`` filtered like the recording, rigid body to first
  order and friction exactly (``BacklashTerm.exact_contribution``), parameters h [rad] and tau_s [N m];
- ``joint_elasticity``: deflection ``c tau``, rigid body to first order and friction exactly
  (``JointElasticityTerm.exact_contribution``), parameter the compliance c [rad/(N m)].

A robot-wide term (the delay) is refitted once with each joint weighted by its remaining residual
instead of its torque RMS (maximum likelihood with one noise level per joint): the nominal friction
misfit of a light wrist joint is a large fraction of its torque and would otherwise pull the shared
delay away from the value the accurate joints agree on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from identification.diagnosis.candidates.deflection import BacklashTerm, JointElasticityTerm
from identification.metrics import rms

SIGNAL_KEYS = ("delay", "backlash", "joint_elasticity")
BACKLASH_MARGIN = (
    0.05  # backlash must fit 5 % better than joint elasticity of the same joint (it has one more parameter)
)
BACKLASH_MAX_FLANK = 0.1  # and change flank within 10 % of the joint's torque RMS (tau_s / RMS)


@dataclass(frozen=True)
class SignalFit:
    """Fitted parameters of the signal-level terms: ``parameters[label]`` is ``(d,)`` for a delay and
    ``(h, tau_s)`` for backlash, ``(c,)`` for joint elasticity; ``sse_start``/``sse`` the weighted training error at
    the start and the end."""

    parameters: dict
    sse_start: float
    sse: float


def exact_contribution(term, context, parameters) -> np.ndarray:
    """Torque (n_samples, n_dof) of a signal-level ``term`` with physical ``parameters``."""
    if term.key in ("delay", "joint_elasticity"):
        return term.exact_contribution(context, float(parameters[0]))
    return term.exact_contribution(context, float(parameters[0]), float(parameters[1]))


def _start(term, context, coefficients):
    c = float(coefficients[0])
    if term.key == "delay":
        return [max(c, 2e-4)]
    if term.key == "joint_elasticity":
        return [max(c, 1e-9)]
    return [max(c, 1e-5), term.torque_scale_nm(context)]


def fit_signal_terms(terms, coefficients, context, base, y, sigma, max_evaluations: int = 200) -> SignalFit | None:
    """Fit the delay and backlash terms among ``terms`` exactly (see the module docstring); None when there are none.

    Parameters
    ----------
    terms, coefficients : sequences
        Kept terms and their linear (screening) coefficients.
    context : DiagnosisContext
        Training recording.
    base : array (n_samples, n_dof, p)
        Columns of the nominal model's free parameters.
    y : array (n_samples, n_dof)
        Measured torque minus the fixed part of the nominal model.
    sigma : array (n_dof,)
        Joint weights (torque RMS).
    max_evaluations : int
        Nelder-Mead evaluations.
    """
    signal = [k for k, term in enumerate(terms) if term.key in SIGNAL_KEYS]
    if not signal:
        return None
    linear = np.concatenate([base] + [terms[k].columns(context) for k in range(len(terms)) if k not in signal], axis=2)

    sizes, start = [], []
    for k in signal:
        s = _start(terms[k], context, coefficients[k])
        sizes.append(len(s))
        start.extend(s)
    start = np.log(np.asarray(start, dtype=float))

    def unpack(v):
        out, i = [], 0
        for n in sizes:
            out.append(np.exp(v[i : i + n]))
            i += n
        return out

    def residual(v, weights, q):
        r = y.copy()
        for k, p in zip(signal, unpack(v)):
            r -= exact_contribution(terms[k], context, p)
        r = (r / weights).ravel()
        return r - q @ (q.T @ r)

    def projector(weights):
        x = (linear / weights[None, :, None]).reshape(-1, linear.shape[2])
        return np.linalg.qr(x)[0]

    def solve(v0, weights, evaluations, ladder):
        q = projector(weights)

        def sse(v):
            r = residual(v, weights, q)
            return float(r @ r)

        # the flank smoothing is poorly known at the start: try a coarse ladder of it first
        candidates = [v0]
        if ladder:
            for i, k in enumerate(signal):
                if terms[k].key == "backlash":
                    offset = int(np.sum(sizes[:i])) + 1
                    for factor in (0.1, 0.3, 3.0):
                        v = v0.copy()
                        v[offset] += np.log(factor)
                        candidates.append(v)
        values = [sse(v) for v in candidates]
        best = candidates[int(np.argmin(values))]
        result = minimize(
            sse,
            best,
            method="Nelder-Mead",
            options={"maxfev": evaluations, "xatol": 1e-3, "fatol": 1e-10 * max(values[0], 1e-300)},
        )
        if result.fun <= min(values):
            return result.x, values[0], float(result.fun)
        return best, values[0], min(values)

    v, sse_start, sse_end = solve(start, sigma, max_evaluations, ladder=True)
    if any(terms[k].joint is None for k in signal):
        # a robot-wide term (the delay) is shared by joints whose nominal misfit differs by orders of magnitude
        # relative to their torque: weight each joint by its remaining residual (maximum likelihood with a
        # variance per joint), so the joints where the model is accurate set the shared parameter
        r = residual(v, sigma, projector(sigma)).reshape(y.shape) * sigma
        weights = np.maximum(rms(r), 1e-3 * sigma)
        v, _, _ = solve(v, weights, max_evaluations // 2, ladder=False)
        r = residual(v, sigma, projector(sigma))
        sse_end = float(r @ r)
    parameters = {terms[k].label: tuple(float(x) for x in p) for k, p in zip(signal, unpack(v))}
    return SignalFit(parameters=parameters, sse_start=sse_start, sse=sse_end)


def _linear_coefficient(term, context, base, y, sigma) -> float:
    """Coefficient of ``term``'s screening column fitted with the nominal columns (weighted least squares)."""
    x = np.concatenate([base, term.columns(context)], axis=2) / sigma[None, :, None]
    beta = np.linalg.lstsq(x.reshape(-1, x.shape[2]), (y / sigma).ravel(), rcond=None)[0]
    return float(beta[-1])


def resolve_deflection(terms, coefficients, fit, context, base, y, sigma):
    """Backlash and joint elasticity of one joint have alike screening columns (both move the recorded
    position with the torque), so the selection can keep the wrong one; refit each kept one exactly as the
    other and keep backlash only when it leaves a weighted training error ``BACKLASH_MARGIN`` below the
    elasticity's (it has one more parameter, and contains the elasticity as its wide-flank limit) and its
    flank smoothing ``tau_s`` is below ``BACKLASH_MAX_FLANK`` times the joint's torque RMS (a play is crossed
    near zero torque; a deflection that saturates only across the working torque is a stiffening compliance).

    Returns ``(terms, coefficients, fit)`` (tuples and the ``SignalFit`` of the kept choice).
    """
    terms, coefficients = tuple(terms), tuple(coefficients)
    for k, term in enumerate(terms):
        if fit is None or term.key not in ("backlash", "joint_elasticity"):
            continue
        other = (JointElasticityTerm if term.key == "backlash" else BacklashTerm)(joint=term.joint).on_training(context)
        if other.label in {t.label for t in terms}:
            continue
        swapped = terms[:k] + (other,) + terms[k + 1 :]
        start = np.array([_linear_coefficient(other, context, base, y, sigma)])
        swapped_coefficients = coefficients[:k] + (start,) + coefficients[k + 1 :]
        alternative = fit_signal_terms(swapped, swapped_coefficients, context, base, y, sigma)
        if alternative is None:
            continue
        # backlash with a flank smoothing beyond the torque range is the elasticity (tanh(tau / ts) ~ tau / ts):
        # its second parameter must earn a clearly smaller error
        backlash_fit, elastic_fit = (fit, alternative) if term.key == "backlash" else (alternative, fit)
        label = BacklashTerm(joint=term.joint).label
        flank = backlash_fit.parameters[label][1] / max(rms(context.tau[:, term.joint]), 1e-12)
        # a play is crossed near zero torque: a flank spread over the working torque is a (stiffening) compliance
        keep_backlash = backlash_fit.sse < (1.0 - BACKLASH_MARGIN) * elastic_fit.sse and flank < BACKLASH_MAX_FLANK
        if keep_backlash != (term.key == "backlash"):
            terms, coefficients, fit = swapped, swapped_coefficients, alternative
    return terms, coefficients, fit
