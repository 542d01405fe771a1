"""Findings that earn their place in the model ``diagnose --apply`` writes: each new finding must lower the validation
error of its joint against the model without it, or it is dropped with its numbers and not written.

model file + the never-worse gate's verdict (``never_worse.GateResult``) + the refit without given findings + the
validation recordings -> the verdict without the findings that gained nothing (``keep_earning``), and their records
(``FindingGain.record``).

The never-worse gate (``never_worse.keep_not_worse``) lets through any finding that leaves no joint worse, and so a
finding that gains nothing: a pre-sliding friction (``reported``: no model file's torque holds it) beside every
joint's RMSE unchanged on the heavy virtual arm, or a torque term fitted to the noise of the training recording. The
rule (``GAIN_RULE``), the same for a torque term, a signal correction and a reported finding: a new finding is written
only if, on at least one joint it acts on and on each validation recording, the written model's RMSE is below that of
the model without it in at least ``GAIN_SHARE`` of the circular block bootstrap draws of their paired difference
(``paired_margin.share_lower``, as ``presliding_or_elasticity`` judges an elasticity against pre-sliding). A finding
with no term (``reported``), or whose every feature the fit's other columns absorbed, leaves the model the same without
it: lower in 0 % of the draws, dropped without a refit.

Why the share of the draws, not the never-worse margin: on the virtual Denso with a true Stribeck peak on joint 4 (4 s
sine recordings, ``tests/.../test_friction_shape_finding.py``), the refit with the peak lowers joint 4 from 0.682 to
0.552 N m, inside a paired-bootstrap margin of 0.16 N m: the error sits in bursts at the reversals, where the draws
are skewed and their standard error overstates the doubt; the peak is lower in 95 % of the draws. Why ``GAIN_SHARE``
is 0.9, a clear majority rather than the 97.7 % (two standard errors) asked of an elasticity: without an effect behind
a finding the share is about uniform on (0, 1) (the measured difference's z-score is about standard normal, the share
its normal probability), so one false finding in ten passes one validation recording and one in a hundred two, while
a true effect measured on a short recording gets few bootstrap blocks (``block_length``: at most a fifth of it) and a
coarse share. On the virtual Denso with a spring on joint 2 (8 s sine recordings, six seeds) the true spring was lower
in every draw each time, and 17 findings forced on it with no effect behind them that the gate let through (springs
on joints 3, 5 and 6, a torque ripple, torque offsets, a Stribeck peak on joint 2) lay between 0 and 92 %, one of
them at 90 % or more.

Why against the model refitted without it, not the model file: the written model is fitted with every finding's
column beside the rigid body, so the model without a finding is another fit, which the gate's ``refit`` gives (the
findings it dropped left out too); taking the column out without a refit leaves the hole the other parameters made
room for, and a finding of noise would look like a gain. Against the model file, one finding would take the credit
of another on its joint (a pre-sliding beside a true spring on joint 2).

Not judged here: the findings the model file carried already (judged when they were written), and a payload (kind
``rigid_body``): the refit without it puts the load back into the last links' parameters, so its RMSE gain is not its
worth; what it adds is a plausible rigid body (``carried_payload``).

The findings that gained nothing are dropped together; when one of them had a term, the model is refitted without
them and the never-worse gate asked again about the refit (it may drop more, or refuse), and the findings left are
judged again, until every finding left has gained. A written finding keeps its numbers (its entry's ``gain``). When
none is left, ``diagnose --apply`` has nothing to apply.
"""

from __future__ import annotations

import copy
import dataclasses
import logging

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.finding_value import validation_rmse, without_entry
from identification.calibration.never_worse import keep_not_worse
from identification.paired_margin import share_lower

__all__ = ["GAIN_KEYS", "GAIN_RULE", "GAIN_SHARE", "NO_GAIN", "FindingGain", "finding_gain", "finding_joints",
           "keep_earning"]  # fmt: skip

logger = logging.getLogger(__name__)

#: The reason's opening words of a finding dropped by ``GAIN_RULE``.
NO_GAIN = "gained nothing"
#: Share of the bootstrap draws in which a finding must lower its joint: a clear majority (module docstring).
GAIN_SHARE = 0.9
#: The keys of ``FindingGain.record`` a written finding's entry keeps as its ``gain``.
GAIN_KEYS = ("joints", "share_lower", "validation_rmse_with", "validation_rmse_without", "refitted")
GAIN_RULE = (
    "a new finding is written only if, on at least one joint it acts on and on each validation recording, the model "
    f"written has a lower RMSE than the model without it in at least {GAIN_SHARE:.0%} of the circular block bootstrap "
    "draws of their paired difference"
)


@dataclasses.dataclass(frozen=True, eq=False)
class FindingGain:
    """One new finding of the written model against the model without it, on its joints.

    Attributes
    ----------
    label, effect : str
    joints : tuple of int
        The joints (0-based) it acts on (``finding_joints``).
    shares : array (n_recordings, n_joints)
        Per validation recording and joint of ``joints``, the share of the bootstrap draws in which the written model's
        RMSE is below the model's without it (NaN where the recording has no torque on the joint).
    rmse_with, rmse_without : array (n_joints,)
        The mean over the validation recordings of each model's RMSE [N m] on ``joints``.
    refitted : bool
        Whether the model without it is a refit (False: the finding has no term, the model without it is the same).
    """

    label: str
    effect: str
    joints: tuple
    shares: np.ndarray
    rmse_with: np.ndarray
    rmse_without: np.ndarray
    refitted: bool

    @property
    def share(self) -> np.ndarray:
        """Per joint of ``joints``, the smallest share over the validation recordings that hold its torque (NaN when
        none does): a finding must gain on each."""
        held = np.isfinite(self.shares)
        return np.where(held.any(axis=0), np.where(held, self.shares, np.inf).min(axis=0), np.nan)

    @property
    def gained(self) -> bool:
        """``GAIN_RULE``: lower in at least ``GAIN_SHARE`` of the draws on one of its joints; a finding none of whose
        joints any recording measures cannot be judged and is kept."""
        share = self.share
        return bool(np.all(np.isnan(share)) or np.any(share >= GAIN_SHARE))

    def reason(self) -> str:
        """``gained nothing on joint 4: lower in 12 % of draws (0.47 N m with it, 0.47 without ...)``."""
        best = int(np.nanargmax(self.share)) if np.any(np.isfinite(self.share)) else 0
        joint, others = self.joints[best] + 1, len(self.joints) - 1
        if not self.refitted:  # the Panda's pre-sliding read "gained nothing: lower in 0% of draws" beside its 42 %
            return (f"{NO_GAIN} in the model written: it holds no torque there (a finding reported, not applied, or "
                    "one the fit's other columns absorbed), so the model with it is the model without it (validation "
                    f"RMSE on joint {joint} {self.rmse_with[best]:.4g} N m either way); the gain the diagnosis "
                    "reports for it is not one a model file can hold")  # fmt: skip
        elsewhere = f" (its best of {others + 1} joints)" if others else ""
        return (f"{NO_GAIN} on joint {joint}: lower in {self.share[best]:.0%} of draws{elsewhere}; validation RMSE "
                f"{self.rmse_with[best]:.4g} N m with it, {self.rmse_without[best]:.4g} N m without it (the model "
                f"refitted without it); {GAIN_RULE}")  # fmt: skip

    def record(self) -> dict:
        """The ``recalibration.dropped_findings`` entry: label, effect, joints (1-based), the RMSE pair on them, the
        share per joint, whether the model was refitted without it, the reason."""
        return {"label": self.label, "effect": self.effect, "joints": [j + 1 for j in self.joints],
                "validation_rmse_with": [float(v) for v in self.rmse_with],
                "validation_rmse_without": [float(v) for v in self.rmse_without],
                "share_lower": [None if not np.isfinite(v) else float(v) for v in self.share],
                "gain_share": GAIN_SHARE, "no_gain": True, "refitted": self.refitted,
                "reason": self.reason()}  # fmt: skip


def finding_joints(entry: dict, n_dof: int) -> list:
    """The joints (0-based) a finding entry acts on: a torque term's joint, else the joints it names (every joint
    for a robot-wide one)."""
    if entry.get("kind") == "torque" and entry.get("term"):
        return [int(entry["term"]["joint"]) - 1]
    return [j - 1 for j in entry.get("joints") or []] or list(range(n_dof))


def holds_nothing(entry: dict) -> bool:
    """Whether a finding holds no torque in its model: reported only, or a torque term whose every feature the fit's
    other columns absorbed."""
    absorbed = entry["kind"] == "torque" and all(c is None for c in entry.get("coefficients") or [None])
    return entry["kind"] == "reported" or absorbed


def finding_gain(entry: dict, written: CalibratedModel, without: CalibratedModel, model, validation, kt=None):
    """The ``FindingGain`` of ``entry`` (a finding of ``written``) against ``without`` (the model without it) on the raw
    ``validation`` recordings, each model prepared as its own file says (``finding_value.validation_rmse``)."""
    shares, with_it, without_it = [], [], []
    for recording in validation:  # both on the raw recording's time grid: the prepared samples are the same instants
        error_w, _, ready_w, predicted_w = validation_rmse(written, model, recording, kt)
        error_o, _, ready_o, predicted_o = validation_rmse(without, model, recording, kt)
        residual_w, residual_o = ready_w.tau - predicted_w, ready_o.tau - predicted_o
        joints, row = finding_joints(entry, len(error_w)), []
        for j in joints:
            n = min(len(residual_w), len(residual_o))
            pair = np.column_stack([residual_o[:n, j], residual_w[:n, j]])
            pair = pair[np.all(np.isfinite(pair), axis=1)]
            row.append(float(share_lower(pair[:, :1], pair[:, 1:])[0]) if len(pair) else np.nan)
        shares.append(row)
        with_it.append(np.asarray(error_w)[joints])
        without_it.append(np.asarray(error_o)[joints])
    return FindingGain(label=entry["label"], effect=entry["effect"], joints=tuple(joints), shares=np.array(shares),
                       rmse_with=np.nanmean(with_it, axis=0), rmse_without=np.nanmean(without_it, axis=0),
                       refitted=without is not written and not holds_nothing(entry))  # fmt: skip


def keep_earning(before, gate, refit, droppable, new, model, validation, kt=None, refits=None) -> tuple:
    """(gate, records): the never-worse ``gate``'s verdict on the findings ``before`` lacked without the new ones
    (labels ``new``) that gained nothing (module docstring), and their ``FindingGain.record``s.

    ``refit``, ``droppable``, ``refits`` are the gate's (``never_worse.keep_not_worse``): ``refit(labels)`` the model
    without the findings ``labels``; ``droppable`` the labels of the findings with a term or a correction."""
    records, gone = [], {d["label"] for d in gate.dropped}
    cache = {}

    def without(labels):
        key = frozenset(labels)
        if key not in cache:
            cache[key] = refit(sorted(key))
        return cache[key]

    while gate.refused is None:  # each round drops one finding or more: at most as many rounds as new findings
        gains = []
        for entry in gate.after.document["findings"]:
            if entry["label"] not in new or entry["kind"] not in ("torque", "signal", "reported"):
                continue
            other = without_entry(gate.after, entry) if holds_nothing(entry) else without(gone | {entry["label"]})[0]
            gains.append((entry, finding_gain(entry, gate.after, other, model, validation, kt)))
        lost = [g for _, g in gains if not g.gained]
        if not lost:
            for entry, gain in gains:  # the written findings' own numbers
                entry["gain"] = {key: gain.record()[key] for key in GAIN_KEYS}
            break
        logger.info("diagnose --apply: %s", "; ".join(f"{g.label}: {g.reason()}" for g in lost))
        records += [g.record() for g in lost]
        labels = {g.label for g in lost}
        gone |= labels  # a later refit leaves them out too
        if not any(g.refitted for g in lost):  # nothing with a torque: the model is the same without them
            document = copy.deepcopy(gate.after.document)
            document["findings"] = [e for e in document["findings"] if e["label"] not in labels]
            gate = dataclasses.replace(gate, after=CalibratedModel(document))
            continue
        gate = _gate_again(before, gate, without, gone, droppable, model, validation, kt, refits)
        gone |= {d["label"] for d in gate.dropped}
    return gate, records


def _gate_again(before, gate, without, gone, droppable, model, validation, kt, refits):
    """The never-worse gate on the refit without ``gone``, its own drops added to ``gate``'s."""
    gone = frozenset(gone)
    left = [label for label in droppable if label not in gone]
    relative = dataclasses.replace(
        refits, refit=lambda labels, k: refits.refit(sorted(set(labels) | gone), k), models={},
        baseline=tuple(label for label in refits.baseline if label not in gone)
    ) if refits is not None else None  # fmt: skip
    again = keep_not_worse(before, without(gone), lambda labels: without(gone | set(labels)), left, model,
                           validation, kt, relative)  # fmt: skip
    return dataclasses.replace(again, dropped=list(gate.dropped) + list(again.dropped))
