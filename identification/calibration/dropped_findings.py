"""The findings a diagnosis found that ``diagnose --apply`` did not write, recorded in the model file it wrote with why
and what to do about each, so that every later reader of that file can name them.

the written model's ``recalibration`` block (the gates' records: ``dropped_findings``, ``never_worse.dropped``) + the
diagnosis's findings (their explanations) -> the model file's ``diagnosis`` block::

    {"version": DIAGNOSIS_VERSION, "dropped": [{"label", "effect", "joints", "reason", "hint"}, ...]}

A finding the written model cannot hold (a pre-sliding friction: a state of the friction that only a LuGre model
file holds) is dropped as having no gain in it (``no_gain``), and its route (``psdm identify --friction lugre``) was
then only in the diagnosis's report, gone once the report was closed. The ``hint`` is the diagnosis's own
explanation of the finding, which names that route; the ``reason`` the gate's. ``psdm validate`` of the file prints
one note per entry (:func:`dropped_notes`). The block describes the diagnosis that wrote the file: a file written
without a dropped finding has none (an older file's is not carried over). Optional and versioned on its own:
older files have none and read as none; older readers ignore it.
"""

from __future__ import annotations

__all__ = ["DIAGNOSIS_VERSION", "dropped_block", "dropped_notes"]

#: The version of the ``diagnosis`` block (1: ``dropped`` with label, effect, joints, reason, hint).
DIAGNOSIS_VERSION = 1


def dropped_block(recalibration: dict, findings) -> dict | None:
    """The ``diagnosis`` block of a model written by ``diagnose --apply`` from its ``recalibration`` block and the
    diagnosis's ``findings`` (``DiagnosisReport.findings``: label, effect, 0-based joints, explanation); None when
    no finding was dropped."""
    records = [*(recalibration.get("dropped_findings") or []),
               *((recalibration.get("never_worse") or {}).get("dropped") or [])]  # fmt: skip
    found = {f.label: f for f in findings}
    out, seen = [], set()
    for record in records:
        label = str(record.get("label"))
        if label in seen:
            continue
        seen.add(label)
        finding = found.get(label)
        joints = record.get("joints") or ([j + 1 for j in finding.joints] if finding is not None else [])
        out.append({
            "label": label,
            "effect": record.get("effect") or getattr(finding, "effect", None),
            "joints": [int(j) for j in joints],
            "reason": str(record.get("reason") or ""),
            "hint": str(getattr(finding, "explanation", "") or ""),
        })  # fmt: skip
    return {"version": DIAGNOSIS_VERSION, "dropped": out} if out else None


def dropped_notes(document) -> list:
    """One sentence per finding the diagnosis that wrote the model file ``document`` dropped (its ``diagnosis``
    block; none in a file without one): the label, why it is not in the model, and the diagnosis's hint."""
    block = (document or {}).get("diagnosis")
    if not isinstance(block, dict):
        return []
    notes = []
    for entry in block.get("dropped") or []:
        if not isinstance(entry, dict):
            continue
        hint = f"; found as: {entry['hint']}" if entry.get("hint") else ""
        notes.append(f"the diagnosis that wrote this model found {entry.get('label')} and did not write it "
                     f"({entry.get('reason') or 'dropped'}){hint}")  # fmt: skip
    return notes
