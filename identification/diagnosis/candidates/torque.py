"""Candidate torques of position or of nothing at all: a spring, a torque offset, a position-periodic ripple.

Each acts on one joint and is an additive torque of (q, t) in the augmented model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import CandidateTerm, joint_columns, joint_expression


@dataclass(frozen=True)
class SpringTerm(CandidateTerm):
    """``spring``: elastic torque ``k (q - q0)`` on one joint (gravity compensator, cable, hose)."""

    joint: int | None = None
    key = "spring"
    explanation = "a position-dependent elastic torque k (q - q0) on the joint (spring balancer, cables)"
    signature = "residual follows joint position, not velocity"

    def feature_names(self):
        self._require_joint()
        return [f"k_q{self.joint + 1}", f"c_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        return joint_columns(
            context, self.joint, np.column_stack([context.q[:, self.joint], np.ones(context.n_samples)])
        )

    def physical_parameters(self, coefficients):
        k, c = (float(x) for x in coefficients)
        return {"k": k, "q0": (-c / k) if k != 0 else 0.0}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return joint_expression(q.shape[0], self.joint, coefficients[0] * q[self.joint] + coefficients[1])


@dataclass(frozen=True)
class TorqueOffsetTerm(CandidateTerm):
    """``torque_offset``: a constant bias on the measured torque (current-sensor offset)."""

    joint: int | None = None
    key = "torque_offset"
    explanation = "a constant bias on the measured torque (sensor or current offset)"
    signature = "residual has a non-zero mean independent of motion"

    def feature_names(self):
        self._require_joint()
        return [f"offset_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        return joint_columns(context, self.joint, np.ones(context.n_samples))

    def physical_parameters(self, coefficients):
        return {"offset": float(coefficients[0])}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return joint_expression(q.shape[0], self.joint, coefficients[0] + 0 * q[self.joint])


@dataclass(frozen=True)
class TorqueRippleTerm(CandidateTerm):
    """``torque_ripple``: torque periodic in the joint angle, ``A sin(h q + phi)`` (cogging, gear ripple)."""

    joint: int | None = None
    harmonic: int | None = None
    harmonics: tuple = tuple(range(2, 17))
    key = "torque_ripple"
    explanation = "a torque periodic in the joint angle, A sin(h q + phase) (motor cogging, gear ripple)"
    signature = "residual oscillates with position at a fixed number of periods per revolution"

    def expand(self, n_dof):
        joints = CandidateTerm.expand(replace(self, harmonic=None), n_dof)
        hs = self.harmonics if self.harmonic is None else (self.harmonic,)
        return tuple(replace(term, harmonic=int(h)) for term in joints for h in hs)

    @property
    def label(self):
        return f"{self.key}[j{self.joint + 1},h={self.harmonic}]"

    def feature_names(self):
        self._require_joint()
        return [f"ripple_sin{self.harmonic}_q{self.joint + 1}", f"ripple_cos{self.harmonic}_q{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        x = self.harmonic * context.q[:, self.joint]
        return joint_columns(context, self.joint, np.column_stack([np.sin(x), np.cos(x)]))

    def physical_parameters(self, coefficients):
        a, b = (float(x) for x in coefficients)
        return {"amplitude": float(np.hypot(a, b)), "harmonic": float(self.harmonic), "phase": float(np.arctan2(b, a))}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        x = self.harmonic * q[self.joint]
        return joint_expression(q.shape[0], self.joint, coefficients[0] * ca.sin(x) + coefficients[1] * ca.cos(x))
