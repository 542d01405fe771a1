"""A calibrated model written into a copy of the robot's own MJCF (``mjcf_export`` of a robot read from MJCF).

The robot's MJCF (its text is in the calibrated-model file) is copied with every other element, comment and
attribute kept, and these changes (``psdm_casadi.mjcf`` says how the file was read):

- each moving body's ``<inertial>`` is the identified rigid body of its joint, in the body's frame (the joint frame
  moved back by the joint's ``pos``); bodies welded to it (a hand, a tool) were lumped into that body by the
  reading, so their ``<inertial>`` is removed (a comment says where their inertia went) and
  ``compiler inertiafromgeom="false"`` keeps MuJoCo from giving them their geoms' mass again; the compiler's
  ``settotalmass``, ``boundmass``, ``boundinertia`` and ``balanceinertia``, which would change the written bodies,
  are removed;
- each joint gets explicit ``armature``, ``damping``, ``frictionloss``, ``stiffness`` (and ``springref``, in the
  file's angle unit) over its default class, and a comment on what MJCF cannot hold of it;
- ``option gravity`` is the robot's; a header comment says where the file comes from.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.dom import minidom
from xml.parsers.expat import ExpatError

import mujoco
import numpy as np
import pinocchio as pin

from codegen.mjcf_elements import header_text, inertial_attributes, joint_attributes, joint_fields
from codegen.target_holds import N_LINK
from codegen.xml_nodes import comment
from psdm_casadi.errors import ModelFileError
from psdm_casadi.mjcf import compile_mjcf
from psdm_casadi.oracle import inertia_from_dynamic_parameters

__all__ = ["copied_mjcf"]

MASS_CHANGING = ("settotalmass", "boundmass", "boundinertia", "balanceinertia")  # compiler attributes, removed


def _elements(root, tag: str) -> list:
    return list(root.getElementsByTagName(tag))


def _set_first(document, root, tag: str, key: str, value: str) -> None:
    """Set ``key`` on every ``<tag>`` child of the root, or add one ``<tag>`` first when there is none."""
    nodes = [n for n in root.childNodes if n.nodeType == n.ELEMENT_NODE and n.tagName == tag]
    if not nodes:
        nodes = [root.insertBefore(document.createElement(tag), root.firstChild)]
    for node in nodes:
        node.setAttribute(key, value)


def _angle_unit(root) -> float:
    """The file's angle unit in radians (MJCF's default is degrees)."""
    units = [n.getAttribute("angle") for n in _elements(root, "compiler") if n.hasAttribute("angle")]
    return 1.0 if units and units[-1] == "radian" else math.pi / 180.0


def _text(calibrated, robot) -> str:
    name = Path(robot.urdf_path).name
    text = calibrated.document["robot"]["files"].get(name)
    return Path(robot.urdf_path).read_text() if text is None else text


def _insert(document, parent, node, anchor) -> None:
    """Insert ``node`` before ``anchor``, followed by the anchor's own line break and indentation."""
    previous = anchor.previousSibling if anchor is not None else None
    indent = ""
    if previous is not None and previous.nodeType == previous.TEXT_NODE and "\n" in previous.data:
        indent = "\n" + previous.data.rsplit("\n", 1)[-1]
    parent.insertBefore(node, anchor)
    if indent:
        parent.insertBefore(document.createTextNode(indent), anchor)


def _replace_inertial(document, body, attributes, note: str | None) -> None:
    """Put an ``<inertial>`` of ``attributes`` where the body's was (first child otherwise), after ``note``."""
    old = [n for n in body.childNodes if n.nodeType == n.ELEMENT_NODE and n.tagName == "inertial"]
    new = document.createElement("inertial")
    for key, value in attributes:
        new.setAttribute(key, value)
    if old:
        body.replaceChild(new, old[0])
        for node in old[1:]:
            body.removeChild(node)
    else:
        _insert(document, body, new, next((n for n in body.childNodes if n.nodeType == n.ELEMENT_NODE), None))
    if note is not None:
        _insert(document, body, comment(document, note), new)


def copied_mjcf(calibrated, robot) -> str:
    """The robot's MJCF with the calibrated model in it (module docstring).

    Raises
    ------
    ModelFileError
        When the MJCF in the model file is not XML or lacks one of the robot's joints.
    """
    text = _text(calibrated, robot)
    try:
        document = minidom.parseString(text.encode("utf-8"))
    except ExpatError as exc:
        raise ModelFileError(f"the robot's MJCF in the calibrated model is not XML ({exc}).") from None
    root = document.documentElement
    compiled = compile_mjcf(text, Path(robot.urdf_path).name)
    joints = {n.getAttribute("name"): n for n in _elements(root, "joint")}
    missing = [name for name in robot.joint_names if name not in joints]
    if missing:
        raise ModelFileError(f"the MJCF of the calibrated model must have the joints {list(robot.joint_names)}; "
                             f"{missing} are missing. Re-run 'psdm identify'.")  # fmt: skip
    fields, unit = joint_fields(calibrated, robot), _angle_unit(root)
    moving = set()
    for j, name in enumerate(robot.joint_names):
        node, body = joints[name], _body_of(joints[name])
        moving.add(body)
        offset = np.array(compiled.jnt_pos[mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_JOINT, name)])
        attributes, note = inertial_attributes(_moved(calibrated.standard[j, :N_LINK], offset))
        _replace_inertial(document, body, attributes, note or f"psdm: the identified body of joint {name!r}")
        for key, value in joint_attributes(fields, j, unit if robot.joints[j].is_revolute else 1.0):
            node.setAttribute(key, value)
        _insert(document, node.parentNode, comment(document, fields.notes[j]), node)
    for body in _elements(root, "body"):
        if body not in moving and _carried(body, moving):
            for inertial in [n for n in body.childNodes if n.nodeType == n.ELEMENT_NODE and n.tagName == "inertial"]:
                note = "psdm: the inertia of this welded body is part of the identified body of the joint it moves with"
                body.replaceChild(comment(document, note), inertial)
    _set_first(document, root, "compiler", "inertiafromgeom", "false")
    for node in _elements(root, "compiler"):  # they would change the written masses and inertias
        for key in MASS_CHANGING:
            if node.hasAttribute(key):
                node.removeAttribute(key)
    _set_first(document, root, "option", "gravity", " ".join(repr(float(g) + 0.0) for g in robot.gravity))
    first = root.firstChild
    root.insertBefore(document.createComment(header_text(calibrated, robot, "a copy of its MJCF")), first)
    root.insertBefore(document.createTextNode("\n  "), first)
    head = text[: text.index("<mujoco")] if "<mujoco" in text else ""
    return (head if head.strip() else '<?xml version="1.0" encoding="utf-8"?>\n') + root.toxml() + "\n"


def _moved(parameters, offset) -> np.ndarray:
    """The joint frame's 10 dynamic parameters (m, m c, inertia about the origin) in the body frame, whose origin
    lies ``offset`` (the joint's ``pos``) behind the joint frame's with the same axes."""
    inertia = inertia_from_dynamic_parameters(parameters)
    return pin.SE3(np.eye(3), np.asarray(offset, dtype=float)).act(inertia).toDynamicParameters()


def _body_of(node):
    """The ``<body>`` an element belongs to (through ``<frame>`` elements), None at the world."""
    node = node.parentNode
    while node is not None and node.nodeType == node.ELEMENT_NODE and node.tagName == "frame":
        node = node.parentNode
    return node if node is not None and node.nodeType == node.ELEMENT_NODE and node.tagName == "body" else None


def _carried(body, moving: set) -> bool:
    """Whether a body without a joint hangs from a moving body (its inertia was lumped into that body)."""
    node = _body_of(body)
    while node is not None:
        if node in moving:
            return True
        node = _body_of(node)
    return False
