"""recalibrate(): a diagnosis' findings added to a calibrated model, identified jointly with it.

calibrated model + DiagnosisReport + recordings -> calibrated model with findings (version 2).

The model with the findings is ``applied_model.applied_model``'s, the one builder of the diagnosis's "after" too
(``diagnosis.applied_after``): the recordings-route fit run again on the training recordings (the model file's own
and the diagnosis's, ``refit_training``) with the findings' columns (a LuGre model identified again as ``psdm identify
--friction lugre`` does), the findings that do not lower the validation RMSE where they act dropped. The result is
judged on the validation recording as ``psdm validate`` judges it (the same corrections and preparation,
``CalibratedModel.predict_recording``), before and after, so the file's numbers are what its exported code gives.

Then the never-worse gate (``never_worse.keep_not_worse``, its record in ``recalibration.never_worse``): no joint's
validation RMSE may rise beyond a noise margin (``never_worse.MARGIN_RULE``) where the refits without each training
block (``refit_folds``) reproduce the rise; otherwise findings are dropped and the model refitted, or
``Recalibration.refused`` names the joints and findings and nothing may be written. Of the findings the gate keeps,
a new one that gains nothing is dropped too (``no_gain.keep_earning``, listed in ``dropped_findings`` with its
numbers): one whose model is not below the model without it on its joints in a clear majority of the bootstrap draws
(``no_gain.GAIN_RULE``); the model is refitted without it and the gate asked again.

A carried finding the diagnosis read at a new size (``resized_findings``) is held at it in every refit, and is no
finding the gates drop: it passed its own test (better on each held-out recording, no joint worse). Where the gates
leave no new finding beside it, or refuse every subset, the model written is the file with that size alone, nothing
refitted (``recalibration.resized_alone``), as when the diagnosis found nothing new: the resize is not lost with them.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import logging

import numpy as np

from identification.calibration.applied_model import applied_model, new_labels, refit_options, refit_without
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.consistency import MASS_CHECK_CONFIGURATIONS, consistency_failure, min_mass_eigenvalue
from identification.calibration.dropped_findings import dropped_block
from identification.calibration.finding_value import validation_rmse, without_entry
from identification.calibration.never_worse import keep_not_worse
from identification.calibration.no_gain import keep_earning
from identification.calibration.payload_fit import carried_configurations
from identification.calibration.refit_folds import training_refits
from identification.calibration.resized_findings import resized_labels
from identification.data.torque_constants import recording_kt
from identification.friction.models import LUGRE_PARAMETER_NAMES

__all__ = ["MASS_CHECK_CONFIGURATIONS", "Recalibration", "consistency_failure", "min_mass_eigenvalue", "recalibrate",
           "validation_rmse"]  # fmt: skip

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True, eq=False)
class Recalibration:
    """The calibrated model before and after the findings, with what changed.

    Attributes
    ----------
    before, after : CalibratedModel
    rmse_before, rmse_after : array (n_dof,)
        Validation RMSE [N m] of each model as ``psdm validate`` computes it.
    moved : list of dict
        The base and drive parameters that moved by more than 3 standard deviations (of the new fit).
    min_mass_eigenvalue : float
        Smallest mass-matrix eigenvalue of the new standard parameters over random configurations.
    refused : str or None
        Why no subset of the findings keeps every joint within its noise margin (``never_worse``); the caller
        writes nothing then. None when ``after`` may be written.
    """

    before: CalibratedModel
    after: CalibratedModel
    rmse_before: np.ndarray
    rmse_after: np.ndarray
    moved: list
    min_mass_eigenvalue: float
    refused: str | None = None


def recalibrate(
    calibrated: CalibratedModel,
    robot,
    model,
    report,
    train,
    validation,
    *,
    robot_source=None,
    configurations=None,
    applied=None,
) -> Recalibration:
    """Identify ``calibrated`` again from ``train`` with the findings of ``report``; judge it on ``validation``.

    Parameters
    ----------
    calibrated : CalibratedModel
        The model the diagnosis started from.
    robot, model : RobotDescription, PSDMModel
        ``calibrated.load_robot()`` and its derived model.
    report : DiagnosisReport
        Of ``diagnose`` run with the calibrated model as the nominal one.
    train, validation : Recording or sequence of Recording
        Raw recordings (as given to the diagnosis; ``train`` with the model file's own training recordings,
        ``refit_training``). With ``applied``, its training recordings replace ``train``.
    robot_source : path, optional
        Robot file written into the new model (default: the file's own copy).
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each ``train`` recording states, taken off its torque already (``payload_check.without_load``);
        listed in the new file's ``configurations``, which keeps the model's own (``carried_configurations``).
    applied : AppliedModel, optional
        The model with the findings already built for these recordings (``applied_model``, as the diagnosis of a
        model file builds its "after": ``DiagnosisReport.applied``); built here when None.

    Returns
    -------
    Recalibration

    Raises
    ------
    ParameterError
        When the report has no finding to apply, or findings a LuGre model cannot hold.
    """
    if applied is None:
        applied = applied_model(calibrated, robot, model, report, train, validation, robot_source)
    train = [train] if not isinstance(train, (list, tuple)) else list(train)
    train = list(applied.train) or train  # the recordings the model was built on (``refit_training``): the gate's too
    validation = [validation] if not isinstance(validation, (list, tuple)) else list(validation)
    kt = recording_kt(robot, *validation)
    gate, dropped = _gate(calibrated, robot, model, applied, train, validation, kt, robot_source)
    after = gate.after
    rmse_before, rmse_after = gate.comparison.before, gate.comparison.after
    scores = [validation_rmse(after, model, r, kt) for r in validation]
    mass = _mass(robot, after, gate.payload)
    moved = _moved(calibrated, after)
    document = after.document
    carried = carried_configurations(calibrated.configurations, configurations, [r.name for r in train])
    document.update({"configurations": carried} if carried else {})
    document["validation"] = {
        "recordings": [
            {"recording": r.name, "rmse": _list(s[0]), "r2": _list(s[1])} for r, s in zip(validation, scores)
        ],
        "min_mass_eigenvalue": None if not np.isfinite(mass) else mass,
    }
    document["recalibration"] = {
        "before": {
            "validation_rmse": _list(rmse_before),
            "consistent": calibrated.consistent,
            "min_pseudo_inertia_eigenvalue": calibrated.document["standard"]["min_pseudo_inertia_eigenvalue"],
        },
        "after": {
            "validation_rmse": _list(rmse_after),
            "consistent": after.consistent,
            "min_pseudo_inertia_eigenvalue": document["standard"]["min_pseudo_inertia_eigenvalue"],
        },
        "moved_parameters": moved,
        "dropped_findings": dropped,
        "never_worse": gate.to_dict(),
    }
    alone = resized_labels(calibrated.document, document) if gate.payload is None else ()  # nothing refitted
    document["recalibration"].update({"resized_alone": list(alone)} if alone else {})
    document.pop("diagnosis", None)  # the block describes the diagnosis that wrote this file, not an older one's
    not_written = dropped_block(document["recalibration"], report.findings)  # with why and the diagnosis's hint
    document.update({} if not_written is None else {"diagnosis": not_written})
    for entry in document["findings"]:
        entry["validation_rmse_before"], entry["validation_rmse_after"] = _list(rmse_before), _list(rmse_after)
        if entry["kind"] in ("torque", "signal"):
            without = without_entry(after, entry)
            entry["validation_rmse_without"] = _list(
                np.mean([validation_rmse(without, model, r, kt)[0] for r in validation], axis=0)
            )
    return Recalibration(before=calibrated, after=after, rmse_before=rmse_before, rmse_after=rmse_after, moved=moved,
                         min_mass_eigenvalue=mass, refused=gate.refused)  # fmt: skip


def _gate(calibrated, robot, model, applied, train, validation, kt, robot_source) -> tuple:
    """(``never_worse.GateResult``, the findings dropped) of ``applied``: the never-worse gate with its refits, and
    ``no_gain``'s; a model nothing was refitted for (``AppliedModel.fit`` None: the file with carried findings resized,
    ``resized_findings``) is judged as it is, with nothing to drop."""
    if applied.fit is None:
        return keep_not_worse(calibrated, (applied.after, None), None, [], model, validation, kt), list(applied.dropped)
    terms, corrections, entries = applied.findings
    findings, droppable = (terms, corrections, entries), [t.label for t in terms] + list(corrections)
    refit_on = functools.partial(refit_without, calibrated, robot, model, findings=findings, robot_source=robot_source)
    refits = training_refits(train, refit_on, droppable, refit_options(calibrated).cutoff_hz, validation)
    refit = refit_on(train)
    gate = keep_not_worse(calibrated, (applied.after, applied.fit), refit, droppable, model, validation, kt, refits)
    new = new_labels(calibrated, entries)
    gate, no_gain = keep_earning(calibrated, gate, refit, droppable, new, model, validation, kt, refits)
    return _resized_alone(calibrated, applied, gate, new, (model, validation, kt)), list(applied.dropped) + no_gain


def _resized_alone(calibrated, applied, gate, new, judged):
    """``gate``, or where it leaves none of the ``new`` findings (or refuses every subset) beside carried findings held
    at a new size (``AppliedModel.resized``), the model file with those sizes alone, judged as it is
    (``resized_findings``: nothing refitted, as without a new finding); the gate's record kept, its search saying so.
    """
    if applied.resized is None:
        return gate
    left = {e["label"] for e in gate.after.document.get("findings") or []} & set(new)
    if left and gate.refused is None:
        return gate
    resized = CalibratedModel(copy.deepcopy(applied.resized.document))
    alone = keep_not_worse(calibrated, (resized, None), None, [], *judged)
    if alone.refused is not None or alone.comparison.worse:
        return gate
    said = "refuses every subset of them" if gate.refused is not None else "leaves none of them"
    labels = ", ".join(resized_labels(calibrated.document, resized.document))
    search = (f"{gate.search}; {said} beside {labels} at the size the data give: the model written is the model file "
              "with that size in place and nothing refitted")  # fmt: skip
    return dataclasses.replace(alone, dropped=list(gate.dropped), search=search)


def _mass(robot, after: CalibratedModel, fit) -> float:
    """The smallest mass-matrix eigenvalue of ``after``'s standard parameters (its joint ``fit``'s; without a fit,
    the file's own rigid body: ``after.standard``); NaN when the model is not checked for consistency."""
    if fit is None:
        checked = after.document["standard"].get("checked", True)
        return min_mass_eigenvalue(robot, after.standard) if checked else float("nan")
    return min_mass_eigenvalue(robot, fit.standard) if fit.checked else float("nan")


def _moved(before: CalibratedModel, after: CalibratedModel) -> list:
    """Base, drive (and LuGre) parameters whose change exceeds 3 standard deviations of the new estimate."""
    out = []
    blocks = [before.document[b] for b in ("base", "drive")], [after.document[b] for b in ("base", "drive")]
    if before.lugre_parameters is not None and after.lugre_parameters is not None:  # LuGre: p1, p2, ... per joint
        for document, listed in zip((before.document, after.document), blocks):
            lugre = document["drive"]["lugre"]
            names = [f"{n}{j + 1}" for n in LUGRE_PARAMETER_NAMES for j in range(before.n_dof)]
            values, std = ([v for n in LUGRE_PARAMETER_NAMES for v in part[n]] for part in (lugre, lugre["std"]))
            listed.append({"names": names, "values": values, "std": std})
    for old, new in zip(*blocks):
        for name, a, b, s in zip(new["names"], _values(old, new["names"]), new["values"], new["std"]):
            if a is None or b is None:
                continue
            sigma = s if s is not None and s > 0 else float("inf")
            if abs(b - a) > 3.0 * sigma:
                out.append({"name": name, "before": a, "after": b, "std": s, "sigmas": abs(b - a) / sigma})
    return out


def _values(block: dict, names: list) -> list:
    lookup = dict(zip(block["names"], block["values"]))
    return [lookup.get(name) for name in names]


def _list(values) -> list:
    return [float(v) for v in np.atleast_1d(values)]
