"""LuGre friction (paper eqs. 12-14) in the vectorised numeric form the virtual robot integrates.

Private to the simulator: the identification side has its own friction models. Everything here
works on all joints at once (arrays of shape (n_dof,)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FRICTION_FIELDS = ("fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1")


@dataclass(frozen=True, eq=False)
class LuGreArrays:
    """LuGre parameters of every joint as arrays of shape (n_dof,); units of ``DriveParameters``."""

    fc: np.ndarray
    fs: np.ndarray
    vs: np.ndarray
    fv: np.ndarray
    dv: np.ndarray
    sigma0: np.ndarray
    sigma1: np.ndarray

    @classmethod
    def from_drives(cls, drives) -> LuGreArrays:
        return cls(**{key: np.array([float(getattr(d, key)) for d in drives]) for key in FRICTION_FIELDS})

    def as_table(self) -> np.ndarray:
        """Shape (n_dof, 7), columns ``FRICTION_FIELDS``."""
        return np.column_stack([getattr(self, key) for key in FRICTION_FIELDS])


def stribeck_g(qd, p: LuGreArrays) -> np.ndarray:
    """g(qd) of eq. 13: (Fc + (Fs - Fc) exp(-(qd/vs)^2)) / sigma0 [rad]."""
    return (p.fc + (p.fs - p.fc) * np.exp(-((qd / p.vs) ** 2))) / p.sigma0


def z_rate(z, qd, p: LuGreArrays) -> np.ndarray:
    """dz/dt of eq. 12: qd - |qd| z / g(qd)."""
    return qd - np.abs(qd) * z / stribeck_g(qd, p)


def friction_torque(z, qd, p: LuGreArrays) -> np.ndarray:
    """Friction torque of eq. 14: sigma0 z + sigma1 zdot + Fv |qd|^dv sign(qd) [N m]."""
    return p.sigma0 * z + p.sigma1 * z_rate(z, qd, p) + p.fv * np.abs(qd) ** p.dv * np.sign(qd)


def steady_state_friction(qd, p: LuGreArrays) -> np.ndarray:
    """Friction at constant velocity (z at rest): (Fc + (Fs-Fc) e^{-(v/vs)^2}) sign v + Fv |v|^dv sign v."""
    return (p.sigma0 * stribeck_g(qd, p) + p.fv * np.abs(qd) ** p.dv) * np.sign(qd)


def z_step(z, qd, h, p: LuGreArrays) -> np.ndarray:
    """Exact solution of eq. 12 over a step ``h`` with the velocity held at ``qd`` (stable for any stiffness).

    With qd frozen, eq. 12 is linear in z with rate ``|qd|/g`` and rest point ``g sign(qd)``.
    """
    g = stribeck_g(qd, p)
    rest = g * np.sign(qd)
    return rest + (z - rest) * np.exp(-np.abs(qd) * h / g)
