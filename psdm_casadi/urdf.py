"""Reading a URDF through Pinocchio: the Pinocchio model of the file and the RobotDescription it gives.

The one place that parses URDF files. The robot-file reader (``robot_file``) calls ``from_urdf``
for ``.urdf`` files and ``[urdf]`` tables; the oracle calls ``load_urdf_model`` to rebuild the
kinematics of a robot that came from a URDF.

Pinocchio's URDF parser (urdfdom, C++) prints its complaints on the process's stderr and, for some
malformed values (``mass="nan"``), skips the element and returns a model anyway. The parser's
output is therefore captured at the file-descriptor level: an ``Error:`` from it turns into a
RobotFileError naming the file (with the parser's own words), anything else goes to ``logging``.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from psdm_casadi.description import GRAVITY_STANDARD, Joint, LinkInertia, RobotDescription, locked_positions
from psdm_casadi.errors import RobotFileError
from psdm_casadi.mjcf import MJCF_SUFFIXES, load_mjcf_model
from psdm_casadi.said_once import say
from psdm_casadi.text_file import read_text_file
from psdm_casadi.values import format_value, inertia_violation

logger = logging.getLogger(__name__)

# A joint origin whose rotation lies this close [rad, about] to a right-angle one (rpy written with 4-5 digits:
# 3.1416, 1.5708) is taken as that right-angle rotation: the derivation needs the exact zeros of its sines.
RIGHT_ANGLE_TOLERANCE = 1e-4

# The stand-in for an unusable URDF inertia is a uniform solid sphere about the link's centre of mass, of the
# link's mass and of the link's size: radius the larger of half the distance to the next joint, the distance of
# the centre of mass from the joint, and this floor [m].
MIN_STAND_IN_RADIUS = 0.02


@dataclass(frozen=True)
class ReplacedInertia:
    """A URDF link inertia that is not physical, and the neutral stand-in the robot carries in its place.

    Parameters
    ----------
    joint : int
        0-based joint whose moving link it is (Pinocchio lumps fixed children onto it).
    link : str
        The URDF link names lumped on that joint, for messages.
    problem : str
        The violated condition, with the principal moments (:func:`psdm_casadi.values.inertia_violation`).
    radius : float
        [m] Radius of the solid sphere of the link's mass that replaces the inertia about the centre of mass.
    """

    joint: int
    link: str
    problem: str
    radius: float

    def message(self, source: str) -> str:
        """The warning: which link, which condition, what replaced it, and the fix."""
        return (
            f"{source}: the inertia of link {self.link} (joint {self.joint + 1}) is unusable: it {self.problem}. "
            f"Its kinematics, mass and centre of mass are kept; its inertia is replaced by a solid sphere of its mass "
            f"(radius {self.radius:.3g} m), the weak prior identification decides from the data. To use the "
            "vendor's inertia, correct it in the URDF (e.g. from the vendor's CAD or xacro)."
        )


@contextmanager
def captured_stderr():
    """Redirect file descriptor 2 (C and C++ ``stderr``) to a temporary file; yield a list that receives its lines.

    Examples
    --------
    >>> with captured_stderr() as lines:            # doctest: +SKIP
    ...     model = pin.buildModelFromUrdf("robot.urdf")
    """
    lines: list[str] = []
    for stream in (sys.stderr, sys.__stderr__):
        if stream is not None:
            stream.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no stderr to protect (a daemon with fd 2 closed)
        yield lines
        return
    try:
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield lines
            finally:
                os.dup2(saved, 2)
                sink.seek(0)
                lines.extend(sink.read().decode("utf-8", "replace").splitlines())
    finally:
        os.close(saved)


def _parser_errors(lines: list) -> list:
    """The messages of urdfdom's ``Error:`` lines (without its ``at line N in file.cpp`` trailers)."""
    errors = []
    for line in lines:
        text = line.strip()
        if text.startswith("Error:"):
            errors.append(" ".join(text[len("Error:") :].split()))
        elif text and not text.startswith("at line "):
            logger.debug("URDF parser: %s", text)
    return errors


def _parse_urdf(path: Path) -> pin.Model:
    """Pinocchio's model of a URDF file, with the parser's stderr captured and its errors raised."""
    read_text_file(path, what="URDF", decode=False)
    failure = None
    with captured_stderr() as lines:
        try:
            model = pin.buildModelFromUrdf(str(path))
        except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with its own text
            failure = str(exc)
    errors = _parser_errors(lines)
    if failure is not None or errors:
        detail = "; ".join(errors[:3]) or failure
        raise RobotFileError(
            f"URDF {path.name!r} must be a valid URDF; Pinocchio could not read the URDF ({detail}). Fix the file."
        )
    return model


def load_urdf_model(path: Path, locked_joints=()) -> pin.Model:
    """Parse a URDF with Pinocchio and lock the named joints at their given positions.

    Parameters
    ----------
    path : str or Path
        URDF file; meshes are not needed.
    locked_joints : sequence of str or (str, float), or mapping str -> float
        Joints fixed at a position [rad or m] (e.g. gripper fingers); a bare name locks at zero.

    Returns
    -------
    pinocchio.Model
        With the inertias and limits of the file; a locked joint's link is fixed to its parent at the
        given position (Pinocchio's ``buildReducedModel`` about that reference configuration).

    Raises
    ------
    RobotFileError
        When Pinocchio cannot parse the file, a locked joint is not a joint of it, or a lock value lies
        outside the joint's limits or is nonzero for a joint with more than one degree of freedom.
    """
    path = Path(path)
    locked = locked_positions(locked_joints)
    if path.suffix.lower() in MJCF_SUFFIXES:
        model = load_mjcf_model(path, [name for name, _ in locked])
    else:
        model = _parse_urdf(path)
    _square_joint_origins(path, model)
    if locked:
        reference = pin.neutral(model)
        ids = []
        for name, value in locked:
            if not model.existJointName(name):
                raise RobotFileError(
                    f"{path.name}: urdf.locked_joints names {name!r}, which is not a joint of the URDF; "
                    f"joints are {list(model.names)[1:]}. Check the spelling."
                )
            ids.append(model.getJointId(name))
            _set_locked_position(path, model, ids[-1], value, reference)
        model = pin.buildReducedModel(model, ids, reference)
    return model


def _square_joint_origins(path: Path, model: pin.Model) -> None:
    """Make joint origins within ``RIGHT_ANGLE_TOLERANCE`` of a right-angle rotation exactly that rotation.

    Vendor URDFs write pi/2 and pi with a few digits (``rpy="3.1416 0 0"``): a sine of 7e-6 where the
    kinematics have a zero, which the derivation's structure cannot hold (it then misses Pinocchio's rnea
    by percent). The change moves no point of the arm by more than the rounding of the file.
    """
    squared = []
    for jid in range(1, model.njoints):
        placement = model.jointPlacements[jid]
        exact = np.round(placement.rotation)
        gap = float(np.abs(placement.rotation - exact).max())
        is_rotation = np.all(np.abs(exact).sum(axis=0) == 1) and np.all(np.abs(exact).sum(axis=1) == 1)
        if 0.0 < gap < RIGHT_ANGLE_TOLERANCE and is_rotation and np.linalg.det(exact) > 0:
            placement.rotation = exact
            model.jointPlacements[jid] = placement
            squared += [model.names[jid]] if gap > 1e-12 else []  # not the round-off of an exact pi/2
    if squared:
        _state_once(
            f"{path.name}: the origins of {', '.join(squared)} are within {RIGHT_ANGLE_TOLERANCE:g} rad of right "
            "angles (rpy written with few digits, e.g. 3.1416); they are taken as exact right angles."
        )


@functools.lru_cache(maxsize=64)
def _state_once(message: str) -> None:
    """Log a choice made on reading a file once per process, not on every reload of the same file."""
    logger.info("%s", message)


def _set_locked_position(path: Path, model: pin.Model, jid: int, value: float, reference: np.ndarray) -> None:
    """Write a locked joint's position ``value`` [rad or m] into the reference configuration, within its limits."""
    jmodel, name = model.joints[jid], model.names[jid]
    idx = jmodel.idx_q
    if jmodel.nq == 1:
        low, high = float(model.lowerPositionLimit[idx]), float(model.upperPositionLimit[idx])
        if np.isfinite(low) and np.isfinite(high) and low < high and not low <= value <= high:
            raise RobotFileError(
                f"{path.name}: locked joint {name!r} must be locked within its limits [{format_value(low)}, "
                f"{format_value(high)}]; got {format_value(value)}. Give a position within them (rad or m)."
            )
        reference[idx] = value
    elif jmodel.nq == 2 and jmodel.nv == 1:  # a continuous joint: (cos, sin) of its angle
        reference[idx : idx + 2] = math.cos(value), math.sin(value)
    elif value != 0.0:
        raise RobotFileError(
            f"{path.name}: locked joint {name!r} has {jmodel.nv} degrees of freedom ({jmodel.shortname()}); it "
            f"can be locked only at its neutral configuration (0); got {format_value(value)}. Lock it at 0."
        )


def from_urdf(path, *, locked_joints=(), gravity=None, name=None, warn: bool = True) -> RobotDescription:
    """Read a URDF through Pinocchio: joints, limits and link inertias.

    Parameters
    ----------
    path : str or Path
        URDF file; meshes are not needed.
    locked_joints : sequence of str or (str, float), or mapping str -> float
        Joints fixed at a position [rad or m] (e.g. gripper fingers); a bare name locks at zero.
    gravity : array, shape (3,), optional
        Gravity acceleration in the base frame [m/s^2]; default ``[0, 0, -9.806132]``.
    name : str, optional
        Robot name; default the file's stem.
    warn : bool
        Log the unusable inertias (below) here; a robot file that may replace them (``[[link]]`` tables) logs
        those that remain itself.

    Returns
    -------
    RobotDescription
        With ``urdf_path`` set, so that the oracle and the derivation rebuild the same kinematics.

    Raises
    ------
    RobotFileError
        When the file is not a readable URDF (the parser's errors are quoted), a locked joint is
        unknown or locked outside its limits, a joint is neither revolute nor prismatic with one
        degree of freedom, its limits are swapped, or a link's mass is negative.

    Warns
    -----
    A link inertia that is not positive semi-definite or violates the triangle inequality (finite
    numbers) is unusable but not refused: the kinematics, mass and centre of mass are kept, the
    inertia is replaced by a solid sphere of the link's mass and size, the warning names the link
    and the violated condition, and ``RobotDescription.replaced_inertias`` lists them. The stand-in is
    the prior of those links like any link's: the fit's pull towards the robot file is weak everywhere
    (it settles only what the data leave free); pulling the stand-in even less let a link shed its mass
    into a far centre of mass on the Kinova currents (0.03 kg at 2 m), so it is not.

    Notes
    -----
    A joint without position limits (lower = upper, the URDF default) gets ``[-pi, pi]``; one
    without a velocity limit 2 rad/s; one without an effort limit no torque limit. URDF has no
    acceleration limits: ``qdd_max`` is 10 (override it in a robot file's ``[urdf.limits.<joint>]``).
    """
    path = Path(path)
    model = load_urdf_model(path, locked_joints)
    joints, links, replaced = [], [], []
    for jid in range(1, model.njoints):
        where = f"{path.name} joint {model.names[jid]!r}"
        try:
            joints.append(_joint(model, jid))
            link, stand_in = _link_inertia(model, jid)
        except RobotFileError as exc:
            raise RobotFileError(f"{where} (link {_body_names(model, jid)}): {exc}") from None
        links.append(link)
        if stand_in is not None:
            replaced.append(stand_in)
            if warn:
                say(logger, stand_in.message(path.name))
    if not joints:
        raise RobotFileError(
            f"{path.name} must hold at least one revolute or prismatic joint; got none (only fixed or floating "
            "joints, or every joint locked). Check the file and the locked joints."
        )
    g = np.array([0.0, 0.0, -GRAVITY_STANDARD]) if gravity is None else gravity
    if gravity is None and path.suffix.lower() in MJCF_SUFFIXES:  # an MJCF states its gravity (option gravity)
        g = np.array(model.gravity.linear, dtype=float)
    return RobotDescription(
        name=name or path.stem,
        joints=tuple(joints),
        convention="standard",
        gravity=g,
        links=tuple(links),
        urdf_path=str(path.resolve()),
        locked_joints=locked_positions(locked_joints),
        source=str(path),
        replaced_inertias=tuple(replaced),
    )


def _link_inertia(model: pin.Model, jid: int):
    """``(LinkInertia, ReplacedInertia or None)`` of joint ``jid``'s link: the file's, or the neutral stand-in.

    A mass, centre of mass and inertia that are finite with a mass >= 0 but an inertia that is not positive
    semi-definite or breaks the triangle inequality (a vendor file edited by hand) are kept for their mass
    and centre of mass; the inertia becomes a solid sphere of the link's mass and size (``MIN_STAND_IN_RADIUS``).
    Anything else that is not physical (a negative or non-finite number) is refused by ``LinkInertia``.
    """
    inertia = model.inertias[jid]
    mass, com, tensor = float(inertia.mass), np.array(inertia.lever), np.array(inertia.inertia)
    problem = None
    if np.isfinite(mass) and mass >= 0 and np.all(np.isfinite(com)) and np.all(np.isfinite(tensor)):
        problem = inertia_violation(tensor)
    if problem is None:
        return LinkInertia(mass=mass, com=com, inertia=tensor), None
    children = [k for k in range(jid + 1, model.njoints) if model.parents[k] == jid]
    reach = max((float(np.linalg.norm(model.jointPlacements[k].translation)) for k in children), default=0.0)
    radius = max(0.5 * reach, float(np.linalg.norm(com)), MIN_STAND_IN_RADIUS)
    sphere = 0.4 * mass * radius**2 * np.eye(3)
    stand_in = ReplacedInertia(joint=jid - 1, link=_body_names(model, jid), problem=problem, radius=radius)
    return LinkInertia(mass=mass, com=com, inertia=sphere), stand_in


def _joint(model: pin.Model, jid: int) -> Joint:
    """The Joint of Pinocchio joint ``jid``: kind and the URDF's limits (defaults where the URDF has none)."""
    jmodel = model.joints[jid]
    shortname = jmodel.shortname()
    if jmodel.nq != 1 or jmodel.nv != 1:
        raise RobotFileError(
            f"the joint must have one degree of freedom (revolute or prismatic); got type {shortname} with "
            f"nq={jmodel.nq}. Lock it or make it revolute with limits."
        )
    kind = "prismatic" if "Prismatic" in shortname or shortname.startswith("JointModelP") else "revolute"
    idx = jmodel.idx_q
    q_min, q_max = float(model.lowerPositionLimit[idx]), float(model.upperPositionLimit[idx])
    if q_min > q_max:
        raise RobotFileError(
            f"<limit> lower must be below upper; got lower={format_value(q_min)}, upper={format_value(q_max)}. "
            "Swap them."
        )
    if not (np.isfinite(q_min) and np.isfinite(q_max) and q_min < q_max):
        q_min, q_max = -math.pi, math.pi
    qd_max = float(model.velocityLimit[idx]) if model.velocityLimit[idx] > 0 else 2.0
    tau_max = float(model.effortLimit[idx]) if model.effortLimit[idx] > 0 else math.inf
    return Joint(
        name=model.names[jid],
        kind=kind,
        q_min=q_min,
        q_max=q_max,
        qd_max=min(qd_max, 1e3),
        qdd_max=10.0,
        tau_max=tau_max,
    )


def moving_link_names(path, locked_joints=()) -> tuple:
    """Per moving joint (base to tip), the URDF links it carries: its child and the fixed links lumped onto it.

    The names a robot file's ``[[link]]`` tables use to replace a URDF link's inertial (``link_overrides``).
    """
    model = load_urdf_model(Path(path), locked_joints)
    return tuple(
        tuple(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jid)
        for jid in range(1, model.njoints)
    )


def _body_names(model: pin.Model, jid: int) -> str:
    """The URDF links whose inertia Pinocchio lumped onto joint ``jid`` (its child and fixed descendants)."""
    names = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jid]
    return ", ".join(repr(n) for n in names) or "?"
