"""Inertial and gravitational candidate terms: rotor inertia, joint coupling, a payload and a tilted base.

Rotor inertia and payload amount to a change of the PSDM base parameters (``theta_change``); coupling is
an additive torque; the gravity tilt is reported as a correction of the mounting.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.diagnosis.candidates.base import MAX_PAYLOAD_REACH, CandidateTerm, joint_columns, joint_expression


@dataclass(frozen=True)
class RotorInertiaTerm(CandidateTerm):
    """``rotor_inertia``: drive (rotor and gear) inertia missing from the joint's mass-matrix diagonal."""

    joint: int | None = None
    key = "rotor_inertia"
    explanation = "drive inertia (rotor, gears) reflected to the joint, missing from the model: Im qdd"
    signature = "residual follows the joint's own acceleration"

    def feature_names(self):
        self._require_joint()
        return [f"Im_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        return joint_columns(context, self.joint, context.qdd[:, self.joint])

    def physical_parameters(self, coefficients):
        return {"inertia": float(coefficients[0])}

    def implausibility(self, coefficients, context=None):
        if float(coefficients[0]) <= 0.0:
            return f"drive inertia {float(coefficients[0]):.3g} kg m^2 is not positive"
        return None

    def theta_change(self, coefficients, parameter_map):
        n_dof = parameter_map.shape[1] // 11
        return parameter_map[:, 11 * self.joint + 10] * float(coefficients[0]) if n_dof else None


@dataclass(frozen=True)
class CouplingTerm(CandidateTerm):
    """``coupling``: velocity/acceleration of joint ``source`` appearing as torque on ``joint``."""

    joint: int | None = None
    source: int | None = None
    key = "coupling"
    explanation = "torque of one joint appearing on another (coupled wrist, differential, cross-talk): c qd_k + d qdd_k"
    signature = "residual of one joint follows the velocity or acceleration of another"

    def expand(self, n_dof):
        pairs = [(j, k) for j in range(n_dof) for k in range(n_dof) if j != k]
        if self.joint is not None:
            pairs = [p for p in pairs if p[0] == self.joint]
        if self.source is not None:
            pairs = [p for p in pairs if p[1] == self.source]
        return tuple(replace(self, joint=j, source=k) for j, k in pairs)

    @property
    def joints(self):
        return () if self.joint is None else (int(self.joint), int(self.source))

    @property
    def label(self):
        return f"{self.key}[j{self.source + 1}->j{self.joint + 1}]"

    def feature_names(self):
        self._require_joint()
        j, k = self.joint + 1, self.source + 1
        return [f"c_qd{k}_on{j}", f"c_qdd{k}_on{j}"]

    def columns(self, context):
        self._require_joint()
        k = self.source
        return joint_columns(context, self.joint, np.column_stack([context.qd[:, k], context.qdd[:, k]]))

    def physical_parameters(self, coefficients):
        return {
            "viscous": float(coefficients[0]),
            "inertia": float(coefficients[1]),
            "source_joint": float(self.source + 1),
        }

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        k = self.source
        return joint_expression(q.shape[0], self.joint, coefficients[0] * qd[k] + coefficients[1] * qdd[k])


@dataclass(frozen=True)
class PayloadTerm(CandidateTerm):
    """``payload``: an unmodelled point mass on the flange: mass m and centre of mass r in the last link frame.

    Its columns are the rigid-body torque per unit mass and first moment added to the last link (RNEA is
    linear in them), i.e. exactly the base-parameter change of a payload (paper eqs. 16-17, folded into
    theta through the parameter map in the augmented model); the payload's own rotational inertia is neglected.
    """

    key = "payload"
    explanation = "an unmodelled end-effector load: mass m with centre of mass r in the flange frame"
    signature = "gravity- and inertia-shaped residual on several joints, largest near the base"
    per_joint = False

    def feature_names(self):
        return ["payload_m", "payload_mx", "payload_my", "payload_mz"]

    def _map(self, parameter_map):
        n_dof = parameter_map.shape[1] // 11
        return parameter_map[:, 11 * (n_dof - 1) : 11 * (n_dof - 1) + 4]

    def columns(self, context):
        return context.payload

    def physical_parameters(self, coefficients):
        m = float(coefficients[0])
        com = (np.asarray(coefficients[1:4], dtype=float) / m) if abs(m) > 1e-9 else np.zeros(3)
        return {"mass": m, "com_x": float(com[0]), "com_y": float(com[1]), "com_z": float(com[2])}

    def theta_change(self, coefficients, parameter_map):
        return self._map(parameter_map) @ np.asarray(coefficients, dtype=float)

    def implausibility(self, coefficients, context=None):
        m = float(coefficients[0])
        if abs(m) < 1e-9:
            return "zero mass"
        com = np.asarray(coefficients[1:4], dtype=float) / m
        if np.linalg.norm(com) > MAX_PAYLOAD_REACH:
            return f"centre of mass {np.linalg.norm(com):.3g} m from the flange (more than {MAX_PAYLOAD_REACH} m)"
        return None

    def interpret(self, coefficients):
        if float(coefficients[0]) < 0.0:
            return (
                "last_link_mass_excess",
                "the last link (flange) is lighter than the robot file says: its mass and "
                "first moments are too large in the prior (a negative payload of |mass| kg)",
            )
        return self.key, self.explanation


@dataclass(frozen=True)
class GravityTiltTerm(CandidateTerm):
    """``gravity_tilt``: the base is mounted off level; gravity rotated by small angles about two axes normal to it."""

    key = "gravity_tilt"
    explanation = "the robot base is not level, so gravity acts in a slightly rotated direction"
    signature = "gravity-shaped residual that follows position on the joints carrying load"
    per_joint = False

    def feature_names(self):
        return ["tilt_a", "tilt_b"]

    def columns(self, context):
        return context.tilt

    def physical_parameters(self, coefficients):
        a, b = (float(x) for x in coefficients)
        return {"angle_deg": float(np.degrees(np.hypot(a, b))), "angle_a_rad": a, "angle_b_rad": b}
