"""A model file's data-chosen torque offsets fitted again in every fit of ``diagnose MODEL``, beside its held value.

Identify chooses a joint's torque offset from the data (``column_choice``, ``--offset auto``) on a fit without the
effects the diagnosis looks for, so the offset takes the mean of whatever torque the model lacks over the recorded
range. Held at the file's value in every fit of the diagnosis, that share stays in it once the diagnosis finds the
effect, and a term with a constant of its own takes it back: a virtual SCARA whose joint 1 carries a ripple,
identified over a range where the ripple's mean is not zero (the file's offset that mean), was diagnosed with a
high-order spring in the ripple's place.

So the nominal model holds the file's value and carries beside it a free ``torque_offset`` column on its joint
(:func:`offset_terms`, ``DiagnosisOptions.carried``, ``carried_terms``), fitted again with the friction in every fit,
the library offering no other offset there (and a spring there no constant of its own, ``CarriedColumns.shaped``).
What it fits is how far the file's offset is off, a parameter of the file, not a finding. :func:`with_file_offsets`
reads it on every recording (``recording_checks.RecordingCheck``: the offset the joint's mean residual leaves there)
and says in the report's notes what the file holds and what each recording wants; then:

- where the refitted value lowers the joint's validation RMSE against the file's by the selection's
  ``min_improvement`` on every validation recording, the file's offset does not hold: a correction of the file's value
  with both numbers (``Finding.correction``, ``report_assembly.held_offset_correction``), which ``diagnose --apply``
  writes, never a missing effect, and never silent however far off the file's value is;
- where the recordings disagree (the refitted value passes that gate on one recording and not on another, or is
  worse than the file's by as much on one), the offset moves between recordings: stated with its numbers, not missing
  physics and not a correction;
- otherwise the file's offset holds, and the note says so.

A spring on the joint takes the offset as its constant (``CarriedColumns.with_constants``), as ``diagnose --apply``
leaves it to the spring (``findings.offsets_left_to_findings``). Offsets identify read as no sensor's
(``counterbalance_record``) are not held at all (``model_file.file_held``) and not carried.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from identification.calibration.counterbalance_record import counterbalance_offsets
from identification.calibration.trajectory_data import drive_offset
from identification.diagnosis.candidates import TorqueOffsetTerm

__all__ = [
    "CORRECTION",
    "HOLDS",
    "MOVES",
    "SPRING",
    "FileOffset",
    "file_offset_joints",
    "offset_terms",
    "read_offset",
    "with_file_offsets",
    "with_offset_columns",
]


def file_offset_joints(document: dict) -> tuple:
    """0-based joints whose nonzero torque offset identify chose from the data (``column_choice``: the request
    ``--offset auto``, the joints in ``offset_joints``), but those identify read as no sensor's
    (``counterbalance_record``, not held)."""
    choice = (document.get("identification") or {}).get("column_choice") or {}
    if (choice.get("request") or {}).get("offset", "on") != "auto":
        return ()
    drive = document.get("drive") or {}
    aside = set(counterbalance_offsets(document))
    joints = [int(j) - 1 for j in choice.get("offset_joints") or ()]
    return tuple(j for j in joints if j not in aside
                 and drive_offset(drive.get("values") or [], drive.get("names") or [], j) != 0.0)  # fmt: skip


def offset_terms(document: dict) -> tuple:
    """The free ``torque_offset`` column of each of a model file's data-chosen offsets (:func:`file_offset_joints`)."""
    return tuple(TorqueOffsetTerm(joint=j) for j in file_offset_joints(document))


#: What the recordings say of a carried offset (module docstring).
CORRECTION, MOVES, HOLDS, SPRING = "correction", "moves", "holds", "spring"


@dataclass(frozen=True)
class FileOffset:
    """A model file's data-chosen torque offset on ``joint`` (0-based) fitted again beside its held value [N m].

    ``held`` the file's value, ``refitted`` the training recordings' (held plus the free column's fit); ``readings``
    ``(recording name, the joint's whole offset there, the refitted value's validation gain against the file's)`` per
    validation recording (the offset the final model's mean residual on the joint leaves there, and ``1 -
    RMSE(refitted) / RMSE(file's value)`` on the joint); ``verdict`` one of ``CORRECTION``, ``MOVES``, ``HOLDS`` or
    ``SPRING`` (left to the constant of the spring ``label``)."""

    joint: int
    held: float
    refitted: float
    readings: tuple
    verdict: str
    label: str = ""

    def sentence(self) -> str:
        """The report's note (its rigid-body notes)."""
        j = self.joint + 1
        if self.verdict == SPRING:
            return (f"the model file's torque offset on joint {j} ({self.held:+.4g} N m, chosen from the data) is left "
                    f"to `{self.label}`'s constant, fitted with it (its rest angle read from the file's offset plus "
                    "the refitted part), as 'diagnose --apply' leaves it to the spring")  # fmt: skip
        each = "; ".join(f"{name} {value:+.4g} N m (gain of the refitted value {gain:.0%})"
                         for name, value, gain in self.readings)  # fmt: skip
        said = (f"the model file's torque offset on joint {j} (chosen from the data) is held at its value with a "
                "free offset beside it, fitted again with the friction in every fit of the diagnosis: the file holds "
                f"{self.held:+.4g} N m, the training recordings' is {self.refitted:+.4g} N m; the validation "
                f"recordings': {each}")  # fmt: skip
        verdicts = {
            CORRECTION: f"the file's value does not hold: a correction of it, not a missing effect (`{self.label}`)",
            MOVES: "it differs between the recordings beyond what one constant holds (a zero that drifts, or a torque "
            "of the state the offset stands in for): not missing physics, and no correction the recordings agree on",
            HOLDS: "the file's value holds on these recordings",
        }
        return f"{said}: {verdicts[self.verdict]}"

    def to_dict(self) -> dict:
        return {
            "joint": self.joint + 1,
            "file": self.held,
            "refitted": self.refitted,
            "recordings": [{"name": n, "offset": v, "gain": g} for n, v, g in self.readings],
            "verdict": self.verdict,
            "label": self.label,
        }


def with_offset_columns(options, document: dict):
    """``options`` (``DiagnosisOptions``) carrying the free column of each of the file's data-chosen offsets
    (:func:`offset_terms`) after what it carries already; unchanged when the file has none or they are carried."""
    labels = {term.label for term in options.carried}
    terms = tuple(term for term in offset_terms(document) if term.label not in labels)
    return replace(options, carried=tuple(options.carried) + terms) if terms else options


def read_offset(report, finding, held: float, min_improvement: float) -> FileOffset:
    """The ``FileOffset`` of a carried offset's ``finding`` in ``report`` beside the file's ``held`` value: its
    readings on every validation recording (``report.recordings``) and the verdict (module docstring) by the
    selection's ``min_improvement``."""
    j = finding.joints[0]
    refitted = held + float(finding.coefficients[0])
    readings = []
    for check in report.recordings:
        verdict = next((v for v in check.findings if v.label == finding.label), None)
        if verdict is None:
            continue
        gain = 1.0 - float(verdict.rmse_with[0]) / max(float(verdict.rmse_without[0]), 1e-300)
        mean = float(check.mean_after[j]) if len(check.mean_after) > j else 0.0
        readings.append((check.name, refitted + mean, gain))
    gains = [gain for _, _, gain in readings]
    verdict = HOLDS
    if gains and all(g >= min_improvement for g in gains):
        verdict = CORRECTION
    elif any(abs(g) >= min_improvement for g in gains):
        verdict = MOVES
    return FileOffset(j, held, refitted, tuple(readings), verdict, finding.label)


def with_file_offsets(report, document: dict, min_improvement: float):
    """``report`` (``DiagnosisReport``) with each carried offset (:func:`offset_terms`) read as the module docstring
    says (``DiagnosisReport.file_offsets``, and a note each in its rigid-body notes): kept among the findings as a
    correction of the file's value where it does not hold, taken out otherwise. ``min_improvement``: the selection's
    (``DiagnosisOptions``)."""
    labels = {term.label for term in offset_terms(document)}
    drive = document.get("drive") or {}
    names, values = drive.get("names") or [], drive.get("values") or []
    springs = {f.joints[0]: f.label for f in report.findings if f.effect == "spring" and len(f.joints) == 1}
    findings, read = [], []
    for finding in report.findings:
        if finding.label not in labels:  # a carried offset stays a torque_offset (never named a counterbalance)
            findings.append(finding)
            continue
        j = finding.joints[0]
        held = drive_offset(values, names, j, required=True)
        if j in springs:
            read.append(FileOffset(j, held, held + float(finding.coefficients[0]), (), SPRING, springs[j]))
            continue
        read.append(read_offset(report, finding, held, min_improvement))
        if read[-1].verdict == CORRECTION:
            findings.append(replace(finding, shape_note=""))
    if not read:
        return report
    notes = tuple(report.rigid_body_notes) + tuple(r.sentence() for r in read)
    return replace(report, findings=tuple(findings), rigid_body_notes=notes, file_offsets=tuple(read))
