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

**Generated or copied.** A robot read from MJCF is written into a copy of its file (``mjcf_copy``), unless it has
locked joints (a gripper's fingers): MuJoCo's file would keep them moving, so such a robot, like a DH or URDF robot,
gets a file generated from its kinematics (locked joints locked) with a capsule per link for the eye (no mass:
``inertiafromgeom="false"``); gravity is the robot's, in its base frame (``<option gravity>``).

**Left out** (the header and a comment on each joint name them with their values, and
``target_holds.friction_not_representable`` / ``findings_not_representable`` give the warnings
``psdm export-mjcf`` prints): a constant torque offset, the Stribeck hump and LuGre bristles, torque findings
other than a linear spring (a non-linear spring, a ripple, a coupling, ...), measurement corrections (delay,
joint elasticity, backlash) and acceleration limits.
"""

from __future__ import annotations

from pathlib import Path
from xml.dom import minidom

import numpy as np
import pinocchio as pin

from codegen.mjcf_copy import copied_mjcf
from codegen.mjcf_elements import header_text, inertial_attributes, joint_attributes, joint_fields
from codegen.model_export import require_standard, write_model
from codegen.target_holds import N_LINK
from codegen.xml_nodes import comment, element, numbers
from psdm_casadi.mjcf import MJCF_SUFFIXES
from psdm_casadi.oracle import build_kinematic_model, link_to_joint_frame_maps
from psdm_casadi.values import exact_text

__all__ = ["export_mjcf", "render_mjcf"]

LINK_RADIUS = 0.02  # [m] radius of the capsules drawn along the links (no mass)


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
    return write_model(calibrated, path, render_mjcf, "MJCF", overwrite, allow_inconsistent)


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
    require_standard(calibrated, "MJCF")
    robot = calibrated.load_robot() if robot is None else robot
    if (
        robot.urdf_path is not None
        and Path(robot.urdf_path).suffix.lower() in MJCF_SUFFIXES
        and not robot.locked_joints
    ):
        return copied_mjcf(calibrated, robot)
    document = _generated(calibrated, robot)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + document.documentElement.toprettyxml(indent="  ")


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
    root.appendChild(element(document, "compiler", [("angle", "radian"), ("inertiafromgeom", "false")]))
    root.appendChild(element(document, "option", [("gravity", numbers(robot.gravity))]))
    worldbody = root.appendChild(element(document, "worldbody"))
    model, _ = build_kinematic_model(robot)
    maps = link_to_joint_frame_maps(robot)
    fields = joint_fields(calibrated, robot)
    axes = _axes(model)
    bodies = {0: worldbody}
    for jid in range(1, model.njoints):
        j, joint = jid - 1, robot.joints[jid - 1]
        placement = model.jointPlacements[jid]
        turn = pin.Quaternion(placement.rotation)
        body = element(document, "body", [("name", f"link{jid}"), ("pos", numbers(placement.translation)),
                                           ("quat", numbers([turn.w, turn.x, turn.y, turn.z]))])  # fmt: skip
        parameters = maps[j] @ calibrated.standard[j, :N_LINK]
        attributes, note = inertial_attributes(parameters)
        if note is not None:
            body.appendChild(comment(document, note))
        body.appendChild(element(document, "inertial", attributes))
        kind, axis = axes[j]
        body.appendChild(comment(document, fields.notes[j]))
        attributes = [("name", joint.name), ("type", kind), ("axis", numbers(axis)), ("limited", "true"),
                      ("range", numbers([joint.q_min, joint.q_max]))] + joint_attributes(fields, j)  # fmt: skip
        body.appendChild(element(document, "joint", attributes))
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
        shapes = [[("type", "capsule"), ("fromto", numbers([0.0, 0.0, 0.0, *end]))] for end in ends] or [
            [("type", "sphere")]
        ]
        for shape in shapes:
            attributes = shape + [("size", exact_text(LINK_RADIUS)), ("contype", "0"), ("conaffinity", "0")]
            bodies[jid].appendChild(element(document, "geom", attributes))


def _actuators(document, robot):
    """A torque motor (gear 1) per joint, limited to the robot's torque limit where it has one."""
    actuator = element(document, "actuator")
    for joint in robot.joints:
        attributes = [("name", f"{joint.name}_motor"), ("joint", joint.name), ("gear", "1")]
        if np.isfinite(joint.tau_max):
            attributes += [("ctrllimited", "true"), ("ctrlrange", numbers([-joint.tau_max, joint.tau_max]))]
        actuator.appendChild(element(document, "motor", attributes))
    return actuator
