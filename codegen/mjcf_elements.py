"""The MJCF pieces of a calibrated model that the generated and the copied MJCF share (``mjcf_export``).

Per joint the calibrated attributes (:class:`JointFields`: armature, damping, frictionloss, stiffness and springref,
and the note of what MJCF cannot hold), per body the ``<inertial>`` of an identified body, and the header comment.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

import numpy as np

from codegen.target_holds import (
    MJCF,
    drive_inertias,
    drive_terms,
    findings_left_out,
    findings_not_representable,
    friction_left_out,
    friction_not_representable,
    linear_springs,
)
from codegen.xml_nodes import numbers
from identification.calibration.coulomb_width import approximated_widths, tanh_text
from psdm_casadi.oracle import inertia_from_dynamic_parameters
from psdm_casadi.values import exact_text

__all__ = ["MIN_BODY", "JointFields", "header_text", "inertial_attributes", "joint_attributes", "joint_fields"]

MIN_BODY = 1e-12  # [kg, kg m^2] the least mass and principal moment written (MuJoCo refuses ~1e-15 and below)


@dataclass(frozen=True)
class JointFields:
    """The MJCF joint attributes of a calibrated model, per joint (module docstring): what MuJoCo will compute with.

    Attributes
    ----------
    armature, damping, frictionloss, stiffness, springref : ndarray, shape (n_dof,)
    notes : tuple of str
        Per joint, what MJCF cannot hold of it (offset, friction shape, findings), for its comment.
    """

    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    stiffness: np.ndarray
    springref: np.ndarray
    notes: tuple


def joint_fields(calibrated, robot) -> JointFields:
    """:class:`JointFields` of a calibrated model (the numbers ``render_mjcf`` writes on each joint).

    A linear spring ``k q + c`` is ``stiffness = k`` and ``springref = -c / k``; one with ``k = 0`` (a constant) has
    no MJCF field and is named in the joint's note.
    """
    terms = drive_terms(calibrated)
    n = calibrated.n_dof
    stiffness, springref, constants = np.zeros(n), np.zeros(n), {}
    for j, (k, c) in linear_springs(calibrated).items():
        if k == 0.0:
            constants[j] = c
        else:
            stiffness[j], springref[j] = k, -c / k
    left_out = friction_left_out(calibrated)
    findings, _ = findings_left_out(calibrated, MJCF)
    offset = "offset" in calibrated.document["drive"]["friction_terms"]
    notes = []
    for j, joint in enumerate(robot.joints):
        unit = "N m" if joint.is_revolute else "N"
        parts = [f"constant torque offset {exact_text(terms['offset'][j])} {unit} (not an MJCF field)"] * offset
        if j in constants:
            parts.append(f"spring finding with k = 0: constant torque {exact_text(constants[j])} {unit} (left out)")
        if left_out is not None:
            parts.append(f"friction not representable in MJCF (left out): {left_out[j]}")
        parts += [f"finding {text}" for text in findings.get(j, ())]
        accel = "rad/s^2" if joint.is_revolute else "m/s^2"
        parts.append(f"acceleration limit {exact_text(joint.qdd_max)} {accel} (not an MJCF field)")
        notes.append("psdm: " + "; ".join(parts))
    return JointFields(drive_inertias(calibrated, robot), terms["fv"], terms["fc"], stiffness, springref, tuple(notes))


# --- elements ------------------------------------------------------------------------------------------------
def inertial_attributes(parameters) -> tuple:
    """(``<inertial>`` attributes, note or None) of 10 dynamic parameters in the body frame.

    The attributes are pos (centre of mass), mass and fullinertia (about the centre of mass). MuJoCo refuses a
    moving body whose mass or a principal moment is below ~1e-15 or whose moments break ``A + B >= C``; a body the
    model leaves without mass or inertia there (a link the data cannot see, a thin rod) gets ``MIN_BODY`` of mass
    and ``pad I`` more inertia (the least that MuJoCo takes, 1e-12 [kg, kg m^2]: a torque change far below the
    1e-9 round trip), said in the returned note.
    """
    inertia = inertia_from_dynamic_parameters(parameters)
    mass, tensor = float(inertia.mass), np.asarray(inertia.inertia, dtype=float)
    a, b, c = np.linalg.eigvalsh(tensor)
    pad = max(MIN_BODY - a, c - a - b + MIN_BODY, 0.0) if (a < MIN_BODY or c - a - b > -MIN_BODY) else 0.0
    note = None
    if mass < MIN_BODY or pad > 0.0:
        note = (
            "psdm: MuJoCo needs a positive mass and principal moments with A + B >= C on a moving body; the model's "
            f"body (mass {exact_text(mass)} kg, principal moments {numbers([a, b, c])} kg m^2) is written with mass "
            f"{exact_text(max(mass, MIN_BODY))} kg and {exact_text(pad)} kg m^2 more on each axis"
        )
        mass, tensor = max(mass, MIN_BODY), tensor + pad * np.eye(3)
    full = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    return [("pos", numbers(inertia.lever)), ("mass", exact_text(mass)), ("fullinertia", numbers(full))], note


def joint_attributes(fields: JointFields, j: int, angle_unit: float = 1.0) -> list:
    """The calibrated attributes of joint ``j``: armature, damping, frictionloss, stiffness and springref.

    ``angle_unit`` is the unit of ``springref`` in radians (a hinge's in a file with ``compiler angle="degree"``:
    ``pi / 180``; 1 for a slide or in radians). A joint without a spring gets ``stiffness="0"`` (a default class's
    spring would otherwise remain, which the model does not have).
    """
    names = ("armature", "damping", "frictionloss", "stiffness")
    out = [(name, exact_text(getattr(fields, name)[j])) for name in names]
    if fields.stiffness[j] != 0.0:
        out.append(("springref", exact_text(fields.springref[j] / angle_unit)))
    return out


def header_text(calibrated, robot, source: str) -> str:
    """The comment that opens the file: where it comes from and what MJCF cannot hold (wrapped lines)."""
    block = calibrated.document["standard"]
    state = "physically consistent" if calibrated.consistent else "NOT physically consistent"
    lines = [
        f"Written by psdm export-mjcf from the calibrated model of {robot.name} "
        f"(created {calibrated.document.get('provenance', {}).get('created', '?')}), {source}.",
        f"Inertial parameters: identified, {state} (smallest pseudo-inertia eigenvalue "
        f"{block['min_pseudo_inertia_eigenvalue']}); each moving body's <inertial> is the whole rigid body the model "
        "attaches to its joint.",
        "Joints: armature = the drive inertia reflected to the joint, damping = fv (viscous), frictionloss = fc: "
        f"MuJoCo's dry-friction constraint (bounded by fc), where the model has {tanh_text(calibrated.coulomb_widths)}"
        + approximated_widths(
            calibrated.coulomb_widths,
            "frictionloss has no smoothing width: every joint's friction "
            "reverses as sharply as MuJoCo's friction constraint makes it",
        )
        + "; a linear spring finding is stiffness and springref."
        + (f" WARNING: {left_out}." if (left_out := friction_not_representable(calibrated, MJCF)) else ""),
        f"Gravity: {numbers(robot.gravity)} m/s^2 in the robot's base frame.",
    ]
    if "offset" in calibrated.document["drive"]["friction_terms"]:
        lines.append("The model's constant torque offsets have no MJCF field: they are in a comment on each joint.")
    if (findings := findings_not_representable(calibrated, MJCF)) is not None:
        lines.append(f"Findings: WARNING: {findings}.")
        lines += [f"Finding {text}." for text in findings_left_out(calibrated, MJCF)[1]]  # on no joint (a delay)
    wrapped = [row for line in lines for row in textwrap.wrap(" ".join(line.replace("--", "- -").split()), 100)]
    return "\n    " + "\n    ".join(wrapped) + "\n"
