"""What a finding of a recalibrated model is worth on the validation recording.

The validation RMSE of a calibrated model as ``psdm validate`` computes it (``validation_rmse``), the model with
one finding taken out and nothing refitted (``without_entry``), and the findings that do not lower the validation
RMSE where they act (``unhelpful_findings``), which ``recalibrate`` drops (issue 16: a finding is kept only if it
lowers the validation RMSE of every joint it names).
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.diagnosis.candidates import MAX_LOAD_FRICTION
from identification.metrics import r2, rmse

__all__ = ["implausibility", "unhelpful_findings", "validation_rmse", "without_entry"]


def validation_rmse(calibrated: CalibratedModel, model, recording, kt=None) -> tuple:
    """(RMSE, R^2, prepared recording, prediction) of a calibrated model on a raw recording, as ``psdm validate``.

    The prediction is ``CalibratedModel.predict_recording``'s: the model's measurement corrections applied to the
    raw recording, then the identification's preparation; a LuGre model's bristle state carried from the raw start
    along the corrected recording.
    """
    prepared, predicted = calibrated.predict_recording(model, recording, kt)
    return rmse(prepared.tau, predicted), r2(prepared.tau, predicted), prepared, predicted


def _judged(entry: dict, with_it, without) -> bool:
    """Whether taking a finding out raises the validation RMSE where it acts: the joint a torque finding acts on
    (a coupling names its source joint too), each joint a joint-level correction names, and the overall
    validation error (sum of squares over the named joints) for a robot-wide correction (a delay)."""
    joints = entry["joints"] or list(range(1, len(with_it) + 1))
    if entry["kind"] == "torque":
        joints = [int(entry["term"]["joint"])]
    elif entry["effect"] == "delay":
        index = [j - 1 for j in joints]
        return float(np.sum(without[index] ** 2)) > float(np.sum(with_it[index] ** 2))
    return all(without[j - 1] > with_it[j - 1] for j in joints)


def implausibility(entry: dict) -> str | None:
    """Why a refitted finding's coefficients are physically meaningless, or None: a load-dependent friction
    coefficient outside (0, MAX_LOAD_FRICTION) (a gear efficiency below 50 %, or friction that falls with the
    load), a negative rotor inertia. The diagnosis applies the same bounds when it selects the finding; the joint
    refit with the rigid body can move the coefficient out of them."""
    values = [c for c in entry.get("coefficients") or [] if c is not None]
    if entry.get("kind") != "torque" or not values:
        return None
    if entry["effect"] == "load_dependent_friction" and not 0.0 < values[0] < MAX_LOAD_FRICTION:
        return f"refitted friction coefficient mu = {values[0]:.3g} outside (0, {MAX_LOAD_FRICTION})"
    if entry["effect"] == "rotor_inertia" and values[0] < 0.0:
        return f"refitted rotor inertia {values[0]:.3g} kg m^2 is negative"
    return None


def unhelpful_findings(after: CalibratedModel, model, validation, kt) -> list:
    """The torque and signal findings whose refitted coefficients are physically meaningless (``implausibility``)
    or whose removal (no refit) does not raise the validation RMSE where they act (``_judged``), with the RMSE pair
    that shows it. A torque finding whose features were all absorbed by the fit's other columns contributes
    nothing by construction and is kept (reported as absorbed), not judged. Implausible findings are returned
    alone when there are any: the others are judged again once those are gone."""
    reasons = [(e, implausibility(e)) for e in after.document["findings"]]
    implausible = [
        {"label": e["label"], "effect": e["effect"], "joints": list(e["joints"] or []), "reason": reason}
        for e, reason in reasons
        if reason is not None
    ]
    if implausible:
        return implausible
    with_it = np.mean([validation_rmse(after, model, r, kt)[0] for r in validation], axis=0)
    out = []
    for entry in after.document["findings"]:
        if entry["kind"] not in ("torque", "signal"):
            continue
        if entry["kind"] == "torque" and all(c is None for c in entry["coefficients"]):
            continue
        without = np.mean([validation_rmse(without_entry(after, entry), model, r, kt)[0] for r in validation], axis=0)
        if _judged(entry, with_it, without):
            continue
        joints = entry["joints"] or list(range(1, len(with_it) + 1))
        out.append(
            {
                "label": entry["label"],
                "effect": entry["effect"],
                "joints": list(joints),
                "validation_rmse_with": [float(with_it[j - 1]) for j in joints],
                "validation_rmse_without": [float(without[j - 1]) for j in joints],
                "reason": "taking it out does not raise the validation RMSE where it acts",
            }
        )
    return out


def without_entry(calibrated: CalibratedModel, entry: dict) -> CalibratedModel:
    """The model with one finding's torque (or correction) taken out and nothing refitted: what it contributes."""
    document = copy.deepcopy(calibrated.document)
    document["findings"] = [e for e in document["findings"] if e["label"] != entry["label"]]
    document["corrections"] = {k: v for k, v in (document.get("corrections") or {}).items() if k != entry["label"]}
    return CalibratedModel(document)
