"""The candidate-term interface and its composition: ``CandidateTerm``, ``CandidateLibrary`` and the shared bounds.

Every family module (``torque``, ``friction``, ``inertial``, ``delay``, ``deflection``) subclasses
``CandidateTerm``; ``+`` composes terms into a ``CandidateLibrary`` like the candidate functions of
pysindy. Fitted parameters are checked against the physical bounds ``MAX_*`` (``identification.physical_bounds``)
(``CandidateTerm.implausibility``, one rule per family, the one place that says what is physically meaningless:
a negative stiffness, an offset or a torque larger than the joint's torque scale ``torque_bound``, a load-dependent
friction taking a large share of the load, a negative inertia, a friction "warm-up" faster than heat spreads, ...).
Sign convention: columns describe torque the motors must supply in addition to the nominal model,
``tau_measured = tau_nominal + columns @ coefficients``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, is_dataclass, replace

import casadi as ca
import numpy as np

from identification.physical_bounds import MAX_TORQUE_SHARE
from psdm_casadi.errors import ParameterError

SMOOTH_VELOCITY = 0.02  # [rad/s] width of the smooth sign tanh(qd / v) of the friction-like terms


def joint_columns(context, joint: int, values) -> np.ndarray:
    """Columns (n_samples, n_dof, k) with ``values`` (n_samples, k) on joint ``joint`` and zero elsewhere."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    out = np.zeros((context.n_samples, context.n_dof, values.shape[1]))
    out[:, joint, :] = values
    return out


def joint_expression(n_dof: int, joint: int, value):
    """Torque (SX, n_dof) with ``value`` on joint ``joint`` and zero elsewhere (the CasADi form of
    ``joint_columns``)."""
    out = ca.SX.zeros(n_dof)
    out[joint] = value
    return out


def torque_bound(context, joint: int) -> float | None:
    """The joint's torque scale [N m] a candidate's torque is judged against (``CandidateTerm.implausibility``): the
    larger of the nominal model's gravity torque amplitude over the recorded range (``DiagnosisContext.gravity``)
    and the peak measured torque (the scale of a joint gravity does not load, such as a vertical first axis, and of a
    spring that is larger than the gravity it balances); None without a context (a term rebuilt from a model file is
    judged by its sign rules only)."""
    if context is None:
        return None
    measured = float(np.max(np.abs(np.asarray(context.tau)[:, joint])))
    gravity = getattr(context, "gravity", None)
    amplitude = 0.0 if gravity is None else float(np.max(np.abs(np.asarray(gravity)[:, joint])))
    return max(amplitude, measured)


def held_offset(context, joint: int) -> float:
    """The torque offset [N m] the nominal model holds on ``joint`` (a model file's, ``DiagnosisContext.held_offsets``)
    beside which a fitted offset is the part the data add; 0 without one or without a context."""
    offsets = getattr(context, "held_offsets", ()) or ()
    return float(offsets[joint]) if joint < len(offsets) else 0.0


def oversized(name: str, torque: float, context, joint: int) -> str | None:
    """Why a term whose torque reaches ``torque`` [N m] on ``joint`` is not physical: it exceeds ``MAX_TORQUE_SHARE``
    times the joint's ``torque_bound`` (an effect larger than all the joint's gravity and measured torque is the fit
    fighting the nominal model, not missing physics); None when it does not, or without a context."""
    bound = torque_bound(context, joint)
    if bound is None or abs(float(torque)) <= MAX_TORQUE_SHARE * bound:
        return None
    return (
        f"{name} {float(torque):.4g} N m is larger than joint {joint + 1}'s gravity torque amplitude and peak measured "
        f"torque ({bound:.4g} N m)"
    )


def _jsonable(value):
    """``value`` as JSON types: numpy scalars as numbers, tuples as lists, dataclasses as dicts of their fields."""
    if is_dataclass(value):
        return {f.name: _jsonable(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, (tuple, list)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    return value


class CandidateTerm:
    """Base class of candidate physics terms.

    A term built without a joint stands for one instance per joint (``expand``); every concrete
    instance provides ``feature_names()`` and ``columns(context)``, an array (n_samples, n_dof,
    n_features) that enters the least-squares fit linearly (nonlinear effects such as a delay, backlash
    and joint elasticity enter through their first-order expansion around the nominal model),
    ``physical_parameters(coefficients)`` turning fitted coefficients into named physical parameters,
    and where possible ``casadi_expression`` for the augmented model.

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
                raise ParameterError(
                    f"{type(self).__name__}.joint must be a joint index 0..{n_dof - 1}; got {self.joint!r}."
                )
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

    @property
    def shape_name(self) -> str:
        """The label with what tells this shape variant from the others of ``shape_variants`` when they share it
        (a lag's column linearised at the nominal size or at the fitted one); the label where it is unique."""
        return self.label

    def _require_joint(self):
        if self.joint is None:
            raise ParameterError(f"{type(self).__name__}.joint is None; call expand(n_dof) to get one term per joint.")

    # --- serialisation --------------------------------------------------------------------------
    def spec(self) -> dict:
        """A small JSON-ready description of the instance: ``{"key": ..., field: value, ...}`` with every dataclass
        field (joint indices 0-based, tuples as lists, nested dataclasses as dicts); ``term_spec.term_from_spec``
        rebuilds the same term from it, so a model file stores a term by its definition, not by a label."""
        return {"key": self.key, **{f.name: _jsonable(getattr(self, f.name)) for f in fields(self)}}

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

    #: parameters of a shape variant fitted beyond its linear coefficients (a gas spring's geometry), counted in the
    #: BIC the selection compares shapes by
    n_shape_parameters = 0

    def shape_variants(self, context, score=None) -> tuple:
        """Alternative shapes of the term to choose from by an information criterion (the selection screens the
        one with the lowest BIC on the training ``context``), simplest first; ``(self,)`` by default.
        ``score(joint, values)``, when given, is the weighted training SSE of the current model with columns
        ``values`` (on the training rows ``score.rows``, k) added on a joint, for shapes whose nonlinear parameters
        are fitted by it (``n_shape_parameters``); ``score.fixed(values)`` the SSE with a torque (rows, n_dof) added
        as it is, the exact profile of a robot-wide signal term (the delay)."""
        return (self,)

    def theta_change(self, coefficients, parameter_map) -> np.ndarray | None:
        """Change of the PSDM base parameters (n_base,) the term amounts to, or None."""
        return None

    def implausibility(self, coefficients, context=None) -> str | None:
        """Why the fitted coefficients are not physical (the selection then skips the term), or None.

        The default accepts any value; terms with a sign or a range (inertia, friction coefficient,
        delay, compliance, backlash) override it.
        """
        return None

    def name_unsupported(self, context) -> str | None:
        """Why the training ``context``'s motion cannot show what the term's name claims, or None (the default).

        A term that fits the torque but whose name the recording cannot back (a ripple, periodic in the angle, over
        less than one of its periods) is named by the selection only when no candidate without such a reason fits
        its joint about as well (``selection``)."""
        return None

    def interpret(self, coefficients) -> tuple:
        """``(effect, explanation)`` reported for the fitted coefficients (the payload term reports a negative
        mass as a last link too heavy in the robot file)."""
        return self.key, self.explanation


@dataclass(frozen=True)
class CandidateLibrary:
    """An ordered set of candidate terms; ``+`` appends terms or libraries."""

    terms: tuple = field(default_factory=tuple)

    def __post_init__(self):
        for term in self.terms:
            if not isinstance(term, CandidateTerm):
                raise ParameterError(
                    f"CandidateLibrary.terms must hold CandidateTerm objects; got {type(term).__name__}."
                )

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
