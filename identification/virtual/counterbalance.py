"""Physical counterbalances for the virtual robot: a balancer that holds up a share of a joint's gravity torque.

A counterbalance on an industrial arm's shoulder (a spring balancer, a gas spring, a cam) is designed against the
arm's weight: it opposes the joint's gravity torque over the whole working range and takes a large share of it. A
cam or strut whose sign and rest angle are drawn without regard to gravity is not one: it adds to the gravity torque
on part of the range, which no real balancer does, and the estimators tuned on it may fail on a real arm.

With the other joints held at a pose, the gravity load torque of a revolute joint is a sinusoid of its own angle,
``G sin(q - q_hang)`` (``gravity_law``: ``G >= 0``, zero where the arm's weight hangs below the axis). The balancers
built here act about that hanging angle with the opposite sign, their first harmonic sized to a ``share`` of ``G``:

- ``cam_counterbalance``: ``CamCounterbalance`` with ``q0 = q_hang``, ``amplitude = -share G / (1 - lobe / 2)``
  (its law ``sin x (1 + lobe cos 2x)`` keeps the sign of ``sin x`` for ``lobe < 1``, so it opposes gravity at every
  angle);
- ``gas_spring_counterbalance``: ``GasSpringCounterbalance`` whose levers are aligned at ``q_hang`` (opposed, the
  strut at its longest, with the arm upright): the compressed strut pushes the arm up, hardest as it comes down.

``balance`` measures a balancer against the gravity torque of recorded poses (the share it takes, the fraction of
samples it opposes), so benchmarks can state what they simulate. One home for the benchmarks' and tests' balancers.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.virtual.effects import CamCounterbalance, GasSpringCounterbalance
from psdm_casadi.errors import ParameterError

#: Angles of a full turn over which a law's first harmonic is taken.
_TURN = np.linspace(-np.pi, np.pi, 721)[:-1]


@dataclass(frozen=True)
class GravityLaw:
    """A joint's gravity load torque as a function of its own angle, the other joints at ``pose``:
    ``amplitude sin(q - hanging)`` [N m] (``amplitude >= 0``; at ``hanging`` [rad] the weight hangs below the axis)."""

    joint: int
    amplitude: float
    hanging: float
    pose: tuple

    def torque(self, angles) -> np.ndarray:
        return self.amplitude * np.sin(np.asarray(angles, dtype=float) - self.hanging)


@dataclass(frozen=True)
class Balance:
    """How a balancer meets the gravity torque of recorded poses: ``share`` is the least-squares fraction of the
    joint's gravity torque it cancels, ``opposing`` the fraction of samples on which its torque has the sign opposite
    to gravity's (1.0 for a counterbalance), ``gravity_rms`` the gravity torque's RMS there [N m]."""

    share: float
    opposing: float
    gravity_rms: float


def gravity_law(robot, joint: int, pose) -> GravityLaw:
    """The gravity load torque of revolute ``joint`` (0-based) over its own angle, the others at ``pose`` (Pinocchio's
    gravity of the robot file's links; a designer balances the arm as drawn, without a tool)."""
    from psdm_casadi.oracle import PinocchioOracle

    pose = np.asarray(pose, dtype=float)
    if pose.shape != (robot.n_dof,):
        raise ParameterError(f"gravity_law: pose must have shape ({robot.n_dof},); got {pose.shape}.")
    angles = np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)
    q = np.tile(pose, (angles.size, 1))
    q[:, joint] = angles
    g = PinocchioOracle(robot).gravity(q)[:, joint]
    (s, c), *_ = np.linalg.lstsq(np.column_stack([np.sin(angles), np.cos(angles)]), g, rcond=None)
    # s sin q + c cos q = G sin(q - h) with G cos h = s, -G sin h = c
    return GravityLaw(joint=joint, amplitude=float(np.hypot(s, c)), hanging=float(np.arctan2(-c, s)), pose=tuple(pose))


def _first_harmonic(law, hanging: float) -> float:
    """The coefficient of ``sin(q - hanging)`` in a load-torque law of the angle over a full turn."""
    return float(2.0 * np.mean(law(hanging + _TURN) * np.sin(_TURN)))


def cam_counterbalance(robot, joint: int, pose, share: float, lobe: float = 0.3) -> CamCounterbalance:
    """A cam balancer on ``joint`` whose first harmonic cancels ``share`` (0-1) of its gravity amplitude at ``pose``."""
    _check(share, lobe)
    gravity = gravity_law(robot, joint, pose)
    amplitude = -share * gravity.amplitude / (1.0 - 0.5 * lobe)
    return CamCounterbalance(joint=joint, amplitude=float(amplitude), q0=gravity.hanging, lobe=float(lobe))


def gas_spring_counterbalance(
    robot, joint: int, pose, share: float, a: float, b: float, stiffening: float
) -> GasSpringCounterbalance:
    """A gas-spring balancer on ``joint``: a strut on levers ``a`` and ``b`` [m], aligned at the hanging angle (so
    opposed, the strut at its longest ``a + b``, with the arm upright), ``stiffening`` (>= 0) times its preload
    stronger when fully compressed, its first harmonic cancelling ``share`` of the gravity amplitude at ``pose``."""
    _check(share, 0.0)
    if not stiffening >= 0:
        raise ParameterError(f"gas_spring_counterbalance: stiffening must be >= 0; got {stiffening!r}.")
    gravity = gravity_law(robot, joint, pose)
    length0 = a + b
    unit = GasSpringCounterbalance(joint=joint, a=a, b=b, q0=gravity.hanging, preload=1.0, length0=length0,
                                   stiffness=stiffening / (length0 - abs(a - b)))  # fmt: skip
    unit.validate(robot.n_dof)
    preload = share * gravity.amplitude / -_first_harmonic(lambda q: -unit.strut_torque(q), gravity.hanging)
    return replace(unit, preload=float(preload), stiffness=float(unit.stiffness * preload))


def balance(robot, effect, q) -> Balance:
    """How ``effect`` (a load torque on one joint) meets the robot file's gravity torque at poses ``q`` (n, n_dof)."""
    from psdm_casadi.oracle import PinocchioOracle

    q = np.atleast_2d(np.asarray(q, dtype=float))
    g = PinocchioOracle(robot).gravity(q)[:, effect.joint]
    torque = np.array([effect.torque(0.0, row, np.zeros_like(row), None)[effect.joint] for row in q])
    return Balance(
        share=float(-np.dot(torque, g) / max(np.dot(g, g), 1e-300)),
        opposing=float(np.mean(torque * g < 0.0)),
        gravity_rms=float(np.sqrt(np.mean(g**2))),
    )


def _check(share, lobe):
    if not 0.0 < share <= 1.0:
        raise ParameterError(f"counterbalance share must be in (0, 1] (of the gravity amplitude); got {share!r}.")
    if not 0.0 <= lobe < 1.0:
        raise ParameterError(f"cam lobe must be in [0, 1) (the law would change sign); got {lobe!r}.")
