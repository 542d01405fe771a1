"""A new finding that splits the torque of a finding the model already carries: not a finding of its own.

``recalibrate`` refits a calibrated model with a diagnosis's findings beside the findings the file already holds. A
diagnosis of a model file leaves the file's own findings out of its nominal model, so it finds them again, often
under another name: the heavy arm's cam counterbalance, which identify took as a linear spring (k = -3330 N m/rad),
came back as a second-harmonic torque ripple. Over the joint's travel the two shapes are nearly one (their torques
correlate at |r| = 0.9996 on the training recording), and the joint refit traded slope between them: the spring's k
went to +3803 against a ripple of 3686 N m, the two summing to about the spring it replaced (issue 25). Neither number
is physics, and the sum barely changed the validation RMSE (joint 2: 125.7 -> 124.5 N m).

The rule (``split_reason``), for each new torque finding N and each finding C the model carries on the same joint:

- their torques, as refitted together, correlate beyond ``SPLIT_CORRELATION`` in magnitude (either sign: traded
  against each other or shared) on the training recordings, so that the data cannot tell the two apart; and
- adding N moves C's coefficients by more than ``SPLIT_SIGMAS`` of C's own standard deviations: C as refitted
  beside N against C as refitted without N on the same recordings (so a different training recording does not
  count as N's doing). That is the bound a refit must respect: a carried finding may not reverse its sign, or change
  its size beyond what its own uncertainty allows, because a new finding was added beside it.

Then N and C split one torque: N is dropped, with C's coefficients before and after and the correlation in the
reason, and C is refitted without it. A new finding that moves C within its uncertainty, or whose torque has a shape
of its own (an effect the carried finding does not describe), is kept and judged on validation as any other.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.finding_value import finding_torques

__all__ = ["SPLIT_CORRELATION", "SPLIT_SIGMAS", "coefficient_shift", "split_reason", "splitting_findings"]

#: Two findings' torques on one joint are one shape to the data beyond this |correlation| ...
SPLIT_CORRELATION = 0.9
#: ... and the new one splits the carried one's torque when it moves a carried coefficient by more than this many of
#: its standard deviations (the 3 sigma of ``recalibrate``'s moved parameters).
SPLIT_SIGMAS = 3.0


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


def splitting_findings(before: CalibratedModel, after: CalibratedModel, refit, model, recordings, kt=None) -> list:
    """The new torque findings of ``after`` that split the torque of a finding ``before`` carries (``split_reason``),
    as ``[{"label", "effect", "joints", "reason", "split"}, ...]`` (``split``: the carried label, the correlation, the
    shift in standard deviations and the carried parameters without and beside it).

    ``refit(labels)`` -> (CalibratedModel, payload) is the joint refit without the findings labelled ``labels``;
    it runs once for each new finding whose torque correlates with a carried one's beyond ``SPLIT_CORRELATION``.
    ``recordings`` are the raw training recordings the refit used (``kt`` for currents only).
    """
    carried = {e["label"] for e in before.document.get("findings") or [] if e.get("kind") == "torque"}
    torques = finding_torques(after, model, recordings, kt) if carried else {}
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
        alone = {e["label"]: e for e in refit([label])[0].document["findings"]}
        for other, correlation in sorted(partners, key=lambda p: -abs(p[1])):
            if other not in alone:  # the refit without it dropped the carried one too (implausible alone)
                continue
            reason = split_reason(alone[other], entries[other], joint, correlation)
            if reason is not None:
                split = {"carried": other, "correlation": correlation,
                         "sigmas": coefficient_shift(alone[other], entries[other])[0],
                         "carried_alone": dict(alone[other]["parameters"]),
                         "carried_beside": dict(entries[other]["parameters"])}  # fmt: skip
                out.append({"label": label, "effect": entries[label]["effect"], "joints": [joint + 1],
                            "reason": reason, "split": split})  # fmt: skip
                break
    return out
