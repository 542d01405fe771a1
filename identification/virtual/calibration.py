"""simulate_calibration(): the paper's calibration experiments run on the virtual robot into a CalibrationData.

The virtual robot does not design experiments: a plan (:class:`CalibrationDesign`, for example
``trajopt.calibration_plan.CalibrationPlan``, passed in by the demo, the command line or a
benchmark) hands it the reference knots ``(t, q)`` of each experiment as plain arrays, which
``simulate_recording`` interpolates and tracks:

- motor: per joint, one sweep without and one with the calibration mass, in a pose the plan
  chooses with the mass's static torque (``load_torque``) that the virtual robot supplies;
- gravity: one out-and-back jog of all joints;
- friction: per joint, one experiment and optionally a second one for validation. The joint
  controller has no friction feed-forward here (the robot being calibrated does not know its
  friction, and a steady-state friction feed-forward switches by 2 Fs at every reversal of the
  reference, which would throw the joint out of the pre-sliding regime); see
  :func:`friction_simulation_options` for the integration settings;
- excitation: the plan's excitation references, or the ones passed in (e.g. sampled from an
  optimised trajectory).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from functools import partial
from typing import Protocol

import numpy as np

from identification.calibration.payload import payload_static_torque
from identification.data.dataset import CalibrationData
from identification.virtual.effects import Payload
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import RobotDescription

__all__ = ["CalibrationDesign", "VirtualCalibrationOptions", "friction_simulation_options", "simulate_calibration"]

logger = logging.getLogger(__name__)


class CalibrationDesign(Protocol):
    """What :func:`simulate_calibration` asks of an experiment plan; every method returns plain arrays.

    A reference is a tuple ``(t, q[, qd[, qdd]])`` as ``simulate_recording`` takes it. Methods that
    draw random numbers receive the calibration's generator, so designs and sensor noise come from
    one seeded stream in experiment order. Joints are 0-based.
    """

    def motor_reference(self, robot, joint: int, load_torque, rng: np.random.Generator) -> tuple:
        """Sweep of ``joint``; ``load_torque(q)`` is the static joint torque of the calibration mass."""

    def gravity_reference(self, robot, rng: np.random.Generator) -> tuple:
        """Out-and-back jog of the joints."""

    def friction_reference(self, robot, joint: int) -> tuple:
        """Friction experiment of ``joint``."""

    def friction_validation_reference(self, robot, joint: int) -> tuple | None:
        """Second friction experiment of ``joint``, or None."""

    def excitation_references(self, robot, rng: np.random.Generator) -> tuple:
        """References of the excitation experiments."""


@dataclass(frozen=True)
class VirtualCalibrationOptions:
    """Settings of the virtual robot in :func:`simulate_calibration` (the experiments come from a plan).

    Parameters
    ----------
    payload : Payload
        Calibration mass of the motor step (its centre of mass off the flange axis loads joint 6).
    simulation : SimulationOptions
        The virtual robot's options (rate, noise; ``payload`` is set per experiment).
    quiet : bool
        No progress log lines.

    Raises
    ------
    ParameterError
        For a payload or simulation of the wrong type.
    """

    payload: Payload = Payload(mass=2.0, com=(0.06, 0.04, 0.05))
    simulation: SimulationOptions = SimulationOptions()
    quiet: bool = False

    def __post_init__(self):
        if not isinstance(self.payload, Payload):
            raise ParameterError(
                f"VirtualCalibrationOptions.payload must be a Payload; got {type(self.payload).__name__}."
            )
        if not isinstance(self.simulation, SimulationOptions):
            raise ParameterError(
                "VirtualCalibrationOptions.simulation must be a SimulationOptions; got "
                f"{type(self.simulation).__name__}."
            )


def friction_simulation_options(options: SimulationOptions) -> SimulationOptions:
    """The virtual robot's settings for a friction experiment, from the general ones.

    No friction feed-forward (the robot being calibrated does not know its friction yet); at least
    4 sub-steps, which resolve the stick-slip of light wrist joints in the Stribeck segments; and the
    leapfrog integrator, whose held commands enter the second difference of q as in continuous
    time (symplectic Euler records them half a sub-step late, which the friction fit sees as a phase
    error of the bristle ringing).
    """
    return replace(options, friction_feedforward=False, substeps=max(int(options.substeps), 4), integrator="leapfrog")


def simulate_calibration(
    robot: RobotDescription,
    design: CalibrationDesign,
    options: VirtualCalibrationOptions | None = None,
    rng: np.random.Generator | None = None,
    joints=None,
    *,
    excitation=None,
    extras=(),
) -> CalibrationData:
    """Simulate the motor, gravity, friction and excitation experiments of a plan on the virtual robot.

    Parameters
    ----------
    robot : RobotDescription
        The true robot (links and drives are the truth).
    design : CalibrationDesign
        The experiment plan, e.g. ``trajopt.calibration_plan.CalibrationPlan()``.
    options : VirtualCalibrationOptions, optional
    rng : numpy.random.Generator, optional
        Sensor noise and the plan's random choices; ``default_rng(0)`` when omitted.
    joints : sequence of int, optional
        Joints (0-based) given motor and friction experiments; all by default.
    excitation : sequence of references, optional
        References of the excitation experiments (e.g. ``(t, q, qd, qdd)`` arrays sampled from an
        optimised trajectory); the plan's ``excitation_references`` by default.
    extras : sequence of ExtraPhysics
        Physics the virtual robot carries in every experiment and the identification does not model.

    Returns
    -------
    CalibrationData

    Examples
    --------
    >>> from trajopt.calibration_plan import CalibrationPlan  # a composer may import both packages
    >>> data = simulate_calibration(robot, CalibrationPlan(), rng=np.random.default_rng(0))  # doctest: +SKIP
    """
    options = VirtualCalibrationOptions() if options is None else options
    rng = np.random.default_rng(0) if rng is None else rng
    joints = list(range(robot.n_dof)) if joints is None else list(joints)
    sim = replace(options.simulation, payload=None)
    loaded = replace(options.simulation, payload=options.payload)
    still = friction_simulation_options(sim)
    load_torque = partial(payload_static_torque, robot, options.payload)

    def run(name, reference, sim_options):
        rec, _ = simulate_recording(robot, reference, sim_options, rng, extras=extras)
        if not options.quiet:
            logger.info("simulate: %s: %.1f s", name, rec.duration)
        return rec.with_signals(name=name)

    motor = []
    for j in joints:
        ref = design.motor_reference(robot, j, load_torque, rng)
        motor.append((j, run(f"motor_j{j + 1}_nominal", ref, sim), run(f"motor_j{j + 1}_payload", ref, loaded)))
    gravity = (run("gravity", design.gravity_reference(robot, rng), sim),)
    friction, friction_validation = [], []
    for j in joints:
        friction.append((j, run(f"friction_j{j + 1}", design.friction_reference(robot, j), still)))
        ref = design.friction_validation_reference(robot, j)
        if ref is not None:
            friction_validation.append((j, run(f"friction_j{j + 1}_validation", ref, still)))
    if excitation is None:
        excitation = design.excitation_references(robot, rng)
    excitation = tuple(
        run("excitation" if len(excitation) == 1 else f"excitation_{k + 1}", reference, sim)
        for k, reference in enumerate(excitation)
    )
    return CalibrationData(
        payload=options.payload,
        motor=tuple(motor),
        gravity=gravity,
        friction=tuple(friction),
        excitation=excitation,
        friction_validation=tuple(friction_validation),
    )
