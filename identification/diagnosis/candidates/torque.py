"""Candidate torques of position or of nothing at all: a spring (linear, a low-order polynomial, or a counterbalance's
odd law about its neutral angle), a torque offset, a position-periodic ripple.

Each acts on one joint and is an additive torque of (q, t) in the augmented model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from scipy.optimize import brentq

from identification.diagnosis.candidates.base import (
    CandidateTerm,
    held_offset,
    joint_columns,
    joint_expression,
    oversized,
)
from identification.diagnosis.candidates.gas_spring import GasSpringTerm, fit_geometry
from identification.diagnosis.candidates.neutral_angle import fit_neutral_angle
from psdm_casadi.errors import ParameterError

MAX_ORDER = 5  # highest polynomial order of a spring's shape
MIN_PERIODS = 1.0  # periods of a ripple the joint's recorded travel must cover for the data to show it is periodic
NEARLY_LINEAR = 2.0  # a polynomial whose stiffness stays within this factor over the range is a linear spring
LEVER_LAW_MIN_DROP = 0.01  # lever law offered where the highest-order polynomial lowers the training SSE this much
#: lowest order of the odd law offered: an odd cubic about a fitted angle plus the constant is every cubic (about its
#: inflection point), the polynomial of order 3 already offered; the odd quintic (5 parameters) is a law of its own
ODD_MIN_ORDER = 5


@dataclass(frozen=True)
class SpringTerm(CandidateTerm):
    """``spring``: elastic torque of the joint angle on one joint (gravity compensator, counterbalance, cable, hose).

    Order 1 is the linear spring ``k (q - q0)`` (columns ``q, 1``); order n > 1 a polynomial
    ``sum_i k_i (q - centre)^i + c`` about the middle of the training range, the shape of a nonlinear
    counterbalance or a cam; with ``odd`` only its odd powers (``x, x^3, x^5``) about the neutral angle ``centre``
    (``neutral_angle``: a gas spring's, a linkage's or a gravity cam's law, odd about the angle where spring and
    lever align). ``shape_variants`` offers orders 1 to ``max_order`` to the selection, and with the selection's
    ``score`` the odd laws of order 5 to ``max_order`` at their fitted neutral angles and, with ``lever_law``, a
    gas-spring lever law (``GasSpringTerm``, its geometry fitted by variable projection); the selection keeps the
    shape with the lowest BIC on the training data (a fitted angle counted) if it carries over to validation.

    Parameters
    ----------
    joint : int or None
    order : int
        Polynomial order (1 to ``MAX_ORDER``; odd and at least 3 with ``odd``).
    max_order : int
        Highest order ``shape_variants`` offers (1 keeps the linear spring only).
    centre : float
        Angle the polynomial is expanded about [rad] (order > 1): the neutral angle with ``odd``.
    q_range : tuple (q_min, q_max) or None
        The training recording's range of the joint [rad]: the stiffness is reported over it.
    lever_law : bool
        Whether ``shape_variants`` also offers the gas-spring lever law (given the residual).
    odd : bool
        Only the odd powers about ``centre``: a counterbalance's law about its neutral angle (files without it read
        as False).
    constant : bool
        Whether the term has a constant column of its own (files without it read as True). False beside a free torque
        offset column the nominal model carries on the joint (``carried_terms.CarriedColumns.shaped``): the two would
        be one column, and the rest angle could not be told from the offset; the report gives the term the combined
        constant back (``CarriedColumns.with_constants``).
    """

    joint: int | None = None
    order: int = 1
    max_order: int = MAX_ORDER
    centre: float = 0.0
    q_range: tuple | None = None
    lever_law: bool = True
    odd: bool = False
    constant: bool = True
    key = "spring"
    explanation = "a position-dependent elastic torque k (q - q0) on the joint (spring balancer, cables)"
    signature = "residual follows joint position, not velocity"

    def __post_init__(self):
        for name in ("order", "max_order"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, np.integer)) and 1 <= value <= MAX_ORDER):
                raise ParameterError(f"SpringTerm.{name} must be an integer 1..{MAX_ORDER}; got {value!r}.")
        if self.odd and (self.order < 3 or self.order % 2 == 0):
            raise ParameterError(f"SpringTerm.order of an odd law must be 3 or 5 (odd, the linear spring is order 1 "
                                 f"without odd); got {self.order!r}.")  # fmt: skip

    @property
    def label(self):
        base = CandidateTerm.label.fget(self)
        if self.order == 1 or self.joint is None:
            return base
        return f"{base[:-1]},order={self.order}{',odd' if self.odd else ''}]"

    @property
    def n_shape_parameters(self) -> int:
        """The neutral angle of an odd law, fitted on the residual (``neutral_angle``): counted in the BIC."""
        return int(self.odd)

    @property
    def exponents(self) -> tuple:
        """The powers of ``q - centre`` the columns hold (before the constant)."""
        return tuple(range(1, self.order + 1, 2 if self.odd else 1))

    def shape_variants(self, context, score=None):
        self._require_joint()
        q = context.q[:, self.joint]
        lo, hi = float(np.min(q)), float(np.max(q))
        linear = replace(self, order=1, centre=0.0, q_range=(lo, hi))
        top = min(self.max_order, MAX_ORDER)
        variants = (linear,) + tuple(
            replace(self, order=o, centre=0.5 * (lo + hi), q_range=(lo, hi), odd=False) for o in range(2, top + 1)
        )
        if score is None or hi - lo <= 0.0:
            return variants
        # the searches cost a grid of fits: only where a position-dependent torque is there to shape
        q = q[score.rows]
        highest = np.column_stack(variants[-1]._powers(q) + [np.ones_like(q)])
        if score(self.joint, highest) > (1.0 - LEVER_LAW_MIN_DROP) * score.sse:
            return variants
        variants += self.odd_laws(q, lambda values: score(self.joint, values), (lo, hi))
        if not self.lever_law:
            return variants
        ratio, q0 = fit_geometry(q, lambda values: score(self.joint, values))
        return variants + (GasSpringTerm(joint=self.joint, ratio=ratio, q0=q0, q_range=(lo, hi)),)

    def odd_laws(self, q, sse, q_range) -> tuple:
        """The odd laws of order ``ODD_MIN_ORDER`` to ``max_order`` (``odd``), each at the neutral angle that minimises
        ``sse(columns)`` on the joint angles ``q`` (``neutral_angle.fit_neutral_angle``); ``q_range`` the recorded
        range."""
        top = min(self.max_order, MAX_ORDER)
        laws = []
        for order in range(ODD_MIN_ORDER, top + 1, 2):
            q0, _ = fit_neutral_angle(q, sse, order)
            laws.append(replace(self, order=order, centre=q0, q_range=tuple(q_range), odd=True))
        return tuple(laws)

    def feature_names(self):
        self._require_joint()
        j = self.joint + 1
        constant = [f"c_{j}"] if self.constant else []
        if self.order == 1:
            return [f"k_q{j}", *constant]
        return [f"k{i}_q{j}" for i in self.exponents] + constant

    def _constant_of(self, coefficients) -> float:
        """The constant [N m] among ``coefficients`` (after the powers' ones); 0 for a term without one."""
        c = np.asarray(coefficients, dtype=float)
        return float(c[len(self.exponents)]) if self.constant else 0.0

    def _powers(self, q):
        if self.order == 1:
            return [q]
        x = q - self.centre
        return [x**i for i in self.exponents]

    def columns(self, context):
        self._require_joint()
        q = context.q[:, self.joint]
        ones = [np.ones(context.n_samples)] if self.constant else []
        return joint_columns(context, self.joint, np.column_stack(self._powers(q) + ones))

    def torque_of_angle(self, q, coefficients) -> np.ndarray:
        """The term's torque [N m] at joint angles ``q`` (array, rad) with fitted ``coefficients``."""
        q = np.asarray(q, dtype=float)
        c = np.asarray(coefficients, dtype=float)
        return sum(a * p for a, p in zip(c, self._powers(q))) + self._constant_of(c)

    def stiffness_range(self, coefficients) -> tuple:
        """Least and largest local stiffness d(torque)/dq [N m/rad] over the training range (``q_range``; the
        coefficient itself for the linear spring)."""
        c = np.asarray(coefficients, dtype=float)
        if self.order == 1 or self.q_range is None:
            return float(c[0]), float(c[0])
        x = np.linspace(self.q_range[0], self.q_range[1], 101) - self.centre
        slope = sum(i * a * x ** (i - 1) for i, a in zip(self.exponents, c))
        return float(np.min(slope)), float(np.max(slope))

    def _secant(self, coefficients) -> float:
        """Mean stiffness over the training range [N m/rad] (the slope of the linear spring)."""
        if self.order == 1 or self.q_range is None:
            return float(coefficients[0])
        lo, hi = self.q_range
        ends = self.torque_of_angle(np.array([lo, hi]), coefficients)
        return float((ends[1] - ends[0]) / max(hi - lo, 1e-12))

    def rest_angle(self, coefficients, offset: float = 0.0) -> float | None:
        """The angle [rad] where the term's torque plus ``offset`` is zero: the spring's rest angle, the one a datasheet
        gives. ``centre`` is where a polynomial is expanded (an odd law's symmetry), not where its torque vanishes; the
        constant (the last coefficient, when the term has one) is in the torque, and ``offset`` is a torque offset
        fitted beside it on the joint that holds it instead (the two are one column: a model file's ``offsetN`` where
        ``c_N`` is absorbed). The root
        nearest the middle of the recorded range, searched over the range widened by its width on each side; None
        without one there."""
        c = np.asarray(coefficients, dtype=float)
        if self.order == 1:
            return float(-(self._constant_of(c) + offset) / c[0]) if c[0] != 0 else None
        if self.q_range is None:
            return None
        lo, hi = (float(x) for x in self.q_range)
        grid = np.linspace(2 * lo - hi, 2 * hi - lo, 601)
        value = self.torque_of_angle(grid, c) + offset

        def torque(q):
            return float(self.torque_of_angle(q, c) + offset)

        ends = [(grid[i], grid[i + 1]) for i in np.flatnonzero(value[:-1] * value[1:] <= 0)]
        roots = [a if torque(a) == 0 else b if torque(b) == 0 else brentq(torque, a, b) for a, b in ends]
        return float(min(roots, key=lambda r: abs(r - 0.5 * (lo + hi)))) if roots else None

    def physical_parameters(self, coefficients):
        if self.order == 1:
            k, c = float(coefficients[0]), self._constant_of(coefficients)
            return {"k": k, "q0": (-c / k) if k != 0 else 0.0}
        low, high = self.stiffness_range(coefficients)
        out = {"k": self._secant(coefficients), "order": float(self.order), "centre": float(self.centre)}
        rest = self.rest_angle(coefficients)
        out.update({} if rest is None else {"rest_angle": rest})  # zero torque, the constant included
        if self.odd:
            out["neutral_angle"] = float(self.centre)
        out.update({"stiffness_min": low, "stiffness_max": high})
        out.update({f"k{i}": float(a) for i, a in zip(self.exponents, coefficients)})
        out["offset"] = self._constant_of(coefficients)
        return out

    def implausibility(self, coefficients, context=None):
        """Not a spring: a negative stiffness (the linear spring's slope, or a polynomial whose stiffness is negative
        and nearly constant, within ``NEARLY_LINEAR``, over the whole recorded range: the torque pushes the joint away
        from its rest angle instead of pulling it back, the sign of a gravity or mass error of the robot file; a
        counterbalance's strongly curved torque, such as a gas spring's near its strut's alignment, may fall over the
        range and stays a candidate), or a torque over the recorded range larger than the joint's torque scale
        (``oversized``)."""
        k = self._secant(coefficients)
        low, high = self.stiffness_range(coefficients)
        if (self.order == 1 and k < 0.0) or (high < 0.0 and low > NEARLY_LINEAR * high):
            return (
                f"negative stiffness k = {k:.3g} N m/rad: a spring pulls the joint back to its rest angle; this torque "
                "pushes it away (a position-dependent torque of another cause, such as a gravity or mass error of the "
                "robot file)"
            )
        if self.q_range is None or context is None:
            return None
        ends = self.torque_of_angle(np.linspace(self.q_range[0], self.q_range[1], 21), coefficients)
        return oversized("spring torque", float(ends[np.argmax(np.abs(ends))]), context, self.joint)

    def interpret(self, coefficients):
        """The effect reported; a negative stiffness is said aloud: it is not a spring (a spring pulls the joint back
        to its rest angle, a negative stiffness pushes it away)."""
        k = self._secant(coefficients)
        low, high = self.stiffness_range(coefficients)
        if k < 0.0:
            return self.key, (
                f"negative stiffness: not a spring (k = {k:.3g} N m/rad: the torque pushes the joint away from its "
                "rest angle instead of pulling it back); a position-dependent torque such as a gravity or mass "
                "error of the robot file, or a counterbalance acting the wrong way"
            )
        if self.order == 1:
            return self.key, self.explanation
        shape = (
            f"a polynomial of order {self.order} in the joint angle (nonlinear counterbalance, cam or gas spring), "
            f"stiffness {low:.3g} to {high:.3g} N m/rad over the recorded range"
        )
        if self.odd:
            shape = (
                f"a counterbalance's law, odd about its neutral angle q0 = {self.centre:.4g} rad (powers "
                f"{', '.join(str(i) for i in self.exponents)} of q - q0: a gas spring, a spring through a linkage or "
                f"a gravity cam), stiffness {low:.3g} to {high:.3g} N m/rad over the recorded range"
            )
        rest = self.rest_angle(coefficients)
        if rest is not None:
            constant = self._constant_of(coefficients)
            shape += f"; zero torque (its rest angle) at q = {rest:.4g} rad, constant {constant:.4g} N m in"
        if low < 0.0 < high:
            shape += "; the stiffness changes sign over the range, so it is not a single spring"
        return self.key, "a position-dependent elastic torque: " + shape

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        constant = coefficients[len(self.exponents)] if self.constant else 0.0
        if self.order == 1:
            return joint_expression(q.shape[0], self.joint, coefficients[0] * q[self.joint] + constant)
        x = q[self.joint] - self.centre
        value = constant + 0 * x
        for i, a in zip(self.exponents, coefficients):
            value = value + a * x**i
        return joint_expression(q.shape[0], self.joint, value)


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

    def implausibility(self, coefficients, context=None):
        """An offset larger than the joint's gravity torque amplitude over the recorded range (and its peak measured
        torque) is the fit fighting the nominal model, not a sensor bias (``oversized``). Beside an offset the nominal
        model holds (a model file's, ``held_offset``) the fit is the part the data add to it: the joint's whole offset,
        the two parts together, is what a sensor's bias is, and is judged (a file's offset far off is corrected by a
        large part, not fought)."""
        held, part = held_offset(context, self.joint), float(coefficients[0])
        reason = oversized("offset", held + part, context, self.joint)
        if reason is None or not held:
            return reason
        return f"{reason} (the joint's whole offset: the model file's part {held:+.4g} N m plus the fit's {part:+.4g})"

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

    def implausibility(self, coefficients, context=None):
        """A ripple larger than the joint's torque scale (``oversized``)."""
        return oversized("ripple amplitude", float(np.hypot(*np.asarray(coefficients, dtype=float)[:2])), context,
                         self.joint)  # fmt: skip

    def periods_covered(self, context) -> float:
        """How many of the ripple's periods (``2 pi / harmonic`` of the angle) the joint's travel in ``context``
        covers."""
        self._require_joint()
        q = context.q[:, self.joint]
        return float(np.max(q) - np.min(q)) * self.harmonic / (2.0 * np.pi)

    def name_unsupported(self, context):
        """A ripple is a periodic function of the angle: a recording whose travel on the joint covers less than
        ``MIN_PERIODS`` of its periods shows a smooth stretch of it, which a spring's polynomial or a lever law
        fits as well; the data then cannot tell the torque is periodic."""
        periods = self.periods_covered(context)
        if periods >= MIN_PERIODS:
            return None
        return (
            f"joint {self.joint + 1}'s recorded travel covers {periods:.2f} of the ripple's period "
            f"(2 pi / {self.harmonic} rad), too little to show a periodic torque"
        )

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        x = self.harmonic * q[self.joint]
        return joint_expression(q.shape[0], self.joint, coefficients[0] * ca.sin(x) + coefficients[1] * ca.cos(x))


def counterbalance_law(joint: int, q, torque, n_eff: float, max_order: int = MAX_ORDER, order: int | None = None):
    """The counterbalance's odd law (``SpringTerm`` with ``odd``) on ``joint`` that a torque supports, or None.

    ``torque`` [N m] is what the spring should explain at the joint angles ``q`` [rad] (a training residual with the
    spring's own torque given back). The laws of order 5 to ``max_order``, each at its fitted neutral angle
    (``SpringTerm.odd_laws``), compete with the linear spring and the cubic (the shapes identify tries anyway) by the
    Bayesian information criterion over ``n_eff`` independent samples, a fitted angle counted as a parameter: None
    where the linear spring or the cubic has the lowest. With ``order``, the law of that order at its fitted angle,
    without a choice (the same law refitted on other data: a block cross-validation's folds)."""
    q, y = np.asarray(q, dtype=float), np.asarray(torque, dtype=float)
    lo, hi = float(np.min(q)), float(np.max(q))
    if hi - lo <= 0.0:
        return None

    def sse(values):
        beta = np.linalg.lstsq(values, y, rcond=None)[0]
        return max(float(np.sum((y - values @ beta) ** 2)), 1e-300)

    def bic(term):
        columns = np.column_stack(term._powers(q) + [np.ones_like(q)])
        return n_eff * np.log(sse(columns)) + (columns.shape[1] + term.n_shape_parameters) * np.log(n_eff)

    base = SpringTerm(joint=joint, max_order=max_order if order is None else order, q_range=(lo, hi))
    if order is not None:
        return base.odd_laws(q, sse, (lo, hi))[-1]
    best, value = None, min(bic(base), bic(replace(base, order=3, centre=0.5 * (lo + hi))))
    for law in base.odd_laws(q, sse, (lo, hi)):
        if bic(law) < value:
            best, value = law, bic(law)
    return best
