"""The friction of a training recording identify did not see, on the joints whose friction drifted between identify's
recordings: what a refit (``refit_training``) needs to move that recording's torque to the friction the model keeps,
as it moves the model file's own recordings (``drift_correction``).

identify's check fitted each of its training recordings' friction beside one shared rigid body (``friction_drift``);
the model file records those fits, not a way to fit a new recording in the same system. A recording handed to
``diagnose MODEL --train A B`` that is not one of the file's is fitted here beside the model file itself, which
stands in for the check's shared part (rigid body, offsets, drive inertias, the findings it holds): on each drifting
joint ``j``, the coefficients ``b`` of the check's friction columns ``D_j(qd)`` that fit
``tau_j - (prediction_j - D_j b_model)`` by least squares, on the recording prepared as the model prepares it
(``CalibratedModel.predict_recording``), ``b_model`` the model's own friction on that joint. The correction then
moves the recording by ``D_j (b - b_kept)`` as it moves identify's recordings: one taken in the conditions the model
keeps is hardly moved (its ``b`` is the kept friction within noise), one taken cold by its own friction change.

Where the model's friction is not in the check's columns (a LuGre model, a file without the drifting joint's
coefficients), the recording cannot be fitted this way: the reason is returned and the refit's note says the
recording keeps its own friction.
"""

from __future__ import annotations

import numpy as np

__all__ = ["new_recording_friction"]

#: Fewest measured samples per friction coefficient for a recording's friction on a joint to be fitted.
SAMPLES_PER_COEFFICIENT = 20


def new_recording_friction(correction, drive, prepared, predicted) -> tuple:
    """``(rows, "")``: the friction of a recording identify did not see on each of ``correction``'s drifting joints
    (one row per ``DriftCorrection.joints`` entry, as its ``names``; NaN where the recording does not measure the
    joint's torque), for ``DriftCorrection.with_recording``; or ``(None, why not)`` (module docstring).

    ``drive`` is the model file's ``drive`` block (its friction's names and values); ``prepared`` and ``predicted``
    the recording as the model prepares it and the model's torque on it [N m] (``CalibratedModel.predict_recording``).
    """
    if drive.get("friction_shape") == "lugre" or drive.get("lugre"):
        return None, "the model's friction is LuGre, not the drift check's columns"
    names, values = list(drive.get("names") or []), list(drive.get("values") or [])
    tau, predicted = np.asarray(prepared.tau, dtype=float), np.asarray(predicted, dtype=float)
    rows = []
    for shift in correction.joints:
        absent = [name for name in shift.names if name not in names]
        if absent:
            return None, f"the model file holds no {', '.join(absent)} (the drift check's friction columns)"
        model = np.array([float(values[names.index(name)]) for name in shift.names])
        j, columns = shift.joint, correction.columns(shift, prepared.qd)
        measured = np.isfinite(tau[:, j]) & np.isfinite(predicted[:, j])
        if measured.sum() < SAMPLES_PER_COEFFICIENT * len(shift.names):
            rows.append(np.full(len(shift.names), np.nan))
            continue
        target = tau[measured, j] - predicted[measured, j] + columns[measured] @ model
        rows.append(np.linalg.lstsq(columns[measured], target, rcond=None)[0])
    return rows, ""
