"""The "after" of a model file's diagnosis: the model ``diagnose --apply`` writes, judged as ``psdm validate`` does.

The diagnosis selects its findings with a linear fit of its own: the file's rigid body held (or recalibrated without
bounds), the friction refitted without bounds, every kept term added, a pre-sliding friction too, which no model file
holds. Reported as the "after", that fit described a model nobody writes: ``diagnose --apply`` identified the file
again with the findings (``applied_model``), another model, and on a heavy arm wrote a joint at 24.7 N m the report
had shown at 13.7. So the report's "after" of a model file is the model with its findings as
``applied_model.applied_model`` builds it, the one builder ``--apply`` hands to the never-worse gate, evaluated on the
first validation recording by ``finding_value.validation_rmse`` (``psdm validate``'s own path). The report keeps the
model (``DiagnosisReport.applied``) so that ``--apply`` judges and writes that same model, and says which model its
"after" is (``DiagnosisReport.after_source``) and which recordings it trained on (``DiagnosisReport.refit_training``:
the model file's own training recordings found again and the training recording, ``refit_training``, so that the
model keeps what the file's other recordings taught it). Where the model cannot be built (a finding a LuGre file
cannot hold, a fit that fails), the "after" stays the diagnosis's own fit and the report says why.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.calibration.applied_model import AppliedModel, applied_model
from identification.calibration.finding_value import validation_rmse
from identification.calibration.no_gain import GAIN_RULE
from identification.calibration.refit_training import training_alone
from identification.calibration.resized_findings import at_data_size, resized_model
from identification.data.torque_constants import recording_kt
from identification.diagnosis.carried_sizes import resized_sizes, written_sizes
from psdm_casadi.errors import PSDMError

__all__ = [
    "APPLIED_AFTER",
    "NOTHING_APPLIED",
    "RESIZED_AFTER",
    "dropped_text",
    "with_applied_after",
    "with_written_after",
]

logger = logging.getLogger(__name__)

APPLIED_AFTER = (
    "the model file identified again, with the findings it can hold, on its own training recordings and the --train "
    "recordings (each once: the Refit line names them), as 'diagnose --apply' writes it (before its never-worse gate), "
    "judged as 'psdm validate' judges it"
)

#: The "after" of a model file whose findings are its own, some at another size (``carried_sizes``).
RESIZED_AFTER = (
    "the model file with {} at the size the data give, written in place of the file's and nothing refitted, as "
    "'diagnose --apply' writes it (before its never-worse gate), judged as 'psdm validate' judges it"
)
#: How the refit with new findings fits a carried finding whose size the diagnosis read as changed.
HELD_AFTER = (
    "not refitted on the model file's recordings beside them, which would blend the file's size with the data's"
)
#: Why a model file's diagnosis applies nothing although it reports findings (``DiagnosisReport.nothing_applied``).
NOTHING_APPLIED = (
    "every finding ({}) is one the model file holds, none at a size the recordings ask to change: nothing to apply, "
    "so no refit was run and the model file stays the model to use"
)


def with_applied_after(report, loaded, train, validation, refit=None):
    """``report`` whose "after" (RMSE, R^2 and prediction on the validation recording ``validation``) is the model file
    ``loaded`` (``calibrated_model.LoadedModel``) with the report's findings as ``applied_model`` builds it from the
    recordings ``refit()`` finds (``refit_training.RefitTraining``: the file's own training recordings and the raw
    ``train`` recording(s); None: ``train`` alone), with that model in ``DiagnosisReport.applied`` and those
    recordings in ``DiagnosisReport.refit_training`` (module docstring); ``report`` as it is without a finding, and
    with the reason in ``after_source`` where the model cannot be built. ``refit`` is called only when there is a
    finding to apply: one the file does not hold. Where every finding is the file's own, the model is the file with
    the sizes that do not hold written in place (``carried_sizes``, ``resized_findings``: nothing refitted), or, when
    all hold, nothing: ``DiagnosisReport.nothing_applied`` says so and no refit is run. Beside a new finding, the
    refit holds those sizes as the diagnosis fitted them on ``train`` (``resized_findings.held_entries``); where
    ``applied_model`` drops every new finding, the model is again the file with the sizes alone."""
    if not report.findings:
        return report
    calibrated, robot, model = loaded.calibrated, loaded.robot, loaded.model
    labels = {entry.get("label") for entry in calibrated.document.get("findings") or ()}
    new, sizes = [f.label for f in report.findings if f.label not in labels], resized_sizes(report, train)
    if not new and not sizes:
        held = ", ".join(f"`{f.label}`" for f in report.findings)
        return replace(report, nothing_applied=NOTHING_APPLIED.format(held))
    if not new:  # the file with the sizes the data give written in place: judged as it is written
        after = resized_model(calibrated, sizes)
        entries = after.document.get("findings") or []
        applied = AppliedModel(after, None, ([t for t, _ in after.torque_findings], after.corrections, entries))
        resized = ", ".join(f"`{label}`" for label in sizes)
        return written_sizes(_judged(report, applied, robot, model, validation, RESIZED_AFTER.format(resized)))
    training = refit() if refit is not None else training_alone(train)
    report = replace(report, refit_training=training)
    recordings = list(training.recordings)  # the file's own as if at the new sizes (``resized_findings``)
    recordings = at_data_size(calibrated, sizes, recordings, training.given(), recording_kt(robot, *recordings))
    try:  # a carried finding at a new size is held at it (``resized_findings.held_entries``), not refitted
        applied = applied_model(calibrated, robot, model, report, recordings, validation, held=sizes)
    except PSDMError as exc:  # the diagnosis's own fit stays the "after", and the report says why
        logger.info("diagnose: the model with the findings could not be built (%s)", exc)
        return replace(report, after_source=f"the diagnosis's own fit with the findings (the model 'diagnose --apply' "
                                            f"would write could not be built: {exc})")  # fmt: skip
    resized = ", ".join(f"`{label}`" for label in sizes)
    held = f"; {resized} held at the size the --train recordings give ({HELD_AFTER})" if sizes else ""
    source = RESIZED_AFTER.format(resized) if applied.fit is None else APPLIED_AFTER + held
    source += f"; not in it: {dropped_text(applied.dropped)}" if applied.dropped else ""
    return written_sizes(_judged(report, applied, robot, model, validation, source))


def dropped_text(dropped) -> str:
    """The findings ``applied_model`` dropped (its ``dropped`` entries), each with the rule that dropped it: one torque
    it shares with a finding the model keeps (``split_torque``, ``offset_split``: an entry with ``split``), or no
    help on validation."""
    said = []
    for entry in dropped:
        split = entry.get("split") or {}
        kept = split.get("new") if split.get("carried") == entry["label"] else split.get("carried")
        said.append(f"{entry['label']} (one torque with {kept}, which the model keeps)" if split
                    else f"{entry['label']} (no help on validation)")  # fmt: skip
    return ", ".join(said)


def _judged(report, applied, robot, model, validation, source: str):
    """``report`` with ``applied`` (``AppliedModel``) as its "after" on the raw ``validation`` recording, as ``psdm
    validate`` judges it, and ``source`` saying which model that is."""
    try:
        kt = recording_kt(robot, validation)
        rmse, r2, prepared, predicted = validation_rmse(applied.after, model, validation, kt)
    except PSDMError as exc:
        logger.info("diagnose: the model with the findings could not be judged (%s)", exc)
        return replace(report, after_source=f"the diagnosis's own fit with the findings (the model 'diagnose --apply' "
                                            f"would write could not be judged: {exc})")  # fmt: skip
    rmse, r2 = _measured_only(report, rmse, r2)
    same = np.shape(predicted) == np.shape(report.validation_final) and np.allclose(
        np.asarray(prepared.t), np.asarray(report.validation_t), rtol=0.0, atol=1e-9
    )
    final = np.asarray(predicted, dtype=float) if same else report.validation_final
    return replace(report, rmse_after=tuple(rmse.tolist()), r2_after=tuple(r2.tolist()), validation_final=final,
                   applied=applied, after_source=source)  # fmt: skip


def with_written_after(report, result, model, validation, kt=None, written: bool = True):
    """``report`` whose "after" is the model ``diagnose --apply`` writes: ``result`` (``recalibrate.Recalibration``)
    is the never-worse gate's verdict on ``DiagnosisReport.applied``; where the gate dropped findings and refitted, the
    "after" is that refit's on the validation recording ``validation`` (raw), and ``after_source`` names what it
    dropped. A refusal writes nothing: the "after" stays the model the gate refused. ``written`` False: what the gates
    left adds nothing to the model file (``recalibration_text.adds_nothing``), so nothing is written, and
    ``after_source`` says so rather than calling the refit the model written."""
    if result.refused is not None or report.applied is None or result.after is report.applied.after:
        return report
    rmse, r2, _, predicted = validation_rmse(result.after, model, validation, kt)
    rmse, r2 = _measured_only(report, rmse, r2)
    final = np.asarray(predicted, dtype=float)
    final = final if final.shape == np.shape(report.validation_final) else report.validation_final
    block = result.after.document["recalibration"]
    dropped = [entry["label"] for entry in block["never_worse"]["dropped"]]
    no_gain = [entry["label"] for entry in block.get("dropped_findings") or [] if entry.get("no_gain")]
    if not written:
        gates = [f"{', '.join(dropped)} (the never-worse gate)" if dropped else "",
                 f"{', '.join(no_gain)} (no gain)" if no_gain else ""]  # fmt: skip
        left = f"without {' and '.join(filter(None, gates))}, " if dropped or no_gain else ""
        source = (f"{report.after_source}; then {left}the refit adds nothing to the model file, so nothing was "
                  "written: this \"after\" is the model file identified again, and the model file stays the model "
                  "to use")  # fmt: skip
        return replace(report, rmse_after=tuple(rmse.tolist()), r2_after=tuple(r2.tolist()), after_source=source,
                       validation_final=final)  # fmt: skip
    source = (f"{report.after_source}; then without {', '.join(dropped)}, which the never-worse gate dropped (the "
              "model written)") if dropped else report.after_source  # fmt: skip
    source += f"; without {', '.join(no_gain)} (gained nothing: {GAIN_RULE})" if no_gain else ""
    alone = ", ".join(f"`{label}`" for label in block.get("resized_alone") or ())
    source += (f"; no new finding left, so the model written is {RESIZED_AFTER.format(alone)} (the model written)"
               if alone else "")  # fmt: skip
    return replace(report, rmse_after=tuple(rmse.tolist()), r2_after=tuple(r2.tolist()), after_source=source,
                   validation_final=final)  # fmt: skip


def _measured_only(report, rmse, r2) -> tuple:
    """(RMSE, R^2) per joint as float arrays, NaN on the joints the diagnosis did not measure (its own "after" has no
    number there), so that the model's "after" claims no more joints than the report."""
    rmse, r2 = (np.asarray(x, dtype=float).copy() for x in (rmse, r2))
    missing = [j for j in range(rmse.size) if not np.isfinite(report.rmse_after[j])]
    rmse[missing], r2[missing] = np.nan, np.nan
    return rmse, r2
