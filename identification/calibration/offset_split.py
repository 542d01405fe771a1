"""A new torque finding that splits the torque of the counterbalance a model carries as its torque offset.

Identify reads a torque offset no sensor has as a counterbalance and, where the spring it tried in the offset's place
does not hold on the held-out motion, keeps the offset as the counterbalance's stand-in (``counterbalance_record``).
``diagnose MODEL`` judges that torque again, names it, and may find the balancer's shape beside it
(``diagnosis.counterbalance_naming.counterbalance_shapes``): the unseen heavy arm's cam came back as a second harmonic
of joint 2's angle once its drive inertia was held with its link. Over the training swing such a shape is mostly a
constant, and the joint refit trades that constant with the offset: the offset moves far beyond its standard
deviation and the shape's torque is its share of the counterbalance's mean with the opposite sign. Neither number is
the counterbalance's; it is one torque written as two, which ``split_torque`` refuses between a carried finding and a
new one.

The rule is ``split_torque``'s, with the model's offset on the joint as the carried finding C and a new torque
finding N on that joint (one without a constant of its own: a spring's constant takes the offset's place,
``findings.offsets_left_to_findings``, and is not beside it):

- their torques, as refitted together, are one shape to the data: the offset's torque is a constant, so their
  correlation is that of N's torque with the constant (``constant_correlation``: its mean over its RMS on the
  training recordings, signed by the offset), beyond ``SPLIT_CORRELATION`` in magnitude; and
- N moves the offset by more than ``SPLIT_SIGMAS`` of its standard deviation (the offset refitted without N against
  beside it, on the same recordings).

Then the model keeps one of the two (``split_torque.one_of_the_two``): the offset, unless N alone (the model refitted
with N and without the offset's column on its joint, ``without_offset``) lowers the joint's validation RMSE against the
offset alone by ``REPLACE_GAIN``; then N replaces the offset and the offset's column is left out of the model. Where
the offset stays and N is a shape of the angle (a ripple) with which the offset predicts the joint better than alone on
every held-out recording (the counterbalance bends over the swing), N is not dropped: the two are written as one
finding, ``counterbalance[jJ]``, its constant and its bend fitted together in the offset's place
(``counterbalance_finding``). Otherwise the one dropped is listed with the offset without and beside N, the
correlation and the joint's validation RMSE with the offset alone, N alone and both.
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.counterbalance_finding import combined_verdict
from identification.calibration.counterbalance_record import counterbalance_offsets
from identification.calibration.finding_value import finding_torques, validation_rmse
from identification.calibration.findings import FindingTerm
from identification.calibration.split_torque import SPLIT_CORRELATION, coefficient_shift, one_of_the_two, split_reason
from identification.calibration.trajectory_data import drive_offset

__all__ = ["HOLDS", "constant_correlation", "offset_entry", "offset_splits", "replaced_offsets", "without_offset"]

#: What a dropped shape's reason adds: the model's offset holds the counterbalance's torque.
HOLDS = (
    "the model's own torque offset on its joint holds its torque: it is the counterbalance identify kept as the "
    "offset, and this finding its shape, one counterbalance, not two findings sharing its torque"
)


def constant_correlation(torque, offset: float) -> float:
    """The correlation of a finding's ``torque`` (training samples) with the constant torque of an ``offset`` [N m]:
    the torque's mean over its RMS, signed by the offset (1 in magnitude: a constant; 0: a torque of mean zero)."""
    torque = np.asarray(torque, dtype=float)
    size = float(np.sqrt(np.mean(torque**2)))
    return float(np.sign(offset) * np.mean(torque) / size) if size > 0.0 else 0.0


def offset_entry(calibrated: CalibratedModel, joint: int) -> dict:
    """The torque offset of ``calibrated`` on the 0-based ``joint`` as a finding entry (``split_torque``'s
    ``coefficient_shift`` and ``split_reason`` read it): its drive column's name, value and standard deviation."""
    drive = calibrated.document["drive"]
    name, names = f"offset{joint + 1}", list(drive["names"])
    value = drive_offset(drive["values"], names, joint)
    std = (drive.get("std") or [None] * len(names))[names.index(name)] if name in names else None
    return {"label": name, "effect": "torque_offset", "feature_names": [name], "coefficients": [value], "std": [std],
            "parameters": {"offset": value}}  # fmt: skip


def without_offset(calibrated: CalibratedModel, joint: int) -> CalibratedModel:
    """``calibrated`` whose refits fit no torque offset on the 0-based ``joint`` (its ``column_choice`` offsets
    without it, the value 0): the model a shape replacing the offset is refitted from."""
    document = copy.deepcopy(calibrated.document)
    choice = document["identification"].setdefault("column_choice", {})
    request = choice.setdefault("request", {})
    every = [int(name[6:]) - 1 for name in document["drive"]["names"] if name[6:].isdigit() and name[:6] == "offset"]
    chosen = [j - 1 for j in choice["offset_joints"]] if request.get("offset", "on") == "auto" else every
    request["offset"], choice["offset_joints"] = "auto", sorted({j + 1 for j in chosen if j != joint})
    drive = document["drive"]
    if f"offset{joint + 1}" in drive["names"]:
        drive["values"][drive["names"].index(f"offset{joint + 1}")] = 0.0
    return CalibratedModel(document)


def replaced_offsets(calibrated: CalibratedModel, dropped) -> CalibratedModel:
    """``calibrated`` without the offsets a shape replaced (``dropped`` entries labelled ``offset<j>`` by
    ``offset_splits``): the model the findings are refitted from after the split."""
    for entry in dropped:
        if entry.get("split", {}).get("carried") == entry["label"] and entry["label"].startswith("offset"):
            calibrated = without_offset(calibrated, int(entry["joints"][0]) - 1)
    return calibrated


def offset_splits(before: CalibratedModel, after: CalibratedModel, refit, alone, model, recordings, kt=(None, None)):
    """The findings to drop where a new torque finding of ``after`` splits the torque of the counterbalance ``before``
    carries as its torque offset on that joint (module docstring), as ``split_torque.splitting_findings`` lists them
    (the shape, with ``HOLDS``; or the offset ``offset<j>`` where the shape replaces it).

    ``refit(labels)`` -> (CalibratedModel, payload): the joint refit without the findings labelled ``labels``;
    ``alone(joint)`` -> (CalibratedModel, payload): the joint refit with every finding and without the offset on the
    0-based ``joint``. A shape the offset keeps is not dropped where the two together bend
    (``counterbalance_finding.combined_verdict``): the entry then names the one counterbalance (``combined``) that
    ``applied_model`` writes in their place. ``recordings`` = (training, validation) raw, ``kt`` their torque
    constants. At most one split per call (the caller refits and asks again)."""
    (train, validation), (kt_train, kt_validation) = recordings, kt
    joints = {j for j in counterbalance_offsets(before.document) if offset_entry(after, j)["coefficients"][0] != 0.0}
    carried = {e["label"] for e in before.document.get("findings") or []}
    new = {e["label"] for e in after.document["findings"]
           if e.get("kind") == "torque" and e["label"] not in carried and (e.get("term") or {}).get("effect")
           != "torque_offset" and int(e["term"]["joint"]) - 1 in joints}  # fmt: skip
    torques = finding_torques(after, model, train, kt_train, labels=new) if new else {}
    entries = {e["label"]: e for e in after.document["findings"]}
    for label, (joint, tau) in torques.items():
        beside = offset_entry(after, joint)
        correlation = constant_correlation(tau, beside["coefficients"][0])
        if not abs(correlation) > SPLIT_CORRELATION:
            continue
        without_new = refit([label])[0]
        carried_alone = offset_entry(without_new, joint)
        reason = split_reason(carried_alone, beside, joint, correlation)
        if reason is None:
            continue
        split = {"new": label, "carried": beside["label"], "correlation": correlation,
                 "sigmas": coefficient_shift(carried_alone, beside)[0],
                 "carried_alone": carried_alone["parameters"], "carried_beside": beside["parameters"]}  # fmt: skip
        models = (without_new, alone(joint)[0], after)  # the offset alone, the new finding alone, both
        each = [[validation_rmse(m, model, r, kt_validation)[0][joint] for r in validation] for m in models]
        rmse = [float(np.mean(x)) for x in each]
        verdict = one_of_the_two(split, rmse, joint, reason, {**entries, beside["label"]: beside})
        term = FindingTerm.from_dict(entries[label]["term"])
        joined = combined_verdict(verdict, term, each[0], each[2])  # the offset and its shape as one counterbalance
        if joined is None and verdict["label"] == label:
            verdict["reason"] += f"; {HOLDS}"
        return [joined or verdict]
    return []
