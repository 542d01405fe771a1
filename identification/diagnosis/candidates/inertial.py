"""Inertial and gravitational candidate terms: rotor inertia, joint coupling, a payload (a point mass or a body
with its own inertia) and a tilted base.

Rotor inertia and payload amount to a change of the PSDM base parameters (``theta_change``); coupling is
an additive torque; the gravity tilt is reported as a correction of the mounting.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.diagnosis.candidates.base import (
    CandidateTerm,
    joint_columns,
    joint_expression,
    oversized,
)
from identification.physical_bounds import MAX_PAYLOAD_REACH, MAX_TILT_DEG
from psdm_casadi.values import inertia_violation

INERTIA_ORDER = ("Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")  # a payload body's inertia entries, Pinocchio's order
#: a fitted payload body's inertia about its centre of mass may miss consistency by this fraction of the largest
#: moment about the flange (what the data determine; a point mass's own inertia is zero up to the noise)
INERTIA_RTOL = 0.05


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

    def implausibility(self, coefficients, context=None):
        """A coupled torque larger than the joint's torque scale (``oversized``) at the source joint's peak speed and
        acceleration of the recording."""
        if context is None:
            return None
        k, c = self.source, np.abs(np.asarray(coefficients, dtype=float))
        peak = c[0] * float(np.max(np.abs(context.qd[:, k]))) + c[1] * float(np.max(np.abs(context.qdd[:, k])))
        return oversized("coupled torque", peak, context, self.joint)

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        k = self.source
        return joint_expression(q.shape[0], self.joint, coefficients[0] * qd[k] + coefficients[1] * qdd[k])


@dataclass(frozen=True)
class PayloadTerm(CandidateTerm):
    """``payload``: an unmodelled body on the flange, as a point mass or as a rigid body with its own inertia.

    Its columns are the rigid-body torque per unit of each dynamic parameter added to the last link (RNEA is
    linear in them), i.e. exactly the base-parameter change of a payload (paper eqs. 16-17, folded into theta
    through the parameter map in the augmented model). ``inertia=False``: mass m and first moments m r (a point
    mass; its rotational inertia, own and about the flange, is neglected). ``inertia=True``: the 10 parameters
    of a body in the last link frame, m, m r and the inertia about the frame origin (Pinocchio's order), as a
    large tool or bar needs; its fit must be a physically consistent body (positive mass, inertia about the
    centre of mass positive semi-definite with the triangle inequality, ``implausibility``). The library's term
    offers both shapes (``shape_variants``) and the selection keeps the body only where the data support it
    (BIC on training, checked on validation).
    """

    inertia: bool = False
    key = "payload"
    explanation = "an unmodelled end-effector load: mass m with centre of mass r in the flange frame"
    signature = "gravity- and inertia-shaped residual on several joints, largest near the base"
    per_joint = False

    @property
    def label(self):
        return "payload[inertia]" if self.inertia else self.key

    def feature_names(self):
        names = ["payload_m", "payload_mx", "payload_my", "payload_mz"]
        return names + [f"payload_{c}" for c in INERTIA_ORDER] if self.inertia else names

    def _n(self) -> int:
        return 10 if self.inertia else 4

    def _map(self, parameter_map):
        n_dof = parameter_map.shape[1] // 11
        return parameter_map[:, 11 * (n_dof - 1) : 11 * (n_dof - 1) + self._n()]

    def columns(self, context):
        return context.payload[:, :, : self._n()]

    def shape_variants(self, context, residual=None):
        return (self,) if self.inertia else (self, replace(self, inertia=True))

    def physical_parameters(self, coefficients):
        c = np.asarray(coefficients, dtype=float)
        m = float(c[0])
        com = (c[1:4] / m) if abs(m) > 1e-9 else np.zeros(3)
        out = {"mass": m, "com_x": float(com[0]), "com_y": float(com[1]), "com_z": float(com[2])}
        if self.inertia:
            about_com = payload_inertia_about_com(c)
            for (a, b), name in zip(((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)), INERTIA_ORDER):
                out[f"{name}_com"] = float(about_com[a, b])
        return out

    def theta_change(self, coefficients, parameter_map):
        return self._map(parameter_map) @ np.asarray(coefficients, dtype=float)

    def implausibility(self, coefficients, context=None):
        m = float(coefficients[0])
        if abs(m) < 1e-9:
            return "zero mass"
        com = np.asarray(coefficients[1:4], dtype=float) / m
        if np.linalg.norm(com) > MAX_PAYLOAD_REACH:
            return f"centre of mass {np.linalg.norm(com):.3g} m from the flange (more than {MAX_PAYLOAD_REACH} m)"
        if self.inertia:
            if m < 0.0:
                return f"a body of negative mass {m:.3g} kg"
            scale = float(np.abs(np.linalg.eigvalsh(_origin_inertia(coefficients))).max())
            problem = inertia_violation(payload_inertia_about_com(coefficients), rtol=0.0, atol=INERTIA_RTOL * scale)
            if problem:
                return f"not a consistent body: its inertia about the centre of mass {problem}"
        return None

    def interpret(self, coefficients):
        if float(coefficients[0]) < 0.0:
            return (
                "last_link_mass_excess",
                "the last link (flange) is lighter than the robot file says: its mass and "
                "first moments are too large in the prior (a negative payload of |mass| kg)",
            )
        if self.inertia:
            return self.key, "an unmodelled end-effector load: a body of mass m, centre of mass r and its own inertia"
        return self.key, self.explanation


def payload_inertia_about_com(coefficients) -> np.ndarray:
    """The 3x3 inertia about the centre of mass [kg m^2] of a payload's 10 dynamic parameters (m, m r, the inertia
    about the flange origin in Pinocchio's order): the origin inertia less the parallel-axis term
    m (|r|^2 1 - r r^T)."""
    c = np.asarray(coefficients, dtype=float)
    m, first = float(c[0]), c[1:4]
    return _origin_inertia(c) - (first @ first * np.eye(3) - np.outer(first, first)) / m


def _origin_inertia(coefficients) -> np.ndarray:
    """The 3x3 inertia about the flange origin of a payload's 10 dynamic parameters."""
    xx, xy, yy, xz, yz, zz = np.asarray(coefficients, dtype=float)[4:10]
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


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

    def implausibility(self, coefficients, context=None):
        """A mounting tilt beyond ``MAX_TILT_DEG``: no robot is bolted that far off level unnoticed (the gravity-shaped
        residual is then the robot file's masses, not the mounting)."""
        angle = float(np.degrees(np.hypot(*np.asarray(coefficients, dtype=float)[:2])))
        return None if angle <= MAX_TILT_DEG else f"a base tilted {angle:.3g} deg (more than {MAX_TILT_DEG:g} deg)"
