"""Hidden effects for the virtual robot that ``extra_physics`` lacks: backlash and joint elasticity.

Both act on the recorded joint position through the ``measure`` hook: the encoder sits on the motor
side, the simulated joint state is the link, and the transmission between them is not rigid.

- ``Backlash``: the motor leads the link by ``(b/2) tanh(tau / tau_s)``: it rests on one flank of the
  gap while torque is transmitted in one direction and crosses the gap when the torque reverses.
- ``JointElasticity``: the motor angle is the link angle plus the torsion ``tau / k``.

The recorded torque ``tau`` is the joint torque the motors supply (what the simulator records).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.virtual.effects import ExtraPhysics
from psdm_casadi.errors import ParameterError


def _check_joint(owner, joint, n_dof):
    if not (isinstance(joint, (int, np.integer)) and 0 <= joint < n_dof):
        raise ParameterError(f"{owner}.joint must be a joint index 0..{n_dof - 1}; got {joint!r}.")


@dataclass(frozen=True)
class Backlash(ExtraPhysics):
    """Play of total width ``width`` [rad] in the transmission of ``joint``; ``torque_scale`` [N m] smooths the flank
    change."""

    joint: int
    width: float
    torque_scale: float = 0.5

    def validate(self, n_dof):
        _check_joint("Backlash", self.joint, n_dof)
        if not (np.isfinite(self.width) and self.width >= 0):
            raise ParameterError(f"Backlash.width must be >= 0 [rad]; got {self.width!r}.")
        if not (np.isfinite(self.torque_scale) and self.torque_scale > 0):
            raise ParameterError(f"Backlash.torque_scale must be positive [N m]; got {self.torque_scale!r}.")

    def measure(self, t, q, tau):
        q = np.array(q, dtype=float)
        q[:, self.joint] += 0.5 * self.width * np.tanh(tau[:, self.joint] / self.torque_scale)
        return q, tau


@dataclass(frozen=True)
class JointElasticity(ExtraPhysics):
    """A torsion spring of stiffness ``stiffness`` [N m/rad] between motor (encoder) and link of ``joint``."""

    joint: int
    stiffness: float

    def validate(self, n_dof):
        _check_joint("JointElasticity", self.joint, n_dof)
        if not (np.isfinite(self.stiffness) and self.stiffness > 0):
            raise ParameterError(f"JointElasticity.stiffness must be positive [N m/rad]; got {self.stiffness!r}.")

    def measure(self, t, q, tau):
        q = np.array(q, dtype=float)
        q[:, self.joint] += tau[:, self.joint] / self.stiffness
        return q, tau
