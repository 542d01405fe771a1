"""Findings that earn their place in the model ``diagnose --apply`` writes: a finding with no term in it lowers no
joint's validation RMSE there, so it is dropped, with the numbers, and not written.

model file + the model the never-worse gate kept (its ``JointComparison`` against the file) + the diagnosis's new
findings -> the findings with no gain in the written model, each with its reason.

The never-worse gate (``never_worse.keep_not_worse``) lets through any finding that leaves no joint worse, and so a
finding that changes nothing: on the heavy virtual arm ``--apply`` wrote two pre-sliding frictions (a state of the
friction no model file's torque holds: ``reported``, no column, no correction) while every joint's validation RMSE
stayed exactly the file's. Such a finding contributes nothing to the written model by construction: the model without
it is the same model (no refit needed to know it), whatever the other findings do to its joints. It is dropped, its
reason quoting its joint's validation RMSE, the model file's and the written model's, with the never-worse margin
(``never_worse.MARGIN_RULE``); the diagnosis's report still names it.

A torque or signal finding is not judged here: its column is fitted with the rigid body, and the finding-value check
(``finding_value.unhelpful_findings``: taking it out raises the RMSE where it acts) and the gate judge it. The margin
is too wide to ask of it: on the virtual Denso with a true Stribeck peak on joint 4 (8 s recordings), the refit with
the peak lowers joint 4 from 0.561 to 0.463 N m, inside the paired-bootstrap margin of 0.10 N m (the error sits in
bursts at the reversals, where that standard error overstates the doubt: ``paired_margin.paired_rmse_draws``).

The findings the model file carried already are not judged here: they were judged when they were written.
"""

from __future__ import annotations

from identification.calibration.never_worse import JointComparison

__all__ = ["NO_GAIN", "finding_joints", "gained_joints", "no_gain_findings"]

#: The reason's opening words of a finding with no gain in the written model.
NO_GAIN = "no gain in the written model"


def finding_joints(entry: dict, n_dof: int) -> list:
    """The joints (0-based) a finding entry acts on: a torque term's joint, else the joints it names (every joint
    for a robot-wide one)."""
    if entry.get("kind") == "torque" and entry.get("term"):
        return [int(entry["term"]["joint"]) - 1]
    return [j - 1 for j in entry.get("joints") or []] or list(range(n_dof))


def gained_joints(comparison: JointComparison, joints=None) -> list:
    """The joints (0-based; among ``joints``, default all) whose validation RMSE after is below before less the
    margin."""
    joints = range(len(comparison.after)) if joints is None else joints
    return [j for j in joints if comparison.before[j] - comparison.after[j] > comparison.margin[j]]


def no_gain_findings(comparison: JointComparison, after, labels) -> list:
    """The records of the ``reported`` findings labelled ``labels`` (the diagnosis's new ones) that ``after`` holds
    (module docstring; ``comparison``: the gate's of ``after`` against the model file): label, effect, joints
    (1-based), the RMSE pair on them (the model file's, the written model's), the reason."""
    out = []
    for entry in after.document["findings"]:
        if entry["label"] not in labels or entry["kind"] != "reported":
            continue
        joints = finding_joints(entry, len(comparison.after))
        gained = gained_joints(comparison, joints)
        by_others = f"; joint {gained[0] + 1} is lowered by the other findings" if gained else ""
        out.append({
            "label": entry["label"],
            "effect": entry["effect"],
            "joints": [j + 1 for j in joints],
            "validation_rmse_with": [float(comparison.after[j]) for j in joints],
            "validation_rmse_without": [float(comparison.before[j]) for j in joints],
            "no_gain": True,
            "refitted": False,
            "reason": f"{NO_GAIN}: {comparison.text(joints[:1])} (the model file -> the model written): it has no "
            f"term there (reported only), so the model without it is the same model{by_others}",
        })  # fmt: skip
    return out
