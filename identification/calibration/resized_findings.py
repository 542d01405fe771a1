"""A model file's torque findings at the size new recordings give them: the file's entries written again in place.

A finding an earlier ``diagnose --apply`` wrote (a ripple, a spring, a coupling ...) is carried by ``diagnose MODEL``
and fitted again (``diagnosis.carried_sizes`` reads whether its size still holds). Where it does not (a worn gear's
ripple, a spring changed), ``diagnose --apply`` writes the data's size in place of the file's, under the same label
(one entry, never a second one beside it), and leaves everything else the file holds as it is: the model judged is
the model written, and nothing else of the file is identified again on recordings that no longer agree with it.
The entry keeps the file's size it replaced (``RESIZED_KEY``), so the file says what changed and why.

Beside a new finding, ``diagnose --apply`` identifies the file again with it on every training recording, the file's
own among them (``applied_model``, ``refit_training``): refitted there, the carried finding's size would be a blend of
the file's recordings' and the new ones', the change the diagnosis read half undone. So the refit holds it at the
size the diagnosis fitted on its ``--train`` recordings (:func:`held_entries`, ``findings.FindingColumns.held``) and
fits everything else around it; where the gates leave no new finding, the model written is the file resized alone.
"""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.findings import HELD_KEY, FindingTerm, physical_parameters, term_values

__all__ = ["RESIZED_KEY", "at_data_size", "held_entries", "resized_labels", "resized_model"]

#: The key of a resized entry's record: the file's coefficients and parameters it replaced, and why.
RESIZED_KEY = "resized"


def resized_model(calibrated: CalibratedModel, sizes: dict) -> CalibratedModel:
    """``calibrated`` with each torque finding labelled in ``sizes`` (``{label: (coefficients, record)}``) at those
    coefficients, its physical parameters with them, and ``record`` (a dict: why) beside the file's values it replaced
    under ``RESIZED_KEY``. A feature the file holds absorbed (``None``) stays absorbed: another column of the file holds
    its torque. Nothing else changes."""
    document = copy.deepcopy(calibrated.document)
    if document.get("findings"):
        document["findings"] = [_resized(entry, sizes) for entry in document["findings"]]
    return CalibratedModel(document)


def held_entries(terms, entries, sizes) -> tuple:
    """``(terms, entries)`` of a refit with new findings (``applied_model.finding_terms``'s) whose carried findings
    labelled in ``sizes`` are held at the size the diagnosis's recordings give (module docstring): their entries
    resized as :func:`resized_model` writes them and marked ``findings.HELD_KEY`` (the refit takes their torque off
    the training recordings, ``FindingColumns.held``), their terms out of the fitted columns. Refitted on every training
    recording, the file's own among them, the size would be a blend of the file's and the data's."""
    if not sizes:
        return list(terms), list(entries)
    held = [_resized(e, sizes) for e in entries]
    for entry in held:
        if entry.get("kind") == "torque" and entry.get("label") in sizes:
            entry[HELD_KEY] = True
    return [t for t in terms if t.label not in sizes], held


def at_data_size(calibrated: CalibratedModel, sizes: dict, recordings, given, kt=None) -> list:
    """The training recordings of a refit that holds the carried findings in ``sizes`` at the data's size
    (:func:`held_entries`): each of the model file's own (``given`` False: not a ``--train`` recording the diagnosis
    fitted the size on) with the torque that size adds over the file's put on its torque, as if recorded at the new
    size; ``kt`` the torque constants of recordings of currents. The file's size was fitted on those recordings: held
    at the data's size without this, the difference stays in their torque, and the rigid body and the friction of the
    refit take it up (the joint the finding acts on predicted worse than the file). A load-dependent friction (a
    multiple of the model's own torque) is left as it is."""
    entries = {e.get("label"): e for e in calibrated.document.get("findings") or () if e.get("kind") == "torque"}
    changes = [(FindingTerm.from_dict(entries[label]["term"]), [0.0 if o is None else float(n) - o for n, o in
                zip(np.asarray(c, dtype=float), entries[label]["coefficients"])])  # absorbed (None): none held
               for label, (c, _) in sizes.items() if label in entries]  # fmt: skip
    changes = [(term, change) for term, change in changes if not term.load_dependent]
    out = []
    for recording, own in zip(recordings, given):
        if own or not changes:
            out.append(recording)
            continue
        q, t = np.asarray(recording.q, dtype=float), np.asarray(recording.t, dtype=float)
        qd = np.gradient(q, t, axis=0) if recording.qd is None else recording.qd
        qdd = np.gradient(qd, t, axis=0) if recording.qdd is None else recording.qdd
        added = np.zeros(q.shape)
        for term, change in changes:
            added[:, term.joint] += sum(c * v for c, v in zip(change, term_values(term, q, qd, qdd)))
        if recording.tau is not None:
            out.append(replace(recording, tau=np.asarray(recording.tau, dtype=float) + added))
        else:
            out.append(replace(recording, current=np.asarray(recording.current, dtype=float) + added / np.asarray(kt)))
    return out


def _resized(entry: dict, sizes: dict) -> dict:
    """A copy of the findings ``entry`` at its size in ``sizes`` (``resized_model``), or as it is."""
    entry = copy.deepcopy(entry)
    if entry.get("kind") != "torque" or entry.get("label") not in sizes:
        return entry
    coefficients, record = sizes[entry["label"]]
    old = list(entry.get("coefficients") or ())
    new = [None if o is None else float(c) for o, c in zip(old, np.asarray(coefficients, dtype=float))]
    entry[RESIZED_KEY] = {"coefficients": old, "parameters": dict(entry.get("parameters") or {}), **record}
    entry["coefficients"] = new
    term = FindingTerm.from_dict(entry["term"])
    entry["parameters"] = physical_parameters(term, [0.0 if c is None else c for c in new])
    return entry


def resized_labels(before: dict, after: dict) -> tuple:
    """The labels of the torque findings the model-file document ``after`` holds at another size than ``before`` (its
    file) by :func:`resized_model` (the record names ``before``'s own coefficients: not a record an older file
    carries into a refit): written in place, something ``diagnose --apply`` writes although no label is new."""
    old = {e.get("label"): e.get("coefficients") for e in before.get("findings") or ()}
    return tuple(e["label"] for e in after.get("findings") or ()
                 if e.get("label") in old and (e.get(RESIZED_KEY) or {}).get("coefficients") == old[e["label"]]
                 and e.get("coefficients") != old[e["label"]])  # fmt: skip
