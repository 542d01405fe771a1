"""Whether a model file's carried torque findings still hold at the file's size, read as ``file_offsets`` reads offsets.

``diagnose MODEL`` carries every torque finding the file holds (``carried_terms``): a column of the nominal model,
its coefficients fitted again. A finding found again under the file's own label is the file's, so ``diagnose
--apply`` added nothing and a real change of its size (a worn gear's ripple, a spring changed) was never written.
Each carried finding is therefore read (:func:`with_carried_sizes`) against the file's size:

- the size fitted again differs from the file's beyond the file's uncertainty (some coefficient more than
  ``MOVED_SIGMAS`` of the file's standard deviations away: the rule of ``recalibrate``'s moved parameters; with no
  standard deviation in the file, the recordings below decide alone), AND
- the file with that size in place of its own (``resized_findings.resized_model``, nothing refitted) predicts each
  held-out recording better on a joint the finding names beyond the paired noise margin, with no joint worse beyond
  it (``never_worse.compare_each``, ``better_on_each``):

then the file's size does not hold: the finding is a correction of the file's value (``Finding.correction``, "the
model file's `X` is off by ..., written as ..."), which ``diagnose --apply`` writes in place of the file's (the same
label, one entry). Otherwise the file's size holds, and the report's note says so with both numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.findings import FindingTerm, physical_parameters
from identification.calibration.never_worse import better_on_each, compare_each
from identification.calibration.resized_findings import resized_model
from identification.data.torque_constants import recording_kt
from identification.diagnosis.carried_terms import KEPT_NOTE

__all__ = ["HOLDS", "MOVED_SIGMAS", "RESIZED", "CarriedSize", "resized_sizes", "with_carried_sizes", "written_sizes"]

#: Standard deviations of the file's coefficient a carried finding's size must move by to be read as changed.
MOVED_SIGMAS = 3.0
#: What the recordings say of a carried finding's size (module docstring).
RESIZED, HOLDS = "resized", "holds"


@dataclass(frozen=True)
class CarriedSize:
    """A carried finding ``label`` (``joints`` 0-based) at the file's size and at the size fitted again.

    ``name`` the parameter the sentence states (a ripple's amplitude, a spring's k, a coupling's viscous), ``file`` and
    ``data`` its two values, ``coefficients`` the coefficients fitted again; ``sigmas`` the largest change of a
    coefficient in the file's standard deviations (NaN: the file states none); ``readings`` per held-out recording
    ``(name, joint, RMSE with the file's size, RMSE with the data's, margin)`` on the joint the finding improves most
    there [N m]; ``better`` the joints better on each recording, ``worse`` ``(recording, joint)`` worse beyond the
    margin; ``verdict`` ``RESIZED`` or ``HOLDS``; ``written`` what ``diagnose --apply`` writes (NaN: not known)."""

    label: str
    joints: tuple
    name: str
    file: float
    data: float
    coefficients: tuple
    sigmas: float
    readings: tuple
    better: tuple
    worse: tuple
    verdict: str
    written: float = float("nan")

    def why(self) -> str:
        """The numbers the verdict rests on."""
        moved = f"{self.sigmas:.1f} standard deviations of the file's" if np.isfinite(self.sigmas) else (
            "the file states no standard deviation")  # fmt: skip
        each = "; ".join(f"{n}: joint {j + 1} {a:.4g} -> {b:.4g} N m (margin {m:.2g})"
                         for n, j, a, b, m in self.readings)  # fmt: skip
        worse = "; ".join(f"{n} joint {j + 1}" for n, j in self.worse)
        worse = f"; worse beyond the margin: {worse}" if worse else ""
        return (
            f"{self.name} {self.file:.4g} in the file, {self.data:.4g} fitted again on the --train recordings "
            f"({moved}); validation RMSE with the file's size -> with the data's: {each}{worse}"
        )

    def sentence(self) -> str:
        """The report's note (its rigid-body notes), and a resized finding's correction."""
        if self.verdict == RESIZED:
            written = f"{self.written:.4g}" if np.isfinite(self.written) else f"{self.data:.4g} (fitted again)"
            return (f"the model file's `{self.label}` is off by {self.data - self.file:+.4g} ({self.why()}): better on "
                    f"each held-out recording beyond the margin and no joint worse, so 'diagnose --apply' writes "
                    f"{self.name} as {written} in place of the file's (the same label; held there in a refit with new "
                    "findings)")  # fmt: skip
        return (f"the model file's `{self.label}` holds at its size ({self.why()}): kept at the file's "
                f"{self.name} {self.file:.4g}")  # fmt: skip

    def to_dict(self) -> dict:
        return {"label": self.label, "joints": [j + 1 for j in self.joints], "parameter": self.name,
                "file": self.file, "data": self.data, "coefficients": list(self.coefficients),
                "sigmas": None if not np.isfinite(self.sigmas) else self.sigmas,
                "recordings": [{"name": n, "joint": j + 1, "rmse_file": a, "rmse_data": b, "margin": m}
                               for n, j, a, b, m in self.readings],
                "better_joints": [j + 1 for j in self.better], "worse": [[n, j + 1] for n, j in self.worse],
                "verdict": self.verdict,
                "written": None if not np.isfinite(self.written) else self.written}  # fmt: skip


def resized_sizes(report, train=()) -> dict:
    """``{label: (coefficients, record)}`` of the report's carried findings whose size does not hold
    (``resized_findings.resized_model``'s ``sizes``): the size the diagnosis fitted on its training recordings
    ``train`` (raw; named in the record's ``fitted_on``), which ``diagnose --apply`` writes, and holds in a refit with
    new findings (``resized_findings.held_entries``)."""
    train = [train] if not isinstance(train, (list, tuple)) else list(train)
    names = [r.name or f"recording {k + 1}" for k, r in enumerate(train)]
    return {s.label: (s.coefficients, {"by": "diagnose --apply", "why": s.why(), "fitted_on": names})
            for s in report.carried_sizes if s.verdict == RESIZED}  # fmt: skip


def with_carried_sizes(report, loaded, validation):
    """``report`` with each carried finding the model file ``loaded`` holds under the same label (and the same
    features) read against the file's size on the raw ``validation`` recordings (module docstring): its
    ``CarriedSize`` in ``DiagnosisReport.carried_sizes``, its note in the rigid-body notes, and a resized one's
    sentence as its ``correction``."""
    calibrated = loaded.calibrated
    entries = {e.get("label"): e for e in calibrated.document.get("findings") or () if e.get("kind") == "torque"}
    kt = recording_kt(loaded.robot, *validation)
    read = {}
    for finding in report.findings:
        entry = entries.get(finding.label)
        if finding.shape_note != KEPT_NOTE or entry is None:
            continue
        if not _same_columns(entry, finding):
            continue  # not the file's columns (a term stated otherwise): nothing to compare
        read[finding.label] = _read(finding, entry, loaded, validation, kt)
    if not read:
        return report
    findings = tuple(replace(f, correction=read[f.label].sentence()) if f.label in read and
                     read[f.label].verdict == RESIZED else f for f in report.findings)  # fmt: skip
    notes = tuple(report.rigid_body_notes) + tuple(s.sentence() for s in read.values() if s.verdict == HOLDS)
    return replace(report, findings=findings, rigid_body_notes=notes, carried_sizes=tuple(read.values()))


def _read(finding, entry, loaded, validation, kt) -> CarriedSize:
    """The ``CarriedSize`` of one carried ``finding`` beside the file's ``entry``."""
    old = np.array([np.nan if c is None else c for c in entry["coefficients"]], dtype=float)
    std = np.array([np.nan if s is None else s for s in entry.get("std") or [None] * old.size], dtype=float)
    new = np.asarray(finding.coefficients, dtype=float)
    stated = np.isfinite(old) & np.isfinite(std) & (std > 0)
    sigmas = float(np.max(np.abs(new - old)[stated] / std[stated])) if np.any(stated) else float("nan")
    moved = not np.isfinite(sigmas) or sigmas > MOVED_SIGMAS
    resized = resized_model(loaded.calibrated, {finding.label: (new, {})})
    comparisons = compare_each(loaded.calibrated, resized, loaded.model, validation, kt)
    better = better_on_each(comparisons, finding.joints)
    worse = tuple((r.name or f"recording {k + 1}", j) for k, (r, c) in enumerate(zip(validation, comparisons))
                  for j in c.worse)  # fmt: skip
    shown = better[0] if better else finding.joints[0]
    readings = tuple((r.name or f"recording {k + 1}", shown, float(c.before[shown]), float(c.after[shown]),
                      float(c.margin[shown])) for k, (r, c) in enumerate(zip(validation, comparisons)))  # fmt: skip
    name = _parameter(entry, finding)
    file_value = float((entry.get("parameters") or {}).get(name, np.nan))
    data = float(finding.parameters.get(name, np.nan))
    verdict = RESIZED if moved and better and not worse else HOLDS
    return CarriedSize(finding.label, tuple(finding.joints), name, file_value, data, tuple(float(c) for c in new),
                       sigmas, readings, better, worse, verdict)  # fmt: skip


def _same_columns(entry, finding) -> bool:
    """Whether ``finding``'s coefficients are those of the file's ``entry`` (the same columns in the same order and
    convention): as many, and the file's term reads from them the physical parameters the diagnosis states (each
    family names its columns its own way: ``ripple_sin6_2`` in the file, ``ripple_sin6_q2`` in the library)."""
    new = np.asarray(finding.coefficients, dtype=float)
    if len(entry.get("coefficients") or ()) != new.size or "term" not in entry:
        return False
    read = physical_parameters(FindingTerm.from_dict(entry["term"]), new)
    shared = [n for n in read if n in finding.parameters]
    return bool(shared) and all(np.isclose(float(read[n]), float(finding.parameters[n]), rtol=1e-6, atol=1e-12)
                                for n in shared)  # fmt: skip


def _parameter(entry, finding) -> str:
    """The parameter the sentence states: the first of the file's entry's the diagnosis's finding states too (a
    spring's k, a ripple's amplitude, a coupling's viscous)."""
    stated = entry.get("parameters") or {}
    return next((n for n in ("k", "amplitude", "viscous") if n in stated and n in finding.parameters), None) or next(
        (n for n in stated if n in finding.parameters), "size"
    )


def written_sizes(report):
    """``report`` whose resized carried findings say the size ``diagnose --apply`` writes: their parameter in the
    model of ``DiagnosisReport.applied`` (the file resized in place, or refitted with new findings, which holds the
    resized ones at the data's size), each correction's sentence with it."""
    if not any(s.verdict == RESIZED for s in report.carried_sizes) or report.applied is None:
        return report
    entries = {e.get("label"): e for e in report.applied.after.document.get("findings") or ()}
    sizes = tuple(replace(s, written=float((entries.get(s.label) or {}).get("parameters", {}).get(s.name, np.nan)))
                  if s.verdict == RESIZED else s for s in report.carried_sizes)  # fmt: skip
    said = {s.label: s.sentence() for s in sizes if s.verdict == RESIZED}
    findings = tuple(replace(f, correction=said[f.label]) if f.label in said else f for f in report.findings)
    return replace(report, carried_sizes=sizes, findings=findings)
