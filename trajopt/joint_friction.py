"""Smooth joint friction of the drives for optimal control: one law as a CasADi Function and in NumPy.

The MPC's model (``trajopt.mpc``) and its plant (``trajopt.mpc_loop``) apply the same
Coulomb-viscous-Stribeck law of the robot file's drive values, with the sign smoothed by tanh so
that a gradient-based solver can differentiate it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from psdm_casadi.description import RobotDescription

# rad/s: width of the smooth sign (controller and plant use the same law)
FRICTION_SMOOTHING = 0.2


def friction_function(robot: RobotDescription):
    """Smooth steady-state joint friction ``qd -> tau_f`` of the robot's drives, or None without drives.

    ``(Fc + (Fs - Fc) exp(-(v / vs)^2)) tanh(v / eps) + Fv v (v^2 + eps^2)^((dv - 1) / 2)`` per joint:
    the Coulomb-viscous-Stribeck law with the sign smoothed so that the solver can differentiate it.
    """
    if robot.drives is None:
        return None
    qd = ca.SX.sym("qd", robot.n_dof)
    out = []
    for j, drive in enumerate(robot.drives):
        v = qd[j]
        coulomb = (drive.fc + (drive.fs - drive.fc) * ca.exp(-((v / drive.vs) ** 2))) * ca.tanh(v / FRICTION_SMOOTHING)
        viscous = drive.fv * v * (v**2 + FRICTION_SMOOTHING**2) ** ((drive.dv - 1) / 2)
        out.append(coulomb + viscous)
    return ca.Function("friction", [qd], [ca.vertcat(*out)], ["qd"], ["tau_f"])


def friction_torque(robot: RobotDescription, qd) -> np.ndarray:
    """Numeric twin of ``friction_function``: the drives' smooth friction torque [N m] at qd (n_dof,)."""
    qd = np.asarray(qd, dtype=float)
    if robot.drives is None:
        return np.zeros_like(qd)
    fc, fs, vs, fv, dv = (np.array([getattr(d, k) for d in robot.drives]) for k in ("fc", "fs", "vs", "fv", "dv"))
    eps = FRICTION_SMOOTHING
    stribeck = (fc + (fs - fc) * np.exp(-((qd / vs) ** 2))) * np.tanh(qd / eps)
    return stribeck + fv * qd * (qd**2 + eps**2) ** ((dv - 1) / 2)
