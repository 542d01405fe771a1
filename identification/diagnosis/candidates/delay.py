"""Signal-level candidate term: a time offset between the torque and the motion signals.

Screened through a first-order column (the tangent at no delay) and, given the selection's score, through the
exact delayed torque at the delay its profile puts lowest (the secant there); ``signal_fit`` fits the exact delay.

Why the secant: a model identified on delayed torque has taken up part of the delay (a LuGre friction's bristle
dynamics and its Stribeck curve mimic a lag), so near no delay the error of that model can even fall towards a
negative delay, while the exact delayed torque, with the model's free parameters refitted at each delay (variable
projection), still has its lowest error at the true delay. The tangent sees only the slope at no delay; the profile
over the delays a recording can hold sees the minimum.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar

from identification.diagnosis.candidates.base import CandidateTerm
from identification.physical_bounds import MAX_DELAY_S
from psdm_casadi.errors import ParameterError

#: Delays of the profile ``shape_variants`` scans, log-spaced from one full-rate sample to ``MAX_DELAY_S``.
SCAN_POINTS = 24


@dataclass(frozen=True)
class DelayTerm(CandidateTerm):
    """``delay``: the torque signal lags the position signal by d seconds (bus or filter delay), all joints.

    First order: ``tau_rec(t) = tau(t - d)`` so ``tau(t) ~ tau_rec + d dtau_rec/dt``; the column is
    ``-dtau_rec/dt`` on every joint with one shared coefficient d. With ``secant_s`` the column is the exact
    ``(tau_rec(t) - tau_rec(t + s)) / s`` at ``s = secant_s``, exact for a coefficient d = s
    (``shape_variants``: the delay where the selection's exact profile is lowest).

    Parameters
    ----------
    secant_s : float or None
        Delay [s] in (0, ``MAX_DELAY_S``) the column is the secant at; None for the tangent at no delay.
    """

    secant_s: float | None = None
    key = "delay"
    explanation = "a time offset between the torque and the motion signals (communication or filter delay)"
    signature = "residual proportional to the rate of change of the torque, on every joint"
    per_joint = False

    def __post_init__(self):
        if self.secant_s is not None and not (
            isinstance(self.secant_s, (float, int, np.floating)) and 0.0 < self.secant_s < MAX_DELAY_S
        ):
            raise ParameterError(
                f"DelayTerm.secant_s must be None or a delay in (0, {MAX_DELAY_S}) s; got {self.secant_s!r}. "
                "Leave it None (the selection sets it)."
            )

    @property
    def n_shape_parameters(self) -> int:
        """The secant's delay, chosen on the training profile, counts in the BIC beside the coefficient."""
        return 0 if self.secant_s is None else 1

    @property
    def shape_name(self) -> str:
        """``delay (tangent)`` or ``delay (secant at 17 ms)``: the two readings the selection compares by BIC."""
        if self.secant_s is None:
            return f"{self.label} (tangent)"
        return f"{self.label} (secant at {1e3 * self.secant_s:.3g} ms)"

    def feature_names(self):
        return ["delay_s"]

    def columns(self, context):
        if self.secant_s is None:
            return -context.tau_rate[:, :, None]
        return (context.delayed_torque_difference(self.secant_s) / self.secant_s)[:, :, None]

    def shape_variants(self, context, score=None):
        """The tangent and, given ``score`` (a ``joint_score.JointScore``), the secant at the delay in (0,
        ``MAX_DELAY_S``) where the exact profile ``score.fixed`` is lowest, unless that is the profile's shortest
        delay (the tangent then stands for it)."""
        tangent = replace(self, secant_s=None)
        if score is None:
            return (tangent,)
        rows = score.rows
        t = context.t[rows]

        def profile(delay: float) -> float:
            shifted = np.column_stack(
                [np.interp(t + delay, context.full_t, context.full_tau[:, j]) for j in range(context.n_dof)]
            )
            return score.fixed(context.tau[rows] - shifted)

        shortest = min(1.0 / context.full_rate_hz, 0.1 * MAX_DELAY_S)
        grid = np.geomspace(shortest, MAX_DELAY_S, SCAN_POINTS, endpoint=False)
        values = [profile(d) for d in grid]
        best = int(np.argmin(values))
        if best == 0:
            return (tangent,)
        upper = grid[best + 1] if best + 1 < grid.size else 0.5 * (grid[best] + MAX_DELAY_S)
        found = minimize_scalar(profile, bounds=(grid[best - 1], upper), method="bounded",
                                options={"xatol": 0.05 / context.full_rate_hz, "maxiter": 20})  # fmt: skip
        delay = float(found.x) if found.fun < values[best] else float(grid[best])
        return tangent, replace(self, secant_s=delay)

    def physical_parameters(self, coefficients):
        return {"delay_s": float(coefficients[0])}

    def exact_contribution(self, context, delay: float) -> np.ndarray:
        """Torque (n_samples, n_dof) a delay of ``delay`` [s] adds to the model, not linearised:
        ``tau_rec(t) - tau_rec(t + d)`` (``DiagnosisContext.delayed_torque_difference``)."""
        return context.delayed_torque_difference(delay)

    def implausibility(self, coefficients, context=None):
        d = float(coefficients[0])
        if not 0.0 < d < MAX_DELAY_S:
            return f"delay {d:.3g} s outside (0, {MAX_DELAY_S}) s"
        return None
