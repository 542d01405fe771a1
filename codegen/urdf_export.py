"""A calibrated model as a URDF: the identified inertias, friction and drive inertias, for other tools.

The last step of the flow, beside the C export: ``calibrated model ─export_urdf→ URDF``.

**Frames.** ``CalibratedModel.standard[i, :10]`` (m, m c, inertia about the origin) is given in link
frame ``i`` of the robot (``psdm_casadi.oracle.build_kinematic_model``; ``link_to_joint_frame_maps``
moves it to Pinocchio's joint frame): for a URDF robot the frame of joint ``i``'s child link, which is
Pinocchio's joint frame; for a standard-DH robot DH frame ``i`` (the joint frame moved by the row's
constant transform); for a modified-DH robot DH frame ``i``, the joint frame. A URDF ``<inertial>``
is written in that link frame: mass ``m``, centre of mass ``c = (mx, my, mz) / m`` as its origin with
``rpy = 0``, and the inertia about the centre of mass, ``I_c = I_o - m S(c)^T S(c)``.

**URDF robots.** The robot's URDF (its text is in the calibrated-model file) is copied with every
other element, comment and attribute kept, and three changes. Pinocchio gives joint ``i`` one rigid
body: its child link plus every link hanging from it by fixed joints and by the robot's locked joints
(a gripper's fingers). The identification sees that body as a whole, which cannot be split back onto
its links, so the identified body is written on joint ``i``'s child link and every link merged into
it that had an ``<inertial>`` gets a zero one (mass 0, kept rather than removed so that the file
says so) and a comment naming the link that carries its inertia: Pinocchio (and any parser that
lumps fixed joints) then rebuilds exactly the identified body, wherever the locked joints are locked.
Locked joints stay as they were (type, limits, dynamics); lock them again when loading the file at
the positions the header names (``pinocchio.buildReducedModel``); unlocked, their links are massless.
Links rigid with the root belong to no body and keep their ``<inertial>``. Each moving joint gets
``<dynamics damping="fv" friction="fc"/>`` (other attributes of an earlier ``<dynamics>`` are
dropped: they described friction the model replaces).

**DH robots** (robot files with DH rows) get a generated URDF: ``base_link`` (DH frame 0), then per joint the
revolute or prismatic joint about its z axis and a fixed joint carrying the DH row (standard
convention: joint, then row; modified: row, then joint), so that link ``link<i>`` is DH frame ``i``;
limits from the robot file (a joint without a torque limit gets ``effort="0"``, which
``psdm_casadi.urdf.from_urdf`` reads back as none; URDF has no acceleration limits).

**Friction shapes URDF cannot hold.** ``<dynamics>`` has Coulomb friction and viscous damping only. For a
Stribeck model (``--friction stribeck``) and a LuGre model (``--friction lugre``) the file gets the honest
part: ``friction = fc``, the sliding level the friction settles at beyond a few ``vs``, and ``damping = fv``;
the static hump (``fs``, ``vs``) and the LuGre bristle dynamics (``sigma0``, ``sigma1``) are left out, their
values written in a comment on each joint, and ``target_holds.friction_not_representable`` gives the warning
``psdm export-urdf`` prints. (Writing ``fs`` instead, or a blend, would be wrong at every sliding speed.)

**Findings** of ``psdm diagnose MODEL --apply`` (torque terms such as a spring, measurement corrections such
as a joint elasticity) have no URDF element either: each is named with its parameters in a comment on its
joint, the header warns (``target_holds``, the statement of what each target holds), and ``psdm export-urdf``
prints the warning.

**Drives.** The model's Coulomb term is ``fc tanh(qd / v)`` (``v`` in the header comment); a torque
offset and the drive inertia have no URDF field and are written as comments on their joint. The
drive inertia ``Ia`` reflected to the joint is Pinocchio's ``model.armature``: Pinocchio's URDF
parser reads ``damping`` and ``friction`` (``model.damping``, ``model.friction``) but no armature, so
set ``model.armature`` from those comments (or ``CalibratedModel.standard[:, 10]`` of the joints the
model has a drive inertia on).

**Gravity.** A URDF carries none; its users assume gravity along ``-z`` of the root. When the
robot's gravity is not along ``-z`` (the Denso's base frame has it along ``+x``), a root link
``world`` is added, with a fixed joint turning the robot's base so that gravity points along ``-z``
of ``world``. The magnitude is stated in the header comment (Pinocchio's default is 9.81 m/s^2).
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from xml.dom import minidom
from xml.parsers.expat import ExpatError

import numpy as np
import pinocchio as pin

from codegen.model_export import require_standard, write_model
from codegen.target_holds import (
    N_LINK,
    drive_inertias,
    drive_terms,
    findings_left_out,
    findings_not_representable,
    friction_left_out,
    friction_not_representable,
)
from codegen.xml_nodes import comment, element, numbers
from identification.calibration.coulomb_width import approximated_widths, tanh_text
from psdm_casadi.errors import ModelFileError
from psdm_casadi.mjcf import MJCF_SUFFIXES
from psdm_casadi.oracle import dh_transform, inertia_from_dynamic_parameters
from psdm_casadi.values import exact_text

__all__ = ["export_urdf", "render_urdf", "urdf_armature"]


def export_urdf(calibrated, path, *, overwrite: bool = False, allow_inconsistent: bool = False) -> Path:
    """Write the URDF of a calibrated model atomically (see the module docstring).

    Parameters
    ----------
    calibrated : CalibratedModel
        Read by ``load_calibrated_model`` (a file of ``psdm identify``).
    path : str or Path
        The ``.urdf`` file to write.
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
        For an inconsistent model without ``allow_inconsistent`` (naming the smallest pseudo-inertia
        eigenvalue), and as :func:`render_urdf`.
    FileExistsError
        When ``path`` exists and ``overwrite`` is false.

    Examples
    --------
    >>> export_urdf(load_calibrated_model("model.json"), "robot.urdf")  # doctest: +SKIP
    """
    return write_model(calibrated, path, render_urdf, "URDF", overwrite, allow_inconsistent)


def render_urdf(calibrated, robot=None) -> str:
    """The URDF text of a calibrated model (module docstring), whether it is consistent or not.

    Parameters
    ----------
    calibrated : CalibratedModel
    robot : RobotDescription, optional
        ``calibrated.load_robot()`` (rebuilt from the texts in the file) when omitted.

    Returns
    -------
    str
        A URDF document.

    Raises
    ------
    ModelFileError
        When the model holds no standard parameters (identified with ``--no-consistency``), a link
        has first moments but no mass, or the robot's URDF cannot be read.
    """
    require_standard(calibrated, "a URDF")
    robot = calibrated.load_robot() if robot is None else robot
    if robot.urdf_path is not None and Path(robot.urdf_path).suffix.lower() in MJCF_SUFFIXES:
        raise ModelFileError(
            f"the robot {robot.name!r} of the calibrated model was read from MJCF ({Path(robot.urdf_path).name}); "
            "export-urdf copies a URDF robot's file or generates one for DH rows. Write it with 'psdm export-mjcf'."
        )
    if robot.urdf_path is not None:
        document = _copied_urdf(calibrated, robot)
    else:
        document = _dh_urdf(calibrated, robot)
    nodes = "\n".join(node.toxml() for node in document.childNodes)
    return f'<?xml version="1.0" encoding="utf-8"?>\n{nodes}\n'


def urdf_armature(calibrated, robot) -> np.ndarray:
    """Drive inertias [kg m^2] per joint the model predicts with (``target_holds.drive_inertias``)."""
    return drive_inertias(calibrated, robot)


# --- numbers and elements ----------------------------------------------------------------------------
def _origin(document, placement: pin.SE3):
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    return element(document, "origin", [("xyz", numbers(placement.translation)), ("rpy", numbers(rpy))])


def _inertial(document, parameters, where: str):
    """``<inertial>`` of 10 link-frame standard parameters: mass, CoM origin (rpy 0), inertia about the CoM."""
    parameters = np.asarray(parameters, dtype=float)
    inertia = inertia_from_dynamic_parameters(parameters)
    if inertia.mass == 0.0 and np.any(parameters[1:4] != 0.0):
        raise ModelFileError(
            f"{where}: a link with first moments {numbers(parameters[1:4])} kg m and no mass cannot be written as a "
            "URDF <inertial>. Re-identify the model (it is not physically consistent)."
        )
    i = np.asarray(inertia.inertia)
    tensor = [("ixx", i[0, 0]), ("ixy", i[0, 1]), ("ixz", i[0, 2]),
              ("iyy", i[1, 1]), ("iyz", i[1, 2]), ("izz", i[2, 2])]  # fmt: skip
    return element(document, "inertial", children=[
        element(document, "origin", [("xyz", numbers(inertia.lever)), ("rpy", "0 0 0")]),
        element(document, "mass", [("value", exact_text(inertia.mass))]),
        element(document, "inertia", [(k, exact_text(v)) for k, v in tensor]),
    ])  # fmt: skip


def _joint_notes(calibrated, robot) -> list:
    """Per joint, the comment on what URDF cannot hold: the drive inertia and a torque offset."""
    armature = urdf_armature(calibrated, robot)
    offsets = drive_terms(calibrated)["offset"]
    left_out = friction_left_out(calibrated)
    findings, _ = findings_left_out(calibrated)
    notes = []
    for j, joint in enumerate(robot.joints):
        inertia_unit, force_unit = ("kg m^2", "N m") if joint.is_revolute else ("kg", "N")
        text = (
            f"psdm: drive inertia (armature, reflected to the joint) Ia = {exact_text(armature[j])} {inertia_unit}; "
            "not a URDF field and not read by Pinocchio's URDF parser: set model.armature"
        )
        if "offset" in calibrated.document["drive"]["friction_terms"]:
            text += f"; constant torque offset {exact_text(offsets[j])} {force_unit} (not a URDF field)"
        if left_out is not None:
            text += f"; friction not representable in URDF (left out): {left_out[j]}"
        text += "".join(f"; finding {finding}" for finding in findings.get(j, ()))
        notes.append(text)
    return notes


def _header(document, calibrated, robot, world: bool, indent: str):
    """The comment that opens the file: where it comes from and what URDF cannot say (wrapped, indented)."""
    block = calibrated.document["standard"]
    state = "physically consistent" if calibrated.consistent else "NOT physically consistent"
    gravity = np.linalg.norm(robot.gravity)
    lines = [
        f"Written by psdm export-urdf from the calibrated model of {robot.name} "
        f"(created {calibrated.document.get('provenance', {}).get('created', '?')}).",
        f"Inertial parameters: identified, {state} (smallest pseudo-inertia eigenvalue "
        f"{block['min_pseudo_inertia_eigenvalue']}). Each moving link's <inertial> is the whole rigid body the "
        "model attaches to its joint (links merged into it have mass 0), in the link frame about its centre of mass.",
        f"Friction: <dynamics friction> is fc, the model's Coulomb term {tanh_text(calibrated.coulomb_widths)}"
        + approximated_widths(
            calibrated.coulomb_widths,
            "URDF has no field for the smoothing width: a reader smooths every joint's sign its own way",
        )
        + "; damping is fv (viscous)."
        + (f" WARNING: {left_out}." if (left_out := friction_not_representable(calibrated)) else ""),
        "Drive inertias (armature) are in a comment on each joint: URDF has no field for them and Pinocchio's URDF "
        "parser does not read one; set model.armature.",
        f"Gravity: {exact_text(gravity)} m/s^2 along -z of the root link"
        + (" 'world' (added: the robot's base frame has gravity " + numbers(robot.gravity) + ")" if world else "")
        + "; set model.gravity (Pinocchio's default is 9.81).",
    ]
    if (findings := findings_not_representable(calibrated)) is not None:
        lines.append(f"Findings: WARNING: {findings}.")
        lines += [f"Finding {text}." for text in findings_left_out(calibrated)[1]]  # on no joint (a delay)
    if robot.locked_joints:
        locked = ", ".join(f"{name} at {exact_text(value)}" for name, value in _locked(robot))
        lines.append(f"Locked joints (lock them there when loading, e.g. pinocchio.buildReducedModel): {locked}.")
    wrapped = [row for line in lines for row in textwrap.wrap(" ".join(line.replace("--", "- -").split()), 100)]
    return document.createComment(indent + "  " + (indent + "  ").join(wrapped) + indent)


def _locked(robot) -> list:
    """The robot's locked joints as ``(name, position)`` pairs (a name alone is locked at 0)."""
    return [(item, 0.0) if isinstance(item, str) else (str(item[0]), float(item[1])) for item in robot.locked_joints]


def _world_placement(gravity) -> pin.SE3 | None:
    """Placement of the base in an added ``world`` link whose -z is gravity (None: gravity is along -z or zero)."""
    g = np.asarray(gravity, dtype=float)
    norm = np.linalg.norm(g)
    down = np.array([0.0, 0.0, -1.0])
    if norm == 0.0 or np.allclose(g / norm, down, rtol=0.0, atol=1e-14):
        return None
    rotation = pin.Quaternion.FromTwoVectors(g / norm, down).matrix()
    return pin.SE3(rotation, np.zeros(3))


def _world(document, placement: pin.SE3, root: str, name: str) -> list:
    joint = element(document, "joint", [("name", f"{name}_to_{root}"), ("type", "fixed")], [
        _origin(document, placement),
        element(document, "parent", [("link", name)]),
        element(document, "child", [("link", root)]),
    ])  # fmt: skip
    return [element(document, "link", [("name", name)]), joint]


def _dynamics(document, terms: dict, j: int):
    return element(
        document, "dynamics", [("damping", exact_text(terms["fv"][j])), ("friction", exact_text(terms["fc"][j]))]
    )


# --- DH robots -----------------------------------------------------------------------------------------
def _dh_urdf(calibrated, robot):
    """A generated URDF of a DH robot: a chain of links, moving joints and fixed joints carrying the DH rows."""
    document = minidom.getDOMImplementation().createDocument(None, "robot", None)
    root = document.documentElement
    root.setAttribute("name", robot.name)
    world = _world_placement(robot.gravity)
    root.appendChild(_header(document, calibrated, robot, world is not None, "\n  "))
    children = [] if world is None else _world(document, world, "base_link", "world")
    children.append(element(document, "link", [("name", "base_link")]))
    terms, notes = drive_terms(calibrated), _joint_notes(calibrated, robot)
    parent = "base_link"
    for j, joint in enumerate(robot.joints):
        link = f"link{j + 1}"
        if robot.convention == "standard":  # joint i turns DH frame i-1; the row then leads to DH frame i
            between = f"frame{j}_q{j + 1}"
            moving, fixed = _dh_moving(document, joint, parent, between), _dh_fixed(document, robot, j, between, link)
            pieces = [moving, between, fixed]
        else:  # the row leads to DH frame i at q_i = 0; joint i turns it
            between = f"frame{j + 1}_zero"
            fixed, moving = _dh_fixed(document, robot, j, parent, between), _dh_moving(document, joint, between, link)
            pieces = [fixed, between, moving]
        moving.appendChild(_dynamics(document, terms, j))
        unit = "rad/s^2" if joint.is_revolute else "m/s^2"
        note = notes[j] + f"; acceleration limit {exact_text(joint.qdd_max)} {unit} (not a URDF field)"
        if not np.isfinite(joint.tau_max):
            note += "; no torque limit (effort 0)"
        pieces.insert(pieces.index(moving), comment(document, note))
        inertial = _inertial(document, calibrated.standard[j, :N_LINK], f"{robot.name} link {j + 1}")
        children += [element(document, "link", [("name", p)]) if isinstance(p, str) else p for p in pieces]
        children.append(element(document, "link", [("name", link)], [inertial]))
        parent = link
    for child in children:
        root.appendChild(child)
    return minidom.parseString(root.toprettyxml(indent="  "))


def _dh_moving(document, joint, parent: str, child: str):
    """The revolute or prismatic joint about z of its parent link, with the robot file's limits."""
    limit = [
        ("lower", exact_text(joint.q_min)),
        ("upper", exact_text(joint.q_max)),
        ("effort", exact_text(joint.tau_max) if np.isfinite(joint.tau_max) else "0"),
        ("velocity", exact_text(joint.qd_max)),
    ]
    return element(document, "joint", [("name", joint.name), ("type", joint.kind)], [
        _origin(document, pin.SE3.Identity()),
        element(document, "parent", [("link", parent)]),
        element(document, "child", [("link", child)]),
        element(document, "axis", [("xyz", "0 0 1")]),
        element(document, "limit", limit),
    ])  # fmt: skip


def _dh_fixed(document, robot, j: int, parent: str, child: str):
    """The fixed joint carrying DH row ``j`` (its constant transform, the joint offset included)."""
    joint = robot.joints[j]
    row = dh_transform(robot.convention, joint.a, joint.alpha, joint.d, joint.theta)
    return element(document, "joint", [("name", f"{joint.name}_dh"), ("type", "fixed")], [
        comment(document, f"DH row {j + 1} ({robot.convention} convention): a, alpha, d, theta = "
                           f"{numbers([joint.a, joint.alpha, joint.d, joint.theta])}"),
        _origin(document, row),
        element(document, "parent", [("link", parent)]),
        element(document, "child", [("link", child)]),
    ])  # fmt: skip


# --- URDF robots ---------------------------------------------------------------------------------------
def _copied_urdf(calibrated, robot):
    """The robot's URDF with the identified bodies, friction and drive notes (module docstring)."""
    name = Path(robot.urdf_path).name
    text = calibrated.document["robot"]["files"].get(name)
    text = Path(robot.urdf_path).read_text() if text is None else text
    try:
        document = minidom.parseString(text.encode("utf-8"))
    except ExpatError as exc:
        raise ModelFileError(f"the robot's URDF {name!r} in the calibrated model is not XML ({exc}).") from None
    root = document.documentElement
    links = {node.getAttribute("name"): node for node in _children(root, "link")}
    joints = {node.getAttribute("name"): node for node in _children(root, "joint")}
    missing = [j for j in robot.joint_names if j not in joints]
    if missing:
        raise ModelFileError(f"the URDF {name!r} of the calibrated model must have the joints "
                             f"{list(robot.joint_names)}; {missing} are missing. Re-run 'psdm identify'.")  # fmt: skip
    terms, notes, standard = drive_terms(calibrated), _joint_notes(calibrated, robot), calibrated.standard
    for j, joint_name in enumerate(robot.joint_names):
        carrier = _child_link(joints[joint_name])
        merged = _merged_links(joints, carrier, {name for name, _ in _locked(robot)})
        note = f"psdm: the identified body of joint {joint_name!r}"
        if merged:
            note += f" ({'links' if len(merged) > 1 else 'link'} {', '.join(map(repr, merged))} merged into it)"
        _place(document, links[carrier], _inertial(document, standard[j, :N_LINK], f"link {carrier!r}"), note)
        for link in merged:
            if _children(links[link], "inertial"):
                zero = _inertial(document, np.zeros(N_LINK), link)
                _place(document, links[link], zero, f"psdm: mass 0, its inertia is part of link {carrier!r}")
        _place(document, joints[joint_name], _dynamics(document, terms, j), notes[j])
    world = _world_placement(robot.gravity)
    first = next(c for c in root.childNodes if c.nodeType == c.ELEMENT_NODE)
    indent = _indent_before(first) or "\n  "
    if world is not None:
        world_name = "world" if "world" not in links else "psdm_world"
        for node in _world(document, world, _root_link(links, joints), world_name):
            root.insertBefore(_indented(document, node, indent, "  "), first)
            root.insertBefore(document.createTextNode(indent), first)
    opening = root.firstChild
    root.insertBefore(document.createTextNode(indent), opening)
    root.insertBefore(_header(document, calibrated, robot, world is not None, indent), opening)
    return document


def _children(node, tag: str) -> list:
    return [c for c in node.childNodes if c.nodeType == c.ELEMENT_NODE and c.tagName == tag]


def _child_link(joint) -> str:
    return _children(joint, "child")[0].getAttribute("link")


def _merged_links(joints: dict, carrier: str, locked: set) -> list:
    """Links Pinocchio merges into the body of ``carrier``: through fixed and locked joints, depth first."""
    merged, stack = [], [carrier]
    while stack:
        link = stack.pop()
        for name, joint in joints.items():
            parent = _children(joint, "parent")[0].getAttribute("link")
            if parent == link and (joint.getAttribute("type") == "fixed" or name in locked):
                merged.append(_child_link(joint))
                stack.append(_child_link(joint))
    return merged


def _root_link(links: dict, joints: dict) -> str:
    children = {_child_link(joint) for joint in joints.values()}
    return next(name for name in links if name not in children)


def _indent_before(node) -> str:
    """The indentation of ``node`` (a newline and the blanks of its line), or '' when it has none."""
    previous = node.previousSibling if node is not None else None
    if previous is None or previous.nodeType != previous.TEXT_NODE or previous.data.strip():
        return ""
    return "\n" + previous.data.rsplit("\n", 1)[-1] if "\n" in previous.data else previous.data


def _indented(document, node, indent: str, unit: str):
    """``node`` with whitespace text so that its children sit one ``unit`` deeper than ``indent``."""
    if node.nodeType != node.ELEMENT_NODE:
        return node
    elements = [c for c in node.childNodes if c.nodeType in (c.ELEMENT_NODE, c.COMMENT_NODE)]
    for child in elements:
        node.insertBefore(document.createTextNode(indent + unit), child)
        _indented(document, child, indent + unit, unit)
    if elements:
        node.appendChild(document.createTextNode(indent))
    return node


def _place(document, parent, new, note: str) -> None:
    """Put ``new`` (after a comment ``note``) where ``parent``'s element of its tag was, or last, indented."""
    old = _children(parent, new.tagName)
    outer = _indent_before(parent) or "\n"
    first = next((c for c in parent.childNodes if c.nodeType == c.ELEMENT_NODE), None)
    indent = _indent_before(old[0] if old else first) or outer + "  "
    unit = indent[len(outer) :] if indent.startswith(outer) and len(indent) > len(outer) else "  "
    _indented(document, new, indent, unit)
    if old:
        parent.replaceChild(new, old[0])
        for extra in old[1:]:
            parent.removeChild(extra)
    else:
        tail = parent.lastChild
        if tail is None or tail.nodeType != tail.TEXT_NODE or tail.data.strip():
            tail = parent.appendChild(document.createTextNode(outer))
        parent.insertBefore(document.createTextNode(indent), tail)
        parent.insertBefore(new, tail)
    parent.insertBefore(comment(document, note), new)
    parent.insertBefore(document.createTextNode(indent), new)
