"""Candidate terms for a transmission that is not rigid: backlash and joint elasticity.

Both make the recorded (motor-side) joint position differ from the link position by a deflection
``s(t)``; the nominal model evaluated on the recorded signals then misses the rigid-body torque change
``-(s dtau/dq + sd dtau/dqd + sdd M)`` (first order) and the friction change of a shifted velocity
(``DiagnosisContext.friction_shift``, a LuGre simulation of the robot file's friction).

``columns`` are the screening form, linear in one coefficient (the friction change linearised at a
nominal size); ``exact_contribution`` is the torque at given physical parameters with the friction
change simulated exactly, fitted by ``signal_fit``. The backlash flank is a function of the unfiltered
measured torque, filtered afterwards like the recording: near a torque reversal the raw torque crosses
zero many times (noise, the drive's ringing), and the flank of the filtered torque is far too sharp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.data.preprocessing import central_difference
from identification.diagnosis.candidates.base import MAX_BACKLASH_RAD, MAX_DEFLECTION_RAD, CandidateTerm
from identification.metrics import rms


def _deflection_columns(context, joint, s, sd, sdd):
    """Rigid-body torque change when the recorded position of ``joint`` is the true one plus a deflection ``s``:
    ``-(s dtau/dq_j + sd dtau/dqd_j + sdd M[:, j])`` (first order), shape (n_samples, n_dof, 1). The friction
    part (the velocity signal is shifted too) is added by the terms through ``DiagnosisContext.friction_shift``."""
    out = -(
        s[:, None] * context.dtau_dq[:, :, joint]
        + sd[:, None] * context.dtau_dqd[:, :, joint]
        + sdd[:, None] * context.mass[:, :, joint]
    )
    return out[:, :, None]


@dataclass(frozen=True)
class BacklashTerm(CandidateTerm):
    """``backlash``: play of width b in the transmission; the motor-side position leads the link by
    ``(b/2) sign(tau)``, switching sides where the transmitted torque reverses."""

    joint: int | None = None
    torque_scale: float = 0.02
    key = "backlash"
    explanation = (
        "play (dead zone) in the transmission: motor and link positions differ by b/2, "
        "switching side when the torque reverses"
    )
    signature = "residual concentrated around torque reversals"

    def feature_names(self):
        self._require_joint()
        return [f"half_backlash_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        j = self.joint
        s, sd, sdd = self._flank(context, 1.0, self.torque_scale_nm(context))
        keep = context.keep
        out = _deflection_columns(context, j, s[keep], sd[keep], sdd[keep])
        friction = self.friction_column(context, sd)
        if friction is not None:
            out[:, j, 0] += friction
        return out

    def friction_column(self, context, sd_full=None):
        """Friction part of the column (n_samples,), or None without drives: the recorded velocity leads by
        (b/2) ds/dt, which moves the friction's sign changes; not linear in b, so it is the finite change of
        the robot file's LuGre friction at a nominal half-width h0 = 0.1 deg, divided by h0."""
        j = self.joint
        if sd_full is None:
            _, sd_full, _ = self._flank(context, 1.0, self.torque_scale_nm(context))
        h0 = np.radians(0.1)
        shift = context.friction_shift(j, h0 * sd_full)
        return None if shift is None else -shift / h0

    def torque_scale_nm(self, context) -> float:
        """The smoothing torque [N m]: ``torque_scale`` times the 95th percentile of the joint's |torque|."""
        return max(self.torque_scale * float(np.percentile(np.abs(context.full_tau[:, self.joint]), 95)), 1e-6)

    def _flank(self, context, half_width, scale):
        """Deflection ``s = h tanh(tau / tau_s)`` of the unfiltered measured torque (the sensor saw the flank
        change of the raw signal), filtered like the recording, with its time derivatives, at full rate."""
        s = context.lowpass_full(half_width * np.tanh(context.raw_torque[:, self.joint] / scale))
        sd, sdd = central_difference(context.full_t, s)
        return s, sd, sdd

    def exact_contribution(self, context, half_width: float, torque_scale_nm: float) -> np.ndarray:
        """Torque (n_samples, n_dof) a play of half-width ``half_width`` [rad] with flank smoothing
        ``torque_scale_nm`` [N m] adds to the nominal model: the rigid-body part to first order in the
        (small) deflection, the friction part exactly (a LuGre simulation at the link velocity
        ``qd_rec - sd``, not linearised: the deflection rate flips the velocity's sign near reversals)."""
        j = self.joint
        s, sd, sdd = self._flank(context, half_width, torque_scale_nm)
        keep = context.keep
        out = _deflection_columns(context, j, s[keep], sd[keep], sdd[keep])[:, :, 0]
        shift = context.friction_shift(j, sd)
        if shift is not None:
            out[:, j] -= shift
        return out

    def physical_parameters(self, coefficients):
        return {"backlash_rad": 2.0 * float(coefficients[0])}

    def implausibility(self, coefficients, context=None):
        b = 2.0 * float(coefficients[0])
        if not 0.0 < b < MAX_BACKLASH_RAD:
            return f"backlash {b:.3g} rad outside (0, {MAX_BACKLASH_RAD}) rad"
        return None


@dataclass(frozen=True)
class JointElasticityTerm(CandidateTerm):
    """``joint_elasticity``: a compliant joint; motor and link angles differ by ``tau / k``."""

    joint: int | None = None
    key = "joint_elasticity"
    explanation = "a compliant transmission: the motor angle differs from the link angle by tau / k"
    signature = "residual follows torque times the position sensitivity and the torque's second derivative"

    def feature_names(self):
        self._require_joint()
        return [f"compliance_{self.joint + 1}"]

    def columns(self, context):
        self._require_joint()
        j = self.joint
        out = _deflection_columns(context, j, context.tau[:, j], context.tau_rate[:, j], context.tau_accel[:, j])
        # friction: the recorded velocity leads by c dtau/dt, which moves the friction's sign changes; not
        # linear in c, so the column is the finite change at a nominal compliance c0 (torsion of 0.2 deg
        # at the joint's RMS torque), divided by c0
        c0 = np.radians(0.2) / max(rms(context.full_tau[:, j]), 1e-9)
        rate = np.gradient(context.full_tau[:, j], context.full_t)
        shift = context.friction_shift(j, c0 * rate)
        if shift is not None:
            out[:, j, 0] -= shift / c0
        return out

    def exact_contribution(self, context, compliance: float) -> np.ndarray:
        """Torque (n_samples, n_dof) a compliance ``compliance`` [rad/(N m)] adds to the nominal model: the
        rigid-body part (linear in it) and the friction part exactly (a LuGre simulation at the link
        velocity ``qd_rec - c dtau/dt``, which moves the friction's sign changes)."""
        j, c = self.joint, float(compliance)
        out = (
            c
            * _deflection_columns(context, j, context.tau[:, j], context.tau_rate[:, j], context.tau_accel[:, j])[
                :, :, 0
            ]
        )
        rate = np.gradient(context.full_tau[:, j], context.full_t)
        shift = context.friction_shift(j, c * rate)
        if shift is not None:
            out[:, j] -= shift
        return out

    def physical_parameters(self, coefficients):
        c = float(coefficients[0])
        return {"compliance_rad_per_Nm": c, "stiffness_Nm_per_rad": (1.0 / c) if c > 0 else float("inf")}

    def implausibility(self, coefficients, context=None):
        c = float(coefficients[0])
        if c <= 0.0:
            return f"compliance {c:.3g} rad/(N m) is not positive"
        if context is not None:
            deflection = c * float(np.max(np.abs(context.tau[:, self.joint])))
            if deflection > MAX_DEFLECTION_RAD:
                return f"torsion {deflection:.3g} rad at the peak torque (more than {MAX_DEFLECTION_RAD} rad)"
        return None
