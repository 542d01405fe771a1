"""Candidate physics terms: what a nominal model may have left out, as columns, CasADi expressions and words.

Terms compose as a library (``SpringTerm() + TorqueOffsetTerm()`` gives a ``CandidateLibrary``), like the
candidate functions of pysindy. A term built without a joint stands for one instance per joint
(``expand``); every concrete instance provides ``feature_names()`` and ``columns(context)``, an array
(n_samples, n_dof, n_features) that enters the least-squares fit linearly (nonlinear effects such as a
delay, backlash and joint elasticity enter through their first-order expansion around the nominal
model), ``physical_parameters(coefficients)`` turning fitted coefficients into named physical
parameters, and where possible ``casadi_expression`` for the augmented model.

The transmission terms (backlash, joint elasticity) live in ``deflection_terms``; fitted parameters are
checked against physical bounds (``CandidateTerm.implausibility``, constants ``MAX_*`` below).

Friction-like columns take the sign of the velocity from ``DiagnosisContext.friction_sign`` (with a
LuGre prior: the exact sign at full rate filtered like the recording, as the measured torque is);
their CasADi expressions use the smooth sign ``tanh(qd / SMOOTH_VELOCITY)``.

Sign convention: columns describe torque the motors must supply in addition to the nominal model,
``tau_measured = tau_nominal + columns @ coefficients``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError

SMOOTH_VELOCITY = 0.02  # [rad/s] width of the smooth sign tanh(qd / v) of the friction-like terms

# plausibility bounds of fitted parameters (``CandidateTerm.implausibility``)
MAX_LOAD_FRICTION = 0.5   # load-dependent friction coefficient mu (gear efficiency above 50 %)
MAX_DELAY_S = 0.1         # torque-to-position delay [s]
MAX_BACKLASH_RAD = 0.05   # total play [rad] (about 3 degrees)
MAX_DEFLECTION_RAD = 0.05  # joint torsion at the peak torque [rad]
MAX_PAYLOAD_REACH = 0.5   # distance of a payload's centre of mass from the flange [m]


def _rows(context, joint: int, values) -> np.ndarray:
    """Columns (n_samples, n_dof, k) with ``values`` (n_samples, k) on joint ``joint`` and zero elsewhere."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    out = np.zeros((context.n_samples, context.n_dof, values.shape[1]))
    out[:, joint, :] = values
    return out


class CandidateTerm:
    """Base class of candidate physics terms.

    Class attributes
    ----------------
    key : str
        The effect's name in reports and JSON (``spring``, ``payload``, ...).
    explanation : str
        The physics in plain language.
    signature : str
        How the effect shows in the residual (used in reports; the fit ranks candidates by it numerically).
    per_joint : bool
        Whether ``expand`` makes one instance per joint.
    """

    key = ""
    explanation = ""
    signature = ""
    per_joint = True

    joint: int | None = None

    # --- composition --------------------------------------------------------------------------
    def __add__(self, other):
        return CandidateLibrary((self,)) + other

    def expand(self, n_dof: int) -> tuple:
        """Concrete instances for a robot with ``n_dof`` joints."""
        if not self.per_joint:
            return (self,)
        if self.joint is not None:
            if not (isinstance(self.joint, (int, np.integer)) and 0 <= self.joint < n_dof):
                raise ParameterError(f"{type(self).__name__}.joint must be a joint index 0..{n_dof - 1}; got {self.joint!r}.")
            return (self,)
        return tuple(replace(self, joint=j) for j in range(n_dof))

    @property
    def joints(self) -> tuple:
        """Joints (0-based) the term acts on; empty for robot-wide terms until fitted."""
        return () if self.joint is None else (int(self.joint),)

    @property
    def label(self) -> str:
        """Short unique label of the instance, e.g. ``spring[j2]``."""
        return self.key if self.joint is None else f"{self.key}[j{self.joint + 1}]"

    def _require_joint(self):
        if self.joint is None:
            raise ParameterError(f"{type(self).__name__}.joint is None; call expand(n_dof) to get one term per joint.")

    # --- interface ----------------------------------------------------------------------------
    def feature_names(self) -> list:
        raise NotImplementedError

    def columns(self, context) -> np.ndarray:
        """Columns (n_samples, n_dof, n_features) on a ``DiagnosisContext``."""
        raise NotImplementedError

    def physical_parameters(self, coefficients) -> dict:
        """Named physical parameters (floats) from the fitted coefficients (n_features,)."""
        return {name: float(c) for name, c in zip(self.feature_names(), coefficients)}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        """Extra torque (SX, n_dof) of the term, or None when it is a signal correction (delay, backlash,
        elasticity) or a change of the base parameters (see ``theta_change``)."""
        return None

    def theta_change(self, coefficients, parameter_map) -> np.ndarray | None:
        """Change of the PSDM base parameters (n_base,) the term amounts to, or None."""
        return None

    def implausibility(self, coefficients, context=None) -> str | None:
        """Why the fitted coefficients are not physical (the selection then skips the term), or None.

        The default accepts any value; terms with a sign or a range (inertia, friction coefficient,
        delay, compliance, backlash) override it.
        """
        return None

    def interpret(self, coefficients) -> tuple:
        """``(effect, explanation)`` reported for the fitted coefficients (the payload term reports a negative
        mass as a last link too heavy in the robot file)."""
        return self.key, self.explanation


def _expr_rows(n_dof: int, joint: int, value):
    out = ca.SX.zeros(n_dof)
    out[joint] = value
    return out


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
        return _rows(context, self.joint, np.column_stack([context.q[:, self.joint], np.ones(context.n_samples)]))

    def physical_parameters(self, coefficients):
        k, c = (float(x) for x in coefficients)
        return {"k": k, "q0": (-c / k) if k != 0 else 0.0}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return _expr_rows(q.shape[0], self.joint, coefficients[0] * q[self.joint] + coefficients[1])


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
        return _rows(context, self.joint, np.ones(context.n_samples))

    def physical_parameters(self, coefficients):
        return {"offset": float(coefficients[0])}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return _expr_rows(q.shape[0], self.joint, coefficients[0] + 0 * q[self.joint])


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
        return _rows(context, self.joint, 0.5 * (1.0 + context.friction_sign(self.joint)))

    def physical_parameters(self, coefficients):
        return {"delta": float(coefficients[0])}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return _expr_rows(q.shape[0], self.joint, 0.5 * coefficients[0] * (1 + ca.tanh(qd[self.joint] / SMOOTH_VELOCITY)))


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
        return _rows(context, j, context.friction_sign(j, np.abs(context.full_tau[:, j])))

    def physical_parameters(self, coefficients):
        return {"coefficient": float(coefficients[0])}

    def implausibility(self, coefficients, context=None):
        mu = float(coefficients[0])
        if not 0.0 < mu < MAX_LOAD_FRICTION:
            return f"friction coefficient mu = {mu:.3g} outside (0, {MAX_LOAD_FRICTION})"
        return None

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        return _expr_rows(q.shape[0], j, coefficients[0] * ca.fabs(tau_nominal[j]) * ca.tanh(qd[j] / SMOOTH_VELOCITY))


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
        return _rows(context, j, context.friction_sign(j, self._shape(context.full_t)))

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

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        return _expr_rows(q.shape[0], j, coefficients[0] * self._shape(t) * ca.tanh(qd[j] / SMOOTH_VELOCITY))


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
        return _rows(context, self.joint, np.column_stack([np.sin(x), np.cos(x)]))

    def physical_parameters(self, coefficients):
        a, b = (float(x) for x in coefficients)
        return {"amplitude": float(np.hypot(a, b)), "harmonic": float(self.harmonic), "phase": float(np.arctan2(b, a))}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        x = self.harmonic * q[self.joint]
        return _expr_rows(q.shape[0], self.joint, coefficients[0] * ca.sin(x) + coefficients[1] * ca.cos(x))


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
        return _rows(context, self.joint, context.qdd[:, self.joint])

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
        return _rows(context, self.joint, np.column_stack([context.qd[:, k], context.qdd[:, k]]))

    def physical_parameters(self, coefficients):
        return {"viscous": float(coefficients[0]), "inertia": float(coefficients[1]), "source_joint": float(self.source + 1)}

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        k = self.source
        return _expr_rows(q.shape[0], self.joint, coefficients[0] * qd[k] + coefficients[1] * qdd[k])


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
        return parameter_map[:, 11 * (n_dof - 1):11 * (n_dof - 1) + 4]

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
            return ("last_link_mass_excess", "the last link (flange) is lighter than the robot file says: its mass and "
                    "first moments are too large in the prior (a negative payload of |mass| kg)")
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


@dataclass(frozen=True)
class CandidateLibrary:
    """An ordered set of candidate terms; ``+`` appends terms or libraries."""

    terms: tuple = field(default_factory=tuple)

    def __post_init__(self):
        for term in self.terms:
            if not isinstance(term, CandidateTerm):
                raise ParameterError(f"CandidateLibrary.terms must hold CandidateTerm objects; got {type(term).__name__}.")

    def __add__(self, other):
        if isinstance(other, CandidateLibrary):
            return CandidateLibrary(self.terms + other.terms)
        if isinstance(other, CandidateTerm):
            return CandidateLibrary(self.terms + (other,))
        return NotImplemented

    def __len__(self):
        return len(self.terms)

    def __iter__(self):
        return iter(self.terms)

    def expand(self, n_dof: int) -> tuple:
        """All concrete instances for a robot with ``n_dof`` joints."""
        return tuple(inst for term in self.terms for inst in term.expand(n_dof))

    @property
    def keys(self) -> tuple:
        return tuple(term.key for term in self.terms)


from identification.diagnosis.deflection_terms import BacklashTerm, JointElasticityTerm  # noqa: E402  (they subclass CandidateTerm)

ALL_TERMS = (TorqueOffsetTerm, SpringTerm, CoulombAsymmetryTerm, LoadDependentFrictionTerm, FrictionDriftTerm,
             TorqueRippleTerm, RotorInertiaTerm, CouplingTerm, PayloadTerm, GravityTiltTerm, DelayTerm,
             BacklashTerm, JointElasticityTerm)
TERMS_BY_KEY = {cls.key: cls for cls in ALL_TERMS}


def default_library() -> CandidateLibrary:
    """Every candidate term, simplest first (ties in the selection go to the earlier term)."""
    return CandidateLibrary(tuple(cls() for cls in ALL_TERMS))


# Effects that the data cannot tell apart under the nominal model (documented in the report):
# with a symmetric Coulomb term in the nominal friction, an asymmetric Coulomb level is a constant
# offset during motion.
EQUIVALENT_EFFECTS = {"coulomb_asymmetry": ("torque_offset",), "torque_offset": ("coulomb_asymmetry",)}
