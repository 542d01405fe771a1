"""Model selection: greedy forward selection of candidate terms on top of the nominal model, judged on held-out data.

Every step fits the nominal friction, the terms kept so far and one more candidate jointly by
weighted least squares on the training recording (each joint's rows weighted by its torque RMS,
so joints count alike), predicts the validation recording, and keeps the candidate
that lowers the weighted validation error most, if it earns its parameters:

- the validation RMSE of at least one joint drops by ``min_improvement`` (default 20 %), and the torque the term
  explains there (``metrics.explained_rms``: ``sqrt(before^2 - after^2)``) is at least ``min_torque_fraction``
  (default 0.4 %) of that joint's torque RMS and ``ROBOT_FLOOR`` of the robot's largest joint torque RMS (floors in
  N m, so the small misfits of the nominal model that filtering and sampling leave, and noise-level changes on the
  weakest joints, do not count, while effects that are small against the torque of loaded joints, such as a
  slightly tilted base, still do). The floor is on the effect's size, not the RMSE drop, which noise shrinks: a
  virtual Denso wrist elasticity of 0.021 N m (0.6 %) dropped an RMSE of 0.025 N m by 0.011 N m (0.3 %);
- the fitted parameters are physically plausible (``CandidateTerm.implausibility``: a positive inertia,
  a friction coefficient below 0.5, a delay between 0 and 0.1 s, ...);
- the validation RMSE of every joint the term acts on and names drops, and for a per-joint term the 20 % drop
  above is on its own joint (a term on joint 3 that helps joint 2 through a shared parameter while joint 3 gets
  worse is not kept);
- the weighted validation error of all joints drops;
- the Bayesian information criterion on the training data drops, counted with the effective
  number of independent samples of a low-pass filtered signal (2 x cut-off x duration per joint).

A term with shape variants (``CandidateTerm.shape_variants``: a spring as a polynomial of order 1 to 3 in the joint
angle, or a gas-spring lever law whose geometry is fitted by variable projection on the current training fit,
``JointScore``, counted in the BIC; a delay as its first-order column or as its exact torque at the delay where
``JointScore.fixed`` puts the exact profile lowest) is screened in the variant with the lowest training BIC, unless
that variant's weighted validation error is above the simplest one's (then the simplest is screened).

A candidate chosen in a round must also hold on a second opinion when one is given (``second_opinion``: the
selection's gates on each further validation recording, or a block cross-validation of the training recording);
one that does not is an unstable finding, not kept, and the next best is tried; nor is a lag that the friction shapes
the nominal model lacks explain (``friction_rival``): those shapes join the candidates instead.

After the forward pass a backward check refits the kept terms without each one in turn: a term that no longer
lowers the validation RMSE of every joint it names (a later term took its part) is dropped and the check repeats
(``SelectionResult.dropped`` says which and why).

A candidate whose name the recording cannot support (``CandidateTerm.name_unsupported``: a torque ripple, periodic in
the angle, on a joint whose recorded travel covers less than one of its periods) is not named when a candidate on
the same joint whose name it supports (a spring, a counterbalance) fits that joint about as well: its validation RMSE
there is close, or it explains about the same torque (``backed_name``).

Ties (gains within 2 % that leave at most ``TIE_REMAINING`` times the best one's remaining error: a gain of
97.9 % leaves 20 times the error of one of 99.9 %) go to the candidate with fewer parameters, then to the earlier
term of the library. Selection stops when no candidate qualifies or ``max_effects`` are kept. Each round's best
candidates, the rejected ones and the kept term are logged at INFO (logger ``identification.diagnosis.selection``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from identification.diagnosis.backed_name import backed_name
from identification.diagnosis.columns import BlockColumns, as_blocks
from identification.diagnosis.design import WeightedDesign, joint_weights, left_out
from identification.diagnosis.joint_score import JointScore
from identification.metrics import explained_rms, rms
from psdm_casadi.errors import ParameterError
from psdm_casadi.log_context import ONCE

logger = logging.getLogger(__name__)

ROBOT_FLOOR = 0.0004  # least explained torque on any joint as a fraction of the robot's largest joint torque RMS
TIE_REMAINING = 1.5  # a tie in gain must leave at most this times the best candidate's remaining validation error
PRUNE_TOLERANCE = 1e-6  # a kept term must lower its joints' validation RMSE by more than this fraction (``_prune``)


@dataclass(frozen=True)
class SelectionStep:
    """One kept term: its instance, the per-joint validation RMSE before and after adding it, the criterion gains."""

    term: object
    joints: tuple
    rmse_before: np.ndarray
    rmse_after: np.ndarray
    rmse_train_before: np.ndarray
    rmse_train_after: np.ndarray
    delta_bic: float
    validation_gain: float
    shape_note: str = ""


@dataclass(frozen=True)
class SelectionResult:
    """Kept terms with their jointly fitted coefficients, and the fits before and after.

    Attributes
    ----------
    steps : tuple of SelectionStep
    coefficients : tuple of arrays
        Final coefficients of each kept term (same order as ``steps``).
    friction_coefficients : array
    rigid_coefficients : array or None
        Base parameters when the rigid body was identified.
    prediction_validation, prediction_train : arrays (n_samples, n_dof)
        Final model torque.
    nominal_validation, nominal_train : arrays (n_samples, n_dof)
        Torque of the nominal model alone.
    candidates_tried : int
    dropped : tuple of str
        Sentences naming the terms the backward check removed, and why.
    unstable : tuple of UnstableFinding
        Candidates that qualified on the validation recording but not on a second opinion (another validation
        recording, or a held-out block of the training data): not kept, reported with their numbers.
    rejected : tuple of (label, reason)
        Candidates whose fit would have qualified but whose parameters are physically meaningless
        (``CandidateTerm.implausibility``), with the reason.
    opinion_route : str
        How the second opinion was formed (``second_opinion.SecondOpinion.route``), or "" without one.
    """

    steps: tuple
    coefficients: tuple
    friction_coefficients: np.ndarray
    rigid_coefficients: np.ndarray | None
    nominal_train: np.ndarray
    nominal_validation: np.ndarray
    prediction_train: np.ndarray
    prediction_validation: np.ndarray
    candidates_tried: int
    dropped: tuple = ()
    unstable: tuple = ()
    rejected: tuple = ()
    opinion_route: str = ""


@dataclass(frozen=True)
class _Limits:
    """What a candidate must achieve (see the module docstring): joint weights, floors, the BIC sample count."""

    sigma: np.ndarray
    torque_rms: np.ndarray
    floor: np.ndarray
    min_improvement: float
    n_eff_total: float
    setting: str = ""  # the pass its log lines name ("[recalibrated rigid body] "; "": one pass)


def acting_joints(term, ct) -> tuple:
    """The joints a per-joint term names and acts on (its columns are non-zero there); empty for robot-wide terms
    (they name the joints they improve, ``_named_joints``)."""
    return tuple(int(j) for j in term.joints if np.any(ct[:, j, :] != 0))


def passes_gates(rmse_before, rmse_after, own, floor, min_improvement, sigma) -> str | None:
    """Why a candidate that takes one recording's per-joint validation RMSE from ``rmse_before`` to ``rmse_after`` fails
    the selection's gates there (module docstring), or None: the RMSE of each of its own joints ``own`` drops, one
    joint's (its own, for a per-joint term) drops by ``min_improvement`` while the term explains a torque of at least
    ``floor`` [N m] there (``metrics.explained_rms``), and the joint-weighted error (``sigma``) drops."""
    own = list(own)
    if own and not np.all(rmse_after[own] < rmse_before[own]):
        return f"raises the validation RMSE of its joint {own[0] + 1}"
    rel = 1.0 - rmse_after / np.maximum(rmse_before, 1e-300)
    improving = (rel >= min_improvement) & (explained_rms(rmse_before, rmse_after) >= floor)
    if not np.any(improving[own] if own else improving):
        return f"lowers no{' own' if own else ''} joint's validation RMSE by {min_improvement:.0%}"
    if np.sum(rmse_after**2 / sigma**2) >= np.sum(rmse_before**2 / sigma**2):
        return "raises the joint-weighted validation error"
    return None


def _shape_fits(design, term, train_ctx, val_ctx, sse, limits, score=None) -> list:
    """Fit each shape variant of ``term`` with the kept terms: ``(variant, ct, cv, k, reason, rv1, sse1, dBIC)``;
    ``k`` counts a variant's shape parameters fitted through ``score`` (a ``JointScore``) too (a gas spring's
    geometry)."""
    p = design.G.shape[0]
    out = []
    for variant in term.shape_variants(train_ctx, score):
        ct, cv = variant.columns(train_ctx), variant.columns(val_ctx)
        beta, sse1, rv1 = design.fit(ct, cv)
        k = ct.shape[2] + variant.n_shape_parameters
        reason = variant.implausibility(beta[p:], train_ctx)
        delta_bic = limits.n_eff_total * np.log(sse1 / sse) + k * np.log(limits.n_eff_total)
        out.append((variant, ct, cv, k, reason, rv1, sse1, float(delta_bic)))
    return out


def _pick_shape(fits, sigma) -> tuple:
    """The variant screened: the lowest training BIC among the plausible ones, unless its weighted validation error
    is above the simplest plausible variant's; ``(fit or None, note)``."""
    plausible = [f for f in fits if f[4] is None]
    if not plausible:
        return None, fits[0][4]
    if len(fits) == 1:
        return plausible[0], ""
    best = min(plausible, key=lambda f: f[7])
    simplest = plausible[0]

    def wval(f):
        return float(np.sum(f[5] ** 2 / sigma**2))

    note = "; ".join(f"{f[0].shape_name}: dBIC {f[7]:.0f}, weighted validation error {wval(f):.4g}" for f in plausible)
    if best is not simplest and wval(best) > wval(simplest):
        return simplest, (f"{simplest[0].shape_name} kept: the lowest-BIC shape did not carry over to validation "
                          f"({note})")  # fmt: skip
    return best, f"{best[0].shape_name} chosen by BIC on the training data, checked on validation ({note})"


class _Qualified(NamedTuple):
    """A candidate that qualified in a round of ``_screen``: its weighted validation ``gain``, parameter count
    ``k``, ``index`` in the remaining candidates, ``term`` (the chosen shape), validation RMSE per joint
    ``rmse_v``, ``delta_bic``, the shape ``note``, why the recording cannot support its name (``unsupported``,
    ``CandidateTerm.name_unsupported``; None when it can) and the validation torque it explains per joint
    (``explained``, ``metrics.explained_rms``)."""

    gain: float
    k: int
    index: int
    term: object
    rmse_v: np.ndarray
    delta_bic: float
    note: str
    unsupported: str | None
    explained: np.ndarray


def _screen(design, remaining, train_ctx, val_ctx, sse, rmse_v, limits):
    """Fit each remaining candidate (in its chosen shape) with the kept terms: ``(qualifying, implausible)``, the
    qualifying ones (``_Qualified``) and ``(label, reason)`` of those whose fit would qualify but whose parameters are
    physically meaningless (every shape implausible; judged in the simplest shape)."""
    score = JointScore(design, sse)
    qualified, scored, rejected, implausible = [], [], [], []
    wval0 = float(np.sum(rmse_v**2 / limits.sigma**2))
    for index, term in enumerate(remaining):
        logger.info("diagnose: screening %s", term.label, extra={"progress": (index + 1, len(remaining)), "tick": True})
        fits = _shape_fits(design, term, train_ctx, val_ctx, sse, limits, score)
        chosen, note = _pick_shape(fits, limits.sigma)
        if chosen is None:
            rejected.append((term.label, note))
            own = acting_joints(fits[0][0], fits[0][1])
            if fits[0][7] < 0 and _gates(rmse_v, fits[0][5], own, limits) is None:
                implausible.append((fits[0][0].label, note))
            continue
        variant, ct, _, k, _, rv1, _, delta_bic = chosen
        wval1 = float(np.sum(rv1**2 / limits.sigma**2))
        gain = (wval0 - wval1) / wval0
        rel, explained = 1.0 - rv1 / np.maximum(rmse_v, 1e-300), explained_rms(rmse_v, rv1)
        scored.append((gain, variant.label, rel, explained, delta_bic, acting_joints(variant, ct)))
        reason = _gates(rmse_v, rv1, acting_joints(variant, ct), limits)
        if reason is not None and reason.startswith("raises the validation RMSE"):
            rejected.append((variant.label, reason))
        elif reason is None and delta_bic < 0:
            unsupported = variant.name_unsupported(train_ctx)
            qualified.append(_Qualified(gain, k, index, variant, rv1, delta_bic, note, unsupported, explained))
    for g, label, rel, e, b, own in sorted(scored, key=lambda x: (x[0], x[1]), reverse=True)[:5]:
        j = int(np.argmax(rel))
        size = _size_text(e, limits.torque_rms, j)
        logger.info(f"diagnose:   candidate {label}: gain {g:.1%}, best joint {j + 1} -{rel[j]:.0%} ({size})"
                    f"{own_joints_text(own, rel, j)}, dBIC {b:.0f}")  # fmt: skip
    for label, reason in rejected[:5]:  # the same rejection in every round and pass: said once (log_context.ONCE)
        logger.info(f"diagnose:   rejected {label}: {reason}", extra=ONCE)
    return qualified, implausible


def own_joints_text(own, rel, best: int) -> str:
    """What a per-joint candidate (on the 0-based joints ``own``) takes off its own joints when its best joint ``best``
    (largest drop ``rel``) is another: a rigid body recalibrated without a spring on joint 4 spreads it over link
    parameters joint 1 shares, so joint 1's drop can be the largest. Empty when the best joint is its own."""
    own = [int(k) for k in own]
    if not own or best in own:
        return ""
    return "; its own joint" + "".join(f" {k + 1} -{rel[k]:.0%}" for k in own)


def _size_text(explained, torque_rms, joint: int) -> str:
    """How much validation residual a candidate takes off [N m RMS] on ``joint`` (its best one), against that joint's
    torque RMS on training (the size the selection's floor reads): "takes 0.51 N m RMS off it, 3.2 % of its torque RMS
    on training". Above that torque RMS it is a ratio, not a share: the nominal model's validation error on the joint
    exceeds the joint's torque (a rigid body recalibrated on short one-way recordings; it was printed as a share of
    the torque above 100 %)."""
    share = float(explained[joint]) / max(float(torque_rms[joint]), 1e-300)
    size = (
        f"{share:.1%} of its torque RMS on training"
        if share <= 1.0
        else (f"{share:.2g} x its torque RMS on training: the nominal model's error there exceeds the joint's torque")
    )
    return f"takes {float(explained[joint]):.3g} N m RMS off it, {size}"  # fmt: skip


def _gates(rmse_before, rmse_after, own, limits) -> str | None:
    """``passes_gates`` with the selection's ``_Limits``."""
    return passes_gates(rmse_before, rmse_after, own, limits.floor, limits.min_improvement, limits.sigma)


def _choose(qualified):
    """The best qualifying candidate; gains within 2 % of the best that leave at most ``TIE_REMAINING`` times its
    remaining error tie, and ties go to fewer parameters, then the earlier term (``backed_name.backed_name`` then checks
    that the recording supports the chosen term's name)."""
    top = max(q.gain for q in qualified)
    left = max(1.0 - top, 1e-12)
    near = [q for q in qualified if q.gain >= top - 0.02 * abs(top) and 1.0 - q.gain <= TIE_REMAINING * left]
    return backed_name(min(near, key=lambda q: (q.k, q.index)), qualified)


def _named_joints(term, rmse_before, rmse_after, joint_threshold) -> tuple:
    """The joints a kept term acts on: its own, or for a robot-wide term those it improves by ``joint_threshold``."""
    if term.joints:
        return term.joints
    rel = 1.0 - rmse_after / np.maximum(rmse_before, 1e-300)
    order = np.argsort(-rel)
    return tuple(int(j) for j in order if rel[j] >= joint_threshold) or (int(order[0]),)


def _design_with(nominal, columns, y_train, y_val, sigma) -> WeightedDesign:
    """A design whose base is the nominal columns followed by the kept terms' ``columns`` ((ct, cv) pairs)."""
    base_t, base_v = nominal
    for ct, cv in columns:
        base_t, base_v = (b.concatenate(BlockColumns.from_dense(c)) for b, c in ((base_t, ct), (base_v, cv)))
    return WeightedDesign(base_t, base_v, y_train, y_val, sigma)


def _prune_ratio(term, joints, rv_full, rv_without, sigma) -> float:
    """Validation error with a kept term over without it: the largest ratio of the joints a per-joint term names; the
    joint-weighted error of every joint for a robot-wide term (a payload, a delay, a tilt), as the selection judged
    it (a payload that takes 3 N m off joint 2 and puts 0.06 N m on joint 5 stays)."""
    if term.joints:
        return float(np.max(rv_full[joints] / np.maximum(rv_without[joints], 1e-300)))
    return float(np.sqrt(np.sum(rv_full**2 / sigma**2) / max(np.sum(rv_without**2 / sigma**2), 1e-300)))


def _prune(nominal, kept, y_train, y_val, sigma) -> tuple:
    """Backward check of the kept terms ``[(step, ct, cv), ...]``: drop, one at a time, a term whose removal does
    not raise the validation RMSE of every joint it names; ``(kept, sentences on the dropped)``."""
    dropped = []
    while len(kept) > 1:
        _, _, rv_full = _design_with(nominal, [(ct, cv) for _, ct, cv in kept], y_train, y_val, sigma).fit()
        worst = None
        for i, (step, ct, _) in enumerate(kept):
            others = [(c, v) for k, (_, c, v) in enumerate(kept) if k != i]
            _, _, rv_without = _design_with(nominal, others, y_train, y_val, sigma).fit()
            joints = list(acting_joints(step.term, ct) or step.joints)
            ratio = _prune_ratio(step.term, joints, rv_full, rv_without, sigma)
            if ratio >= 1.0 - PRUNE_TOLERANCE and (worst is None or ratio > worst[1]):
                worst = (i, ratio, joints)
        if worst is None:
            break
        i, ratio, joints = worst
        label = kept[i][0].term.label
        sentence = (
            f"{label} dropped: with the other kept terms it no longer lowers the validation RMSE of joint "
            f"{', '.join(str(j + 1) for j in joints)} (ratio {ratio:.3f} with/without it)"
        )
        logger.info(f"diagnose: {sentence}")
        dropped.append(sentence)
        kept = kept[:i] + kept[i + 1 :]
    return kept, tuple(dropped)


def forward_select(
    instances,
    train_ctx,
    val_ctx,
    base_train,
    base_val,
    y_train,
    y_val,
    *,
    min_improvement=0.2,
    max_effects=4,
    effective_samples=None,
    joint_threshold=0.1,
    min_torque_fraction=0.004,
    opinion=None,
    rival=None,
    setting: str = "",
) -> SelectionResult:
    """Greedy forward selection of candidate term instances, then a backward check (see the module docstring).

    Parameters
    ----------
    instances : sequence of CandidateTerm
        Concrete instances (``CandidateLibrary.expand``).
    train_ctx, val_ctx : DiagnosisContext
    base_train, base_val : BlockColumns or arrays (n_samples, n_dof, p)
        Columns of the nominal model's free parameters (friction, and base parameters if identified).
    y_train, y_val : arrays (n_samples, n_dof)
        Measured torque minus the fixed part of the nominal model.
    min_improvement : float
        Fraction by which one joint's validation RMSE must drop.
    max_effects : int
    effective_samples : float, optional
        Independent samples per joint in the training data (for the BIC); default n_samples.
    joint_threshold : float
        Relative validation RMSE reduction above which a joint is named for a robot-wide term.
    min_torque_fraction : float
        Least torque a term explains on the improving joint (``metrics.explained_rms``), as a fraction of that joint's
        torque RMS (a floor in N m below which a change is not worth reporting; default 0.4 %).
    opinion : second_opinion.SecondOpinion, optional
        Judges each candidate the forward pass would keep on more validation recordings or held-out blocks of the
        training data; one that does not hold is reported unstable, not kept (``SelectionResult.unstable``).
    rival : friction_rival.FrictionRival, optional
        A lag is kept only if it beats the friction shapes the nominal model lacks on every validation recording (the
        shapes then join the candidates); the sentences on the lags it refuses lead ``SelectionResult.dropped``.
    setting : str
        The pass the log lines name (a diagnosis's with the nominal or the recalibrated rigid body; "": none).
    """
    if not 0.0 < min_improvement < 1.0:
        raise ParameterError(f"DiagnosisOptions.min_improvement must be in (0, 1); got {min_improvement!r}.")
    if not (isinstance(max_effects, (int, np.integer)) and max_effects >= 0):
        raise ParameterError(f"DiagnosisOptions.max_effects must be an integer >= 0; got {max_effects!r}.")
    n_eff = float(effective_samples) if effective_samples is not None else float(y_train.shape[0])
    # joint weights: torque RMS of each joint on the training data, so joints count alike whatever their size
    torque_rms = rms(train_ctx.tau)
    sigma = joint_weights(train_ctx.tau, left_out(train_ctx))
    # least explained torque per joint in N m: a fraction of that joint's own torque RMS (joints count alike), and
    # at least ROBOT_FLOOR of the robot's largest joint torque RMS (noise-level changes on the weakest joints)
    floor = np.maximum(min_torque_fraction * torque_rms, ROBOT_FLOOR * float(np.max(torque_rms)))
    limits = _Limits(sigma=sigma, torque_rms=torque_rms, floor=floor, min_improvement=min_improvement,
                     n_eff_total=n_eff * y_train.shape[1], setting=f"[{setting}] " if setting else "")  # fmt: skip
    nominal = (as_blocks(base_train), as_blocks(base_val))
    design = WeightedDesign(*nominal, y_train, y_val, sigma)
    _, _, _, _, nominal_train, nominal_val = design.fit(full=True)
    kept, tried, unstable, rejected = _forward(design, list(instances), (train_ctx, val_ctx), limits, max_effects,
                                               joint_threshold, (opinion, rival))  # fmt: skip
    kept, dropped = _prune(nominal, kept, y_train, y_val, sigma)
    dropped = tuple(rival.sentences if rival is not None else ()) + dropped
    design = _design_with(nominal, [(ct, cv) for _, ct, cv in kept], y_train, y_val, sigma)
    beta, _, _, _, pred_t, pred_v = design.fit(full=True)
    p0 = nominal[0].n_columns
    bounds = np.cumsum([p0] + [ct.shape[2] for _, ct, _ in kept])
    coefficients = [beta[start:stop].copy() for start, stop in zip(bounds[:-1], bounds[1:])]
    return SelectionResult(
        steps=tuple(step for step, _, _ in kept),
        coefficients=tuple(coefficients),
        friction_coefficients=beta[:p0].copy(),
        rigid_coefficients=None,
        nominal_train=nominal_train,
        nominal_validation=nominal_val,
        prediction_train=pred_t,
        prediction_validation=pred_v,
        candidates_tried=tried,
        dropped=dropped,
        unstable=unstable,
        rejected=rejected,
        opinion_route=opinion.route if opinion is not None else "",
    )


def _forward(design, remaining, contexts, limits, max_effects, joint_threshold, judges=(None, None)) -> tuple:
    """The forward pass: ``([(step, ct, cv), ...], candidates tried, unstable, rejected)``; ``design`` grows with each
    kept term; ``judges`` (a ``second_opinion.SecondOpinion`` and a ``friction_rival.FrictionRival``, each or None)
    judge each chosen candidate before it is kept."""
    train_ctx, val_ctx = contexts
    _, sse, rmse_t, rmse_v, _, _ = design.fit(full=True)
    kept, tried, unstable, rejected = [], 0, [], {}
    while len(kept) < max_effects and remaining:
        qualified, implausible = _screen(design, remaining, train_ctx, val_ctx, sse, rmse_v, limits)
        rejected.update(implausible)
        tried += len(remaining)
        chosen, drop = _stable_choice(design, qualified, judges, limits, unstable)
        offers = judges[1].take_offers() if judges[1] is not None else []  # friction shapes that explain a lag
        if chosen is None and not offers:
            break
        remaining = [r for i, r in enumerate(remaining) if i not in drop and (chosen is None or i != chosen.index)]
        remaining += offers
        if chosen is None:
            continue
        gain, term, delta_bic, note = chosen.gain, chosen.term, chosen.delta_bic, chosen.note
        ct, cv = term.columns(train_ctx), term.columns(val_ctx)
        _, _, rt1, rv1, _, _ = design.fit(ct, cv, full=True)
        step = SelectionStep(term=term, joints=_named_joints(term, rmse_v, rv1, joint_threshold),
                             rmse_before=rmse_v.copy(), rmse_after=rv1.copy(), rmse_train_before=rmse_t.copy(),
                             rmse_train_after=rt1.copy(), delta_bic=float(delta_bic), validation_gain=float(gain),
                             shape_note=note)  # fmt: skip
        logger.info(f"diagnose: {limits.setting}kept {term.label} (validation gain {gain:.1%}, dBIC {delta_bic:.0f})")
        if note:
            logger.info(f"diagnose:   shape: {note}")
        kept.append((step, ct, cv))
        design.set_base(design.base_train.concatenate(BlockColumns.from_dense(ct)),
                        design.base_val.concatenate(BlockColumns.from_dense(cv)))  # fmt: skip
        for judge in (j for j in judges if j is not None):
            judge.keep(term)
        _, sse, rmse_t, rmse_v, _, _ = design.fit(full=True)
    labels = {step.term.label for step, _, _ in kept} | {u.label for u in unstable}
    return kept, tried, tuple(unstable), tuple((k, v) for k, v in rejected.items() if k not in labels)


def _stable_choice(design, qualified, judges, limits, unstable: list) -> tuple:
    """The best qualifying candidate that holds on the second opinion and, for a lag, beats the friction rival
    (``judges``): ``(chosen or None, indices of the candidates refused)``; each unstable one is appended to
    ``unstable`` (the rival keeps its own sentences and offers) and the next best is tried."""
    opinion, rival = judges
    drop = set()
    while qualified:
        chosen = _choose(qualified)
        verdict = None if opinion is None else opinion.judge(design, chosen.term, limits)
        explained = None if verdict is not None or rival is None else rival.judge(design, chosen.term, limits, unstable)
        if verdict is None and explained is None:
            return chosen, drop
        if verdict is not None:
            logger.info(f"diagnose: {limits.setting}{verdict.sentence()}")
            unstable.append(verdict)
        drop.add(chosen.index)
        qualified = [q for q in qualified if q.index != chosen.index]
    return None, drop
