"""CalibrationPlan: the settings of every experiment of one calibration, handing their references to a robot.

The virtual robot (``identification.virtual.calibration.simulate_calibration``) runs a whole
calibration from a plan without importing trajopt: it calls the ``*_reference`` methods, which
return the knots ``(t, q)`` of the experiments of :mod:`trajopt.experiments` as plain arrays.
Those that draw random numbers take the calibration's generator, so the designs and the sensor
noise come from one seeded stream in experiment order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ParameterError
from trajopt.experiments import (
    choose_motor_pose,
    friction_experiment,
    gravity_experiment,
    motor_experiment,
    oscillation_experiment,
    sine_experiment,
)
from trajopt.friction_design import FrictionDesign

__all__ = ["CalibrationPlan"]


@dataclass(frozen=True)
class CalibrationPlan:
    """Settings of the motor, gravity, friction and excitation experiments of one calibration.

    The defaults are those of the experiment functions.

    Parameters
    ----------
    motor_speed : float
        Sweep speed of ``motor_experiment`` [rad/s].
    motor_range_fraction : float
        Swept share of each joint range.
    gravity_duration : float
        Length of the out-and-back jog of ``gravity_experiment`` [s].
    gravity_speed : float
        Jog speed [rad/s].
    excitation_duration : float
        Length of the sum-of-sines stand-in excitation [s].
    friction_design : FrictionDesign
        Content of each joint's friction experiment (``FrictionDesign.quick()`` for a shorter one).
    friction_amplitudes : tuple of float or None
        When given, the friction experiment is instead ``oscillation_experiment`` with these
        amplitudes [rad] (quick, but it does not resolve sigma0, sigma1 and vs), without a validation run.
    friction_validation : bool
        Also run ``friction_design.validation()`` per joint.

    Raises
    ------
    ParameterError
        Naming the field.

    Examples
    --------
    >>> plan = CalibrationPlan(gravity_duration=40.0, friction_design=FrictionDesign.quick())
    >>> plan.gravity_speed
    0.15
    """

    motor_speed: float = 0.25
    motor_range_fraction: float = 0.4
    gravity_duration: float = 120.0
    gravity_speed: float = 0.15
    excitation_duration: float = 30.0
    friction_design: FrictionDesign = FrictionDesign()
    friction_amplitudes: tuple | None = None
    friction_validation: bool = True

    def __post_init__(self):
        for name in ("motor_speed", "motor_range_fraction", "gravity_duration", "gravity_speed", "excitation_duration"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"CalibrationPlan.{name} must be positive; got {value!r}.")
        if not isinstance(self.friction_design, FrictionDesign):
            raise ParameterError(
                f"CalibrationPlan.friction_design must be a FrictionDesign; got {type(self.friction_design).__name__}."
            )
        if self.friction_amplitudes is not None:
            amplitudes = tuple(float(a) for a in np.atleast_1d(self.friction_amplitudes))
            if not amplitudes or not all(np.isfinite(a) and a > 0 for a in amplitudes):
                raise ParameterError(
                    "CalibrationPlan.friction_amplitudes must be positive amplitudes [rad] or None; "
                    f"got {self.friction_amplitudes!r}."
                )
            object.__setattr__(self, "friction_amplitudes", amplitudes)

    def motor_reference(self, robot, joint: int, load_torque, rng: np.random.Generator) -> tuple:
        """Knots ``(t, q)`` of joint ``joint``'s motor sweep in a pose the calibration mass loads (``load_torque``)."""
        pose = choose_motor_pose(robot, joint, load_torque, rng, range_fraction=self.motor_range_fraction)
        return motor_experiment(
            robot, joint, speed=self.motor_speed, range_fraction=self.motor_range_fraction, pose=pose
        ).reference()

    def gravity_reference(self, robot, rng: np.random.Generator) -> tuple:
        """Knots ``(t, q)`` of the gravity jog of all joints."""
        return gravity_experiment(robot, duration=self.gravity_duration, speed=self.gravity_speed, rng=rng).reference()

    def friction_reference(self, robot, joint: int) -> tuple:
        """Knots ``(t, q)`` of joint ``joint``'s friction experiment."""
        if self.friction_amplitudes is not None:
            return oscillation_experiment(robot, joint, amplitudes=self.friction_amplitudes).reference()
        return friction_experiment(robot, joint, self.friction_design).reference()

    def friction_validation_reference(self, robot, joint: int) -> tuple | None:
        """Knots ``(t, q)`` of joint ``joint``'s second friction experiment, or None when the plan has none."""
        if self.friction_amplitudes is not None or not self.friction_validation:
            return None
        return friction_experiment(robot, joint, self.friction_design.validation()).reference()

    def excitation_references(self, robot, rng: np.random.Generator) -> tuple:
        """Knots ``((t, q),)`` of the excitation experiments: one sum of sines."""
        return (sine_experiment(robot, duration=self.excitation_duration, rng=rng).reference(),)
