"""ChainRegressor: the numeric regressor of a model derived without a monomial table (robots beyond 8 joints, trees).

Such a model states its base parameters through a standard-parameter preimage T (joint-frame
parameters, 11 per joint): Y_b(q, qd, qdd) = Y_std(q, qd, qdd) T, Y_std being Pinocchio's joint
torque regressor (plus the rotor inertia column qdd_i of joint i). The model carries its joint tree
(parents, joint placements, axes, gravity) so that it evaluates without the robot file, like a
model with E and P does; the cost per sample is one recursive regressor, linear in the number of
links.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from psdm_casadi.errors import ShapeError

N_LINK = 10  # Pinocchio's dynamic parameters per joint frame
N_JOINT = 11  # ... plus the rotor inertia
ARRAY_NAMES = ("parents", "placements", "axes", "gravity", "preimage", "gravity_mask")


def joint_axes(model: pin.Model) -> np.ndarray:
    """Per joint the unit motion at q = 0 in its own frame, shape (n_dof, 6): (linear, angular)."""
    data = model.createData()
    q = pin.neutral(model)
    pin.computeJointJacobians(model, data, q)
    axes = np.empty((model.nv, 6))
    for jid in range(1, model.njoints):
        jacobian = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)
        axes[model.joints[jid].idx_v] = jacobian[:, model.joints[jid].idx_v]
    return axes


def stacked_standard_regressor(model: pin.Model, data, q, qd, qdd) -> np.ndarray:
    """Pinocchio's joint-frame regressor with the rotor columns, shape (n_samples, n_dof, 11 n_dof)."""
    n_samples, n = q.shape
    out = np.zeros((n_samples, n, N_JOINT * n))
    link_columns = (np.arange(N_JOINT * n) % N_JOINT) < N_LINK
    rotor = np.arange(n) * N_JOINT + N_LINK
    for s in range(n_samples):
        out[s][:, link_columns] = pin.computeJointTorqueRegressor(model, data, q[s], qd[s], qdd[s])
    out[:, np.arange(n), rotor] = qdd
    return out


@dataclass(frozen=True, eq=False)
class ChainRegressor:
    """The joint tree and the standard-parameter preimage of a model without monomial table.

    Parameters
    ----------
    parents : array of int, shape (n_dof,)
        Parent joint of each joint, -1 for the base (a tree: several joints may share a parent).
    placements : array, shape (n_dof, 4, 4)
        Each joint frame's placement in its parent's frame at q = 0 (homogeneous).
    axes : array, shape (n_dof, 6)
        Each joint's unit motion in its own frame, (linear, angular): a revolute joint has a zero
        linear part, a prismatic joint a zero angular part.
    gravity : array, shape (3,)
        Gravity acceleration in the base frame [m/s^2].
    preimage : array, shape (11 n_dof, n_base)
        T: joint-frame standard parameters (Pinocchio's 10 per joint frame, then the rotor inertia)
        of unit base parameters, so that Y_b = Y_std T.
    gravity_mask : array of bool, shape (n_base,)
        The base parameters with a gravity column.
    """

    parents: np.ndarray
    placements: np.ndarray
    axes: np.ndarray
    gravity: np.ndarray
    preimage: np.ndarray
    gravity_mask: np.ndarray

    def __post_init__(self):
        values = {
            "parents": np.asarray(self.parents, dtype=np.int64),
            "placements": np.asarray(self.placements, dtype=float),
            "axes": np.asarray(self.axes, dtype=float),
            "gravity": np.asarray(self.gravity, dtype=float),
            "preimage": np.asarray(self.preimage, dtype=float),
            "gravity_mask": np.asarray(self.gravity_mask, dtype=bool),
        }
        n = values["parents"].size
        l = values["preimage"].shape[-1] if values["preimage"].ndim == 2 else -1
        expected = {
            "placements": (n, 4, 4),
            "axes": (n, 6),
            "gravity": (3,),
            "preimage": (N_JOINT * n, l),
            "gravity_mask": (l,),
        }
        for name, shape in expected.items():
            if values[name].shape != shape:
                raise ShapeError(f"ChainRegressor.{name} must have shape {shape}; got {values[name].shape}.")
        if np.any(values["parents"] >= np.arange(n)) or np.any(values["parents"] < -1):
            raise ShapeError(
                f"ChainRegressor.parents must name an earlier joint or -1 for each joint; got {values['parents']}."
            )
        for name, value in values.items():
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def from_pinocchio(cls, model: pin.Model, preimage, gravity_mask) -> ChainRegressor:
        """The joint tree of a Pinocchio model of 1-DOF joints (gravity from ``model.gravity``)."""
        return cls(
            parents=np.array([model.parents[jid] - 1 for jid in range(1, model.njoints)]),
            placements=np.array([model.jointPlacements[jid].homogeneous for jid in range(1, model.njoints)]),
            axes=joint_axes(model),
            gravity=np.array(model.gravity.linear),
            preimage=preimage,
            gravity_mask=gravity_mask,
        )

    @property
    def n_dof(self) -> int:
        return self.parents.size

    @property
    def n_base(self) -> int:
        return self.preimage.shape[1]

    def pinocchio_model(self) -> pin.Model:
        """A Pinocchio model with this joint tree and zero inertia: its joint frames are the preimage's."""
        model = pin.Model()
        for i in range(self.n_dof):
            placement = pin.SE3(self.placements[i, :3, :3].copy(), self.placements[i, :3, 3].copy())
            model.addJoint(int(self.parents[i]) + 1, self._joint_model(i), placement, f"joint{i + 1}")
        model.gravity.linear = self.gravity.copy()
        return model

    def _joint_model(self, i: int):
        """Pinocchio's joint model of joint i: an axis-aligned one when the axis is a coordinate axis."""
        revolute = np.linalg.norm(self.axes[i, 3:]) > 0.5
        axis = self.axes[i, 3:] if revolute else self.axes[i, :3]
        axis = axis / np.linalg.norm(axis)
        aligned = np.flatnonzero(np.abs(axis) == 1.0)
        if aligned.size == 1 and axis[aligned[0]] > 0:
            letter = "XYZ"[int(aligned[0])]
            return getattr(pin, f"JointModel{'R' if revolute else 'P'}{letter}")()
        return pin.JointModelRevoluteUnaligned(axis) if revolute else pin.JointModelPrismaticUnaligned(axis)

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """Y_b for every sample, shape (n_samples, n_dof, n_base); q, qd, qdd each (n_samples, n_dof)."""
        model = self.pinocchio_model()
        standard = stacked_standard_regressor(model, model.createData(), q, qd, qdd)
        return standard @ self.preimage

    def arrays(self) -> dict:
        """The arrays to store in a model file, keyed ``chain_<name>``."""
        return {f"chain_{name}": getattr(self, name) for name in ARRAY_NAMES}

    @classmethod
    def from_arrays(cls, arrays) -> ChainRegressor:
        """Inverse of :meth:`arrays`."""
        return cls(**{name: arrays[f"chain_{name}"] for name in ARRAY_NAMES})

    def same_as(self, other) -> bool:
        """True when every array is identical."""
        return isinstance(other, ChainRegressor) and all(
            np.array_equal(getattr(self, name), getattr(other, name)) for name in ARRAY_NAMES
        )
