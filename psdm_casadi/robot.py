"""The robot, first step of the flow: the RobotDescription value and the three ways to build one.

A robot comes from Python DH rows (``from_dh``, here), from a TOML robot file (``load_robot``, in
``robot_file``) or from a URDF read by Pinocchio (``from_urdf``, in ``urdf``). The value itself and
its parts live in ``description``. This module is the one import path for all of them; it imports
those modules and none of them imports it, so there is no cycle.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.description import (
    CONVENTIONS,
    GRAVITY_STANDARD,
    JOINT_KINDS,
    PHYSICAL_PARAMETER_NAMES,
    DriveParameters,
    Joint,
    LinkInertia,
    RobotDescription,
    parse_parameter_name,
    physical_to_dynamic,
)
from psdm_casadi.errors import RobotFileError
from psdm_casadi.robot_file import (
    BUILTIN_ROBOTS_DIR,
    ROBOT_FORMAT,
    builtin_robot_names,
    load_robot,
    resolve_robot_path,
    robot_from_mapping,
)
from psdm_casadi.urdf import from_urdf

__all__ = [
    "BUILTIN_ROBOTS_DIR",
    "CONVENTIONS",
    "GRAVITY_STANDARD",
    "JOINT_KINDS",
    "PHYSICAL_PARAMETER_NAMES",
    "ROBOT_FORMAT",
    "DriveParameters",
    "Joint",
    "LinkInertia",
    "RobotDescription",
    "builtin_robot_names",
    "from_dh",
    "from_urdf",
    "load_robot",
    "parse_parameter_name",
    "physical_to_dynamic",
    "resolve_robot_path",
    "robot_from_mapping",
]


def from_dh(
    rows,
    *,
    convention="standard",
    kinds=None,
    gravity=(0.0, 0.0, -GRAVITY_STANDARD),
    name="robot",
    drive_inertia=(),
    massless_links=(),
    zero_parameters=(),
    links=None,
    rotor_inertia=None,
    limits=None,
) -> RobotDescription:
    """Build a RobotDescription from DH rows ``(a, alpha, d, theta)``.

    Parameters
    ----------
    rows : sequence of 4-sequences
        DH rows (a [m], alpha [rad], d [m], theta offset [rad]).
    kinds : sequence of str, optional
        "revolute" (default) or "prismatic" per joint.
    limits : sequence of dict, optional
        Per joint keyword limits (q_min, q_max, qd_max, qdd_max, tau_max).
    convention, gravity, name, drive_inertia, massless_links, zero_parameters, links, rotor_inertia
        As in RobotDescription.

    Returns
    -------
    RobotDescription

    Raises
    ------
    RobotFileError
        When a row does not have four values, or a joint, limit or assumption is invalid.
    """
    rows = [tuple(float(x) for x in row) for row in rows]
    kinds = kinds or ["revolute"] * len(rows)
    limits = limits or [{}] * len(rows)
    joints = []
    for i, (row, kind, lim) in enumerate(zip(rows, kinds, limits)):
        if len(row) != 4:
            raise RobotFileError(f"from_dh rows[{i}] must be (a, alpha, d, theta); got {len(row)} values.")
        a, alpha, d, theta = row
        if kind == "prismatic":
            lim = {"q_min": -0.5, "q_max": 0.5, **lim}
        joints.append(Joint(name=f"joint{i + 1}", kind=kind, a=a, alpha=alpha, d=d, theta=theta, **lim))
    return RobotDescription(
        name=name,
        joints=tuple(joints),
        convention=convention,
        gravity=np.asarray(gravity),
        drive_inertia=tuple(drive_inertia),
        massless_links=tuple(massless_links),
        zero_parameters=tuple(zero_parameters),
        links=links,
        rotor_inertia=rotor_inertia,
    )
