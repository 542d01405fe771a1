"""ExtraTerms: known additive torques (a diagnosis finding: spring, offset, ripple) fitted in the four steps.

An effect the nominal model leaves out (a cable-harness spring, a balancer) corrupts every step of
the calibration it touches: the gravity step folds its torque into the gravity parameters, the
friction step into LuGre, the inertial step into the inertias. Once ``diagnose`` has named it, the
effect is a *known term*: a candidate term of :mod:`identification.diagnosis.candidates` whose
torque is linear in its coefficients, ``tau_extra = columns(q, qd, qdd, t) @ c``. The pipeline then
gives each linear step the terms' columns beside its own (``GravityIdentifier`` and
``InertialIdentifier``), removes the fitted torque where a step cannot fit it (the friction
experiments, the refinement) and adds it to every prediction (Table 3, ``IdentifiedModel``).

Only terms that are a torque of the joint state qualify (``casadi_expression`` not None and no
change of the base parameters): spring (linear or polynomial), torque offset, torque ripple, an unnamed
(sparse) effect. A saved model stores each term by its spec (``CandidateTerm.spec``) and rebuilds it from it. Signal
corrections (delay, backlash, elasticity) and inertial findings (payload, rotor inertia) are not
extra torques; the four-step route refuses them with the reason.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError

__all__ = ["TermContext", "ExtraTerms", "extra_torque", "holds_extra", "with_extra_columns", "unfitted", "fitted_extra"]

logger = logging.getLogger(__name__)

_PROBE_DOF = 12  # joints of the symbols and samples a term is probed with (``_unsupported``)


@dataclass(frozen=True, eq=False)
class TermContext:
    """The signals a state-dependent candidate term reads its columns from (one preprocessed recording).

    Parameters
    ----------
    t : array, shape (n_samples,)
    q, qd, qdd : arrays, shape (n_samples, n_dof)
        [rad, rad/s, rad/s^2]; qd and qdd may be None for position-only terms.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None = None
    qdd: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        return int(self.q.shape[0])

    @property
    def n_dof(self) -> int:
        return int(self.q.shape[1])

    @classmethod
    def of(cls, rec, every: int = 1) -> TermContext:
        """The context of a :class:`~identification.data.recording.Recording`, every ``every``-th sample."""
        sl = slice(None, None, int(every))

        def pick(a):
            return None if a is None else np.asarray(a)[sl]

        return cls(np.asarray(rec.t)[sl], np.asarray(rec.q)[sl], pick(rec.qd), pick(rec.qdd))


@dataclass(frozen=True, eq=False)
class ExtraTerms:
    """Known additive torque terms and, once fitted, their coefficients and standard errors.

    Parameters
    ----------
    terms : tuple of CandidateTerm
        Concrete instances (joint set), e.g. ``(SpringTerm(joint=3),)`` or ``report.augmented.terms``.
    coefficients : array, shape (n_features,), optional
        Concatenated coefficients of the terms in ``terms`` order (None before a fit).
    std : array, shape (n_features,), optional
        Their standard errors.

    Raises
    ------
    ParameterError
        A term that is not a torque of the joint state, or coefficients of the wrong length.

    Examples
    --------
    >>> from identification.diagnosis.candidates import SpringTerm
    >>> extra = ExtraTerms((SpringTerm(joint=3),))
    >>> extra.feature_names
    ('k_q4', 'c_4')
    """

    terms: tuple
    coefficients: np.ndarray | None = None
    std: np.ndarray | None = None

    def __post_init__(self):
        terms = tuple(self.terms)
        if not terms:
            raise ParameterError("ExtraTerms.terms must hold at least one term; got none. Pass None for no terms.")
        for term in terms:
            _check_term(term)
        object.__setattr__(self, "terms", terms)
        n = sum(len(term.feature_names()) for term in terms)
        for name in ("coefficients", "std"):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.array(value, dtype=float).reshape(-1)
            if value.shape != (n,):
                raise ShapeError(f"ExtraTerms.{name} must have {n} entries (one per feature); got {value.shape}.")
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def n_features(self) -> int:
        return len(self.feature_names)

    @property
    def feature_names(self) -> tuple:
        return tuple(name for term in self.terms for name in term.feature_names())

    @property
    def labels(self) -> tuple:
        return tuple(term.label for term in self.terms)

    @property
    def fitted(self) -> bool:
        return self.coefficients is not None

    def columns(self, rec, every: int = 1) -> np.ndarray:
        """The terms' columns on a recording, shape (n_samples, n_dof, n_features) [N m per coefficient]."""
        context = rec if isinstance(rec, TermContext) else TermContext.of(rec, every)
        return np.concatenate([np.asarray(term.columns(context), dtype=float) for term in self.terms], axis=2)

    def torque(self, rec, every: int = 1) -> np.ndarray:
        """The fitted terms' torque on a recording [N m], shape (n_samples, n_dof).

        Raises
        ------
        ParameterError
            When the terms are not fitted yet.
        """
        if not self.fitted:
            raise ParameterError(
                f"ExtraTerms {list(self.labels)} have no coefficients; fit them first (a calibration step "
                "or ExtraTerms.with_fit)."
            )
        return self.columns(rec, every) @ self.coefficients

    def with_fit(self, coefficients, std=None) -> ExtraTerms:
        """The same terms with fitted ``coefficients`` (and standard errors ``std``)."""
        return ExtraTerms(self.terms, coefficients, std)

    def split(self) -> list:
        """Per term: ``(term, coefficients, std)`` slices of the concatenated vectors (None before a fit)."""
        out, start = [], 0
        for term in self.terms:
            stop = start + len(term.feature_names())
            coef = None if self.coefficients is None else self.coefficients[start:stop]
            std = None if self.std is None else self.std[start:stop]
            out.append((term, coef, std))
            start = stop
        return out

    def casadi_torque(self, q, qd, qdd, t, tau_nominal):
        """The fitted terms' torque as a CasADi expression (n_dof) of the symbols ``q, qd, qdd, t``."""
        total = 0
        for term, coef, _ in self.split():
            if coef is None:
                raise ParameterError(f"ExtraTerms {term.label} has no coefficients; fit it first.")
            total = total + term.casadi_expression(q, qd, qdd, t, tau_nominal, [float(c) for c in coef])
        return total

    def to_dict(self) -> list:
        """Per term: label, effect, joints (1-based), feature names, the term's spec (``CandidateTerm.spec``, from which
        ``term_spec.term_from_spec`` rebuilds it), coefficients, sigma and physical parameters."""
        out = []
        for term, coef, std in self.split():
            entry = {
                "label": term.label,
                "effect": term.key,
                "joints": [j + 1 for j in term.joints],
                "feature_names": list(term.feature_names()),
                "spec": term.spec(),
            }
            if coef is not None:
                entry["coefficients"] = [float(c) for c in coef]
                entry["physical"] = {k: float(v) for k, v in term.physical_parameters(coef).items()}
            if std is not None:
                entry["std"] = [float(s) for s in std]
            out.append(entry)
        return out

    @classmethod
    def from_diagnosis(cls, report) -> ExtraTerms:
        """The torque-type findings of a :class:`~identification.diagnosis.report.DiagnosisReport`, as fitted terms.

        The coefficients the diagnosis fitted are kept as start values; the calibration refits them.
        Findings that are no torque of the joint state (a delay, a payload) are left out and logged.

        Raises
        ------
        ParameterError
            When the report holds no torque-type finding (nothing to recalibrate with).
        """
        augmented = report.augmented
        terms, coefs = [], []
        for term, coef in zip(getattr(augmented, "terms", ()), getattr(augmented, "coefficients", ())):
            reason = _unsupported(term)
            if reason is None:
                terms.append(term)
                coefs.extend(float(c) for c in coef)
            else:
                logger.info("recalibration: finding %s is not an extra torque (%s); left out", term.label, reason)
        if not terms:
            raise ParameterError(
                "ExtraTerms.from_diagnosis: the diagnosis found no torque-type term (spring, offset, ripple) to "
                f"recalibrate with; its findings are {list(report.effects)}."
            )
        return cls(tuple(terms), np.array(coefs))


def extra_torque(extra, rec, every: int = 1) -> np.ndarray:
    """``extra.torque(rec)`` or zeros when ``extra`` is None [N m], shape (n_samples, n_dof)."""
    if extra is None:
        return np.zeros_like(np.asarray(rec.q)[:: int(every)], dtype=float)
    return extra.torque(rec, every)


def holds_extra(extra) -> bool:
    """Whether the gravity step holds ``extra`` (fitted: its torque is removed) instead of fitting its columns."""
    return extra is not None and extra.fitted


def with_extra_columns(y, extra, rec, every: int = 1) -> np.ndarray:
    """``y`` (n_samples, n_dof, k) with the extra terms' columns on ``rec`` appended along the last axis."""
    if extra is None:
        return y
    return np.concatenate([y, extra.columns(rec, every)], axis=2)


def unfitted(extra):
    """``extra`` without its coefficients (the inertial step always fits them)."""
    return None if extra is None else ExtraTerms(extra.terms)


def fitted_extra(extra, coef, covariance, start: int):
    """``extra`` with the coefficients ``coef[start:]`` and their standard errors; None without extra terms."""
    if extra is None:
        return None
    std = np.sqrt(np.clip(np.diag(covariance)[start:], 0.0, None))
    return extra.with_fit(coef[start:], std)


def _unsupported(term) -> str | None:
    """Why ``term`` cannot be an extra torque of the four-step calibration, or None."""
    for name in ("feature_names", "columns", "casadi_expression", "theta_change", "label", "key"):
        if not hasattr(term, name):
            return f"it is not a candidate term (no {name})"
    if getattr(term, "joint", 0) is None and getattr(term, "per_joint", False):
        return "its joint is not set (use term.expand(n_dof) or pass joint=...)"
    n = len(term.feature_names())
    try:
        change = term.theta_change(np.ones(n), np.zeros((1, 11 * _PROBE_DOF)))
    except (AttributeError, IndexError, TypeError, ValueError):
        change = "unknown"
    if change is not None:
        return "it changes the base parameters (an inertial finding), which the inertial step identifies itself"
    q = ca.SX.sym("q", _PROBE_DOF)
    t = ca.SX.sym("t")
    try:
        expression = term.casadi_expression(q, q, q, t, q, [1.0] * n)
    except (IndexError, RuntimeError, TypeError):
        expression = None
    if expression is None:
        return "it is a signal correction (delay, backlash, elasticity), not a torque of the joint state"
    probe = TermContext(np.zeros(2), np.zeros((2, q.shape[0])), np.zeros((2, q.shape[0])), np.zeros((2, q.shape[0])))
    try:
        term.columns(probe)
    except AttributeError as exc:
        return f"its columns need more than the joint state ({exc})"
    return None


def _check_term(term) -> None:
    reason = _unsupported(term)
    if reason is not None:
        raise ParameterError(
            f"ExtraTerms.terms: {getattr(term, 'label', type(term).__name__)} cannot be fitted by the four-step "
            f"calibration: {reason}. Pass torque terms of the joint state (spring, torque_offset, torque_ripple)."
        )
