"""Motor-side recordings mapped to the joint side (and back), through the robot's transmission.

The robot file states which signals a controller logs on the motor side (``[recording].side``) and
the gears between motors and joints (``[transmission]``, :class:`psdm_casadi.transmission.Transmission`).
:func:`to_joint_side` maps such a recording once, when it is read, so that every command (identify,
validate, diagnose) works on joint-side signals::

    q = N_q^-1 theta_m + q_0     qd = N_q^-1 qd_m     qdd = N_q^-1 qdd_m     tau = N_q^T tau_m

The currents of an uncoupled transmission stay currents, signed like their joint: the [[drive]] tables' kt is
the joint-side constant ``|N_i| kt_m`` (a robot file with ``motor_kt`` gives its drives these,
``transmission_file.drives_with_motor_kt``), so every command sees currents, whose torque holds the rotors'
inertia and the gears' loss. The currents of a coupled transmission (or of drives without those constants)
become joint torques ``N_q^T (kt_m * i_m)`` through the motors' torque constants (``motor_kt``); a coupled one
without them is refused. :func:`to_motor_side` is the inverse (a virtual controller's log).
"""

from __future__ import annotations

import logging

import numpy as np

from identification.data.recording import Recording
from psdm_casadi.errors import RecordingError

__all__ = ["to_joint_side", "to_motor_side"]

logger = logging.getLogger(__name__)


def _motor_signals(recording: Recording, robot) -> tuple:
    """The signals of ``recording`` the robot file says are on the motor side (none without a layout)."""
    layout = robot.recording_layout
    if layout is None:
        return ()
    return tuple(s for s in layout.motor_signals if getattr(recording, s) is not None)


def _mapped_motion(recording: Recording, robot, to_joint: bool):
    """(motor-side signals, transmission, changes): the angles, rates and torques among the signals mapped to the
    joint side (``to_joint``) or back to the motor side; None for a recording without motor-side signals."""
    signals = _motor_signals(recording, robot)
    if not signals:
        return None
    t = _transmission(recording, robot)
    if to_joint:
        positions, rates, torques = t.joint_positions, t.joint_rates, t.joint_torques
    else:
        positions, rates, torques = t.motor_positions, t.motor_rates, t.motor_torques
    changes = {s: rates(getattr(recording, s)) for s in ("qd", "qdd") if s in signals}
    if "q" in signals:
        changes["q"] = positions(recording.q)
    if "tau" in signals:
        changes["tau"] = torques(recording.tau)
    return signals, t, changes


def to_joint_side(recording: Recording, robot) -> Recording:
    """The joint-side recording of one logged with the motor-side signals of ``robot.recording_layout``.

    Parameters
    ----------
    recording : Recording
        As read from the files (motor angles [rad], motor torques [N m], currents [A] where stated).
    robot : RobotDescription
        With its ``transmission`` and ``recording_layout`` (a robot without them: returned unchanged).

    Returns
    -------
    Recording
        Joint positions, velocities, accelerations and torques (currents where they stay currents).

    Raises
    ------
    RecordingError
        When the recording's joint count is not the transmission's, or it holds motor currents of a
        coupled transmission without the motors' torque constants.
    """
    mapped = _mapped_motion(recording, robot, to_joint=True)
    if mapped is None:
        return recording
    signals, transmission, changes = mapped
    if "current" in signals:
        changes.update(_joint_currents(recording, transmission, robot.drives))
    logger.info(
        "%s: %s mapped from the motor side to the joints (gear ratios %s%s)",
        recording.name or "recording",
        ", ".join(signals),
        ", ".join(f"{r:g}" for r in transmission.gear_ratios),
        ", coupled" if transmission.is_coupled else "",
    )
    return recording.with_signals(**changes)


def _joint_currents(recording: Recording, transmission, drives) -> dict:
    """Joint-signed currents of an uncoupled transmission (with ``motor_kt``: where the drives hold its joint-side
    constants, ``Transmission.joint_kt``, as a robot file's do), else joint torques of motor currents (``motor_kt``)."""
    joint_kt = transmission.joint_kt
    if joint_kt is not None and drives is not None and recording.tau is None:
        if np.allclose([drive.kt for drive in drives], joint_kt, rtol=1e-9, atol=0.0):
            return {"current": recording.current * np.sign(transmission.gear_ratios)}
    if transmission.motor_kt is not None:
        tau = transmission.current_torques(recording.current)
        if recording.tau is not None:  # a recorded torque is kept; the currents it replaces are dropped
            return {"current": None}
        return {"tau": tau, "current": None}
    if transmission.is_coupled:
        raise RecordingError(
            f"{recording.name or 'recording'}: motor currents of a coupled transmission become joint torques only "
            "through the motors' torque constants; got none. Add motor_kt = [...] (N m/A per motor) to the robot "
            "file's [transmission] table, or record the currents on the joint side."
        )
    return {"current": recording.current * np.sign(transmission.gear_ratios)}


def to_motor_side(recording: Recording, robot) -> Recording:
    """The inverse of :func:`to_joint_side`: the recording a controller would log on the motor side.

    Joint torques become motor torques ``N_q^-T tau``. Currents become motor currents: the joint-signed
    currents of an uncoupled transmission without ``motor_kt`` are signed back; with ``motor_kt`` they are
    the currents of the motor torques, ``N_q^-T tau / kt_m`` (the recording needs ``tau``); a coupled
    transmission without ``motor_kt`` cannot log currents, so they are dropped where ``tau`` is recorded.

    Raises
    ------
    RecordingError
        As :func:`to_joint_side`, and for currents without torques that cannot be mapped.
    """
    mapped = _mapped_motion(recording, robot, to_joint=False)
    if mapped is None:
        return recording
    signals, transmission, changes = mapped
    if "current" in signals:
        changes["current"] = _motor_currents(recording, transmission, robot.drives)
    return recording.with_signals(**changes)


def _motor_currents(recording: Recording, transmission, drives):
    """The motor currents :func:`to_joint_side` maps back to ``recording``'s (module docstring); None: dropped.

    The joint torque is the recorded ``tau``, else the joint-side currents times the drives' ``kt``."""
    if transmission.motor_kt is None and not transmission.is_coupled:
        return recording.current * np.sign(transmission.gear_ratios)
    tau = recording.tau
    if tau is None and drives is not None:
        tau = recording.current * np.array([drive.kt for drive in drives])
    if tau is None:
        raise RecordingError(
            f"{recording.name or 'recording'}: joint-side currents map back to motor currents only for an uncoupled "
            "transmission without motor_kt, or through the joint torques. Record tau, or state [[drive]] kt."
        )
    if transmission.motor_kt is None:
        logger.info("%s: the currents are dropped (a coupled transmission without motor_kt)", recording.name)
        return None
    return transmission.motor_torques(tau) / transmission.motor_kt


def _transmission(recording: Recording, robot):
    transmission = robot.transmission
    if transmission is None:  # the robot-file reader refuses this; a RobotDescription built in Python may not
        raise RecordingError(
            f"{robot.name}: its recording layout puts signals on the motor side but it has no transmission. "
            "Add a [transmission] table to the robot file."
        )
    if recording.n_dof != transmission.n_dof:
        raise RecordingError(
            f"{recording.name or 'recording'}: {recording.n_dof} joint columns, but the transmission of "
            f"{robot.name} couples {transmission.n_dof} motors. Record one column per motor."
        )
    return transmission
