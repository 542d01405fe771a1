"""The friction rival of a lag: a delay (or a joint elasticity, a backlash) is named only if it predicts every
validation recording better than the friction shapes the nominal model lacks.

A torque that lags the motion is what a delay of the torque signal does, and also what friction the nominal model
lacks does around every velocity reversal: a Stribeck peak, a viscous curve that is not linear, pre-sliding (the
friction builds up over a small displacement after each reversal, LuGre's bristles). A deflection of the transmission
(elasticity, backlash) shifts the velocity the friction sees by the torque's rate: a lag of the friction too. On the
virtual Denso (LuGre friction, no delay) a diagnosis with a Coulomb-viscous nominal model named a delay of 4-6.5 ms,
and without the delay a joint elasticity; the recording itself has no lag: with the simulator's own friction filtered
like the recording, the torque fits the motion best 0.25 ms *early* (the command held over each sample period, see
``virtual.simulation``); with its steady-state friction evaluated on the filtered velocity, 3 ms late.

``FrictionRival.judge`` lets such a candidate compete with a family of friction-shape columns on the same held-out
recordings. The family has three columns on each joint the candidate acts on (every joint for a delay), each with its
scale fitted on the training recording (the value of a log-spaced grid whose single column lowers the training error
most, with the nominal model and the kept terms):

- ``exp(-(qd/vs)^2) sign(qd)``: a Stribeck peak of velocity ``vs``;
- ``tanh(qd/v)``: a smooth Coulomb friction that reaches its level over the velocity scale ``v`` (and bends the
  viscous curve);
- ``u(t) - sign(qd)`` with ``du/dq = (1 - u sign(qd)) / x0``: pre-sliding (Dahl; the bristle state of a LuGre model
  with ``fs = fc``), the friction deficit over the displacement ``x0`` after each reversal.

Both are fitted on the training recording with the nominal model and the kept terms, and judged on every validation
recording. A delay acts on every joint with one coefficient: it is kept only if, added beside the family, it still
passes the selection's gates (``selection.passes_gates``) on each recording. A deflection of one joint (elasticity,
backlash) has one column against the family's three on that joint: it is kept only if it alone predicts each recording
better (joint-weighted validation error) than the family alone. (Judged beside the family, a true elasticity of the
benchmark's scenario failed the 20 % gate its joint's friction columns share with it.) A lag that loses is not named,
and the report's notes say so with the numbers (``sentences``), and the family's shapes (a Stribeck peak, a smooth
Coulomb friction, pre-sliding, each on each joint of the lag, its scale fitted again:
``candidates.friction.lacking_friction_shapes``) are offered to the selection as candidates where the nominal friction
lacks them (a model file's Coulomb-viscous or Stribeck friction; ``offer``), screened and judged as every candidate
(the gates on each validation recording, the second opinion, plausible coefficients): what explains the lag is then
named, and a model file takes it (``diagnose --apply``; pre-sliding, a state of the friction, is reported with its
route). A true delay also lags the inertial and gravity torque, and a true elasticity the rigid body's torque through
the deflection, which no friction shape follows: a 10 ms delay on the virtual Denso is still named first, and
``benchmarks/diagnosis.py``'s delay, backlash and elasticity scenarios still find theirs.

An elasticity that wins is still not named where a friction shape on its joint was the better candidate before it but
did not hold on the second opinion (``stand_in``): its fitted torque then follows the same reversals (on the unseen
UR5-like arm's LuGre wrist, pre-sliding lowered joint 5 by 56 % and failed the held-out blocks; the elasticity after
it, 0.02 deg of torsion at the joint's RMS torque, lowered it by 35 %). A true elasticity's torque sits at the
reversals too (the friction shift), so where it lives does not tell them apart; the benchmark's wrist elasticity
(scenario 12) has no such rival on a LuGre nominal model and is named.

An elasticity that wins against the family is still not named where it does not beat pre-sliding alone on its joint,
on every validation recording and by the never-worse margin on three of the four blocks of the training recording
held out in turn (``presliding_rival``, ``presliding_or_elasticity``): the pair is then reported ("pre-sliding or
elasticity on joint N") with both numbers and the recording that tells them apart, and neither is named from it.

No friction shape is fitted or compared on a joint that never reverses in training (``one_way``: the rule by which
identify holds such a joint's friction, ``excitation_check.one_way_joints``): a Stribeck peak and pre-sliding live at
reversals and a smooth Coulomb level is a constant there, so their columns are undetermined and their fit explodes on
validation (a lag then "wins" against a meaningless error). The family covers the lag's other joints; a deflection
of a one-way joint meets no rival (only ``stand_in``), and the report's notes say once per joint that its friction
shape is not compared.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.calibration.coulomb_width import widths_text
from identification.calibration.trajectory_checks import MIN_REVERSAL_FRACTION
from identification.data.excitation_check import one_way_velocities
from identification.diagnosis.candidates.friction import lacking_friction_shapes, recording_cache
from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.context import simulate_friction
from identification.diagnosis.presliding_or_elasticity import compare
from identification.diagnosis.selection import passes_gates
from identification.metrics import rmse

logger = logging.getLogger(__name__)

STRIBECK_VELOCITIES = np.geomspace(0.005, 0.5, 7)  # vs [rad/s] of the Stribeck column's grid
SMOOTH_VELOCITIES = np.geomspace(0.01, 1.0, 7)  # v [rad/s] of the smooth Coulomb column's grid
PRESLIDING_DISPLACEMENTS = np.geomspace(1e-4, 1e-2, 7)  # x0 [rad] of the pre-sliding column's grid
_SHAPE_COLUMNS = {}  # each recording's columns (``shape_column``, ``recording_cache``)
SHAPES = ("stribeck", "smooth_coulomb", "presliding")
LAGS = ("delay", "joint_elasticity", "backlash")  # the candidates whose torque a lag of the friction mimics
STAND_INS = ("presliding", "friction_shape")  # friction shapes an elasticity stands in for when they do not hold


def shape_column(ctx, joint: int, shape: str, scale: float) -> np.ndarray:
    """One friction-shape column of ``joint`` on the grid (n_samples,): evaluated at full rate on the recorded velocity
    and, like the nominal friction columns, filtered as the recording when ``ctx.filtered_friction``. Computed once
    per context (every lag the rival judges searches the same grids on the same recordings), read-only."""
    cache = recording_cache(ctx, _SHAPE_COLUMNS)
    key = (int(joint), shape, float(scale))
    if key not in cache:
        cache[key] = _shape_column(ctx, int(joint), shape, float(scale))
        cache[key].flags.writeable = False
    return cache[key]


def _shape_column(ctx, joint: int, shape: str, scale: float) -> np.ndarray:
    from identification.friction.models import LuGreParameters

    qd = np.asarray(ctx.full_qd[:, joint], dtype=float)
    sign = np.sign(qd)
    if shape == "stribeck":
        values = np.exp(-((qd / scale) ** 2)) * sign
    elif shape == "smooth_coulomb":
        values = np.tanh(qd / scale)
    else:  # a LuGre bristle with fc = fs = 1 and sigma0 = 1/x0 is the Dahl state u in [-1, 1]
        unit = LuGreParameters(fc=1.0, fs=1.0, vs=1.0, fv=0.0, dv=1.0, sigma0=1.0 / scale, sigma1=0.0)
        values = simulate_friction(unit, ctx.full_t, qd) - sign
    return ctx.lowpass(values) if ctx.filtered_friction else values[ctx.keep]


def family_columns(ctx, scales: np.ndarray, joints) -> np.ndarray:
    """The family's columns on ``joints`` (n_samples, n_dof, 3 len(joints)), joint-major, at ``scales`` (n_dof, 3)
    in ``SHAPES``'s order."""
    joints = list(joints)
    out = np.zeros((ctx.n_samples, ctx.n_dof, 3 * len(joints)))
    for i, j in enumerate(joints):
        for k, shape in enumerate(SHAPES):
            out[:, j, 3 * i + k] = shape_column(ctx, j, shape, float(scales[j, k]))
    return out


def fitted_scales(design, ctx, joints) -> np.ndarray:
    """Each joint's scale of each shape (n_dof, 3; NaN off ``joints``): the grid value whose column alone, added to
    ``design`` (the nominal model and the kept terms), gives the lowest training error on ``ctx`` (the training
    recording)."""
    grids = (STRIBECK_VELOCITIES, SMOOTH_VELOCITIES, PRESLIDING_DISPLACEMENTS)
    n = ctx.n_dof
    scales = np.full((n, 3), np.nan)
    blank = np.zeros((design.y_val.shape[0], n, 1))
    for j in joints:
        for k, (shape, grid) in enumerate(zip(SHAPES, grids)):
            errors = []
            for scale in grid:
                column = np.zeros((ctx.n_samples, n, 1))
                column[:, j, 0] = shape_column(ctx, j, shape, float(scale))
                errors.append(design.fit(column, blank)[1])
            scales[j, k] = grid[int(np.argmin(errors))]
    return scales


def validation_errors(design, columns_t, columns_v: list, validations: list) -> list:
    """Per-joint validation RMSE (n_dof,) on each validation recording of ``design`` with the candidate columns
    ``columns_t`` fitted on the training recording; ``columns_v[i]`` are the columns on ``validations[i] = (ctx, base,
    y)``."""
    p = design.G.shape[0]
    beta = design.fit(columns_t, np.zeros((design.y_val.shape[0],) + columns_t.shape[1:]))[0]
    return [rmse(y, base.predict(beta[:p]) + cv @ beta[p:]) for cv, (_, base, y) in zip(columns_v, validations)]


class FrictionRival:
    """The friction rival of a lag candidate (``LAGS``; module docstring).

    Parameters
    ----------
    train_ctx : DiagnosisContext
        The training recording.
    validations : sequence of (DiagnosisContext, BlockColumns, array)
        Each validation recording's context, nominal columns and fitted torque, the selection's first; ``keep`` adds
        the kept terms' columns as the selection adds them to its design.
    offer : bool
        Whether the shapes are offered where a lag loses: where the nominal friction lacks them (a model file's
        Coulomb-viscous or Stribeck friction); a robot file's LuGre drives state their bristles, so there the lag is
        only not named.

    Attributes
    ----------
    sentences : list of str
        One per candidate not named, with the numbers (``SelectionResult.dropped`` carries them to the report).
    offered : dict of label -> FrictionShapeTerm
        The friction shapes offered as candidates where a lag lost (``take_offers``).
    """

    def __init__(self, train_ctx, validations, offer: bool = True, held=None):
        self.train_ctx, self.offer, self.held = train_ctx, bool(offer), held
        self.validations = [list(v) for v in validations]
        self.sentences = []
        self.offered, self.new_offers = {}, []
        self._one_way, self._said_one_way = None, set()

    @property
    def one_way(self) -> tuple:
        """The joints (0-based) that never reverse in training (module docstring), found on first use."""
        if self._one_way is None:
            ctx = self.train_ctx
            self._one_way = tuple(one_way_velocities(ctx.qd, range(ctx.n_dof), speed=ctx.coulomb_velocity,
                                                     min_fraction=MIN_REVERSAL_FRACTION))  # fmt: skip
        return self._one_way

    def keep(self, term) -> None:
        """A kept term joins the validation recordings' base columns."""
        for v in self.validations:
            v[1] = v[1].concatenate(BlockColumns.from_dense(term.columns(v[0])))

    def judge(self, design, term, limits, unstable=()) -> str | None:
        """None when ``term`` is not a lag (``LAGS``) or wins against the friction family on every validation recording
        (module docstring: a delay beside the family passes the selection's gates, ``selection.passes_gates`` with
        ``limits``; a deflection of one joint predicts better than the family on that joint); otherwise the sentence
        saying why it is not named (also appended to ``sentences``)."""
        if getattr(term, "key", None) not in LAGS:
            return None
        joints = self._determined(term)
        if not joints:  # no friction shape the training data determine on the lag's joints: nothing to compare
            return self.stand_in(term, unstable)
        logger.info(f"diagnose: {term.label} against the friction shapes the nominal model lacks ...")
        scales = fitted_scales(design, self.train_ctx, joints)
        family = (family_columns(self.train_ctx, scales, joints),
                  [family_columns(ctx, scales, joints) for ctx, _, _ in self.validations])  # fmt: skip
        lag = (term.columns(self.train_ctx), [term.columns(ctx) for ctx, _, _ in self.validations])
        rival = validation_errors(design, *family, self.validations)
        if term.joints:  # the deflection alone against the family alone
            errors = validation_errors(design, *lag, self.validations)
            weighted = [(_weighted(f, limits.sigma), _weighted(e, limits.sigma)) for f, e in zip(rival, errors)]
            failures = [None if e < f else "predicts no better than the friction shapes alone" for f, e in weighted]
            compared = "with the friction shapes vs with it"
        else:  # the delay beside the family
            both = (
                np.concatenate([family[0], lag[0]], axis=2),
                [np.concatenate(p, axis=2) for p in zip(family[1], lag[1])],
            )
            errors = validation_errors(design, *both, self.validations)
            failures = [passes_gates(f, e, [], limits.floor, limits.min_improvement, limits.sigma)
                        for f, e in zip(rival, errors)]  # fmt: skip
            weighted = [(_weighted(f, limits.sigma), _weighted(e, limits.sigma)) for f, e in zip(rival, errors)]
            compared = "with the friction shapes, without/with it"
        numbers = "; ".join(f"recording {i + 1}: {a:.4g} -> {b:.4g}" for i, (a, b) in enumerate(weighted))
        if all(f is None for f in failures):
            logger.info(f"diagnose:   {term.label} wins against the friction shapes ({numbers})")
            return self.stand_in(term, unstable) or self.presliding_rival(design, term, scales)
        failure = next(f for f in failures if f is not None)
        sentence = (
            f"{term.label} not named: beside friction shapes the nominal model lacks (a Stribeck peak, a smooth "
            f"Coulomb friction, pre-sliding; scales fitted per joint) it {failure} on validation recording "
            f"{failures.index(failure) + 1} (joint-weighted validation error {compared}: {numbers}): a lag of the "
            f"friction, not {_what(term)}"
        )
        logger.info(f"diagnose: {sentence}")
        self.sentences.append(sentence)
        if self.offer:
            self._offer(joints)
        return sentence

    def _determined(self, term) -> list:
        """The joints of ``term`` (every joint for a delay) that reverse in training, on which the friction shapes are
        fitted and compared; the others (``one_way``, module docstring) are said once each (``sentences``)."""
        joints = list(term.joints) or list(range(self.train_ctx.n_dof))
        skipped = [j for j in joints if j in self.one_way and j not in self._said_one_way]
        if skipped:
            self._said_one_way.update(skipped)
            names = ", ".join(str(j + 1) for j in skipped)
            one, speed = len(skipped) == 1, widths_text(self.train_ctx.coulomb_velocity)
            sentence = (
                (f"joint {names} never reverses" if one else f"joints {names} never reverse")
                + " in training: "
                + ("its friction shape is" if one else "their friction shapes are")
                + f" not compared with a lag on {'it' if one else 'them'} ({term.label}: faster than {speed} each way "
                f"on less than {MIN_REVERSAL_FRACTION:.0%} of the samples, the shapes' fit is undetermined there)"
            )
            logger.info(f"diagnose: {sentence}")
            self.sentences.append(sentence)
        return [j for j in joints if j not in self.one_way]

    def stand_in(self, term, unstable) -> str | None:
        """The sentence saying why a joint elasticity is not named where a friction shape on its joint (pre-sliding, a
        Stribeck peak, a smooth Coulomb friction) was the better candidate before it but did not hold on the second
        opinion (``unstable``, ``second_opinion.UnstableFinding``), or None. The elasticity's fitted torque then
        follows the same reversals: its compliance shifts the friction's sign changes by ``c dtau/dt``, what a LuGre
        bristle does (the unseen UR5-like arm's joint 5: pre-sliding lowered it by 56 %, the elasticity by 35 %)."""
        if term.key != "joint_elasticity":
            return None
        shapes = [u.label for u in unstable if u.effect in STAND_INS and set(u.joints) & set(term.joints)]
        if not shapes:
            return None
        sentence = (
            f"{term.label} not named: {shapes[0]} explained joint {term.joints[0] + 1}'s validation torque better "
            f"but does not hold on the second opinion; the elasticity follows the same velocity reversals (its "
            f"compliance shifts the friction's sign changes): a friction that the data cannot pin down, not "
            f"{_what(term)}"
        )
        logger.info(f"diagnose: {sentence}")
        self.sentences.append(sentence)
        return sentence

    def presliding_rival(self, design, term, scales) -> str | None:
        """The sentence saying why a joint elasticity is not named where it does not beat pre-sliding alone on its
        joint by the noise margin on three of four held-out training blocks (``presliding_or_elasticity``: the pair is
        ambiguous, or pre-sliding explains the joint better), or None (named; not an elasticity)."""
        if term.key != "joint_elasticity":
            return None
        j = term.joints[0]
        pair = compare(design, term, PreslidingColumn(j, float(scales[j, 2])), self.train_ctx, self.validations)
        if pair.elasticity_wins:
            logger.info(
                f"diagnose:   {term.label} beats pre-sliding on joint {j + 1} on {pair.blocks_won} of "
                f"{len(pair.blocks)} training blocks"
            )
            return None
        sentence = pair.sentence()
        logger.info(f"diagnose: {sentence}")
        self.sentences.append(sentence)
        return sentence

    def _offer(self, joints) -> None:
        """Offer the family's shapes (``lacking_friction_shapes``: Stribeck, smooth Coulomb, pre-sliding) on ``joints``,
        each once; the selection fits their scales. A shape the nominal model holds on a joint (``held(term)``: a model
        file's, ``file_friction.FileFriction.holds``) is not offered there."""
        for term in (replace(shape, joint=j) for j in joints for shape in lacking_friction_shapes()):
            if self.held is not None and self.held(term):
                continue
            if term.label not in self.offered:
                self.offered[term.label] = term
                self.new_offers.append(term)

    def take_offers(self) -> list:
        """The friction shapes offered since the last call (the selection screens them as candidates)."""
        offers, self.new_offers = self.new_offers, []
        return offers


class PreslidingColumn:
    """Pre-sliding's column on ``joint`` (n_samples, n_dof, 1) at displacement ``x0`` on a context (``shape_column``;
    ``presliding_or_elasticity.compare`` takes it)."""

    def __init__(self, joint: int, x0: float):
        self.joint, self.x0 = int(joint), float(x0)

    def __call__(self, ctx) -> np.ndarray:
        out = np.zeros((ctx.n_samples, ctx.n_dof, 1))
        out[:, self.joint, 0] = shape_column(ctx, self.joint, "presliding", self.x0)
        return out


def _weighted(errors, sigma) -> float:
    """The joint-weighted validation error ``sum_j (rmse_j / sigma_j)^2`` of per-joint RMSE ``errors``."""
    return float(np.sum(np.asarray(errors) ** 2 / sigma**2))


def _what(term) -> str:
    return "of the torque signal" if term.key == "delay" else f"a deflection of joint {term.joints[0] + 1}"
