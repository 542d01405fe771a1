"""Reading an MJCF (MuJoCo's XML) through MuJoCo's own compiler: the Pinocchio model of the arm (or tree) in the file.

The one place that parses MJCF files; ``urdf.load_urdf_model`` calls :func:`load_mjcf_model` for ``.xml``
files, so that a robot read from MJCF is built, locked, derived and cached like one read from a URDF
(``RobotDescription.urdf_path`` then names the ``.xml`` file).

**What is read.** MuJoCo compiles the file (defaults classes, ``compiler angle`` in degrees or radians, frames
given by ``pos``/``quat``/``euler``/``axisangle``/``xyaxes``/``zaxis``, ``fullinertia`` or ``diaginertia`` and
``quat`` of the inertials), and the compiled model gives the chain: one Pinocchio joint per ``hinge`` or ``slide``
joint, its frame the body's frame moved to the joint's ``pos``, its axis the joint's, its angle MuJoCo's ``qpos``
(a joint's ``ref`` included); bodies welded to a moving body (no joint) are lumped into it, as Pinocchio lumps a
URDF's fixed links; bodies welded to the world are the base and carry no inertia of the arm. Joint ranges are the
``range`` of limited joints (else ``[-pi, pi]``, as for a URDF); the torque limit the joint's ``actuatorfrcrange``
or its actuators' ``forcerange`` (times gear), else none; gravity ``option gravity``. ``armature``, ``damping`` and
``frictionloss`` are not read: they are what identification finds.

**Meshes are not needed.** Only the kinematics and inertials matter: the file is compiled without its assets
(meshes, textures, materials), without the geoms of bodies that have an ``<inertial>`` and without ``<include>``
files, so that a robot reads the same with or without its meshes (from a calibrated-model file, which keeps only
the XML's text). A body without ``<inertial>`` takes its inertia from its geoms, which then must not be meshes.

**Refused** with a RobotFileError naming the element and the fix: free and ball joints, more than one joint on a
body, tendons, equality constraints (closed loops), ``<include>``. Branches (two moving bodies below one: a torso
with two arms) are read as a tree, as from a URDF. A gripper's fingers (Menagerie's Panda: two slide joints, a
fixed tendon and an equality constraint between them) are read when their joints are locked (``--lock``): the
couplings of locked joints only are dropped.
"""

from __future__ import annotations

import importlib.util
import logging
import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from psdm_casadi.errors import RobotFileError
from psdm_casadi.text_file import read_text_file


def _lazy_module(name: str):
    """``name`` imported on its first attribute use (``importlib.util.LazyLoader``): MuJoCo (~20 MB resident) is
    loaded only when an MJCF file is read, not by every process that imports the robot readers (a fleet's Dask
    worker)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


mujoco = _lazy_module("mujoco")

__all__ = ["MJCF_SUFFIXES", "compile_mjcf", "load_mjcf_model", "mjcf_gravity", "route_mujoco_warnings"]

logger = logging.getLogger(__name__)

MJCF_SUFFIXES = (".xml", ".mjcf")
STRIPPED_SECTIONS = ("asset", "sensor", "visual", "keyframe", "contact", "custom")  # no part of the arm's dynamics
ASSET_REFERENCES = ("material", "mesh", "hfield", "texture", "skin")  # attributes naming an asset that is removed
UNIT_AXES = {(1.0, 0.0, 0.0): pin.JointModelRX, (0.0, 1.0, 0.0): pin.JointModelRY, (0.0, 0.0, 1.0): pin.JointModelRZ}
UNIT_SLIDES = {(1.0, 0.0, 0.0): pin.JointModelPX, (0.0, 1.0, 0.0): pin.JointModelPY, (0.0, 0.0, 1.0): pin.JointModelPZ}


def _mujoco_warning(text: str) -> None:
    logger.warning("MuJoCo: %s", " ".join(str(text).split()))


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to ``logging`` rather than to a ``MUJOCO_LOG.TXT`` in the working folder (unless the
    process installed its own handler)."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_mujoco_warning)


def _refuse_unsupported(path: Path, root: ET.Element, locked=()) -> None:
    """Refuse what an arm of hinge and slide joints cannot hold (module docstring), naming the element;
    couplings of locked joints only are removed (:func:`_drop_locked_couplings`)."""
    _drop_locked_couplings(path, root, set(locked))
    for tag, what, fix in (
        ("include", "an <include> file", "inline it, or pass the included robot file itself"),
        ("freejoint", "a free joint (a floating base)", "fix the base: remove the <freejoint>"),
    ):
        if any(True for _ in root.iter(tag)):
            raise RobotFileError(
                f"MJCF {path.name!r} holds {what}, which psdm cannot read (an arm of hinge and slide joints, "
                f"a chain or a tree); {fix}."
            )


def _drop_locked_couplings(path: Path, root: ET.Element, locked: set) -> None:
    """Remove the fixed tendons and joint/tendon equality constraints that couple locked joints only (a gripper's
    fingers) with the actuators on those tendons; refuse any other tendon or equality constraint."""
    removed = set()
    for section in list(root.iter("tendon")):
        for tendon in list(section):
            joints = {node.get("joint") for node in tendon.iter("joint")}
            if tendon.tag != "fixed" or not joints or not joints <= locked:
                raise RobotFileError(
                    f"MJCF {path.name!r} holds the {tendon.tag} tendon {tendon.get('name', '?')!r} (joints "
                    f"{sorted(j for j in joints if j)}), which psdm cannot read (an arm of hinge and slide "
                    "joints); lock the joints it couples (a gripper's: --lock, or locked_joints in a robot file's "
                    "[urdf] table) or remove the <tendon>."
                )
            removed.add(tendon.get("name"))
            section.remove(tendon)
    for section in list(root.iter("equality")):
        for constraint in list(section):
            joints = {constraint.get(key) for key in ("joint1", "joint2")} - {None}
            tendons = {constraint.get(key) for key in ("tendon1", "tendon2")} - {None}
            if not ((constraint.tag == "joint" and joints and joints <= locked) or (tendons and tendons <= removed)):
                named = f"<{constraint.tag}> {constraint.get('name') or ''}".strip()
                raise RobotFileError(
                    f"MJCF {path.name!r} holds the equality constraint {named} (closed loops, coupled joints), which "
                    "psdm cannot read (an arm without closed loops); remove it, or lock the joints it couples (--lock)."
                )
            section.remove(constraint)
    for section in root.iter("actuator"):
        for actuator in [a for a in section if a.get("tendon") in removed]:
            section.remove(actuator)


def _stripped(path: Path, root: ET.Element) -> str:
    """The file's XML without assets, asset references, visual-only geoms and sensors (module docstring)."""
    for parent in [root, *root.iter()]:
        for child in list(parent):
            if child.tag in STRIPPED_SECTIONS:
                parent.remove(child)
    for node in root.iter():
        for key in ASSET_REFERENCES:
            node.attrib.pop(key, None)
        if node.tag == "compiler":
            for key in ("meshdir", "texturedir", "assetdir"):
                node.attrib.pop(key, None)
    from_geoms = any(node.get("inertiafromgeom") == "true" for node in root.iter("compiler"))
    for body in root.iter("body"):
        if body.find("inertial") is not None and not from_geoms:
            for geom in body.findall("geom"):
                body.remove(geom)
    return ET.tostring(root, encoding="unicode")


def _compiled(path: Path, locked=()) -> mujoco.MjModel:
    """MuJoCo's compiled model of the stripped file, its errors as a RobotFileError."""
    return compile_mjcf(read_text_file(path, what="MJCF"), path.name, locked)


def compile_mjcf(text: str, name: str = "MJCF", locked=()) -> mujoco.MjModel:
    """MuJoCo's model of an MJCF text compiled without its meshes (module docstring), for its dynamics.

    ``locked`` names the joints the caller locks: tendons and equality constraints coupling only them are removed.

    Raises
    ------
    RobotFileError
        Naming ``name``, for text that is not MJCF, holds what psdm refuses, or MuJoCo cannot compile.
    """
    path = Path(name)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(f"MJCF {path.name!r} must be valid XML; got {exc}. Fix the file.") from None
    if root.tag != "mujoco":
        raise RobotFileError(
            f"MJCF {path.name!r} must have the root element <mujoco>; got <{root.tag}>. Give an MJCF file (or a "
            "URDF ending in .urdf)."
        )
    _refuse_unsupported(path, root, locked)
    route_mujoco_warnings()
    try:
        return mujoco.MjModel.from_xml_string(_stripped(path, root))
    except ValueError as exc:
        detail = " ".join(str(exc).split())
        hint = " (a body without <inertial> takes its inertia from its geoms, here meshes: give it an <inertial>)"
        raise RobotFileError(
            f"MJCF {path.name!r} must compile in MuJoCo without its meshes; MuJoCo says: {detail}"
            + (hint if "mesh" in detail.lower() else "")
            + ". Fix the file."
        ) from None


def mjcf_gravity(path) -> np.ndarray:
    """The file's gravity [m/s^2] (``<option gravity>``, MuJoCo's default ``0 0 -9.81``)."""
    return np.array(_compiled(Path(path)).opt.gravity, dtype=float)


def _frame(mj: mujoco.MjModel, body: int) -> pin.SE3:
    """The placement of a body's frame in its parent body's frame."""
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, mj.body_quat[body])
    return pin.SE3(rotation.reshape(3, 3), np.array(mj.body_pos[body], dtype=float))


def _inertia(mj: mujoco.MjModel, body: int, offset: np.ndarray) -> pin.Inertia:
    """The body's inertia in its frame moved by ``offset`` (the joint position): mass, centre of mass, tensor."""
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, mj.body_iquat[body])
    rotation = rotation.reshape(3, 3)
    tensor = rotation @ np.diag(mj.body_inertia[body]) @ rotation.T
    return pin.Inertia(float(mj.body_mass[body]), np.array(mj.body_ipos[body]) - offset, 0.5 * (tensor + tensor.T))


def _joint_model(path: Path, mj: mujoco.MjModel, joint: int, name: str):
    kind = int(mj.jnt_type[joint])
    axis = np.array(mj.jnt_axis[joint], dtype=float)
    if kind == mujoco.mjtJoint.mjJNT_HINGE:
        unit = UNIT_AXES.get(tuple(axis))
        return unit() if unit is not None else pin.JointModelRevoluteUnaligned(axis)
    if kind == mujoco.mjtJoint.mjJNT_SLIDE:
        unit = UNIT_SLIDES.get(tuple(axis))
        return unit() if unit is not None else pin.JointModelPrismaticUnaligned(axis)
    what = "a free joint (a floating base)" if kind == mujoco.mjtJoint.mjJNT_FREE else "a ball joint"
    raise RobotFileError(
        f"MJCF {path.name!r} joint {name!r} is {what}; psdm reads hinge and slide joints only. Fix the base or "
        "replace the ball joint by three hinges in a chain of bodies."
    )


def _reference_motion(mj: mujoco.MjModel, joint: int) -> pin.SE3:
    """The joint's motion by ``-ref``: MuJoCo's angle is ``ref`` where the body sits as written, Pinocchio's is 0
    at its joint placement, so the placement is turned back by ``ref`` and both read the same angle."""
    ref = float(mj.qpos0[mj.jnt_qposadr[joint]])
    axis = np.array(mj.jnt_axis[joint], dtype=float)
    if ref == 0.0:
        return pin.SE3.Identity()
    if mj.jnt_type[joint] == mujoco.mjtJoint.mjJNT_HINGE:
        return pin.SE3(pin.AngleAxis(-ref, axis).matrix(), np.zeros(3))
    return pin.SE3(np.eye(3), -ref * axis)


def _name(mj: mujoco.MjModel, kind, index: int, fallback: str) -> str:
    return mujoco.mj_id2name(mj, kind, index) or fallback


def _torque_limit(mj: mujoco.MjModel, joint: int) -> float:
    """The joint's ``actuatorfrcrange``, else its actuators' ``forcerange`` times gear, else infinity."""
    if mj.jnt_actfrclimited[joint]:
        return float(np.abs(mj.jnt_actfrcrange[joint]).max())
    limits = [
        float(np.abs(mj.actuator_forcerange[a]).max() * abs(mj.actuator_gear[a, 0]))
        for a in range(mj.nu)
        if mj.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
        and mj.actuator_trnid[a, 0] == joint
        and mj.actuator_forcelimited[a]
    ]
    return max(limits) if limits else math.inf


def load_mjcf_model(path, locked=()) -> pin.Model:
    """The Pinocchio model of the arm (a chain or a tree) of an MJCF file (module docstring).

    Parameters
    ----------
    path : str or Path
        MJCF file (``.xml``); meshes are not needed.
    locked : iterable of str
        Joints the caller locks (``urdf.load_urdf_model``): tendons and equality constraints that couple only them
        are dropped.

    Returns
    -------
    pinocchio.Model
        One joint per hinge or slide joint with the file's inertias, ranges, torque limits (velocity limits 0:
        MJCF has none) and gravity; a body frame per MuJoCo body.

    Raises
    ------
    RobotFileError
        For a file MuJoCo cannot compile without its meshes, and for what the module docstring refuses.
    """
    path, locked = Path(path), set(locked)
    mj = _compiled(path, locked)
    model = pin.Model()
    model.name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, 0) or path.stem
    carrier = {0: (0, pin.SE3.Identity(), 0)}  # body -> (Pinocchio joint it moves with, its frame there, frame id)
    lower, upper, effort = [], [], []
    for body in range(1, mj.nbody):
        body_name = _name(mj, mujoco.mjtObj.mjOBJ_BODY, body, f"body{body}")
        parent_joint, parent_frame, parent_id = carrier[int(mj.body_parentid[body])]
        frame = parent_frame * _frame(mj, body)
        if mj.body_jntnum[body] > 1:
            raise RobotFileError(
                f"MJCF {path.name!r} body {body_name!r} has {mj.body_jntnum[body]} joints; psdm reads one joint per "
                "body. Give each joint a body of its own (a massless body between them)."
            )
        if mj.body_jntnum[body] == 0:
            if parent_joint > 0:
                model.appendBodyToJoint(parent_joint, _inertia(mj, body, np.zeros(3)), frame)
            carrier[body] = (parent_joint, frame, model.addBodyFrame(body_name, parent_joint, frame, parent_id))
            continue
        joint = int(mj.body_jntadr[body])
        joint_name = _name(mj, mujoco.mjtObj.mjOBJ_JOINT, joint, f"{body_name}_joint")
        offset = np.array(mj.jnt_pos[joint], dtype=float)
        jmodel = _joint_model(path, mj, joint, joint_name)
        placement = frame * pin.SE3(np.eye(3), offset) * _reference_motion(mj, joint)
        jid = model.addJoint(parent_joint, jmodel, placement, joint_name)
        model.appendBodyToJoint(jid, _inertia(mj, body, offset), pin.SE3.Identity())
        joint_frame = model.addJointFrame(jid, parent_id)
        body_frame = model.addBodyFrame(body_name, jid, pin.SE3(np.eye(3), -offset), joint_frame)
        carrier[body] = (jid, pin.SE3(np.eye(3), -offset), body_frame)
        limited = bool(mj.jnt_limited[joint])
        lower.append(float(mj.jnt_range[joint, 0]) if limited else -math.inf)
        upper.append(float(mj.jnt_range[joint, 1]) if limited else math.inf)
        effort.append(_torque_limit(mj, joint))
    model.lowerPositionLimit, model.upperPositionLimit = np.array(lower), np.array(upper)
    model.effortLimit, model.velocityLimit = np.array(effort), np.zeros(len(effort))
    if hasattr(model, "lowerEffortLimit"):  # Pinocchio 4 keeps both bounds (the lower velocity one as a magnitude)
        model.lowerEffortLimit, model.lowerVelocityLimit = -np.array(effort), np.zeros(len(effort))
    model.gravity.linear = np.array(mj.opt.gravity, dtype=float)
    return model
