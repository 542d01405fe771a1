"""A robot file's ``[[link]]`` tables on a URDF robot: inertials that replace the URDF's, link by link.

Vendor URDFs often carry inertials that are wrong (edited by hand, copied from another variant, without
the tool that hangs at the flange). The identification takes the robot's link inertials as its prior and
centres its mass bounds on them (0.5-2x by default), so a URDF mass that is too low presses a link
against its upper bound. A robot file with a ``[urdf]`` table may therefore state, per URDF link::

    [[link]]
    name = "forearm_link"     # a URDF link moved by a joint (or a fixed link lumped onto it)
    mass = 0.9302             # [kg]
    com = [0.0, -0.0755, -0.0150]                          # optional, in the link frame [m]
    inertia = [0.008147, 0.000631, 0.008316, 0.0, 0.0, -0.0005]   # optional, about the COM: Ixx Iyy Izz Ixy Ixz Iyz

The values replace those of the whole body the joint moves (its child link with the fixed links Pinocchio
lumps onto it). A key left out keeps the URDF's value; a mass given without an inertia scales the URDF's
inertia about the centre of mass by the ratio of the masses (the same shape, heavier or lighter), so that
the link stays physical. A stated inertia replaces a URDF inertia that was unusable (its stand-in, see
``urdf.from_urdf``), which is then no longer reported.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from psdm_casadi.description import LinkInertia, RobotDescription
from psdm_casadi.errors import RobotFileError
from psdm_casadi.file_values import file_number, file_vector
from psdm_casadi.urdf import moving_link_names
from psdm_casadi.values import format_value

__all__ = ["LINK_OVERRIDE_KEYS", "apply_link_overrides"]

logger = logging.getLogger(__name__)

#: The keys of a ``[[link]]`` table in a robot file with a ``[urdf]`` table.
LINK_OVERRIDE_KEYS = ("name", "mass", "com", "inertia", "rotor_inertia")
_EXAMPLE = '[[link]] with name = "forearm_link" and mass = 0.93 (optional com = [...], inertia = [...])'


def apply_link_overrides(robot: RobotDescription, tables, where: str) -> RobotDescription:
    """``robot`` (read from its URDF) with the inertials of the robot file's ``[[link]]`` tables in place.

    Raises
    ------
    RobotFileError
        Naming the file, the table and the fix: not a list of tables, an unknown key, a missing or unknown
        link name, two tables for the same joint, a value that is not physical.
    """
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise RobotFileError(f"{where} [[link]] must be an array of tables; got {format_value(tables)}. {_EXAMPLE}.")
    names = moving_link_names(robot.urdf_path, robot.locked_joints)
    links, rotor = list(robot.links), np.array(robot.rotor_inertia, dtype=float)
    replaced = {r.joint: r for r in robot.replaced_inertias}
    seen = {}
    for i, table in enumerate(tables):
        lwhere = f"{where} link[{i + 1}]"
        joint = _joint_of(table, names, lwhere)
        if joint in seen:
            raise RobotFileError(
                f"{lwhere} names {table['name']!r}, moved by the same joint as link[{seen[joint] + 1}] "
                f"({' + '.join(names[joint])} are one body). State the body once."
            )
        seen[joint] = i
        links[joint], stated_inertia = _override(links[joint], table, lwhere)
        if "rotor_inertia" in table:
            rotor[joint] = _rotor(table["rotor_inertia"], lwhere)
        if stated_inertia:
            replaced.pop(joint, None)
        logger.debug("%s: link %s (joint %d) %s from the robot file", where, table["name"], joint + 1, links[joint])
    return replace(robot, links=tuple(links), rotor_inertia=rotor, replaced_inertias=tuple(replaced.values()))


def _joint_of(table: dict, names: tuple, where: str) -> int:
    """The 0-based joint whose body holds the table's ``name``, after checking its keys."""
    unknown = sorted(str(k) for k in set(table) - set(LINK_OVERRIDE_KEYS))
    if unknown:
        raise RobotFileError(
            f"{where} has unknown key(s) {unknown}; allowed keys in a robot file with a [urdf] table are "
            f"{list(LINK_OVERRIDE_KEYS)}. Check the spelling."
        )
    if "name" not in table or not isinstance(table["name"], str):
        raise RobotFileError(f"{where}.name must name a URDF link; got {format_value(table.get('name'))}. {_EXAMPLE}.")
    if len(table) == 1:
        raise RobotFileError(
            f"{where} states nothing about {table['name']!r}; give mass, com, inertia or rotor_inertia."
        )
    for joint, bodies in enumerate(names):
        if table["name"] in bodies:
            return joint
    moving = [n for bodies in names for n in bodies]
    raise RobotFileError(
        f"{where}.name must be a URDF link moved by a joint; got {table['name']!r}. Links are {moving}; check the "
        "spelling (a link fixed to the world carries no joint torque)."
    )


def _override(link: LinkInertia, table: dict, where: str) -> tuple:
    """(the link with the table's mass, com and inertia; whether an inertia was stated)."""
    mass = link.mass
    if "mass" in table:
        mass = file_number(table["mass"], f"{where}.mass", "Give the mass in kg.")
        if mass < 0:
            raise RobotFileError(f"{where}.mass must be >= 0 [kg]; got {format_value(mass)}. Give the mass in kg.")
    com = file_vector(table["com"], 3, f"{where}.com") if "com" in table else link.com
    if "inertia" in table:
        inertia = file_vector(table["inertia"], 6, f"{where}.inertia ([Ixx, Iyy, Izz, Ixy, Ixz, Iyz])")
    else:  # the URDF's shape, scaled with the mass
        inertia = link.inertia * (mass / link.mass) if link.mass > 0 else np.zeros((3, 3))
    try:
        return LinkInertia(mass=mass, com=com, inertia=inertia), "inertia" in table
    except RobotFileError as exc:
        raise RobotFileError(f"{where}: {exc}") from None


def _rotor(value, where: str) -> float:
    rotor = file_number(value, f"{where}.rotor_inertia", "Give it in kg m^2.")
    if rotor < 0:
        raise RobotFileError(f"{where}.rotor_inertia must be >= 0 [kg m^2]; got {format_value(rotor)}. Fix the sign.")
    return rotor
