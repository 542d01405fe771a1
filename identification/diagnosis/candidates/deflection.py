"""Candidate terms for a transmission that is not rigid: backlash and joint elasticity.

Both make the recorded (motor-side) joint position differ from the link position by a deflection
``s(t)``; the nominal model evaluated on the recorded signals then misses the rigid-body torque change
``-(s dtau/dq + sd dtau/dqd + sdd M)`` (first order) and the friction change of a shifted velocity
(``DiagnosisContext.friction_shift``, a LuGre simulation of the robot file's friction).

``columns`` are the screening form, linear in one coefficient (the friction change as the secant at a size:
``secant``, else a nominal one, 0.1 deg of half-play or 0.2 deg of torsion at the joint's RMS torque on the
training recording, ``TrainingTorque.on_training``; the backlash's flank smoothing likewise);
``exact_contribution`` is the torque at given physical parameters with the friction change simulated exactly,
fitted by ``signal_fit``. The friction change is far from linear in the deflection, so ``shape_variants`` offers
beside the nominal secant the one at the size where the exact contribution fits the training recording best
(``fitted_secant``, on ``JointScore.fixed``; the BIC counts that size): the diagnosis benchmark's backlash at seeds
1 and 2 (0.43 and 0.30 deg of play on the Denso's joints 5 and 6) lost to the friction shapes the nominal model lacks
with the 0.1 deg secant (seed 1: joint-weighted validation error 0.000633 against their 0.000575) and wins with the
fitted one (0.000366), its width then fitted within 3 % and 7 %. The backlash flank is a function of the unfiltered
measured torque, filtered afterwards like the recording: near a torque reversal the raw torque crosses
zero many times (noise, the drive's ringing), and the flank of the filtered torque is far too sharp.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.data.preprocessing import central_difference
from identification.diagnosis.candidates.base import CandidateTerm
from identification.metrics import rms
from identification.physical_bounds import MAX_BACKLASH_RAD, MAX_DEFLECTION_RAD
from psdm_casadi.errors import ParameterError

#: Half-width [rad] of the play the backlash column's friction part is the secant at, unless fitted (``secant``).
NOMINAL_HALF_WIDTH = float(np.radians(0.1))
#: Torsion [rad] at the joint's RMS torque the elasticity column's friction part is the secant at, unless fitted.
NOMINAL_TORSION = float(np.radians(0.2))
#: Sizes of the exact profile ``shape_variants`` scans, log-spaced from the nominal to ten times it. Not below: there a
#: deflection's friction part is the friction's own lag (pre-sliding), which the friction rival is there to tell from
#: it; on ``test_diagnosis_friction_rival``'s Stribeck-peak Denso a secant at 0.014 deg of half-play made a backlash
#: of that size plausible beside the joint's pre-sliding and took 40 % of its level.
SCAN_POINTS = 9
_SHIFTS = {}  # each recording's friction shifts of a deflection at the scanned sizes (``_shift``, ``recording_cache``)


def fitted_secant(profile, nominal: float, upper: float) -> float | None:
    """The size where the exact training profile ``profile(size)`` (an SSE) is lowest on a log grid of
    ``SCAN_POINTS`` from ``nominal`` to ``min(10 nominal, upper)``, refined to the vertex of the parabola through the
    best point and its neighbours; None when that is within 10 % of the nominal size (its secant stands for it)."""
    if upper <= 1.1 * nominal:
        return None
    grid = np.geomspace(nominal, min(10.0 * nominal, upper), SCAN_POINTS)
    values = np.array([profile(float(x)) for x in grid])
    best = int(np.argmin(values))
    size = float(grid[best])
    i = int(np.clip(best, 1, grid.size - 2))
    x, y = np.log(grid[i - 1 : i + 2]), values[i - 1 : i + 2]
    curvature = y[0] - 2 * y[1] + y[2]
    if curvature > 0 and i == best:  # the vertex, within the neighbours
        size = float(np.exp(x[1] + np.clip(0.5 * (y[0] - y[2]) / curvature, -1, 1) * (x[2] - x[1])))
    return None if abs(np.log(size / nominal)) < 0.1 else size


def _check_secant(name: str, secant) -> None:
    """Refuse a secant that is no size (``BacklashTerm.secant``, ``JointElasticityTerm.secant``)."""
    number = isinstance(secant, (float, int, np.floating)) and not isinstance(secant, bool)
    if secant is not None and not (number and np.isfinite(secant) and secant > 0):
        raise ParameterError(
            f"{name}.secant must be None (the nominal secant) or a size > 0 (the half-play [rad] or the compliance "
            f"[rad/(N m)] the friction column is the secant at); got {secant!r}."
        )


class TrainingTorque:
    """A deflection column sized by a statistic of its joint's torque, fixed on the training recording.

    The backlash's flank smoothing (``torque_scale`` times the 95th percentile of |tau|) and the elasticity's nominal
    secant (``NOMINAL_TORSION`` at the RMS torque) scale with the joint's torque. The friction part is far from
    linear in either size, so the column must be built at one size on every recording: taken on each recording's own
    torque, the validation column was another column than the training one's, wrong by several N m in the tens of
    milliseconds after each velocity reversal (``test_elasticity_column``, ``test_backlash_column``).
    ``on_training`` takes the statistic on the training recording into the field ``size_field`` (so the model file's
    spec keeps it); a term not fixed takes it on the recording its columns are built on.
    """

    #: the dataclass field keeping the statistic [N m] on the training recording (None: each recording's own)
    size_field = ""
    #: what the statistic is, for messages
    size_name = ""

    @staticmethod
    def statistic(tau) -> float:
        """The statistic [N m] of the joint's torque ``tau`` (full rate) the column's size scales with."""
        raise NotImplementedError

    def _check_training_torque(self) -> None:
        size = getattr(self, self.size_field)
        number = isinstance(size, (float, int, np.floating)) and not isinstance(size, bool)
        if size is not None and not (number and np.isfinite(size) and size > 0):
            name = type(self).__name__
            raise ParameterError(
                f"{name}.{self.size_field} must be None (the recording's own) or the joint's {self.size_name} [N m] "
                f"> 0 on the training recording ({name}.on_training); got {size!r}."
            )

    def on_training(self, context):
        """This term with its size fixed on the training recording ``context`` (kept when already set)."""
        self._require_joint()
        if getattr(self, self.size_field) is not None:
            return self
        return replace(self, **{self.size_field: self.training_torque(context)})

    def training_torque(self, context) -> float:
        """The statistic [N m]: the one fixed on the training recording, else the joint's on ``context``."""
        size = getattr(self, self.size_field)
        return float(size) if size is not None else max(self.statistic(context.full_tau[:, self.joint]), 1e-9)


def _shift(context, key: tuple, joint: int, rate_full, size: float):
    """``context.friction_shift(joint, size * rate_full)``, kept per recording for the scanned sizes (``key`` names
    the rate's kind): the selection scans the same grid again in every round."""
    from identification.diagnosis.candidates.friction import recording_cache

    cache = recording_cache(context, _SHIFTS)
    entry = (*key, int(joint), float(size))
    if entry not in cache:
        cache[entry] = context.friction_shift(joint, size * rate_full)
    return cache[entry]


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
class BacklashTerm(TrainingTorque, CandidateTerm):
    """``backlash``: play of width b in the transmission; the motor-side position leads the link by
    ``(b/2) sign(tau)``, switching sides where the transmitted torque reverses. The flank smoothing is
    ``torque_scale`` times ``torque_p95``, the 95th percentile of the joint's |torque| on the training recording
    (``on_training``; None: each recording's own)."""

    joint: int | None = None
    torque_scale: float = 0.02
    secant: float | None = None
    torque_p95: float | None = None
    key = "backlash"
    size_field = "torque_p95"
    size_name = "95th percentile of |torque|"
    explanation = (
        "play (dead zone) in the transmission: motor and link positions differ by b/2, "
        "switching side when the torque reverses"
    )
    signature = "residual concentrated around torque reversals"

    def __post_init__(self):
        _check_secant(type(self).__name__, self.secant)
        self._check_training_torque()

    @staticmethod
    def statistic(tau) -> float:
        return float(np.percentile(np.abs(tau), 95))

    @property
    def n_shape_parameters(self) -> int:
        """The secant's half-width, chosen on the training profile, counts in the BIC beside the coefficient."""
        return 0 if self.secant is None else 1

    @property
    def shape_name(self) -> str:
        """``backlash[j2] (friction part at the nominal 0.1 deg half-width)`` or ``... at the fitted 0.22 deg``."""
        if self.secant is None:
            return f"{self.label} (friction part at the nominal {np.degrees(NOMINAL_HALF_WIDTH):.2g} deg half-width)"
        return f"{self.label} (friction part at the fitted {np.degrees(self.secant):.2g} deg half-width)"

    def feature_names(self):
        self._require_joint()
        return [f"half_backlash_{self.joint + 1}"]

    def shape_variants(self, context, score=None):
        """The column with its friction part the secant at ``NOMINAL_HALF_WIDTH`` and, given ``score`` (a
        ``joint_score.JointScore``), the one at the half-width where the exact contribution's training profile
        (``score.fixed``) is lowest: the friction shift is far from linear in the play (at seed 1 of the diagnosis
        benchmark a 0.22 deg half-width on the Denso's joint 5 lost to the friction shapes with the 0.1 deg secant).
        Both have their flank smoothing fixed on the training recording ``context`` (``on_training``)."""
        if context is None:
            return (replace(self, secant=None),)
        nominal = replace(self.on_training(context), secant=None)
        if score is None:
            return (nominal,)
        scale = nominal.torque_scale_nm(context)
        rows, j, keep = score.rows, self.joint, context.keep
        s, sd, sdd = self._flank(context, 1.0, scale)
        rigid = _deflection_columns(context, j, s[keep], sd[keep], sdd[keep])[rows, :, 0]

        def profile(half_width: float) -> float:
            torque = half_width * rigid
            shift = _shift(context, ("backlash", scale), j, sd, half_width)
            if shift is not None:
                torque[:, j] -= shift[rows]
            return score.fixed(torque)

        secant = fitted_secant(profile, NOMINAL_HALF_WIDTH, 0.5 * MAX_BACKLASH_RAD)
        return (nominal,) if secant is None else (nominal, replace(nominal, secant=secant))

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
        the robot file's LuGre friction at the half-width h0 (``secant``, else ``NOMINAL_HALF_WIDTH``), divided by
        h0."""
        j = self.joint
        if sd_full is None:
            _, sd_full, _ = self._flank(context, 1.0, self.torque_scale_nm(context))
        h0 = NOMINAL_HALF_WIDTH if self.secant is None else self.secant
        shift = context.friction_shift(j, h0 * sd_full)
        return None if shift is None else -shift / h0

    def torque_scale_nm(self, context) -> float:
        """The smoothing torque [N m]: ``torque_scale`` times the 95th percentile of the joint's |torque| on the
        training recording (``torque_p95``), or on ``context`` when the term was not fixed there (``on_training``)."""
        return max(self.torque_scale * self.training_torque(context), 1e-6)

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
class JointElasticityTerm(TrainingTorque, CandidateTerm):
    """``joint_elasticity``: a compliant joint; motor and link angles differ by ``tau / k``."""

    joint: int | None = None
    secant: float | None = None
    torque_rms: float | None = None
    key = "joint_elasticity"
    size_field = "torque_rms"
    size_name = "RMS torque"
    explanation = "a compliant transmission: the motor angle differs from the link angle by tau / k"
    signature = "residual follows torque times the position sensitivity and the torque's second derivative"

    def __post_init__(self):
        _check_secant(type(self).__name__, self.secant)
        self._check_training_torque()

    @staticmethod
    def statistic(tau) -> float:
        return rms(tau)

    def nominal_compliance(self, context) -> float:
        """The compliance [rad/(N m)] of the nominal secant: ``NOMINAL_TORSION`` at ``torque_rms``, or at the joint's
        RMS torque on ``context`` when the term was not fixed on a training recording (``on_training``)."""
        return NOMINAL_TORSION / self.training_torque(context)

    @property
    def n_shape_parameters(self) -> int:
        """The secant's compliance, chosen on the training profile, counts in the BIC beside the coefficient."""
        return 0 if self.secant is None else 1

    @property
    def shape_name(self) -> str:
        """``joint_elasticity[j2] (friction part at the nominal compliance, 0.2 deg at RMS torque)`` or ``... at the
        fitted compliance 0.000274 rad/(N m)``: the two readings of one compliance the selection compares by BIC."""
        if self.secant is None:
            twist = np.degrees(NOMINAL_TORSION)
            return f"{self.label} (friction part at the nominal compliance, {twist:.2g} deg at RMS torque)"
        return f"{self.label} (friction part at the fitted compliance {self.secant:.3g} rad/(N m))"

    def feature_names(self):
        self._require_joint()
        return [f"compliance_{self.joint + 1}"]

    def shape_variants(self, context, score=None):
        """The column with its friction part the secant at ``NOMINAL_TORSION`` at the joint's RMS torque on the
        training recording ``context`` (``on_training``) and, given ``score``, the one at the compliance where the
        exact contribution's training profile is lowest (as the backlash's ``shape_variants``)."""
        if context is None:
            return (replace(self, secant=None),)
        nominal = replace(self.on_training(context), secant=None)
        if score is None:
            return (nominal,)
        j, rows = self.joint, score.rows
        peak = max(float(np.max(np.abs(context.tau[:, j]))), 1e-9)
        rigid = _deflection_columns(context, j, context.tau[:, j], context.tau_rate[:, j], context.tau_accel[:, j])
        rigid = rigid[rows, :, 0]
        rate = np.gradient(context.full_tau[:, j], context.full_t)

        def profile(compliance: float) -> float:
            torque = compliance * rigid
            shift = _shift(context, ("elasticity",), j, rate, compliance)
            if shift is not None:
                torque[:, j] -= shift[rows]
            return score.fixed(torque)

        secant = fitted_secant(profile, nominal.nominal_compliance(context), MAX_DEFLECTION_RAD / peak)
        return (nominal,) if secant is None else (nominal, replace(nominal, secant=secant))

    def columns(self, context):
        self._require_joint()
        j = self.joint
        out = _deflection_columns(context, j, context.tau[:, j], context.tau_rate[:, j], context.tau_accel[:, j])
        # friction: the recorded velocity leads by c dtau/dt, which moves the friction's sign changes; not
        # linear in c, so the column is the finite change at a compliance c0 (``secant``, else the nominal torsion
        # of 0.2 deg at the training RMS torque), divided by c0
        c0 = self.nominal_compliance(context) if self.secant is None else self.secant
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
