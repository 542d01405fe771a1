"""Friction-like candidate terms: Coulomb asymmetry, load-dependent friction and friction drifting with time.

Their columns take the sign of the velocity from ``DiagnosisContext.friction_sign`` (with a LuGre
prior: the exact sign at full rate filtered like the recording, as the measured torque is); their
CasADi expressions use the smooth sign ``tanh(qd / SMOOTH_VELOCITY)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import (
    MAX_LOAD_FRICTION,
    MIN_DRIFT_TIME_CONSTANT_S,
    SMOOTH_VELOCITY,
    CandidateTerm,
    joint_columns,
    joint_expression,
    oversized,
)


@dataclass(frozen=True)
class CoulombAsymmetryTerm(CandidateTerm):
    """``coulomb_asymmetry``: extra Coulomb friction in the positive direction only."""

    joint: int | None = None
    key = "coulomb_asymmetry"
    explanation = "Coulomb friction that differs between positive and negative motion"
    signature = "residual is a step between the two velocity signs"

    def feature_names(self):
        self._require_joint()
        return [f"delta_fc_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        return joint_columns(context, self.joint, 0.5 * (1.0 + context.friction_sign(self.joint)))

    def implausibility(self, coefficients, context=None):
        """A direction-dependent friction step larger than the joint's torque scale (``oversized``)."""
        return oversized("friction step", float(coefficients[0]), context, self.joint)

    def physical_parameters(self, coefficients):
        return {"delta": float(coefficients[0])}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return joint_expression(
            q.shape[0], self.joint, 0.5 * coefficients[0] * (1 + ca.tanh(qd[self.joint] / SMOOTH_VELOCITY))
        )


@dataclass(frozen=True)
class LoadDependentFrictionTerm(CandidateTerm):
    """``load_dependent_friction``: friction proportional to the transmitted torque ``mu |tau| sign(qd)``."""

    joint: int | None = None
    key = "load_dependent_friction"
    explanation = "friction that grows with the transmitted load, mu |tau| sign(qd) (gear tooth friction)"
    signature = "friction-like residual whose size follows the torque magnitude"

    def feature_names(self):
        self._require_joint()
        return [f"mu_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        j = self.joint
        return joint_columns(context, j, context.friction_sign(j, np.abs(context.full_tau[:, j])))

    def physical_parameters(self, coefficients):
        return {"coefficient": float(coefficients[0])}

    def implausibility(self, coefficients, context=None):
        mu = float(coefficients[0])
        if not 0.0 < mu < MAX_LOAD_FRICTION:
            return (
                f"friction coefficient mu = {mu:.3g} outside (0, {MAX_LOAD_FRICTION}): a gear's tooth friction "
                "does not take that share of the load"
            )
        return None

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        return joint_expression(
            q.shape[0], j, coefficients[0] * ca.fabs(tau_nominal[j]) * ca.tanh(qd[j] / SMOOTH_VELOCITY)
        )


@dataclass(frozen=True)
class FrictionDriftTerm(CandidateTerm):
    """``friction_drift``: Coulomb friction changing with time (warm-up): linearly, or with a time constant
    ``time_constant`` [s] as ``rate T (1 - exp(-t / T))`` once ``refine_fit`` has fitted it."""

    joint: int | None = None
    time_constant: float | None = None
    key = "friction_drift"
    explanation = "Coulomb friction that changes with time as the gear warms up: rate t sign(qd)"
    signature = "friction-like residual growing over the recording"

    def feature_names(self):
        self._require_joint()
        return [f"drift_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        j = self.joint
        return joint_columns(context, j, context.friction_sign(j, self._shape(context.full_t)))

    def _shape(self, t):
        if self.time_constant is None:
            return t
        big_t = self.time_constant
        return big_t * (1.0 - (ca.exp(-t / big_t) if isinstance(t, ca.SX) else np.exp(-np.asarray(t) / big_t)))

    def physical_parameters(self, coefficients):
        out = {"rate": float(coefficients[0])}
        if self.time_constant is not None:
            out["time_constant_s"] = float(self.time_constant)
        return out

    def implausibility(self, coefficients, context=None):
        """A time constant below ``MIN_DRIFT_TIME_CONSTANT_S`` (heat spreads over minutes: a friction that settles
        within seconds is a start-up transient of the recording, not a warm-up), or a friction change over the
        recording larger than the joint's torque scale (``oversized``)."""
        big_t = self.time_constant
        if big_t is not None and big_t < MIN_DRIFT_TIME_CONSTANT_S:
            settled = float(coefficients[0]) * big_t
            return (
                f"time constant {big_t:.3g} s below the {MIN_DRIFT_TIME_CONSTANT_S:g} s of a thermal warm-up (gears "
                f"and lubricant warm up over minutes): a Coulomb friction that settles by {settled:.4g} N m within "
                f"{3.0 * big_t:.3g} s of the recording's start is a start-up transient (the first motion after a "
                "standstill, the controller settling, the filter's edge), not a drift"
            )
        if context is None:
            return None
        ends = self._shape(np.asarray([context.full_t[0], context.full_t[-1]], dtype=float))
        change = float(coefficients[0]) * float(ends[1] - ends[0])
        return oversized("friction change over the recording", change, context, self.joint)

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        return joint_expression(q.shape[0], j, coefficients[0] * self._shape(t) * ca.tanh(qd[j] / SMOOTH_VELOCITY))
