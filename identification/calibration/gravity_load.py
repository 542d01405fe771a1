"""Which joints gravity can give a torque: the one answer for every reading that needs a joint gravity loads.

A counterbalance or spring balances a gravity torque, and a fitted gravity torque can depart from the robot file's
only where gravity acts; an upright arm's base axis, parallel to gravity at every pose, carries neither. Whether
gravity loads a joint is a property of the arm's kinematics, not of the masses its robot file states: a body anywhere
beyond a joint whose axis is not parallel to gravity (a tool, a payload, a link the file states massless) gives it a
torque. The robot file's own gravity torque, or the regressor of a model derived from it (which drops the parameters
of a link the file states massless), would answer no on a joint whose distal links the file states massless (the
virtual Denso's joint 6) while a tool the recording carries loads it. The answer here is Pinocchio's gravity torque
of a unit body off every axis on the last link (so carried by every joint) at the recorded poses, or at seeded poses
within the joint limits where none are given: a joint carries gravity where that torque is not nil (beyond
``CARRIES`` of the largest joint's, a rounding).

Its readers: ``clear_ask.gravity_free`` (no counterbalance named where gravity gives no torque),
``gravity_departure.theta_departures`` (no departure read there) and ``envelope_report`` (the joint a link's
counterbalance acts on is one the link's weight loads, at or before the link). ``recorded_poses`` is the poses they
and ``offset_reading`` read the robot file's gravity torque at.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CARRIES", "STRIDE", "joints_carrying_gravity", "recorded_poses"]

#: Every how many recorded samples a gravity torque is evaluated (gravity is smooth in the pose).
STRIDE = 5
#: A joint's gravity torque below this share of the largest joint's is rounding: the joint carries no gravity.
CARRIES = 1e-9
#: The seeded poses within the joint limits read where no recorded poses are given.
POSES = 16


def recorded_poses(recordings) -> np.ndarray:
    """Every ``STRIDE``-th recorded pose of ``recordings`` (each with ``q``, samples x joints), stacked [rad or m]."""
    return np.concatenate([np.asarray(r.q, dtype=float)[::STRIDE] for r in recordings])


def joints_carrying_gravity(robot, q=None) -> np.ndarray:
    """Per joint, whether gravity can give it a torque at the poses ``q`` (samples, joints; None: ``POSES`` seeded
    poses within the joint limits): whether Pinocchio's gravity torque of a unit body off every axis on the last link
    (a tool's: every joint carries it) is not nil there (module docstring). The robot file's masses do not enter: a
    joint whose distal links the file states massless still carries a tool's weight."""
    from psdm_casadi.oracle import PinocchioOracle

    n = robot.n_dof
    if q is None:
        low = np.maximum(np.asarray(robot.q_min, dtype=float), -np.pi)
        high = np.minimum(np.asarray(robot.q_max, dtype=float), np.pi)
        q = np.random.default_rng(0).uniform(low, high, (POSES, n))
    parameters = np.zeros((n, 11))
    parameters[-1, :4] = (1.0, 0.3, 0.2, 0.1)  # 1 kg, its centre 0.37 m off the link frame in every direction
    parameters[-1, [4, 6, 9]] = 1.0
    torque = np.abs(PinocchioOracle(robot, parameters).gravity(np.asarray(q, dtype=float).reshape(-1, n)))
    peak = torque.max(axis=0, initial=0.0)
    return peak > CARRIES * max(float(peak.max(initial=0.0)), 1e-300)
