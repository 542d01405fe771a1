"""A model file's torque findings at the size new recordings give them: the file's entries written again in place.

A finding an earlier ``diagnose --apply`` wrote (a ripple, a spring, a coupling ...) is carried by ``diagnose MODEL``
and fitted again (``diagnosis.carried_sizes`` reads whether its size still holds). Where it does not (a worn gear's
ripple, a spring changed), ``diagnose --apply`` writes the data's size in place of the file's, under the same label
(one entry, never a second one beside it), and leaves everything else the file holds as it is: the model judged is
the model written, and nothing else of the file is identified again on recordings that no longer agree with it.
The entry keeps the file's size it replaced (``RESIZED_KEY``), so the file says what changed and why.
"""

from __future__ import annotations

import copy

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.findings import FindingTerm, physical_parameters

__all__ = ["RESIZED_KEY", "resized_labels", "resized_model"]

#: The key of a resized entry's record: the file's coefficients and parameters it replaced, and why.
RESIZED_KEY = "resized"


def resized_model(calibrated: CalibratedModel, sizes: dict) -> CalibratedModel:
    """``calibrated`` with each torque finding labelled in ``sizes`` (``{label: (coefficients, record)}``) at those
    coefficients, its physical parameters with them, and ``record`` (a dict: why) beside the file's values it replaced
    under ``RESIZED_KEY``. A feature the file holds absorbed (``None``) stays absorbed: another column of the file holds
    its torque. Nothing else changes."""
    document = copy.deepcopy(calibrated.document)
    for entry in document.get("findings") or []:
        if entry.get("kind") != "torque" or entry.get("label") not in sizes:
            continue
        coefficients, record = sizes[entry["label"]]
        old = list(entry.get("coefficients") or ())
        new = [None if o is None else float(c) for o, c in zip(old, np.asarray(coefficients, dtype=float))]
        entry[RESIZED_KEY] = {"coefficients": old, "parameters": dict(entry.get("parameters") or {}), **record}
        entry["coefficients"] = new
        term = FindingTerm.from_dict(entry["term"])
        entry["parameters"] = physical_parameters(term, [0.0 if c is None else c for c in new])
    return CalibratedModel(document)


def resized_labels(before: dict, after: dict) -> tuple:
    """The labels of the torque findings the model-file document ``after`` holds at another size than ``before`` (its
    file) by :func:`resized_model` (the record names ``before``'s own coefficients: not a record an older file
    carries into a refit): written in place, something ``diagnose --apply`` writes although no label is new."""
    old = {e.get("label"): e.get("coefficients") for e in before.get("findings") or ()}
    return tuple(e["label"] for e in after.get("findings") or ()
                 if e.get("label") in old and (e.get(RESIZED_KEY) or {}).get("coefficients") == old[e["label"]]
                 and e.get("coefficients") != old[e["label"]])  # fmt: skip
