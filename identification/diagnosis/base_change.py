"""A rotor inertia inside the base parameters of a model file: a change of those parameters, not missing physics.

A joint's drive inertia ``Ia_j qdd_j`` whose column lies in the span of the base regressor (the first joint's, about a
vertical axis, adds to its link's Izz; ``merged_rotors.merged_rotor_map``) is held by the base parameters of any model
that identifies them. A model file's rigid body is identified: a ``rotor_inertia`` its diagnosis finds there, with the
file's rigid body held, says that the data want those base parameters elsewhere (the belt cobot of
``benchmarks/unseen_belt_cobot.py``: the consistent fit left its joint-1 parameter 0.16 below the least squares' on
its own training data, and the diagnosis, the pre-sliding of joint 1 taken out, wanted 0.24 more), not that the model
lacks a term; ``diagnose --apply`` identifies the rigid body again. So :func:`as_base_changes` takes such a finding
out of the report's findings and says in its rigid-body notes which base parameters it moves and by how much. A robot
file's diagnosis keeps it (``report_assembly.with_rotor_note``: what the robot file lacks).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.merged_rotors import merged_rotor_map

__all__ = ["as_base_changes", "base_changes"]

#: Base parameters a note lists per finding, largest change first.
LISTED = 3


def base_changes(findings, robot, model) -> dict:
    """{label: (joint (0-based), inertia [kg m^2], ((base parameter name, change), ...))} of the ``rotor_inertia``
    ``findings`` on one joint each whose drive inertia lies inside ``model``'s base parameters (``merged_rotor_map`` on
    ``robot``'s random states): the base parameters it moves, largest change first (``LISTED``)."""
    out = {}
    for finding in findings:
        if finding.effect != "rotor_inertia" or len(finding.joints) != 1:
            continue
        j = int(finding.joints[0])
        coefficients = merged_rotor_map(model, robot, [j]).get(j)
        if coefficients is None:
            continue
        inertia = float(finding.coefficients[0])
        change = inertia * np.asarray(coefficients, dtype=float)
        order = [k for k in np.argsort(-np.abs(change)) if change[k] != 0.0][:LISTED]
        out[finding.label] = (j, inertia, tuple((str(model.base_names[k]), float(change[k])) for k in order))
    return out


def as_base_changes(report, robot, model):
    """``report`` (a ``DiagnosisReport`` of a model file's rigid body, held) without its ``rotor_inertia`` findings
    inside the base parameters (:func:`base_changes`), each said as a change of those parameters in the rigid-body
    notes."""
    changes = base_changes(report.findings, robot, model)
    if not changes:
        return report
    notes = []
    for label, (j, inertia, moved) in changes.items():
        listed = ", ".join(f"{name} {change:+.4g}" for name, change in moved)
        notes.append(f"`{label}` ({inertia:.4g} kg m^2) is no missing physics: joint {j + 1}'s drive inertia lies "
                     f"inside the base parameters, which the model file identified, so the data want those elsewhere "
                     f"({listed}); 'diagnose --apply' identifies the rigid body again")  # fmt: skip
    kept = tuple(f for f in report.findings if f.label not in changes)
    return replace(report, findings=kept, rigid_body_notes=tuple(report.rigid_body_notes) + tuple(notes))
