"""A counterbalance on one joint as one term: its constant and its bend, ``c + a sin(h q) + b cos(h q)``.

Not a library candidate the selection offers (the library finds a balancer as a torque offset, a spring or a ripple of
the joint's angle, ``counterbalance_naming``): the shape a model file writes where identify kept the counterbalance as
the joint's torque offset and the diagnosis found its bend beside it as a low harmonic of the angle
(``calibration.counterbalance_finding``). Over a joint's swing such a harmonic is mostly a constant, so beside the
offset the two trade it and neither is the counterbalance's number; one term holding both has one constant, fitted
once. ``term_spec`` rebuilds it from a model file, so the fit, the prediction, the diagnosis of that file (a carried
column) and the exported code hold the same columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import CandidateTerm, joint_columns, joint_expression
from psdm_casadi.errors import ParameterError

__all__ = ["CounterbalanceTerm"]


@dataclass(frozen=True)
class CounterbalanceTerm(CandidateTerm):
    """``counterbalance``: a balancer's torque on ``joint``, its constant and its bend over the swing as the
    ``harmonic``-th harmonic of the joint's angle (module docstring). The constant's feature is named as a spring's
    (``c_<j>``, ``held_friction.CONSTANT_FEATURE``): it takes the place of a torque offset chosen from the data on the
    joint (``findings.offsets_left_to_findings``), not a column beside it."""

    joint: int | None = None
    harmonic: int = 2
    key = "counterbalance"
    explanation = (
        "a counterbalance (spring or cam balancer) on the joint: its torque over the swing, a constant and its bend "
        "as a low harmonic of the joint's angle, written as one term"
    )
    signature = "a torque of the joint's angle that is mostly a constant over its swing and bends with it"

    def __post_init__(self):
        if not (isinstance(self.harmonic, (int, np.integer)) and self.harmonic >= 1):
            raise ParameterError(f"CounterbalanceTerm.harmonic must be an integer >= 1; got {self.harmonic!r}.")

    def feature_names(self):
        self._require_joint()
        j, h = self.joint + 1, self.harmonic
        return [f"c_{j}", f"counterbalance_sin{h}_q{j}", f"counterbalance_cos{h}_q{j}"]

    def columns(self, context):
        self._require_joint()
        x = self.harmonic * context.q[:, self.joint]
        return joint_columns(context, self.joint, np.column_stack([np.ones_like(x), np.sin(x), np.cos(x)]))

    def physical_parameters(self, coefficients):
        """The ``constant`` [N m] and the bend's ``amplitude`` [N m], ``harmonic`` and ``phase`` [rad]
        (``a sin(h q) + b cos(h q) = amplitude sin(h q + phase)``)."""
        c, a, b = (float(x) for x in coefficients)
        return {"constant": c, "amplitude": float(np.hypot(a, b)), "harmonic": float(self.harmonic),
                "phase": float(np.arctan2(b, a))}  # fmt: skip

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        x = self.harmonic * q[self.joint]
        c0, c1, c2 = (float(c) if not isinstance(c, (ca.SX, ca.MX, ca.DM)) else c for c in coefficients[:3])
        value = c0 + c1 * ca.sin(x) + c2 * ca.cos(x)
        return joint_expression(q.shape[0], self.joint, value)
