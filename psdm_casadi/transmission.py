"""Transmission: the gears and couplings between the motors and the joints, and the maps of signals across them.

Controllers log motor-side signals: encoder angles ``theta_m``, motor torques ``tau_m``, motor currents
``i_m``. With the joint -> motor position coupling ``N_q`` (gear ratios on the diagonal; a coupled wrist
adds off-diagonal entries, e.g. the Staubli TX40's motor 6 turns with joints 5 and 6) and the joint
positions ``q_0`` at which the encoders read zero (the motor positions at q = 0 are ``theta_0 = -N_q q_0``)::

    theta_m = N_q (q - q_0) = N_q q + theta_0          q = N_q^-1 theta_m + q_0
    qd_m    = N_q qd                   qd = N_q^-1 qd_m            (accelerations alike)
    tau_j   = N_q^T tau_m              tau_m = N_q^-T tau_j

The torque map is the transpose of the position map: the power ``tau_m . qd_m = tau_m^T N_q qd`` the
motors deliver is the power ``tau_j . qd`` the joints receive (friction in the gears aside, which the
identified friction absorbs). Motor currents become joint torques through the motors' torque constants:
``tau_j = N_q^T (kt_m * i_m)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import RobotFileError
from psdm_casadi.values import float_array, format_value

__all__ = ["Transmission", "SINGULAR_RCOND"]

#: Smallest reciprocal condition number of a coupling matrix that can be inverted reliably.
SINGULAR_RCOND = 1e-12


@dataclass(frozen=True, eq=False)
class Transmission:
    """The joint -> motor maps of a robot (module docstring).

    Parameters
    ----------
    coupling : array, shape (n_dof, n_dof)
        ``N_q``: motor positions per joint position (``theta_m = N_q (q - joint_offsets)``); gear ratios on
        the diagonal, couplings off it. Must be invertible.
    joint_offsets : array, shape (n_dof,), optional
        Joint positions [rad or m] at which the motor encoders read zero; zero by default.
    motor_kt : array, shape (n_dof,), optional
        Motor torque constants [N m/A] at the motor, for motor-side currents.
    rated_current : array, shape (n_dof,), optional
        Each motor's rated current [A]: a controller that logs its currents in per cent of it (``--columns
        i=CurrAct_A:%``) is read in amperes through it (``robot_recordings``).

    Raises
    ------
    RobotFileError
        When the matrix is not square, singular, or a value is not finite, naming the fix.

    Examples
    --------
    >>> n_q = np.diag([32.0, 32.0, 45.0, -48.0, 45.0, 32.0]); n_q[5, 4] = 32.0
    >>> tx40 = Transmission(coupling=n_q)
    >>> tx40.joint_positions(np.array([[0, 0, 0, 0, 32.0, 32.0]]))
    array([[0., 0., 0., 0., 1., 0.]])
    """

    coupling: np.ndarray
    joint_offsets: np.ndarray | None = None
    motor_kt: np.ndarray | None = None
    rated_current: np.ndarray | None = None

    def __post_init__(self):
        matrix = float_array(self.coupling, "Transmission.coupling", "an n x n matrix")
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] == 0:
            raise RobotFileError(
                f"Transmission.coupling must be a square n x n matrix (one row per motor, one column per joint); "
                f"got shape {matrix.shape}. Give one row of n numbers per motor."
            )
        n = matrix.shape[0]
        if not np.all(np.isfinite(matrix)):
            raise RobotFileError(f"Transmission.coupling must be finite; got {format_value(matrix)}. Fix the values.")
        if 1.0 / max(np.linalg.cond(matrix), 1.0) < SINGULAR_RCOND:
            raise RobotFileError(
                f"Transmission.coupling must be invertible (every joint position recoverable from the motors'); got "
                f"a singular matrix {format_value(matrix.tolist())}. Check the gear ratios (none may be 0) and the "
                "couplings (no two motors may see the same combination of joints)."
            )
        object.__setattr__(self, "coupling", _frozen(matrix))
        for key in ("joint_offsets", "motor_kt", "rated_current"):
            value = getattr(self, key)
            if value is None:
                continue
            vector = float_array(value, f"Transmission.{key}", f"{n} numbers").reshape(-1)
            if vector.shape != (n,) or not np.all(np.isfinite(vector)):
                raise RobotFileError(
                    f"Transmission.{key} must be {n} finite numbers (one per motor); got {format_value(value)}."
                )
            if key == "motor_kt" and np.any(vector <= 0):
                raise RobotFileError(
                    f"Transmission.motor_kt must be > 0 [N m/A] for every motor; got {format_value(vector)}. "
                    "Give the motors' torque constants (the gear's sign is in the coupling)."
                )
            if key == "rated_current" and np.any(vector <= 0):
                raise RobotFileError(
                    f"Transmission.rated_current must be > 0 [A] for every motor; got {format_value(vector)}. "
                    "Give the motors' rated (continuous) currents from their datasheet."
                )
            object.__setattr__(self, key, _frozen(vector))
        if self.joint_offsets is None:
            object.__setattr__(self, "joint_offsets", _frozen(np.zeros(n)))

    # --- views -----------------------------------------------------------------------------------
    @property
    def n_dof(self) -> int:
        return int(self.coupling.shape[0])

    @property
    def motor_offsets(self) -> np.ndarray:
        """Motor positions [rad] at q = 0: ``theta_0 = -N_q q_0``."""
        return -self.coupling @ self.joint_offsets

    @property
    def gear_ratios(self) -> np.ndarray:
        """The diagonal of the coupling: motor turns per turn of its own joint."""
        return np.diag(self.coupling).copy()

    @property
    def is_coupled(self) -> bool:
        """Whether a motor turns with another joint than its own (an off-diagonal coupling entry)."""
        return bool(np.any(self.coupling - np.diag(np.diag(self.coupling))))

    @property
    def joint_kt(self) -> np.ndarray | None:
        """Joint-side torque constants ``|N_ii| kt_m`` [N m/A] of the joint-signed currents ``sign(N_ii) i_m`` of an
        uncoupled transmission with ``motor_kt`` (``tau_j = N_ii kt_m i_m``); None when coupled or without
        ``motor_kt``. A robot file's ``[[drive]]`` tables take them (``transmission_file.drives_with_motor_kt``), so
        motor currents reach identify as currents: their torque holds the rotors' inertia and the gears' loss."""
        if self.motor_kt is None or self.is_coupled:
            return None
        return np.abs(self.gear_ratios) * self.motor_kt

    # --- motor side -> joint side (arrays are (n_samples, n_dof)) -------------------------------
    def joint_positions(self, theta_m) -> np.ndarray:
        """``q = N_q^-1 theta_m + q_0`` [rad]."""
        return self.joint_rates(theta_m) + self.joint_offsets

    def joint_rates(self, rate_m) -> np.ndarray:
        """Joint velocities or accelerations of the motors' ones: ``N_q^-1 x_m``."""
        return np.linalg.solve(self.coupling, np.asarray(rate_m, dtype=float).T).T

    def joint_torques(self, tau_m) -> np.ndarray:
        """``tau_j = N_q^T tau_m`` [N m] (the power-consistent map)."""
        return np.asarray(tau_m, dtype=float) @ self.coupling

    def current_torques(self, current_m) -> np.ndarray:
        """Joint torques of motor currents: ``N_q^T (kt_m * i_m)``; needs ``motor_kt``."""
        if self.motor_kt is None:
            raise RobotFileError(
                "Transmission.motor_kt is needed to turn motor currents into joint torques; got none. "
                "Add motor_kt = [...] (N m/A per motor) to the robot file's [transmission] table."
            )
        return self.joint_torques(np.asarray(current_m, dtype=float) * self.motor_kt)

    # --- joint side -> motor side ------------------------------------------------------------------
    def motor_positions(self, q) -> np.ndarray:
        """``theta_m = N_q (q - q_0)`` [rad]."""
        return self.motor_rates(np.asarray(q, dtype=float) - self.joint_offsets)

    def motor_rates(self, rate) -> np.ndarray:
        """Motor velocities or accelerations of the joints' ones: ``N_q x``."""
        return np.asarray(rate, dtype=float) @ self.coupling.T

    def motor_torques(self, tau_j) -> np.ndarray:
        """The motor torques that give joint torques ``tau_j``: ``tau_m = N_q^-T tau_j`` [N m]."""
        return np.linalg.solve(self.coupling.T, np.asarray(tau_j, dtype=float).T).T


def _frozen(array: np.ndarray) -> np.ndarray:
    out = np.array(array, dtype=float, copy=True)
    out.setflags(write=False)
    return out
