"""Friction-like candidate terms: Coulomb asymmetry, load-dependent friction, friction drifting with time, and the
friction shapes a Coulomb-viscous model lacks (offered by ``friction_rival``).

Their columns take the sign of the velocity from ``DiagnosisContext.friction_sign`` (with a LuGre
prior: the exact sign at full rate filtered like the recording, as the measured torque is); their
CasADi expressions use the smooth sign ``tanh(qd / SMOOTH_VELOCITY)``.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import (
    SMOOTH_VELOCITY,
    CandidateTerm,
    joint_columns,
    joint_expression,
    oversized,
)
from identification.physical_bounds import MAX_LOAD_FRICTION, MIN_DRIFT_TIME_CONSTANT_S, POSITIVE_FRICTION_SHAPES
from psdm_casadi.errors import ParameterError


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


FRICTION_SHAPES = ("stribeck", "smooth_coulomb")  # the shapes a ``FrictionShapeTerm`` takes
# the velocity scales [rad/s] a ``FrictionShapeTerm`` searches (log-spaced, about 21 % apart), per shape
# (and the displacements [rad] a ``PreslidingTerm`` searches: each one a simulation of the bristle state)
SCALE_GRIDS = {"stribeck": np.geomspace(0.005, 0.5, 25), "smooth_coulomb": np.geomspace(0.01, 1.0, 25),
               "presliding": np.geomspace(1e-4, 3e-2, 13)}  # fmt: skip

_GRID_COLUMNS = {}  # each recording's grid columns (``FrictionShapeTerm.grid_columns``, ``recording_cache``)


def recording_cache(context, store: dict) -> dict:
    """The dict in ``store`` of columns computed from ``context``'s motion (``full_qd``, ``full_t``, ``keep``, ``qd``,
    the cut-off and ``filtered_friction``): shared by every context of one recording (the diagnosis with the identified
    rigid body has a context of its own holding the same arrays), dropped with the recording's ``full_qd``. A context
    without these attributes (a test's namespace) gets a fresh dict: nothing is cached."""
    try:
        motion = (context.full_t, context.keep, context.qd)
        signature = tuple(id(part) for part in motion) + (context.cutoff_hz, bool(context.filtered_friction))
        full_qd = context.full_qd
    except AttributeError:
        return {}
    ident = id(full_qd)
    if ident not in store:
        store[ident] = {}
        weakref.finalize(full_qd, store.pop, ident, None)
    # the entry holds the motion's arrays, so their ids are not reused while it lives
    return store[ident].setdefault(signature, (motion, {}))[1]


@dataclass(frozen=True)
class FrictionShapeTerm(CandidateTerm):
    """``friction_shape``: friction of a shape a Coulomb-viscous model lacks, on one joint:

    - ``stribeck``: a Stribeck peak ``exp(-(qd/vs)^2) sign(qd)`` of velocity ``vs = scale`` (the static friction above
      the Coulomb level, coefficient ``fs - fc > 0``);
    - ``smooth_coulomb``: ``tanh(qd/v)``, a Coulomb friction that reaches its level over the velocity ``v = scale``
      (and bends the viscous curve; coefficient > 0: below zero the friction falls with speed, a Stribeck peak's
      shape, ``implausibility``).

    Built without a ``scale`` (a candidate), its one shape variant has the scale of least training error on
    ``SCALE_GRIDS[shape]``, refined by a parabola in log scale through the best three (``n_shape_parameters``: counted
    in the BIC). A candidate where the nominal friction is a model file's (Coulomb-viscous or Stribeck at fixed
    velocities: ``lacking_friction_shapes``), the Stribeck peak beside the robot file's LuGre friction too (a hump at
    another velocity than the drive's), and offered by ``friction_rival`` on the joints of a lag these shapes
    explain. On a diagnosis context the sign is
    ``friction_sign``'s; as a torque of the state (a model file's finding, the exported code) it is the smooth sign
    ``tanh(qd / velocity)``, the Stribeck column of ``trajectory_data.friction_term``.
    """

    joint: int | None = None
    shape: str = "stribeck"
    scale: float | None = None
    velocity: float = SMOOTH_VELOCITY
    key = "friction_shape"
    explanation = "friction that is not Coulomb-viscous"
    signature = "friction-like residual about the velocity reversals (which the lag of a delay or a deflection mimics)"
    n_shape_parameters = 1

    def __post_init__(self):
        if self.shape not in FRICTION_SHAPES:
            raise ParameterError(f"FrictionShapeTerm.shape must be one of {FRICTION_SHAPES}; got {self.shape!r}.")
        if not ((self.scale is None or self.scale > 0) and self.velocity > 0):
            raise ParameterError(f"FrictionShapeTerm scale and velocity must be > 0 [rad/s]; got {self.scale!r}, "
                                 f"{self.velocity!r}.")  # fmt: skip

    @property
    def label(self) -> str:
        return f"{self.key}[j{self.joint + 1},{self.shape}]" if self.joint is not None else self.key

    def feature_names(self):
        self._require_joint()
        return [f"{'fs_minus_fc' if self.shape == 'stribeck' else 'smooth_fc'}_{self.joint + 1}"]

    def shape_variants(self, context, score=None):
        """``(self,)`` with a scale; without, the one variant at the scale of least training error (``score``)."""
        if self.scale is not None or score is None:
            return (self if self.scale is not None else self._scaled(float(np.median(SCALE_GRIDS[self.shape]))),)
        grid = SCALE_GRIDS[self.shape]
        columns = self.grid_columns(context)[score.rows]
        sse = np.array([score(self.joint, columns[:, k]) for k in range(grid.size)])
        i = int(np.clip(np.argmin(sse), 1, grid.size - 2))
        x, y = np.log(grid[i - 1 : i + 2]), sse[i - 1 : i + 2]
        curvature = y[0] - 2 * y[1] + y[2]
        best = grid[int(np.argmin(sse))]
        if curvature > 0:  # the vertex of the parabola, within the neighbours
            best = float(np.exp(x[1] + np.clip(0.5 * (y[0] - y[2]) / curvature, -1, 1) * (x[2] - x[1])))
        return (self._scaled(best),)

    def grid_columns(self, context) -> np.ndarray:
        """The joint's column at each scale of ``SCALE_GRIDS[self.shape]`` (n_samples, grid size), computed once per
        context, joint and shape (the selection searches the scale again in every round, on the same training context;
        a pre-sliding column is a simulation of the bristle state), the values of ``columns``."""
        cache = recording_cache(context, _GRID_COLUMNS)
        key = (type(self).__name__, self.shape, self.joint)
        if key not in cache:
            grid = SCALE_GRIDS[self.shape]
            cache[key] = np.column_stack([self._scaled(s).columns(context)[:, self.joint, 0] for s in grid])
            cache[key].flags.writeable = False
        return cache[key]

    def _scaled(self, scale: float):
        return replace(self, scale=float(scale), velocity=min(SMOOTH_VELOCITY, 0.5 * float(scale)))

    def _values(self, qd, symbolic: bool):
        exp, tanh = (ca.exp, ca.tanh) if symbolic else (np.exp, np.tanh)
        if self.shape == "stribeck":
            return exp(-((qd / self.scale) ** 2)) * tanh(qd / self.velocity)
        return tanh(qd / self.scale)

    def columns(self, context):
        self._require_joint()
        if self.scale is None:  # a candidate judged without its shape fitted (confounding): the grid's middle
            return self._scaled(float(np.median(SCALE_GRIDS[self.shape]))).columns(context)
        j = self.joint
        if not hasattr(context, "full_qd"):  # a model file's recording (``extra_terms.TermContext``)
            return joint_columns(context, j, self._values(np.asarray(context.qd)[:, j], False))
        qd = np.asarray(context.full_qd[:, j], dtype=float)
        if self.shape == "stribeck":
            return joint_columns(context, j, context.friction_sign(j, np.exp(-((qd / self.scale) ** 2))))
        values = np.tanh(qd / self.scale)
        return joint_columns(context, j, context.lowpass(values) if context.filtered_friction else values[context.keep])

    def physical_parameters(self, coefficients):
        name = "stribeck_peak_Nm" if self.shape == "stribeck" else "smooth_coulomb_Nm"
        scale = "stribeck_velocity_rad_s" if self.shape == "stribeck" else "velocity_scale_rad_s"
        return {name: float(coefficients[0]), scale: float(self.scale)}

    def implausibility(self, coefficients, context=None):
        """Each shape's sign is its physics: a Stribeck "peak" below the Coulomb level (a dip: friction that rises
        with speed, a smooth onset's shape) or a smooth Coulomb friction below zero (friction that falls with speed
        past its scale, static above kinetic: a Stribeck peak's shape) is not the shape it is named; or a friction
        larger than the joint's torque scale (``oversized``). The shapes so bounded are
        ``physical_bounds.POSITIVE_FRICTION_SHAPES``, which the consistent fit (``FindingTerm.lower_bounds``) and the
        refit's judge (``finding_value.implausibility``) bound alike."""
        c = float(coefficients[0])
        if self.shape in POSITIVE_FRICTION_SHAPES and c <= 0.0:
            if self.shape == "stribeck":
                return f"Stribeck peak {c:.3g} N m <= 0: friction below the Coulomb level at low speed is not a peak"
            past = "its velocity scale" if self.scale is None else f"{self.scale:.3g} rad/s"
            return (f"smooth Coulomb friction {c:.3g} N m <= 0: friction that falls with speed past {past} is a "
                    "Stribeck peak's shape, not a Coulomb friction reached smoothly")  # fmt: skip
        return oversized("friction", c, context, self.joint)

    def interpret(self, coefficients):
        c, j = float(coefficients[0]), self.joint + 1
        if self.shape == "stribeck":
            what = f"a Stribeck peak of {c:.3g} N m above the Coulomb level, fading over {self.scale:.3g} rad/s"
        else:
            what = f"a smooth Coulomb friction of {c:+.3g} N m reached over {self.scale:.3g} rad/s"
        return self.key, f"friction on joint {j} is not Coulomb-viscous: {what}"

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return joint_expression(q.shape[0], self.joint, coefficients[0] * self._values(qd[self.joint], True))


@dataclass(frozen=True)
class PreslidingTerm(FrictionShapeTerm):
    """``presliding``: after each velocity reversal the friction builds up over a displacement ``x0 = scale`` [rad]
    instead of switching at once (Dahl's model, the bristle state of a LuGre friction with ``fs = fc``): the column is
    ``u(t) - sign(qd)`` with ``du/dq = (1 - u sign(qd)) / x0`` from the recorded velocity, its coefficient the
    Coulomb level that builds up (> 0). A lag of the friction that a delay or a joint elasticity mimics.

    A state of the friction, not a torque of ``(q, qd, qdd)``: a model file holds it only as LuGre friction (``psdm
    identify --friction lugre``), so the finding is reported with that route, not applied (``findings.finding_kind``
    ``reported``).
    """

    shape: str = "presliding"
    key = "presliding"
    explanation = "friction that builds up over a small displacement after each reversal (pre-sliding)"

    def __post_init__(self):
        if self.shape != "presliding" or not (self.scale is None or self.scale > 0):
            raise ParameterError(f"PreslidingTerm: shape 'presliding' and scale > 0 [rad]; got {self.shape!r}, "
                                 f"{self.scale!r}.")  # fmt: skip

    @property
    def label(self) -> str:
        return self.key if self.joint is None else f"{self.key}[j{self.joint + 1}]"

    def feature_names(self):
        self._require_joint()
        return [f"presliding_fc_{self.joint + 1}"]

    def columns(self, context):
        from identification.friction.models import LuGreParameters
        from identification.friction.simulation import simulate_lugre

        self._require_joint()
        if self.scale is None:
            return self._scaled(float(np.median(SCALE_GRIDS[self.shape]))).columns(context)
        qd = np.asarray(context.full_qd[:, self.joint], dtype=float)
        unit = LuGreParameters(fc=1.0, fs=1.0, vs=1.0, fv=0.0, dv=1.0, sigma0=1.0 / self.scale, sigma1=0.0)
        values = simulate_lugre(unit, context.full_t, qd, z0=0.0)[0] - np.sign(qd)  # context.simulate_friction
        return joint_columns(context, self.joint, context.lowpass(values) if context.filtered_friction else
                             values[context.keep])  # fmt: skip

    def physical_parameters(self, coefficients):
        return {"presliding_coulomb_Nm": float(coefficients[0]), "presliding_displacement_rad": float(self.scale)}

    def implausibility(self, coefficients, context=None):
        c = float(coefficients[0])
        if c <= 0.0:
            return f"pre-sliding level {c:.3g} N m <= 0: friction that overshoots after a reversal is not pre-sliding"
        return oversized("friction", c, context, self.joint)

    def interpret(self, coefficients):
        return self.key, (
            f"friction on joint {self.joint + 1} is not Coulomb-viscous: pre-sliding, a Coulomb friction of "
            f"{float(coefficients[0]):.3g} N m that builds up over {self.scale * 1e3:.3g} mrad after each reversal "
            "(LuGre's bristles); a state of the friction, which a model file holds only as LuGre friction of every "
            "joint ('psdm identify --friction lugre'): reported, not applied"
        )

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        return None


def lacking_friction_shapes(nominal: str = "coulomb_viscous") -> tuple:
    """The friction-shape candidates a nominal friction model (``nominal.FRICTION_MODELS``) lacks on every joint, each
    scale fitted. A Coulomb-viscous (or fixed-velocity Stribeck) model: a Stribeck peak and a smooth Coulomb friction
    (``FrictionShapeTerm``), pre-sliding (``PreslidingTerm``). The robot file's LuGre friction has its bristles (the
    pre-sliding) and one Stribeck peak at the drive's velocity: a Stribeck peak at another velocity (a grease or seal
    hump wider than the drive's curve)."""
    if nominal == "lugre":
        return (FrictionShapeTerm(shape="stribeck"),)
    return tuple(FrictionShapeTerm(shape=shape) for shape in FRICTION_SHAPES) + (PreslidingTerm(),)
