"""The never-worse gate of a refit that writes a model: no joint's validation RMSE may rise beyond the noise.

calibrated model before + refitted model + validation recordings -> ``JointComparison`` (per joint before, after,
noise margin, the joints made worse) -> ``keep_not_worse`` (the findings kept, the ones dropped and why, or a
refusal).

A refit with findings is judged on the validation recordings as ``psdm validate`` judges it
(``finding_value.validation_rmse``). A finding that lowers the overall error can still raise it on joints it does
not act on (a robot-wide delay that helps the wrists and hurts the base joints; a rigid body refitted around a
spring): such a model is not written. The allowance is the noise of the comparison itself, derived from the data:

- the paired difference of the two models' RMSE on the same validation samples, resampled by a circular block
  bootstrap (``BOOTSTRAP_SAMPLES`` draws, fixed seed) whose block length is where the autocorrelation of the
  difference of the squared residuals first drops below 1/e (twice that lag; at least ``n**(1/3)``): the
  standard error of the RMSE change a different stretch of the same motion would give;
- the margin is ``MARGIN_SIGMAS`` of those standard errors, and never below ``MARGIN_FLOOR`` of the joint's RMSE
  before (a change that small is below what a validation RMSE tells).

That margin counts the noise of the validation samples only; both models are also estimates from one training
recording. A joint over its margin is therefore worse unless the second opinion shows the rise is that noise
(``TrainingRefits``, when the caller gives one): both models identified again on the training data without each of its
blocks; the rise is noise only when the mean over those refits of the joint's validation RMSE change is within the
margin AND the validation rise beyond the margin is within ``ESTIMATION_SIGMAS`` jackknife standard errors of the
change (``sqrt((k-1)/k sum (c_i - mean)^2)`` over the k refits' changes c_i: how much the full fit's change varies
with its training data). The validation recording is the user's judge: the refits may waive a rise of the size their
own spread shows, never a rise far beyond it, since the model written is the full fit, not the refits' mean. On a
heavy virtual arm (1 kHz, 3 min) a joint-3 rise 20.1 -> 24.7 N m (margin 2.6) was waived by refits whose mean change
was -0.77 N m, their spread far below the 2 N m excess: the full fit held a Coulomb friction at its bound beside a
collinear smooth-Coulomb column, a model the refits do not describe. On the virtual Denso with a spring on joint
2 and a delay on the wrist (``tests/identification/test_never_worse.py``), the model refitted with the spring alone
raises joint 3 from 1.089 to 1.126 N m (margin 0.035) on the validation recording, and by 0.04-0.25 N m on nine other
motions, while the four refits without a quarter of the training data each lower it or leave it (mean change -0.11 to
-0.29 N m on the same ten motions): the full fit's model before had the spring absorbed into the links in a way that
happened to cancel part of the delayed wrist's misfit on joint 3 (over eight other training recordings the spring's
change on joint 3 ranges from -0.17 to +0.04 N m, mean -0.03). The delay's harm is confirmed on every motion (joint
3: +0.85 N m, the refits' mean +1.17; +0.7 to +4.0 on the other motions).

``keep_not_worse`` searches which findings to drop when a joint is worse than before plus its margin. With at most
``EXHAUSTIVE_MAX`` findings it may drop, every subset is refitted and checked, and of those that keep every joint
within its margin the one with the largest improvement (``improvement``: the mean over joints of the relative
validation RMSE drop) is written: dropping one finding at a time can remove the wrong one first (the finding that
most repairs the worst joint may be the one that helps the other joints most). Beyond that, greedily: while a joint
is worse, the finding whose removal (with a refit) most lowers the RMSE of the joint that is most over its margin is
dropped, and the model is refitted and checked again. When only dropping every finding the gate may drop passes (the
refit is then the model before, or a joint is still worse), or a joint is worse and no finding can be dropped (a
payload the refit's rigid body takes up), nothing is kept: the refit is refused (``GateResult.refused``, naming the
joints and the findings) and the caller writes nothing. The stored record (``JointComparison.to_dict``,
``GateResult.search``) says per joint which part of the margin rule set its margin, and how the subset was searched.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field, replace

import numpy as np

from identification.calibration.finding_value import validation_rmse
from identification.calibration.shared_barrier import shared_solvers
from identification.paired_margin import (
    BOOTSTRAP_SAMPLES,
    MARGIN_FLOOR,
    MARGIN_SIGMAS,
    block_length,
    noise_margin,
    paired_rmse_margin,
)
from psdm_casadi.errors import PSDMError

__all__ = [
    "BOOTSTRAP_SAMPLES",
    "ESTIMATION_SIGMAS",
    "EXHAUSTIVE_MAX",
    "MARGIN_FLOOR",
    "MARGIN_RULE",
    "MARGIN_SIGMAS",
    "GateResult",
    "JointComparison",
    "TrainingRefits",
    "better_on_each",
    "block_length",
    "compare_each",
    "compare_models",
    "keep_not_worse",
    "improvement",
    "paired_rmse_margin",
    "pooled_comparison",
]

logger = logging.getLogger(__name__)

#: Most droppable findings whose every subset is tried (2**8 - 1 refits at most); greedy beyond.
EXHAUSTIVE_MAX = 8
#: Jackknife standard errors of the training fit's change (over the refits without each block) a validation rise beyond
#: its margin may be and still be waived as that fit's estimation noise.
ESTIMATION_SIGMAS = 2.0
MARGIN_RULE = (
    f"a joint is worse when its validation RMSE after exceeds before + margin; margin = max({MARGIN_SIGMAS:g} x the "
    f"standard error of the paired RMSE difference (circular block bootstrap, block = twice the lag where the "
    f"autocorrelation of the squared-residual difference drops below 1/e), {MARGIN_FLOOR:.0%} of the RMSE before); "
    "a joint over it is not worse only if both models identified again on the training data without each of its "
    "blocks show the rise is the training fit's estimation noise: the mean of their validation RMSE changes is within "
    f"the margin and the rise beyond the margin is within {ESTIMATION_SIGMAS:g} jackknife standard errors of their "
    "changes; without such refits the validation recordings alone decide"
)


@dataclass(frozen=True, eq=False)
class JointComparison:
    """Validation RMSE [N m] per joint of a model before and after a refit, with the noise margin.

    Attributes
    ----------
    before, after, margin : arrays (n_dof,)
        The mean over the validation recordings of each model's RMSE (as ``psdm validate``), and the margin
        (``MARGIN_RULE``).
    standard_error : array (n_dof,) or None
        The standard error of the paired RMSE difference the margin was derived from (None: not known).
    refit_change : array (n_dof,) or None
        The second opinion (``TrainingRefits``): the mean over the refits without each training block of the
        validation RMSE change (after - before); None: not asked (no joint over its margin, or no refits).
    refit_folds : int
        How many refits ``refit_change`` is the mean of.
    refit_spread : array (n_dof,) or None
        The jackknife standard error of the change over those refits (``sqrt((k-1)/k sum (c_i - mean)^2)``): the
        estimation noise of the full fit's change a validation rise beyond its margin may be waived as.
    """

    before: np.ndarray
    after: np.ndarray
    margin: np.ndarray
    standard_error: np.ndarray | None = None
    refit_change: np.ndarray | None = None
    refit_folds: int = 0
    refit_spread: np.ndarray | None = None

    @classmethod
    def from_noise(cls, before, after, standard_error) -> JointComparison:
        """The comparison with ``MARGIN_RULE``'s margin: ``MARGIN_SIGMAS`` standard errors of the paired difference,
        never below ``MARGIN_FLOOR`` of the RMSE before."""
        margin = noise_margin(before, standard_error)
        return cls(before=before, after=after, margin=margin, standard_error=standard_error)

    def confirmed_by(self, changes) -> JointComparison:
        """This comparison with the second opinion of ``changes`` (folds, n_dof): each refit's validation RMSE change
        (after - before) without one training block."""
        changes = np.atleast_2d(np.asarray(changes, dtype=float))
        k, mean = len(changes), changes.mean(axis=0)
        spread = np.sqrt((k - 1) / k * np.sum((changes - mean) ** 2, axis=0)) if k > 1 else np.full_like(mean, np.inf)
        return replace(self, refit_change=mean, refit_folds=k, refit_spread=spread)

    @property
    def excess(self) -> np.ndarray:
        """How far each joint is above before + margin [N m] on the validation recordings (<= 0: within it); a joint
        above it whose rise the refits do not confirm is not worse (``worse``), and counts 0 here."""
        excess = self.after - self.before - self.margin
        return np.where(self._confirmed(), excess, np.minimum(excess, 0.0))

    def _confirmed(self) -> np.ndarray:
        """Per joint, whether the refits leave the rise standing (True without refits): their mean change exceeds the
        margin too, or the validation rise beyond the margin exceeds ``ESTIMATION_SIGMAS`` of their spread."""
        if self.refit_change is None:
            return np.ones(len(self.after), dtype=bool)
        spread = np.inf if self.refit_spread is None else self.refit_spread
        beyond = self.after - self.before - self.margin > ESTIMATION_SIGMAS * spread
        return (self.refit_change > self.margin) | beyond

    @property
    def worse(self) -> tuple:
        """The joints (0-based) whose RMSE after exceeds before + margin, confirmed by the refits when asked."""
        return tuple(int(j) for j in np.flatnonzero(self.excess > 0))

    @property
    def cleared(self) -> tuple:
        """The joints (0-based) above before + margin on the validation recordings whose rise the refits without each
        training block do not reproduce (the training fit's estimation noise)."""
        over = self.after - self.before - self.margin > 0
        return tuple(int(j) for j in np.flatnonzero(over & ~self._confirmed()))

    def worst(self) -> int:
        """The joint (0-based) most over its margin, relative to its RMSE before."""
        return int(np.argmax(self.excess / np.maximum(self.before, 1e-12)))

    def margin_sources(self) -> list:
        """Per joint, the sentence saying which part of ``MARGIN_RULE`` set its margin, with the numbers."""
        out = []
        for j, (before, margin) in enumerate(zip(self.before, self.margin)):
            floor = MARGIN_FLOOR * before
            if self.standard_error is None:
                out.append(f"joint {j + 1}: {margin:.3g} N m")
                continue
            noise = MARGIN_SIGMAS * self.standard_error[j]
            which = (f"{MARGIN_SIGMAS:g} standard errors of the paired difference ({noise:.3g} N m), above the "
                     f"{MARGIN_FLOOR:.0%} floor ({floor:.3g} N m)") if noise >= floor else (
                     f"the {MARGIN_FLOOR:.0%} floor of the RMSE before ({floor:.3g} N m), above {MARGIN_SIGMAS:g} "
                     f"standard errors of the paired difference ({noise:.3g} N m)")  # fmt: skip
            out.append(f"joint {j + 1}: {margin:.3g} N m = {which}")
        for j in self.cleared:
            out[j] += (f"; {self.before[j]:.4g} -> {self.after[j]:.4g} N m is over it, but not worse: the mean change "
                       f"of the {self.refit_folds} refits without each training block is {self.refit_change[j]:+.3g} "
                       f"N m, within it, and the rise beyond it is within {ESTIMATION_SIGMAS:g} x their spread "
                       f"({self._spread_text(j)}): the training fit's estimation noise")  # fmt: skip
        return out

    def _spread_text(self, j: int) -> str:
        return "not known" if self.refit_spread is None else f"{self.refit_spread[j]:.3g} N m"

    def to_dict(self) -> dict:
        se = None if self.standard_error is None else _floats(self.standard_error)
        return {"validation_rmse_before": _floats(self.before), "validation_rmse_after": _floats(self.after),
                "margin": _floats(self.margin), "margin_standard_error": se, "margin_sigmas": MARGIN_SIGMAS,
                "margin_floor": MARGIN_FLOOR, "margin_source": self.margin_sources(),
                "refit_change": None if self.refit_change is None else _floats(self.refit_change),
                "refit_folds": self.refit_folds,
                "refit_spread": None if self.refit_spread is None else _floats(self.refit_spread),
                "estimation_sigmas": ESTIMATION_SIGMAS, "cleared_by_refits": [j + 1 for j in self.cleared],
                "worse_joints": [j + 1 for j in self.worse], "margin_rule": MARGIN_RULE}  # fmt: skip

    def text(self, joints=None) -> str:
        """``joint 2: 0.31 -> 0.49 N m (margin 0.012)`` for ``joints`` (0-based; default the worse ones), with the
        refits' mean change when they were asked (``; refits without each training block: +0.15``)."""
        joints = self.worse if joints is None else joints
        refits = ["" if self.refit_change is None else f"; refits without each training block: {v:+.2g}"
                  for v in (self.refit_change if self.refit_change is not None else self.after)]  # fmt: skip
        return "; ".join(
            f"joint {j + 1}: {self.before[j]:.4g} -> {self.after[j]:.4g} N m (margin {self.margin[j]:.2g}{refits[j]})"
            for j in joints
        )


def _floats(values) -> list:
    return [float(v) for v in np.atleast_1d(values)]


def compare_models(before, after, model, validation, kt=None) -> JointComparison:
    """``JointComparison`` of two calibrated models on the raw ``validation`` recordings (a list), each prepared
    as its own file says (``CalibratedModel.predict_recording``); the margin combines the recordings' standard
    errors as that of a mean."""
    return pooled_comparison(compare_each(before, after, model, validation, kt))


def compare_each(before, after, model, validation, kt=None) -> tuple:
    """One ``JointComparison`` per raw recording of ``validation`` (as ``compare_models`` on that recording alone):
    a finding that must hold on each recording is judged on these."""
    out = []
    for recording in validation:  # both on the raw recording's time grid: the prepared samples are the same instants
        error_b, _, ready_b, predicted_b = validation_rmse(before, model, recording, kt)
        error_a, _, ready_a, predicted_a = validation_rmse(after, model, recording, kt)
        se = paired_rmse_margin(ready_b.tau - predicted_b, ready_a.tau - predicted_a)[2]
        out.append(JointComparison.from_noise(np.asarray(error_b), np.asarray(error_a), se))
    return tuple(out)


def better_on_each(comparisons, joints) -> tuple:
    """Those of ``joints`` (0-based) the model after predicts better than the one before beyond the margin on each
    held-out recording (``comparisons``: one ``JointComparison`` each, ``compare_each``)."""
    return tuple(j for j in joints if all(c.after[j] < c.before[j] - c.margin[j] for c in comparisons))


def pooled_comparison(comparisons) -> JointComparison:
    """The comparisons of several recordings as one: the mean RMSE per joint, the standard error of that mean. A joint
    without torque in a recording (NaN there: a dead channel) counts in the recordings that hold it only, and is NaN
    where none does."""
    if all(np.all(np.isfinite(c.before) & np.isfinite(c.after)) for c in comparisons):
        before = np.mean([c.before for c in comparisons], axis=0)
        after = np.mean([c.after for c in comparisons], axis=0)
        standard_error = np.sqrt(np.sum(np.square([c.standard_error for c in comparisons]), axis=0)) / len(comparisons)
        return JointComparison.from_noise(before, after, standard_error)
    stack = {k: np.array([getattr(c, k) for c in comparisons]) for k in ("before", "after", "standard_error")}
    held = np.isfinite(stack["before"]) & np.isfinite(stack["after"])
    count = held.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = {k: np.where(count > 0, np.where(held, v, 0.0).sum(axis=0) / count, np.nan) for k, v in stack.items()}
        se = np.sqrt((np.where(held, stack["standard_error"], 0.0) ** 2).sum(axis=0)) / np.maximum(count, 1)
    return JointComparison.from_noise(mean["before"], mean["after"], np.where(count > 0, se, np.nan))


def improvement(comparison: JointComparison) -> float:
    """The mean over joints of the relative validation RMSE drop (before - after) / before: what a subset of the
    findings is ranked by (joints count alike whatever their torque)."""
    return float(np.mean((comparison.before - comparison.after) / np.maximum(comparison.before, 1e-12)))


@dataclass(frozen=True, eq=False)
class TrainingRefits:
    """The gate's second opinion: the models identified again on the training data without each of its blocks.

    Attributes
    ----------
    refit : callable
        ``refit(labels, k)`` -> CalibratedModel: the refit on the training data without block ``k`` and without the
        findings labelled ``labels``.
    folds : int
        How many blocks (each left out once).
    baseline : tuple of str
        The labels whose drop gives the model before's structure (every finding the gate may drop).
    solvers : dict
        The barrier-path solvers the refits share (``shared_barrier``: one per structure, kept between the gate's
        turns; a caller's, e.g. ``BlockFolds.solvers``, to share them with its other fold fits).
    """

    refit: object
    folds: int
    baseline: tuple = ()
    models: dict = field(default_factory=dict, repr=False)
    solvers: dict = field(default_factory=dict, repr=False)

    def model(self, labels, k: int):
        """Block ``k``'s refit without ``labels`` (each refitted once; a judge, so its consistent fits share their
        solvers: ``shared_barrier``)."""
        key = (frozenset(labels), k)
        if key not in self.models:
            with shared_solvers(self.solvers):
                self.models[key] = self.refit(sorted(key[0]), k)
        return self.models[key]

    def changes(self, labels, model, validation, kt=None) -> np.ndarray:
        """(folds, n_dof): per block, the validation RMSE change [N m] (mean over ``validation``) of its refit without
        ``labels`` against its refit without every finding (``baseline``)."""
        out = []
        for k in range(self.folds):
            pair = (self.model(self.baseline, k), self.model(labels, k))
            rmse = [np.mean([validation_rmse(m, model, r, kt)[0] for r in validation], axis=0) for m in pair]
            out.append(rmse[1] - rmse[0])
        return np.array(out)

    def confirm(self, comparison: JointComparison, labels, model, validation, kt=None) -> JointComparison:
        """``comparison`` (of the model without ``labels``) with the refits' second opinion when a joint is over its
        margin; unchanged when none is, when a refit fails, or when the model judged has the baseline's structure
        (``labels`` drop every finding of ``baseline``: each block's pair is one model, its change 0 by construction,
        which cleared every joint of a refit with no finding left: a virtual cobot's joint 2 1.03 -> 1.69 N m was
        written as 'not worse'); the validation recordings alone decide then."""
        if not comparison.worse or set(labels) >= set(self.baseline):
            return comparison
        try:
            return comparison.confirmed_by(self.changes(labels, model, validation, kt))
        except PSDMError as error:
            logger.info("never worse: no second opinion from the training blocks (%s)", str(error).splitlines()[0])
            return comparison


@dataclass(frozen=True, eq=False)
class GateResult:
    """What ``keep_not_worse`` decided.

    Attributes
    ----------
    after : CalibratedModel
        The refitted model with the findings kept (the last one tried when refused).
    payload : object
        What ``refit`` returned beside it.
    comparison : JointComparison
        Of that refit against the model before.
    dropped : list of dict
        Per finding dropped by the gate, in order: label, the joint it repaired, the RMSE pair with and without it,
        the reason.
    refused : str or None
        Why no subset of the findings is not worse (joints and findings named), or None.
    search : str
        How the findings to drop were searched (every subset, or greedily), and what was found.
    """

    after: object
    payload: object
    comparison: JointComparison
    dropped: list
    refused: str | None = None
    search: str = ""

    def to_dict(self) -> dict:
        """The ``recalibration.never_worse`` block: the comparison, the findings dropped, the refusal, the search."""
        return {**self.comparison.to_dict(), "dropped": self.dropped, "refused": self.refused, "search": self.search}


def keep_not_worse(before, first, refit, droppable, model, validation, kt=None, refits=None) -> GateResult:
    """Drop findings until no joint is worse than ``before`` beyond its margin, or refuse (module docstring: every
    subset with at most ``EXHAUSTIVE_MAX`` droppable findings, greedily beyond).

    Parameters
    ----------
    before : CalibratedModel
        The model the findings were added to.
    first : tuple (CalibratedModel, object)
        The refit with every finding: the new model and any payload the caller needs back.
    refit : callable
        ``refit(labels)`` -> (CalibratedModel, payload): the refit without the findings labelled ``labels``.
    droppable : sequence of str
        Labels of the findings the gate may drop (those that change the fit: torque terms and corrections).
    model : PSDMModel
    validation : list of Recording
        Raw validation recordings.
    kt : array (n_dof,), optional
        Torque constants of recordings with currents only.
    refits : TrainingRefits, optional
        The second opinion a joint over its margin must have to be worse (None: the validation recordings alone).
    """
    after, payload = first

    def judge(candidate, labels):
        comparison = compare_models(before, candidate, model, validation, kt)
        return comparison if refits is None else refits.confirm(comparison, labels, model, validation, kt)

    comparison = judge(after, ())
    if not comparison.worse:
        cleared = ", ".join(f"joint {j + 1}" for j in comparison.cleared)
        cleared = f" ({cleared} over the margin, not in the refits without each training block)" if cleared else ""
        return GateResult(after, payload, comparison, [], search=f"none, no joint is worse{cleared}")
    if 0 < len(droppable) <= EXHAUSTIVE_MAX:
        return _every_subset((after, payload, comparison), refit, list(droppable), judge)
    return _greedy((after, payload, comparison), refit, list(droppable), judge)


def _every_subset(first, refit, droppable, judge) -> GateResult:
    """``keep_not_worse`` by trying every non-empty subset of ``droppable`` to drop: of those leaving every joint
    within its margin (dropping them all does not count: that is the model before), the largest ``improvement``,
    fewer dropped on a tie."""
    _, _, comparison = first
    trials = {}
    for size in range(1, len(droppable) + 1):
        for labels in itertools.combinations(droppable, size):
            candidate, extra = refit(list(labels))
            trials[labels] = (judge(candidate, labels), candidate, extra)
    passing = [k for k, t in trials.items() if not t[0].worse and len(k) < len(droppable)]
    tried = f"every subset of the {len(droppable)} findings it may drop tried ({len(trials)} refits)"
    if not passing:
        names = ", ".join(droppable)
        least = min(trials, key=lambda k: (len(trials[k][0].worse), float(np.sum(np.maximum(trials[k][0].excess, 0)))))
        only_all = " except dropping every one (the model before)" if not trials[tuple(droppable)][0].worse else ""
        refused = (f"no subset of the findings ({names}) keeps every joint's validation RMSE within its noise margin: "
                   f"with all of them {comparison.text()}; {tried}, each leaves a joint worse{only_all}")  # fmt: skip
        trial, after, payload = trials[least]
        reason = f"the subset closest to passing drops {', '.join(least)}"
        return GateResult(after, payload, trial, _records(least, comparison, trials, reason), refused, tried)
    chosen = max(passing, key=lambda k: (improvement(trials[k][0]), -len(k)))
    trial, after, payload = trials[chosen]
    search = (f"{tried}; {len(passing)} keep every joint within its margin; the one dropping {', '.join(chosen)} "
              f"improves most (mean relative validation RMSE drop {improvement(trial):.1%})")  # fmt: skip
    logger.info("never worse: %s", search)
    reason = (f"of the subsets that keep every joint within its margin, the one without {', '.join(chosen)} "
              f"improves most ({improvement(trial):.1%})")  # fmt: skip
    return GateResult(after, payload, trial, _records(chosen, comparison, trials, reason), search=search)


def _records(labels, comparison: JointComparison, trials: dict, reason: str) -> list:
    """The stored record of each finding dropped in ``labels`` (``GateResult.dropped``): the joint most over its margin
    with every finding, its RMSE before, with them all, without the subset, and without the finding alone."""
    worst = comparison.worst()
    trial = trials[tuple(labels)][0]
    return [{
        "label": label,
        "joint": worst + 1,
        "validation_rmse_before": float(comparison.before[worst]),
        "validation_rmse_with": float(comparison.after[worst]),
        "validation_rmse_without": float(trial.after[worst]),
        "validation_rmse_without_it_alone": float(trials[(label,)][0].after[worst]),
        "margin": float(comparison.margin[worst]),
        "reason": f"with every finding joint {worst + 1} is worse than before beyond the noise margin "
        f"({comparison.text([worst])}); {reason}: joint {worst + 1} {trial.after[worst]:.4g} N m",
    } for label in labels]  # fmt: skip


def _greedy(first, refit, droppable, judge) -> GateResult:
    """``keep_not_worse`` greedily (more than ``EXHAUSTIVE_MAX`` findings, or none to drop): while a joint is worse,
    drop the finding whose removal most lowers the RMSE of the joint most over its margin."""
    after, payload, comparison = first
    remaining, dropped, first_text = list(droppable), [], comparison.text()
    while comparison.worse and remaining:
        worst = comparison.worst()
        trials = {}
        for label in remaining:
            labels = [d["label"] for d in dropped] + [label]
            candidate, extra = refit(labels)
            trials[label] = (judge(candidate, labels), (candidate, extra))
        label = min(remaining, key=lambda k: (trials[k][0].after[worst], len(trials[k][0].worse)))
        trial, (after, payload) = trials[label]
        logger.info("never worse: %s raised joint %d; dropped and refitted", label, worst + 1)
        dropped.append({
            "label": label,
            "joint": worst + 1,
            "validation_rmse_before": float(comparison.before[worst]),
            "validation_rmse_with": float(comparison.after[worst]),
            "validation_rmse_without": float(trial.after[worst]),
            "margin": float(comparison.margin[worst]),
            "reason": f"with it joint {worst + 1} is worse than before beyond the noise margin "
            f"({comparison.text([worst])}); without it {trial.after[worst]:.4g} N m",
        })  # fmt: skip
        remaining.remove(label)
        comparison = trial
    search = (f"greedily, one finding at a time ({len(droppable)} findings it may drop, more than {EXHAUSTIVE_MAX} "
              "for every subset)") if droppable else "no finding to drop"  # fmt: skip
    if comparison.worse or (dropped and not remaining):
        still = f"; without any, still {comparison.text()}" if comparison.worse and dropped else ""
        turns = "; ".join(f"{d['label']} ({d['reason']})" for d in dropped) or (
            "none (no finding adds a column or a correction: the refit's rigid body takes them up)")  # fmt: skip
        names = ", ".join(droppable) or "none to drop"
        return GateResult(after, payload, comparison, dropped, refused=(
            f"no subset of the findings ({names}) keeps every joint's validation RMSE within its noise margin: with "
            f"all of them {first_text}{still}; dropped in turn: {turns}"), search=search)  # fmt: skip
    return GateResult(after, payload, comparison, dropped, search=search)
