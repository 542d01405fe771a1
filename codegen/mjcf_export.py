"""A calibrated model as MJCF (MuJoCo's XML): identified inertials, drive inertias, friction and springs, for MuJoCo.

The last step of the flow, beside the C and URDF exports: ``calibrated model ─export_mjcf→ MJCF``. What MJCF
holds of a model and what it leaves out is stated once for every target in ``target_holds``.

**Bodies.** Every moving joint of the robot is one MuJoCo body whose frame is the joint frame of the robot's
Pinocchio model (``psdm_casadi.oracle.build_kinematic_model``): its ``<inertial>`` is the identified rigid body of
the joint, ``CalibratedModel.standard[i, :10]`` moved from the link frame to the joint frame
(``link_to_joint_frame_maps``), written as its mass, centre of mass (``pos``) and the inertia about the centre
of mass as ``fullinertia`` (exact floats; MuJoCo diagonalises it on loading).

**Joints** are ``hinge`` or ``slide`` about the joint axis, with ``range`` (radians: the file sets
``compiler angle="radian"``), ``armature`` = the drive inertia ``Ia`` reflected to the joint (0 where the model has
none), ``damping`` = ``fv``, ``frictionloss`` = ``fc`` and, for a linear spring finding ``k q + c``,
``stiffness = k`` and ``springref = -c / k``. MuJoCo's inverse dynamics (``mj_inverse``) then computes
``M(q) qdd + c(q, qd) + g(q) + Ia qdd + fv qd + k q + c``, the calibrated model's torque without its Coulomb term
and torque offset. ``frictionloss`` is MuJoCo's dry-friction constraint: its force is bounded by ``fc`` and opposes
the motion, where the model has ``fc tanh(qd / v)``. Each joint also gets a ``<motor>`` (gear 1) limited to the
robot's torque limit, so that the file simulates under torque control as it is.

**Generated, not copied.** The file is generated from the robot's kinematics (DH rows or URDF, locked joints
locked) with a capsule per link for the eye (no mass: ``inertiafromgeom="false"``); gravity is the robot's,
in its base frame (``<option gravity>``).

**Left out** (the header and a comment on each joint name them with their values, and
``target_holds.friction_not_representable`` / ``findings_not_representable`` give the warnings
``psdm export-mjcf`` prints): a constant torque offset, the Stribeck hump and LuGre bristles, torque findings
other than a linear spring (a non-linear spring, a ripple, a coupling, ...), measurement corrections (delay,
joint elasticity, backlash) and acceleration limits.
"""

from __future__ import annotations

import textwrap
from xml.dom import minidom

import numpy as np
import pinocchio as pin

from codegen.target_holds import (
    MJCF,
    N_LINK,
    drive_inertias,
    drive_terms,
    findings_left_out,
    findings_not_representable,
    friction_left_out,
    friction_not_representable,
    linear_springs,
)
from psdm_casadi.errors import ModelFileError
from psdm_casadi.fileio import atomic_write
from psdm_casadi.oracle import build_kinematic_model, inertia_from_dynamic_parameters, link_to_joint_frame_maps
from psdm_casadi.values import exact_text

__all__ = ["JointFields", "export_mjcf", "joint_fields", "render_mjcf"]

LINK_RADIUS = 0.02  # [m] radius of the capsules drawn along the links (no mass)
MIN_BODY = 1e-12  # [kg, kg m^2] the least mass and principal moment written (MuJoCo refuses ~1e-15 and below)


def export_mjcf(calibrated, path, *, overwrite: bool = False, allow_inconsistent: bool = False):
    """Write the MJCF of a calibrated model atomically (see the module docstring).

    Parameters
    ----------
    calibrated : CalibratedModel
        Read by ``load_calibrated_model`` (a file of ``psdm identify``).
    path : str or Path
        The ``.xml`` file to write.
    overwrite : bool
        Replace an existing file.
    allow_inconsistent : bool
        Write a model whose standard parameters are not physically consistent (said in the file).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ModelFileError
        For an inconsistent model without ``allow_inconsistent``, and as :func:`render_mjcf`.
    FileExistsError
        When ``path`` exists and ``overwrite`` is false.
    """
    if not calibrated.consistent and not allow_inconsistent:
        raise ModelFileError(
            f"the calibrated model is not physically consistent (smallest pseudo-inertia eigenvalue "
            f"{calibrated.document['standard']['min_pseudo_inertia_eigenvalue']}); no MJCF was written to "
            f"{str(path)!r}. Pass --allow-inconsistent to write it marked as such."
        )
    text = render_mjcf(calibrated)
    return atomic_write(path, lambda handle: handle.write(text), overwrite)


class JointFields:
    """The MJCF joint attributes of a calibrated model, per joint (module docstring): what MuJoCo will compute with.

    Attributes
    ----------
    armature, damping, frictionloss, stiffness, springref : ndarray, shape (n_dof,)
    notes : list of str
        Per joint, what MJCF cannot hold of it (offset, friction shape, findings), for its comment.
    """

    def __init__(self, calibrated, robot):
        terms = drive_terms(calibrated)
        n = calibrated.n_dof
        self.armature = drive_inertias(calibrated, robot)
        self.damping, self.frictionloss = terms["fv"], terms["fc"]
        self.stiffness, self.springref = np.zeros(n), np.zeros(n)
        for j, (k, c) in linear_springs(calibrated).items():
            if k == 0.0:  # a constant: a torque offset MJCF cannot hold (kept in the notes by the finding)
                continue
            self.stiffness[j], self.springref[j] = k, -c / k
        left_out = friction_left_out(calibrated)
        findings, _ = findings_left_out(calibrated, MJCF)
        offset = "offset" in calibrated.document["drive"]["friction_terms"]
        self.notes = []
        for j, joint in enumerate(robot.joints):
            unit = "N m" if joint.is_revolute else "N"
            parts = (
                [f"constant torque offset {exact_text(terms['offset'][j])} {unit} (not an MJCF field)"]
                if offset
                else []
            )
            if left_out is not None:
                parts.append(f"friction not representable in MJCF (left out): {left_out[j]}")
            parts += [f"finding {text}" for text in findings.get(j, ())]
            accel = "rad/s^2" if joint.is_revolute else "m/s^2"
            parts.append(f"acceleration limit {exact_text(joint.qdd_max)} {accel} (not an MJCF field)")
            self.notes.append("psdm: " + "; ".join(parts))


def joint_fields(calibrated, robot) -> JointFields:
    """:class:`JointFields` of a calibrated model (the numbers :func:`render_mjcf` writes on each joint)."""
    return JointFields(calibrated, robot)


def render_mjcf(calibrated, robot=None) -> str:
    """The MJCF text of a calibrated model (module docstring), whether it is consistent or not.

    Parameters
    ----------
    calibrated : CalibratedModel
    robot : RobotDescription, optional
        ``calibrated.load_robot()`` (rebuilt from the texts in the file) when omitted.

    Raises
    ------
    ModelFileError
        When the model holds no standard parameters (identified with ``--no-consistency``).
    """
    standard = calibrated.standard
    if not np.all(np.isfinite(standard)):
        raise ModelFileError(
            "CalibratedModel.standard must hold finite standard parameters to write MJCF; got none (the model was "
            "identified with --no-consistency: base parameters only). Re-run 'psdm identify' without it."
        )
    robot = calibrated.load_robot() if robot is None else robot
    document = _generated(calibrated, robot)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + document.documentElement.toprettyxml(indent="  ")


# --- elements ------------------------------------------------------------------------------------------------
def _nums(values) -> str:
    return " ".join(exact_text(v) for v in values)


def _comment(document, text: str):
    return document.createComment(" " + " ".join(str(text).replace("--", "- -").split()) + " ")


def _element(document, tag: str, attributes=(), children=()):
    node = document.createElement(tag)
    for key, value in attributes:
        node.setAttribute(key, value)
    for child in children:
        node.appendChild(child)
    return node


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
            f"body (mass {exact_text(mass)} kg, principal moments {_nums([a, b, c])} kg m^2) is written with mass "
            f"{exact_text(max(mass, MIN_BODY))} kg and {exact_text(pad)} kg m^2 more on each axis"
        )
        mass, tensor = max(mass, MIN_BODY), tensor + pad * np.eye(3)
    full = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    return [("pos", _nums(inertia.lever)), ("mass", exact_text(mass)), ("fullinertia", _nums(full))], note


def joint_attributes(fields: JointFields, j: int) -> list:
    """The calibrated attributes of joint ``j``: armature, damping, frictionloss (stiffness, springref: a spring)."""
    out = [("armature", exact_text(fields.armature[j])), ("damping", exact_text(fields.damping[j])),
           ("frictionloss", exact_text(fields.frictionloss[j]))]  # fmt: skip
    if fields.stiffness[j] != 0.0:
        out += [("stiffness", exact_text(fields.stiffness[j])), ("springref", exact_text(fields.springref[j]))]
    return out


def header_text(calibrated, robot, source: str) -> str:
    """The comment that opens the file: where it comes from and what MJCF cannot hold (wrapped lines)."""
    block = calibrated.document["standard"]
    drive = calibrated.document["drive"]
    state = "physically consistent" if calibrated.consistent else "NOT physically consistent"
    lines = [
        f"Written by psdm export-mjcf from the calibrated model of {robot.name} "
        f"(created {calibrated.document.get('provenance', {}).get('created', '?')}), {source}.",
        f"Inertial parameters: identified, {state} (smallest pseudo-inertia eigenvalue "
        f"{block['min_pseudo_inertia_eigenvalue']}); each moving body's <inertial> is the whole rigid body the model "
        "attaches to its joint.",
        "Joints: armature = the drive inertia reflected to the joint, damping = fv (viscous), frictionloss = fc: "
        f"MuJoCo's dry-friction constraint (bounded by fc), where the model has fc tanh(qd / "
        f"{drive['coulomb_velocity']} rad/s); a linear spring finding is stiffness and springref."
        + (f" WARNING: {left_out}." if (left_out := friction_not_representable(calibrated, MJCF)) else ""),
        f"Gravity: {_nums(robot.gravity)} m/s^2 in the robot's base frame.",
    ]
    if "offset" in drive["friction_terms"]:
        lines.append("The model's constant torque offsets have no MJCF field: they are in a comment on each joint.")
    if (findings := findings_not_representable(calibrated, MJCF)) is not None:
        lines.append(f"Findings: WARNING: {findings}.")
        lines += [f"Finding {text}." for text in findings_left_out(calibrated, MJCF)[1]]  # on no joint (a delay)
    wrapped = [row for line in lines for row in textwrap.wrap(" ".join(line.replace("--", "- -").split()), 100)]
    return "\n    " + "\n    ".join(wrapped) + "\n"


# --- generated from the robot's kinematics ------------------------------------------------------------------
def _axes(model: pin.Model) -> list:
    """Per moving joint, ("hinge" or "slide", unit axis in its joint frame) from Pinocchio's motion subspace."""
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    out = []
    for jid in range(1, model.njoints):
        subspace = np.asarray(data.joints[jid].S).reshape(6)
        linear, angular = subspace[:3], subspace[3:]
        out.append(("hinge", angular) if np.linalg.norm(angular) > 0 else ("slide", linear))
    return out


def _generated(calibrated, robot):
    """A generated MJCF: nested bodies on the robot's joint frames, each with its identified inertial."""
    document = minidom.getDOMImplementation().createDocument(None, "mujoco", None)
    root = document.documentElement
    root.setAttribute("model", robot.name)
    root.appendChild(document.createComment(header_text(calibrated, robot, "generated from its kinematics")))
    root.appendChild(_element(document, "compiler", [("angle", "radian"), ("inertiafromgeom", "false")]))
    root.appendChild(_element(document, "option", [("gravity", _nums(robot.gravity))]))
    worldbody = root.appendChild(_element(document, "worldbody"))
    model, _ = build_kinematic_model(robot)
    maps = link_to_joint_frame_maps(robot)
    fields = joint_fields(calibrated, robot)
    axes = _axes(model)
    bodies = {0: worldbody}
    for jid in range(1, model.njoints):
        j, joint = jid - 1, robot.joints[jid - 1]
        placement = model.jointPlacements[jid]
        turn = pin.Quaternion(placement.rotation)
        body = _element(document, "body", [("name", f"link{jid}"), ("pos", _nums(placement.translation)),
                                           ("quat", _nums([turn.w, turn.x, turn.y, turn.z]))])  # fmt: skip
        parameters = maps[j] @ calibrated.standard[j, :N_LINK]
        attributes, note = inertial_attributes(parameters)
        if note is not None:
            body.appendChild(_comment(document, note))
        body.appendChild(_element(document, "inertial", attributes))
        kind, axis = axes[j]
        body.appendChild(_comment(document, fields.notes[j]))
        attributes = [("name", joint.name), ("type", kind), ("axis", _nums(axis)), ("limited", "true"),
                      ("range", _nums([joint.q_min, joint.q_max]))] + joint_attributes(fields, j)  # fmt: skip
        body.appendChild(_element(document, "joint", attributes))
        bodies[model.parents[jid]].appendChild(body)
        bodies[jid] = body
    _add_link_geoms(document, model, bodies)
    root.appendChild(_actuators(document, robot))
    return document


def _add_link_geoms(document, model: pin.Model, bodies: dict) -> None:
    """A massless capsule from each body's origin to each child body's (a sphere where they coincide)."""
    for jid in range(1, model.njoints):
        children = [k for k in range(jid + 1, model.njoints) if model.parents[k] == jid]
        ends = [
            model.jointPlacements[k].translation
            for k in children
            if np.linalg.norm(model.jointPlacements[k].translation) > 1e-9
        ]
        shapes = [[("type", "capsule"), ("fromto", _nums([0.0, 0.0, 0.0, *end]))] for end in ends] or [
            [("type", "sphere")]
        ]
        for shape in shapes:
            attributes = shape + [("size", exact_text(LINK_RADIUS)), ("contype", "0"), ("conaffinity", "0")]
            bodies[jid].appendChild(_element(document, "geom", attributes))


def _actuators(document, robot):
    """A torque motor (gear 1) per joint, limited to the robot's torque limit where it has one."""
    actuator = _element(document, "actuator")
    for joint in robot.joints:
        attributes = [("name", f"{joint.name}_motor"), ("joint", joint.name), ("gear", "1")]
        if np.isfinite(joint.tau_max):
            attributes += [("ctrllimited", "true"), ("ctrlrange", _nums([-joint.tau_max, joint.tau_max]))]
        actuator.appendChild(_element(document, "motor", attributes))
    return actuator
