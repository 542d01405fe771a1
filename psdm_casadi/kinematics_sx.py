"""Joint placements of a Pinocchio model as CasADi SX of q: the kinematic half of every Newton-Euler graph.

Shared by the recursive evaluation of PSDM models (``psdm_casadi.recursive``) and the direct
Newton-Euler peer of the speed benchmark (``codegen.peers.rnea_sx``). Numbers of the model that are
rounding noise of cos(pi/2) are set to exactly 0 so that CasADi folds the products away.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError

# Pinocchio joint short names -> (kind, axis) for the 1-DOF joints supported here.
_AXIS_JOINTS = {
    "JointModelRX": ("revolute", (1.0, 0.0, 0.0)),
    "JointModelRY": ("revolute", (0.0, 1.0, 0.0)),
    "JointModelRZ": ("revolute", (0.0, 0.0, 1.0)),
    "JointModelPX": ("prismatic", (1.0, 0.0, 0.0)),
    "JointModelPY": ("prismatic", (0.0, 1.0, 0.0)),
    "JointModelPZ": ("prismatic", (0.0, 0.0, 1.0)),
}
ZERO_TOLERANCE = 1e-14  # model numbers smaller than this are rounding noise of cos(pi/2); set them to 0


def clean(values) -> np.ndarray:
    """A float array with entries below ZERO_TOLERANCE in magnitude set to exactly 0."""
    arr = np.array(values, dtype=float)
    arr[np.abs(arr) < ZERO_TOLERANCE] = 0.0
    return arr


def cross(a, b):
    """Cross product of two SX 3-vectors, written out so that CasADi folds zero entries."""
    return ca.vertcat(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _joint_kind_axis(jmodel, name, caller):
    short = jmodel.shortname()
    if short in _AXIS_JOINTS:
        return _AXIS_JOINTS[short]
    if short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        kind = "revolute" if "Revolute" in short else "prismatic"
        return kind, tuple(float(a) for a in np.asarray(jmodel.extract().axis).ravel())
    raise ParameterError(
        f"{caller} model joint {name!r} must be a 1-DOF revolute or prismatic joint; got {short}. "
        "Lock it (pinocchio.buildReducedModel) or use a URDF with revolute/prismatic joints."
    )


def _axis_rotation(axis, c, s):
    """Rotation by an angle about a unit axis, from its cosine and sine (Rodrigues)."""
    x, y, z = axis
    t = 1 - c
    rows = [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
    return ca.vertcat(*[ca.horzcat(*row) for row in rows])


@dataclass(frozen=True)
class JointChain:
    """Placements of every joint frame in its parent's frame, as SX of q.

    Attributes
    ----------
    parents : tuple of int
        Parent joint index of each joint (-1 for the base).
    rotations, translations : tuple of casadi.SX
        R_i (3, 3) and p_i (3, 1): a vector x in frame i is ``R_i x + p_i`` in the parent's frame.
    revolute : tuple of bool
    axes : tuple of casadi.SX
        The joint axis in its own frame, (3, 1), constant.
    """

    parents: tuple
    rotations: tuple
    translations: tuple
    revolute: tuple
    axes: tuple

    @property
    def n_dof(self) -> int:
        return len(self.parents)


def joint_chain(model, q, caller: str = "joint_chain") -> JointChain:
    """The JointChain of a Pinocchio model of 1-DOF joints at the SX configuration q.

    Raises
    ------
    ParameterError
        When a joint is not a 1-DOF revolute or prismatic joint, or nq != nv.
    """
    if model.nq != model.nv:
        raise ParameterError(
            f"{caller} model must have nq == nv; got nq={model.nq}, nv={model.nv}. "
            "Lock joints with more than one configuration variable."
        )
    parents, rotations, translations, revolute, axes = [], [], [], [], []
    for jid in range(1, model.njoints):
        jmodel = model.joints[jid]
        kind, axis = _joint_kind_axis(jmodel, model.names[jid], caller)
        placement = model.jointPlacements[jid]
        rot0 = ca.SX(ca.DM(clean(placement.rotation)))
        p0 = ca.SX(ca.DM(clean(placement.translation)))
        qi = q[jmodel.idx_q]
        axis = clean(axis)
        if kind == "revolute":
            rotations.append(ca.mtimes(rot0, _axis_rotation(axis, ca.cos(qi), ca.sin(qi))))
            translations.append(p0)
        else:
            rotations.append(rot0)
            translations.append(p0 + ca.mtimes(rot0, ca.SX(ca.DM(axis))) * qi)
        parents.append(model.parents[jid] - 1)
        revolute.append(kind == "revolute")
        axes.append(ca.SX(ca.DM(axis)))
    return JointChain(tuple(parents), tuple(rotations), tuple(translations), tuple(revolute), tuple(axes))
