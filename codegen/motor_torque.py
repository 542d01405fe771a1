"""The motor torques of a model, for a robot whose controller commands the motors: ``tau_m = N_q^-T tau``.

A robot file's ``[transmission]`` (``psdm_casadi.transmission.Transmission``) couples motors and
joints by ``theta_m = N_q q + theta_0``; the power-consistent torque map is ``tau = N_q^T tau_m``, so
the motor torques that produce the model's joint torques are ``N_q^-T tau``. :func:`add_motor_torque`
adds that Function to a model's DynamicsFunctions; ``export_c`` then writes ``psdm_motor_torque``.
"""

from __future__ import annotations

import copy
import dataclasses

import casadi as ca
import numpy as np

__all__ = ["add_motor_torque"]


def add_motor_torque(functions, transmission):
    """The Functions with ``motor_torque`` = ``N_q^-T inverse_dynamics`` (same inputs); unchanged without transmission.

    Parameters
    ----------
    functions : DynamicsFunctions
        Built last (after the drive and finding terms), so that ``motor_torque`` maps the full joint torque.
    transmission : psdm_casadi.transmission.Transmission or None
        The robot's (``RobotDescription.transmission``).

    Returns
    -------
    DynamicsFunctions

    Examples
    --------
    >>> functions = add_motor_torque(build_functions(model), robot.transmission)   # doctest: +SKIP
    >>> functions.motor_torque(q, qd, qdd, theta)          # == N_q^-T tau            # doctest: +SKIP
    """
    if transmission is None:
        return functions
    tau_function = functions.inverse_dynamics
    inputs = tau_function.mx_in()
    inverse_transpose = ca.DM(np.linalg.inv(transmission.coupling.T))
    tau_m = ca.mtimes(inverse_transpose, tau_function(*inputs))
    names = [tau_function.name_in(i) for i in range(tau_function.n_in())]
    motor = ca.Function("motor_torque", inputs, [tau_m], names, ["tau_m"])
    if dataclasses.is_dataclass(functions):
        return dataclasses.replace(functions, motor_torque=motor)
    out = copy.copy(functions)  # a namespace of Functions named like DynamicsFunctions
    out.motor_torque = motor
    return out
