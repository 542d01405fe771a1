"""A new finding that splits the torque of a finding the model already carries: not a finding of its own.

``recalibrate`` refits a calibrated model with a diagnosis's findings beside the findings the file already holds. A
diagnosis of a model file carries the file's own findings in its nominal model (``diagnosis.carried_terms``), but a
torque of the angle may still be found beside one of them under another name: the heavy arm's cam counterbalance, which
identify took as a linear spring (k = -3330 N m/rad), came back as a second-harmonic torque ripple. Over the joint's
travel the two shapes are nearly one (their torques correlate at |r| = 0.9996 on the training recording), and the joint
refit traded slope between them: the spring's k went to +3803 against a ripple of 3686 N m, the two summing to about the
spring it replaced (issue 25). Neither number is physics, and the sum barely changed the validation RMSE (joint 2: 125.7
-> 124.5 N m).


The rule (``split_reason``), for each new torque finding N and each finding C the model carries on the same joint:

- their torques, as refitted together, correlate beyond ``SPLIT_CORRELATION`` in magnitude (either sign: traded
  against each other or shared) on the training recordings, so that the data cannot tell the two apart; and
- adding N moves C's coefficients by more than ``SPLIT_SIGMAS`` of C's own standard deviations: C as refitted
  beside N against C as refitted without N on the same recordings (so a different training recording does not
  count as N's doing). That is the bound a refit must respect: a carried finding may not reverse its sign, or change
  its size beyond what its own uncertainty allows, because a new finding was added beside it.

Then N and C split one torque, and the model keeps one of the two (``one_of_the_two``): C, refitted without N, unless
N alone lowers the joint's validation RMSE against C alone by ``REPLACE_GAIN``, the gain a diagnosis asks of a finding
(then N replaces C: the same torque in a better shape, as a cam found as a second harmonic where the file carries a
linear spring). The one dropped is listed with C's coefficients without and beside N, the correlation and the joint's
validation RMSE with C alone, N alone and both. A new finding that moves C within its uncertainty, or whose torque has
a shape of its own (an effect the carried finding does not describe), is kept and judged on validation as any other.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.finding_value import finding_torques, validation_rmse

__all__ = [
    "REPLACE_GAIN",
    "SPLIT_CORRELATION",
    "SPLIT_SIGMAS",
    "coefficient_shift",
    "one_of_the_two",
    "split_reason",
    "splitting_findings",
]

#: Two findings' torques on one joint are one shape to the data beyond this |correlation| ...
SPLIT_CORRELATION = 0.9
#: ... and the new one splits the carried one's torque when it moves a carried coefficient by more than this many of
#: its standard deviations (the 3 sigma of ``recalibrate``'s moved parameters).
SPLIT_SIGMAS = 3.0
#: A new finding replaces the carried one it splits when, alone, it lowers the joint's validation RMSE by this share
#: against the carried one alone: what a diagnosis asks of a finding (``DiagnosisOptions.min_improvement``).
REPLACE_GAIN = 0.2


def coefficient_shift(alone: dict, beside: dict) -> tuple:
    """(largest ``|beside - alone| / std`` over the features fitted in both, that feature's name) of a finding's
    entries refitted without (``alone``, whose ``std`` counts) and with (``beside``) a new finding; (0.0, None)
    when no feature has a coefficient and a positive standard deviation in both."""
    shifts = [
        (abs(b - a) / s, name)
        for name, a, s, b in zip(alone["feature_names"], alone["coefficients"], alone["std"], beside["coefficients"])
        if a is not None and b is not None and s is not None and np.isfinite(s) and s > 0.0
    ]
    return max(shifts, default=(0.0, None))


def split_reason(carried_alone: dict, carried_beside: dict, joint: int, correlation: float) -> str | None:
    """Why a new finding on ``joint`` (0-based) splits the torque of the carried finding whose entries refitted
    without and beside it are ``carried_alone`` and ``carried_beside`` (their torques correlating ``correlation``
    on the training data), or None when it does not (module docstring)."""
    if not abs(correlation) > SPLIT_CORRELATION:
        return None
    sigmas, feature = coefficient_shift(carried_alone, carried_beside)
    if not sigmas > SPLIT_SIGMAS:
        return None
    label = carried_alone["label"]
    alone, beside = carried_alone.get("parameters") or {}, carried_beside.get("parameters") or {}
    moves = [f"{k} {v:+.4g} -> {beside[k]:+.4g}" for k, v in alone.items() if beside.get(k, v) != v]
    moves = ", ".join([moves[0].replace(" ", " would go ", 1), *moves[1:]]) if moves else "coefficients would move"
    return (f"splits joint {joint + 1}'s torque with the carried {label}: beside it, {label}'s {moves} ({feature} by "
            f"{sigmas:.1f} of its standard deviations), the two torques correlating {correlation:+.4f} on the "
            "training data: one torque, not two findings")  # fmt: skip


def splitting_findings(
    before: CalibratedModel, after: CalibratedModel, refit, model, recordings, kt=(None, None)
) -> list:
    """The findings to drop where a new torque finding of ``after`` splits the torque of a finding ``before`` carries
    (``split_reason``): the new one, or the carried one when the new one alone describes the torque better
    (``one_of_the_two``); as ``[{"label", "effect", "joints", "reason", "split"}, ...]`` (``split``: the two labels,
    the correlation, the shift in standard deviations, the carried parameters without and beside the new one, and the
    joint's validation RMSE of each alone and of both).

    ``refit(labels)`` -> (CalibratedModel, payload) is the joint refit without the findings labelled ``labels``;
    it runs once for each new finding whose torque correlates with a carried one's beyond ``SPLIT_CORRELATION``, and
    once more for a split. ``recordings`` = (training, validation): the raw recordings the refit used and those it is
    judged on, ``kt`` their torque constants (recordings with currents only).
    """
    (train, validation), (kt_train, kt_validation) = recordings, kt
    carried = {e["label"] for e in before.document.get("findings") or [] if e.get("kind") == "torque"}
    torques = finding_torques(after, model, train, kt_train) if carried else {}
    old = [(label, joint, tau) for label, (joint, tau) in torques.items() if label in carried]
    entries = {e["label"]: e for e in after.document["findings"]}
    out = []
    for label, (joint, tau) in torques.items():
        if label in carried:
            continue
        partners = [(c, float(np.corrcoef(tau, t)[0, 1])) for c, j, t in old if j == joint]
        partners = [(c, r) for c, r in partners if abs(r) > SPLIT_CORRELATION]
        if not partners:
            continue
        without_new = refit([label])[0]
        alone = {e["label"]: e for e in without_new.document["findings"]}
        for other, correlation in sorted(partners, key=lambda p: -abs(p[1])):
            if other not in alone:  # the refit without it dropped the carried one too (implausible alone)
                continue
            reason = split_reason(alone[other], entries[other], joint, correlation)
            if reason is None:
                continue
            split = {"new": label, "carried": other, "correlation": correlation,
                     "sigmas": coefficient_shift(alone[other], entries[other])[0],
                     "carried_alone": dict(alone[other]["parameters"]),
                     "carried_beside": dict(entries[other]["parameters"])}  # fmt: skip
            models = (without_new, refit([other])[0], after)  # the carried alone, the new alone, both
            rmse = [np.mean([validation_rmse(m, model, r, kt_validation)[0] for r in validation], axis=0)[joint]
                    for m in models]  # fmt: skip
            out.append(one_of_the_two(split, [float(x) for x in rmse], joint, reason, entries))
            break
    return out


def one_of_the_two(split: dict, rmse, joint: int, reason: str, entries: dict) -> dict:
    """The dropped-finding entry of a split (``splitting_findings``) whose joint's (0-based) validation RMSE is
    ``rmse`` = [with the carried finding alone, the new one alone, both]: the carried finding is replaced when the
    new one alone lowers that RMSE by at least ``REPLACE_GAIN`` (the gain a diagnosis asks of a finding); otherwise
    the new one is dropped."""
    carried, new, both = rmse
    split = {**split, "validation_rmse": {"carried_alone": carried, "new_alone": new, "both": both}}
    gain = 1.0 - new / carried if carried > 0.0 else 0.0
    numbers = (f"joint {joint + 1}'s validation RMSE {carried:.4g} N m with {split['carried']} alone, {new:.4g} with "
               f"{split['new']} alone ({abs(gain):.0%} {'lower' if gain >= 0 else 'higher'}), {both:.4g} with "
               "both")  # fmt: skip
    if gain >= REPLACE_GAIN:
        label, reason = split["carried"], (
            f"replaced by {split['new']}, the same torque in a better shape ({numbers}; a replacement must lower it "
            f"by {REPLACE_GAIN:.0%}): {split['new']} {reason}")  # fmt: skip
    else:
        label, reason = (
            split["new"],
            (f"{reason} ({numbers}; it would replace {split['carried']} only by lowering it by {REPLACE_GAIN:.0%})"),
        )
    return {"label": label, "effect": entries[label]["effect"], "joints": [joint + 1], "reason": reason,
            "split": split}  # fmt: skip
