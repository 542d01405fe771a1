"""Reading a URDF through Pinocchio: the Pinocchio model of the file and the RobotDescription it gives.

The one place that parses URDF files. The robot-file reader (``robot_file``) calls ``from_urdf``
for ``.urdf`` files and ``[urdf]`` tables; the oracle calls ``load_urdf_model`` to rebuild the
kinematics of a robot that came from a URDF.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin

from psdm_casadi.description import GRAVITY_STANDARD, Joint, LinkInertia, RobotDescription
from psdm_casadi.errors import RobotFileError


def load_urdf_model(path: Path, locked_joints=()) -> pin.Model:
    """Parse a URDF with Pinocchio and lock the named joints at zero.

    Parameters
    ----------
    path : str or Path
        URDF file; meshes are not needed.
    locked_joints : sequence of str
        Joints fixed at zero (e.g. gripper fingers).

    Returns
    -------
    pinocchio.Model
        With the inertias and limits of the file.

    Raises
    ------
    RobotFileError
        When Pinocchio cannot parse the file or a locked joint is not a joint of it.
    """
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with its own text
        raise RobotFileError(f"{Path(path).name}: Pinocchio could not read the URDF ({exc}). Fix the file.") from None
    if locked_joints:
        ids = []
        for name in locked_joints:
            if not model.existJointName(name):
                raise RobotFileError(
                    f"{Path(path).name}: urdf.locked_joints names {name!r}, which is not a joint of the URDF; "
                    f"joints are {list(model.names)[1:]}."
                )
            ids.append(model.getJointId(name))
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model


def from_urdf(path, *, locked_joints=(), gravity=None, name=None) -> RobotDescription:
    """Read a URDF through Pinocchio: joints, limits and link inertias.

    Parameters
    ----------
    path : str or Path
        URDF file; meshes are not needed.
    locked_joints : sequence of str
        Joints fixed at zero (e.g. gripper fingers).
    gravity : array, shape (3,), optional
        Gravity acceleration in the base frame [m/s^2]; default ``[0, 0, -9.806132]``.
    name : str, optional
        Robot name; default the file's stem.

    Returns
    -------
    RobotDescription
        With ``urdf_path`` set, so that the oracle and the derivation rebuild the same kinematics.

    Raises
    ------
    RobotFileError
        When Pinocchio cannot parse the file, a locked joint is unknown, or a joint is neither
        revolute nor prismatic with one degree of freedom.
    """
    path = Path(path)
    model = load_urdf_model(path, locked_joints)
    joints, links = [], []
    for jid in range(1, model.njoints):
        jmodel = model.joints[jid]
        shortname = jmodel.shortname()
        if jmodel.nq != 1 or jmodel.nv != 1:
            raise RobotFileError(
                f"{path.name}: joint {model.names[jid]!r} has type {shortname} with nq={jmodel.nq}; "
                "only 1-DOF revolute or prismatic joints are supported. Lock it or make it revolute with limits."
            )
        kind = "prismatic" if "Prismatic" in shortname or shortname.startswith("JointModelP") else "revolute"
        idx = jmodel.idx_q
        q_min, q_max = float(model.lowerPositionLimit[idx]), float(model.upperPositionLimit[idx])
        if not (np.isfinite(q_min) and np.isfinite(q_max) and q_min < q_max):
            q_min, q_max = -math.pi, math.pi
        qd_max = float(model.velocityLimit[idx]) if model.velocityLimit[idx] > 0 else 2.0
        tau_max = float(model.effortLimit[idx]) if model.effortLimit[idx] > 0 else math.inf
        joints.append(
            Joint(
                name=model.names[jid],
                kind=kind,
                q_min=q_min,
                q_max=q_max,
                qd_max=min(qd_max, 1e3),
                qdd_max=10.0,
                tau_max=tau_max,
            )
        )
        inertia = model.inertias[jid]
        links.append(
            LinkInertia(mass=float(inertia.mass), com=np.array(inertia.lever), inertia=np.array(inertia.inertia))
        )
    g = np.array([0.0, 0.0, -GRAVITY_STANDARD]) if gravity is None else gravity
    return RobotDescription(
        name=name or path.stem,
        joints=tuple(joints),
        convention="standard",
        gravity=g,
        links=tuple(links),
        urdf_path=str(path.resolve()),
        locked_joints=tuple(locked_joints),
    )
