"""Signal-level candidate term: a time offset between the torque and the motion signals.

Screened through a first-order column here; ``signal_fit`` fits the exact delay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates.base import MAX_DELAY_S, CandidateTerm


@dataclass(frozen=True)
class DelayTerm(CandidateTerm):
    """``delay``: the torque signal lags the position signal by d seconds (bus or filter delay), all joints.

    First order: ``tau_rec(t) = tau(t - d)`` so ``tau(t) ~ tau_rec + d dtau_rec/dt``; the column is
    ``-dtau_rec/dt`` on every joint with one shared coefficient d.
    """

    key = "delay"
    explanation = "a time offset between the torque and the motion signals (communication or filter delay)"
    signature = "residual proportional to the rate of change of the torque, on every joint"
    per_joint = False

    def feature_names(self):
        return ["delay_s"]

    def columns(self, context):
        return -context.tau_rate[:, :, None]

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
