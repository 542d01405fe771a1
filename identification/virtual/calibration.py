"""simulate_calibration(): the four calibration experiments of the paper run on the virtual robot.

Produces the :class:`identification.data.dataset.CalibrationData` the pipeline consumes, kept short so
simulation plus identification of the Denso fits in a few minutes (defaults at 1 kHz):

- motor: per joint, a 0.25 rad/s sweep over 40 % of the range and back, without and with the mass,
  in a pose (seeded random search) where the mass loads the swept joint most (slow: with eq. 16's
  static load the mass's velocity terms biased Kt of joint 1 by 0.1 % at this speed;
  ``MotorIdentifier(load="dynamic")``, the default, removes them);
- gravity: one 120 s out-and-back jog of all joints at about 0.15 rad/s (long and slow: the smallest
  gravity parameters of the Denso carry torques of a few hundredths of a N m);
- friction: per joint, ``experiments.friction_reference`` of a ``FrictionDesign`` (28 s: pre-sliding, break-away,
  Stribeck and sliding segments) and a second run of the design at 1.3 times its frequencies for
  validation; the joint controller has no friction feed-forward here (the robot being calibrated
  does not know its friction, and a steady-state friction feed-forward switches by 2 Fs at every
  reversal of the reference, which would throw the joint out of the pre-sliding regime) and the
  virtual robot integrates with at least 4 sub-steps per sample (with the default 2 the stick-slip
  of the light wrist joints in the Stribeck segments is under-resolved, and the simulated friction
  departs from the LuGre equations by 0.15 N m, which biased vs by 27 % on joint 5) by the
  second-order leapfrog scheme (``SimulationOptions.integrator``; with symplectic Euler the recorded
  commands are off by half a sub-step against the positions, which biased sigma1 of joints 1-3 by
  70-170 %);
- excitation: a 30 s sum of sines (``experiments.sine_reference``), the stand-in for trajopt's
  optimised excitation (identification never imports trajopt).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from psdm_casadi.cli import progress
from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import RobotDescription

from identification.virtual import experiments
from identification.data.dataset import CalibrationData
from identification.virtual.experiments import FrictionDesign
from identification.virtual.effects import Payload
from identification.calibration.payload import payload_static_torque
from identification.virtual.simulation import SimulationOptions, simulate_recording

__all__ = ["VirtualCalibrationOptions", "simulate_calibration", "motor_pose"]


@dataclass(frozen=True)
class VirtualCalibrationOptions:
    """Durations and settings of :func:`simulate_calibration`.

    Parameters
    ----------
    payload : Payload
        Calibration mass of the motor step (its centre of mass off the flange axis loads joint 6).
    motor_speed : float
        Sweep speed [rad/s].
    motor_range_fraction : float
        Swept share of each joint range.
    gravity_duration : float
        [s] of the out-and-back jog.
    gravity_speed : float
        Jog speed [rad/s].
    excitation_duration : float
        [s] of the sum-of-sines trajectory.
    friction_design : FrictionDesign
        Content of each joint's friction experiment (``FrictionDesign.quick()`` for a 14 s version).
    friction_amplitudes : tuple of float or None
        When given, the friction experiment is instead a short run of growing sine-cubed
        oscillations of these amplitudes [rad] (``experiments.oscillation_reference``; quick, but
        it does not resolve sigma0, sigma1 and vs) without a validation run.
    friction_validation : bool
        Also record ``friction_design.validation()`` per joint (``CalibrationData.friction_validation``).
    simulation : SimulationOptions
        The virtual robot's options (rate, noise; ``payload`` is set per experiment).
    quiet : bool
        No progress lines.
    """

    payload: Payload = Payload(mass=2.0, com=(0.06, 0.04, 0.05))
    motor_speed: float = 0.25
    motor_range_fraction: float = 0.4
    gravity_duration: float = 120.0
    gravity_speed: float = 0.15
    excitation_duration: float = 30.0
    friction_design: FrictionDesign = FrictionDesign()
    friction_amplitudes: tuple | None = None
    friction_validation: bool = True
    simulation: SimulationOptions = SimulationOptions()
    quiet: bool = False

    def __post_init__(self):
        for name in ("motor_speed", "motor_range_fraction", "gravity_duration", "gravity_speed", "excitation_duration"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"VirtualCalibrationOptions.{name} must be positive; got {value!r}.")
        if not isinstance(self.friction_design, FrictionDesign):
            raise ParameterError("VirtualCalibrationOptions.friction_design must be a FrictionDesign; got "
                                 f"{type(self.friction_design).__name__}.")


def motor_pose(robot: RobotDescription, joint: int, payload: Payload, rng: np.random.Generator,
               n_candidates: int = 48, range_fraction: float = 0.4) -> np.ndarray:
    """A pose in which the calibration mass loads ``joint`` strongly all along its sweep (seeded search)."""
    home = experiments.home_pose(robot)
    lo, hi = robot.q_min, robot.q_max
    best, best_score = home, -1.0
    for k in range(n_candidates):
        pose = home if k == 0 else rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
        _, q = experiments.motor_reference(robot, joint, range_fraction=range_fraction, pose=pose)
        torque = payload_static_torque(robot, payload, q[:: max(1, q.shape[0] // 40)])[:, joint]
        score = float(np.sqrt(np.mean(torque**2)) * min(1.0, np.abs(torque).min() / (np.abs(torque).max() + 1e-12) + 0.5))
        if score > best_score:
            best, best_score = pose, score
    return best


def simulate_calibration(robot: RobotDescription, options: VirtualCalibrationOptions | None = None,
                         rng: np.random.Generator | None = None, joints=None, *, excitation=None,
                         extras=()) -> CalibrationData:
    """Simulate the motor, gravity, friction and excitation experiments of the paper on the virtual robot.

    Parameters
    ----------
    robot : RobotDescription
        The true robot (links and drives are the truth).
    options : VirtualCalibrationOptions, optional
    rng : numpy.random.Generator, optional
        Sensor noise and random poses/trajectories; ``default_rng(0)`` when omitted.
    joints : sequence of int, optional
        Joints (0-based) given motor and friction experiments; all by default.
    excitation : sequence of references, optional
        References of the excitation experiments (e.g. ``(t, q, qd, qdd)`` arrays sampled from an
        optimised trajectory); a sum of sines of ``options.excitation_duration`` by default.
    extras : sequence of ExtraPhysics
        Physics the virtual robot carries in every experiment and the identification does not model.

    Returns
    -------
    CalibrationData
    """
    options = VirtualCalibrationOptions() if options is None else options
    rng = np.random.default_rng(0) if rng is None else rng
    joints = list(range(robot.n_dof)) if joints is None else list(joints)
    sim = replace(options.simulation, payload=None)
    loaded = replace(options.simulation, payload=options.payload)

    def run(name, reference, sim_options):
        rec, _ = simulate_recording(robot, reference, sim_options, rng, extras=extras)
        progress(f"simulate: {name}: {rec.duration:.1f} s", quiet=options.quiet)
        return rec.with_signals(name=name)

    motor = []
    for j in joints:
        pose = motor_pose(robot, j, options.payload, rng, range_fraction=options.motor_range_fraction)
        ref = experiments.motor_reference(robot, j, speed=options.motor_speed,
                                          range_fraction=options.motor_range_fraction, pose=pose)
        motor.append((j, run(f"motor_j{j + 1}_nominal", ref, sim), run(f"motor_j{j + 1}_payload", ref, loaded)))
    gravity = (run("gravity", experiments.gravity_reference(robot, duration=options.gravity_duration,
                                                                speed=options.gravity_speed, rng=rng), sim),)
    # the controller does not know the friction yet; 4 sub-steps resolve the stick-slip of the light wrist
    # joints in the Stribeck segments (with 2 the simulated friction departs from the LuGre ODE by 0.15 N m)
    # leapfrog: the held commands enter the second difference of q as in continuous time (synthetic docstring)
    still = replace(sim, friction_feedforward=False, substeps=max(int(sim.substeps), 4), integrator="leapfrog")
    friction, friction_validation = [], []
    for j in joints:
        if options.friction_amplitudes is not None:
            ref = experiments.oscillation_reference(robot, j, amplitudes=options.friction_amplitudes)
            friction.append((j, run(f"friction_j{j + 1}", ref, still)))
            continue
        ref = experiments.friction_reference(robot, j, options.friction_design)
        friction.append((j, run(f"friction_j{j + 1}", ref, still)))
        if options.friction_validation:
            ref = experiments.friction_reference(robot, j, options.friction_design.validation())
            friction_validation.append((j, run(f"friction_j{j + 1}_validation", ref, still)))
    if excitation is None:
        excitation = (experiments.sine_reference(robot, duration=options.excitation_duration, rng=rng),)
    excitation = tuple(run("excitation" if len(excitation) == 1 else f"excitation_{k + 1}", reference, sim)
                       for k, reference in enumerate(excitation))
    return CalibrationData(payload=options.payload, motor=tuple(motor), gravity=gravity, friction=tuple(friction),
                           excitation=excitation, friction_validation=tuple(friction_validation))
