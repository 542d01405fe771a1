"""The shape of a URDF robot's links: points of their collision (else visual) geometry, in each link's frame.

The identification bounds each link's mass by an ellipsoid around its shape (``identification.calibration.
envelope``). Pinocchio reads the geometry (``buildGeomFromUrdf``, meshes through hpp-fcl, ``package://`` paths
resolved in the URDF's folder and the folders above it, and ``ROS_PACKAGE_PATH``); a box, cylinder, sphere or
capsule gives the corners of its bounding box, a mesh its vertices. Geometry fixed to a locked joint (a gripper
finger) or to a fixed child link counts for the moving link it is fixed to. A URDF without geometry, or whose
meshes cannot be found, gives none (the caller falls back to the kinematic lengths).
"""

from __future__ import annotations

import itertools
import logging
from pathlib import Path

import numpy as np
import pinocchio as pin

from psdm_casadi.urdf import captured_stderr

__all__ = ["link_geometry_points"]

logger = logging.getLogger(__name__)


def _corners(half) -> np.ndarray:
    """The 8 corners of a box of half extents ``half`` about the origin."""
    return np.array(list(itertools.product(*[(-h, h) for h in half])))


def shape_points(geometry) -> np.ndarray | None:
    """Points (k, 3) whose hull holds an hpp-fcl shape, in its own frame; None for a kind not handled."""
    kind = type(geometry).__name__
    if kind == "Box":
        return _corners(np.asarray(geometry.halfSide, dtype=float))
    if kind in ("Cylinder", "Cone"):
        return _corners([geometry.radius, geometry.radius, geometry.halfLength])
    if kind == "Capsule":
        return _corners([geometry.radius, geometry.radius, geometry.halfLength + geometry.radius])
    if kind == "Sphere":
        return _corners([geometry.radius] * 3)
    if hasattr(geometry, "vertices") and callable(geometry.vertices):
        vertices = np.asarray(geometry.vertices(), dtype=float).reshape(-1, 3)
        return vertices if vertices.size else None
    return None


_SAID = set()  # (URDF, failures) already said in this process: a command builds the envelopes once per fit


def _geometry(model, path: Path):
    """Pinocchio's collision geometry of the URDF, else its visual geometry; None when neither can be read."""
    package_dirs = [str(p) for p in list(path.parents)[:6]]
    failed = {}
    for kind in (pin.GeometryType.COLLISION, pin.GeometryType.VISUAL):
        try:
            with captured_stderr():
                geometry = pin.buildGeomFromUrdf(model, str(path), kind, package_dirs=package_dirs)
        except (RuntimeError, ValueError, OSError) as exc:
            failed[kind.name.lower()] = str(exc).strip()
            continue
        if geometry.ngeoms:
            return geometry, kind.name.lower()
    said = (str(path.resolve()), tuple(failed.items()))
    if failed and said not in _SAID:  # said once per file and process (identify reads it for each of its fits)
        _SAID.add(said)
        logger.info("%s: its %s geometry cannot be read (%s); the links' envelopes come from the kinematic lengths "
                    "instead (the meshes' package folder in the URDF's folder or one above it makes them readable)",
                    path.name, " and ".join(failed), "; ".join(dict.fromkeys(failed.values())))  # fmt: skip
    return None


def link_geometry_points(robot) -> tuple:
    """Per joint of ``robot``, the points (k, 3) of its link's URDF geometry in the link frame, or None.

    Returns ``(points per joint, "collision" or "visual")``, or ``((None,) * n_dof, "")`` for a robot not read
    from a URDF or a URDF without readable geometry.
    """
    none = ((None,) * robot.n_dof, "")
    if robot.urdf_path is None or Path(robot.urdf_path).suffix.lower() != ".urdf":  # DH rows, or an MJCF file
        return none
    path = Path(robot.urdf_path)
    try:
        with captured_stderr():
            model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError, OSError):
        return none
    found = _geometry(model, path)
    if found is None:
        return none
    geometry, kind = found
    q = pin.neutral(model)
    for name, value in robot.locked_joints:
        if model.existJointName(name):
            q[model.joints[model.getJointId(name)].idx_q] = value
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    names = list(robot.joint_names)
    parts = [[] for _ in names]
    for item in geometry.geometryObjects:
        points = shape_points(item.geometry)
        joint = item.parentJoint
        while joint > 0 and model.names[joint] not in names:  # a locked joint's link belongs to its parent
            joint = model.parents[joint]
        if points is None or joint == 0:  # the base's geometry bounds no moving link
            continue
        placed = data.oMi[joint].actInv(data.oMi[item.parentJoint] * item.placement)  # shape frame in the link's
        parts[names.index(model.names[joint])].append(points @ placed.rotation.T + placed.translation)
    return tuple(np.vstack(p) if p else None for p in parts), kind
