"""What a finding of a recalibrated model is worth on the validation recording.

The validation RMSE of a calibrated model as ``psdm validate`` computes it (``validation_rmse``), the model with
one finding taken out and nothing refitted (``without_entry``), and the findings that do not lower the validation
RMSE where they act (``unhelpful_findings``), which ``recalibrate`` drops (issue 16: a finding is kept only if it
lowers the validation RMSE of every joint it names).

Two torque findings on one joint whose torques cancel each other (``cancelling_findings``: anti-correlated beyond
``CANCEL_CORRELATION`` and together less than ``CANCEL_SHARE`` of the smaller) are not physics but a nearly collinear
pair fitted with huge opposite coefficients: a torque ripple a diagnosis found beside the spring the model file
carries came out as k = -6.8e4 N m/rad against a ripple of 3.5e4 N m (issue 25). The newer of the two (later in the
file's findings: the file's own come first) is dropped and the older refitted alone.
"""

from __future__ import annotations

import copy
import itertools

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.metrics import r2, rmse
from identification.physical_bounds import MAX_LOAD_FRICTION, POSITIVE_FRICTION_SHAPES

__all__ = [
    "CANCEL_CORRELATION",
    "CANCEL_SHARE",
    "cancelling_findings",
    "cancelling_pairs",
    "finding_torques",
    "implausibility",
    "unhelpful_findings",
    "validation_rmse",
    "without_entry",
]

#: Two findings' torques on one joint cancel when their correlation is below this ...
CANCEL_CORRELATION = -0.9
#: ... and the RMS of their sum is below this share of the smaller one's RMS.
CANCEL_SHARE = 0.5


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
    """Why a refitted finding's coefficients are physically meaningless, or None: a load-dependent friction coefficient
    outside (0, MAX_LOAD_FRICTION) (a gear efficiency below 50 %, or friction that falls with the load), a negative
    rotor inertia, a Stribeck peak not above the Coulomb level, a smooth Coulomb friction not above zero (friction
    falling with speed: a Stribeck peak's shape, ``FrictionShapeTerm.implausibility``; the positive shapes are
    ``physical_bounds.POSITIVE_FRICTION_SHAPES``). The diagnosis applies the
    same bounds when it selects the finding; the joint refit with the rigid body can move the coefficient out of
    them."""
    values = [c for c in entry.get("coefficients") or [] if c is not None]
    if entry.get("kind") != "torque" or not values:
        return None
    if entry["effect"] == "load_dependent_friction" and not 0.0 < values[0] < MAX_LOAD_FRICTION:
        return f"refitted friction coefficient mu = {values[0]:.3g} outside (0, {MAX_LOAD_FRICTION})"
    if entry["effect"] == "rotor_inertia" and values[0] < 0.0:
        return f"refitted rotor inertia {values[0]:.3g} kg m^2 is negative"
    shape = entry["term"]["spec"].get("shape") if entry["effect"] == "friction_shape" else None
    if shape in POSITIVE_FRICTION_SHAPES and values[0] <= 0.0:
        if shape == "stribeck":
            return f"refitted Stribeck peak {values[0]:.3g} N m is not above the Coulomb level"
        return f"refitted smooth Coulomb friction {values[0]:.3g} N m is not above zero (a Stribeck peak's shape)"
    return None


def unhelpful_findings(after: CalibratedModel, model, validation, kt) -> list:
    """The torque and signal findings whose refitted coefficients are physically meaningless (``implausibility``)
    or whose removal (no refit) does not raise the validation RMSE where they act (``_judged``), with the RMSE pair
    that shows it. A torque finding whose features were all absorbed by the fit's other columns contributes
    nothing by construction and is kept (reported as absorbed), not judged. Implausible findings are returned
    alone when there are any, then cancelling ones (``cancelling_findings``): the others are judged again once those
    are gone."""
    reasons = [(e, implausibility(e)) for e in after.document["findings"]]
    implausible = [
        {"label": e["label"], "effect": e["effect"], "joints": list(e["joints"] or []), "reason": reason}
        for e, reason in reasons
        if reason is not None
    ]
    if implausible:
        return implausible
    cancelling = cancelling_findings(after, model, validation[0], kt)
    if cancelling:
        return cancelling
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


def cancelling_findings(after: CalibratedModel, model, recording, kt=None) -> list:
    """The newer finding of each pair of torque findings on one joint whose torques on ``recording`` cancel
    (``cancelling_pairs``; each one's torque as ``finding_torques`` gives it)."""
    entries = [e for e in after.document["findings"]
               if e["kind"] == "torque" and any(c is not None for c in e["coefficients"])]  # fmt: skip
    if len(entries) < 2:
        return []
    torques = finding_torques(after, model, [recording], kt)
    effects = {e["label"]: e["effect"] for e in entries}
    return [{**d, "effect": effects[d["label"]]} for d in cancelling_pairs([(k, *v) for k, v in torques.items()])]


def finding_torques(calibrated: CalibratedModel, model, recordings, kt=None, labels=None) -> dict:
    """``{label: (0-based joint, torque array)}`` of the fitted torque findings (those labelled ``labels``, default
    every one with a fitted coefficient), in the file's order: each one's torque on its joint is the model's
    prediction less the prediction without it, on ``recordings`` (raw, prepared as the model's) one after another."""
    entries = [e for e in calibrated.document["findings"]
               if e["kind"] == "torque" and any(c is not None for c in e["coefficients"])
               and (labels is None or e["label"] in labels)]  # fmt: skip
    if not entries:
        return {}
    full = [validation_rmse(calibrated, model, r, kt)[3] for r in recordings]
    out = {}
    for entry in entries:
        joint = int(entry["term"]["joint"]) - 1
        without = [validation_rmse(without_entry(calibrated, entry), model, r, kt)[3] for r in recordings]
        out[entry["label"]] = (joint, np.concatenate([f[:, joint] - w[:, joint] for f, w in zip(full, without)]))
    return out


def cancelling_pairs(torques) -> list:
    """``[{"label", "joints", "reason"}, ...]``: of ``torques`` = ``[(label, 0-based joint, torque array), ...]`` in
    the order the findings were added, the newer of each pair on one joint anti-correlated beyond
    ``CANCEL_CORRELATION`` whose sum's RMS is below ``CANCEL_SHARE`` of the smaller one's (module docstring)."""
    out, dropped = [], set()
    for (older, j, a), (newer, k, b) in itertools.combinations(torques, 2):
        if j != k or older in dropped or newer in dropped:
            continue
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        ra, rb, rs = (float(np.sqrt(np.mean(x**2))) for x in (a, b, a + b))
        if min(ra, rb) <= 0.0 or rs >= CANCEL_SHARE * min(ra, rb):
            continue
        correlation = float(np.corrcoef(a, b)[0, 1])
        if correlation < CANCEL_CORRELATION:
            dropped.add(newer)
            out.append({"label": newer, "joints": [j + 1],
                        "reason": f"cancels {older} on joint {j + 1} (torque RMS {rb:.4g} and {ra:.4g} N m, together "
                        f"{rs:.4g} N m; correlation {correlation:.3f}): two findings fitted to cancel each other are "
                        f"not physics; {older} refitted without it"})  # fmt: skip
    return out
