"""The torque constants [N m/A] a recording of currents is read with: the robot file's [[drive]] tables.

A recording holds joint torques (``tau``) or motor currents (``current``); the currents become joint torques
``kt * i`` (``Recording.joint_torque``) through the joint-side constants of the robot's drives
(``motor_side`` explains how a robot file's ``motor_kt`` becomes those). Every command that reads a recording
(identify, validate, diagnose, the reports) asks here, so that they all read the same currents the same way.
"""

from __future__ import annotations

import numpy as np

__all__ = ["drive_kt", "recording_kt"]


def drive_kt(robot):
    """The torque constants [N m/A] of ``robot``'s drives (joint side), one per joint; None without drives."""
    if robot.drives is None:
        return None
    return np.array([d.kt for d in robot.drives], dtype=float)


def recording_kt(robot, *recordings):
    """The torque constants [N m/A] ``recordings`` of currents are read with (:func:`drive_kt`); None when every
    one of them holds joint torques (nothing to read), or ``robot`` has no drives."""
    if all(r.tau is not None for r in recordings):
        return None
    return drive_kt(robot)
