"""A model file's drive-inertia columns ``Ia<j>`` fitted again in every fit of ``diagnose MODEL``, as its friction is.

Identify fits a drive inertia outside the base parameters as a column of its own (``separate_inertia``). Whatever
torque of the joint's acceleration the model lacks, that column takes: a torque ripple periodic in the joint angle
projects onto ``qdd_j`` on a periodic trajectory (the belt cobot of ``benchmarks/unseen_belt_cobot.py``: its joint 6's
7-per-turn ripple took the file's ``Ia6`` to 3.7 times the belt's reflected inertia; without the ripple identify gets
it within 10 %). Held at the file's value in every fit of the diagnosis (``held_friction.without_held_rotors``), that
share stayed in the drive inertia once the diagnosis found the ripple, and an unnamed sparse term (``qdd6`` among its
features) took it back: a false finding beside the true one.

So the diagnosis's nominal model keeps each of the file's drive columns (held at the file's value, so that a
recalibrated rigid body keeps it) and carries beside it a free ``rotor_inertia`` column on its joint
(``DiagnosisOptions.carried``, ``carried_terms``): its coefficient, the change of the file's value, is fitted again
with the friction in every fit, and the library offers no other rotor inertia on that joint. It is a parameter of
the model file, not a finding: :func:`without_drive_columns` takes it out of the report's findings and says in the
report's rigid-body notes what the file holds and what the data want beside the findings (``diagnose --apply``'s
refit identifies the drive columns again anyway, ``applied_after``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.trajectory_data import drive_column_joint
from identification.diagnosis.candidates import RotorInertiaTerm

__all__ = ["drive_column_terms", "refitted_drive_inertias", "with_drive_columns", "without_drive_columns"]


def drive_column_terms(document: dict) -> tuple:
    """The free ``rotor_inertia`` column of each drive-inertia column ``Ia<j>`` of a model file's ``document`` (its
    ``drive.names``), in joint order."""
    names = document.get("drive", {}).get("names", ())
    joints = sorted({drive_column_joint(n) for n in names if n.startswith("Ia") and n[2:].isdigit()})
    return tuple(RotorInertiaTerm(joint=j) for j in joints)


def with_drive_columns(options, document: dict):
    """``options`` (``DiagnosisOptions``) carrying the file's drive columns (:func:`drive_column_terms`) after what it
    carries already; unchanged when the file has none or they are carried."""
    labels = {term.label for term in options.carried}
    terms = tuple(term for term in drive_column_terms(document) if term.label not in labels)
    return replace(options, carried=tuple(options.carried) + terms) if terms else options


def refitted_drive_inertias(report, document: dict) -> dict:
    """{``Ia<j>``: (the file's value, the value fitted again) [kg m^2]} of the drive columns ``report``'s final model
    carried (:func:`with_drive_columns`): the file's value plus the carried column's coefficient in the augmented
    model (the model the report's findings are fitted in)."""
    labels = {term.label for term in drive_column_terms(document)}
    drive = dict(zip(document["drive"]["names"], document["drive"]["values"]))
    augmented = report.augmented
    out = {}
    for term, coefficients in zip(augmented.terms, augmented.coefficients) if augmented is not None else ():
        if term.label in labels:
            name = f"Ia{term.joint + 1}"
            held = float(drive.get(name, 0.0))
            out[name] = (held, held + float(np.asarray(coefficients, dtype=float).ravel()[0]))
    return out


def without_drive_columns(report, document: dict):
    """``report`` (``DiagnosisReport``) without the findings of the carried drive columns (:func:`with_drive_columns`),
    a rigid-body note saying per joint the file's drive inertia and the value the data want beside the findings
    (:func:`refitted_drive_inertias`)."""
    labels = {term.label for term in drive_column_terms(document)}
    kept = tuple(f for f in report.findings if not (f.label in labels and f.effect == "rotor_inertia"))
    if len(kept) == len(report.findings):
        return report
    values = refitted_drive_inertias(report, document)
    parts = "; ".join(f"{name} {held:.4g} in the file, {fitted:.4g} kg m^2 fitted again"
                      for name, (held, fitted) in values.items())  # fmt: skip
    note = ("the model file's drive inertias outside the base parameters (its drive columns) are fitted again with the "
            f"friction in every fit of the diagnosis, as identify fits them, not findings: {parts}")  # fmt: skip
    return replace(report, findings=kept, rigid_body_notes=tuple(report.rigid_body_notes) + (note,))
