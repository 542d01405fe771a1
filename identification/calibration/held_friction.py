"""Friction held at given values in a fit: its torque taken off the prepared recordings, its columns left out.

``TrajectoryOptions.held_friction`` names drive columns (``fc<j>``, ``fv<j>``) and the value each is held at (a joint
whose friction the data do not determine: ``one_way_friction``). The fit (``trajectory_fit.identify_trajectories``)
then sees the torque the held friction leaves, ``tau - D_held f_held``, fits every other parameter to it with the held
columns out of both the least-squares and the consistent fit, and reports the held values as the columns'
estimates (standard deviation 0: not estimated). A held joint's friction is Coulomb-viscous (its smoothing velocity
the fit's): a Stribeck hump is no more determined than the Coulomb level it sits on.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.trajectory_data import drive_column_joint, friction_term
from psdm_casadi.errors import ParameterError

__all__ = ["HELD_TERMS", "check_held_friction", "held_friction_columns", "subtract_held_friction",
           "with_held_values"]  # fmt: skip

#: The friction terms that may be held: Coulomb and viscous (a held joint is Coulomb-viscous).
HELD_TERMS = ("fc", "fv")


def _term(name: str) -> str:
    return name.rstrip("0123456789")


def check_held_friction(options) -> None:
    """Raise ``ParameterError`` unless ``options.held_friction`` is ``((name, value), ...)`` of finite values of
    ``fc<j>``/``fv<j>`` columns the fit has (``options.friction``), on joints not of the Stribeck shape."""
    held = options.held_friction
    for entry in held:
        ok = isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[0], str)
        if not ok or _term(entry[0]) not in HELD_TERMS or _term(entry[0]) not in options.friction:
            raise ParameterError(f"TrajectoryOptions.held_friction must hold (name, value) pairs of the columns "
                                 f"{HELD_TERMS} the fit has ({options.friction}), e.g. ('fc3', 0.2); got "
                                 f"{entry!r}.")  # fmt: skip
        if not np.isfinite(float(entry[1])):
            raise ParameterError(f"TrajectoryOptions.held_friction: {entry[0]} must be held at a finite value; got "
                                 f"{entry[1]!r}.")  # fmt: skip
    if held and "fs" in options.friction:
        joints = sorted({drive_column_joint(name) + 1 for name, _ in held})
        shaped = options.stribeck_joints is None or {j - 1 for j in joints} & set(options.stribeck_joints)
        if shaped:
            raise ParameterError(
                f"TrajectoryOptions.held_friction: held joints {joints} must be Coulomb-viscous; "
                "leave them out of stribeck_joints."
            )


def subtract_held_friction(prepared, options) -> list:
    """The prepared recordings with the held friction's torque taken off (``options.held_friction``)."""
    if not options.held_friction:
        return list(prepared)
    out = []
    for recording in prepared:
        tau = np.array(recording.tau, dtype=float)
        for name, value in options.held_friction:
            j = drive_column_joint(name)
            tau[:, j] -= float(value) * friction_term(_term(name), recording.qd[:, j], options.coulomb_velocity)
        out.append(replace(recording, tau=tau))
    return out


def held_friction_columns(names, options, n_base: int) -> set:
    """The indices (after the ``n_base`` base parameters) of the held columns among the drive columns ``names``."""
    return {n_base + list(names).index(name) for name, _ in options.held_friction}


def with_held_values(fit, options):
    """``fit`` (a ``TrajectoryFit``) with its held columns at their held values, in the estimate and the least-squares
    estimate alike (their standard deviations stay 0: not estimated)."""
    if not options.held_friction:
        return fit
    drive, drive_ols = np.array(fit.drive, dtype=float), np.array(fit.drive_ols, dtype=float)
    for name, value in options.held_friction:
        k = fit.drive_names.index(name)
        drive[k] = drive_ols[k] = float(value)
    return replace(fit, drive=drive, drive_ols=drive_ols)
