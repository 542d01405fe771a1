"""Calibration experiments of the paper (sections 3.1-3.3) as trajectories a robot, real or virtual, runs.

Each design is a dense, smooth path of knots ``(t, q)`` (500 per second) that a cubic spline
interpolates to the positions, velocities and accelerations a controller tracks; the virtual robot
(``identification.virtual``) is handed the same knots, so what a user records is what the
identification was validated on.

- ``motor_experiment`` (3.1): one joint swept at constant speed over part of its range and back,
  the others held (run with and without the calibration mass; ``choose_motor_pose`` picks the pose);
- ``gravity_experiment`` (3.2): the joints jogged slowly and together, then back along the same path;
- ``friction_experiment`` (3.3): one joint through the segments of a
  :class:`~trajopt.friction_design.FrictionDesign` (pre-sliding, break-away, Stribeck, sliding);
- ``oscillation_experiment``: one joint through sine-cubed oscillations of growing amplitude (a short,
  coarse friction experiment for quick runs);
- ``sine_experiment``: a sum of sines per joint (eq. 22), a stand-in for an optimised excitation.

Joints are 0-based here; user-facing text and file columns number them from 1.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from psdm_casadi.errors import ParameterError
from trajopt.constraints import JointLimits
from trajopt.experiment_trajectory import ExperimentTrajectory, verify_experiment
from trajopt.friction_design import FrictionDesign

__all__ = [
    "GRID_HZ",
    "ExperimentTrajectory",
    "home_pose",
    "motion_centre",
    "motor_experiment",
    "choose_motor_pose",
    "gravity_experiment",
    "friction_experiment",
    "oscillation_experiment",
    "sine_experiment",
]

GRID_HZ = 500.0  # knots per second of every design


def home_pose(robot) -> np.ndarray:
    """Zero clipped into the joint ranges: the pose of the joints an experiment does not move."""
    return np.clip(np.zeros(robot.n_dof), robot.q_min, robot.q_max)


def motion_centre(robot) -> np.ndarray:
    """Zero clipped into the middle half of each joint's range: the centre a motion of every joint swings about.

    A range that holds zero well inside keeps zero (the designs of symmetric arms are unchanged); a joint whose range
    ends at or near zero (the Panda's joint 4, [-3.07, -0.07] rad) is centred a quarter of its range inside, so it
    has room to move both ways instead of none.
    """
    quarter = 0.25 * (np.asarray(robot.q_max, dtype=float) - np.asarray(robot.q_min, dtype=float))
    return np.clip(np.zeros(robot.n_dof), robot.q_min + quarter, robot.q_max - quarter)


def _check_joint(robot, joint, owner) -> int:
    if isinstance(joint, bool) or not (isinstance(joint, (int, np.integer)) and 0 <= joint < robot.n_dof):
        raise ParameterError(f"{owner}.joint must be a 0-based joint index 0..{robot.n_dof - 1}; got {joint!r}.")
    return int(joint)


def _check_positive(owner, **values):
    for name, value in values.items():
        if isinstance(value, bool) or not (
            isinstance(value, (int, float, np.number)) and np.isfinite(value) and value > 0
        ):
            raise ParameterError(f"{owner}.{name} must be a positive number; got {value!r}.")


def _check_fraction(owner, name, value):
    _check_positive(owner, **{name: value})
    if value > 1:
        raise ParameterError(f"{owner}.{name} must be in (0, 1]; got {value!r}. Use e.g. 0.5.")


def _pose(robot, pose, owner) -> np.ndarray:
    if pose is None:
        return home_pose(robot)
    pose = np.asarray(pose, dtype=float)
    if pose.shape != (robot.n_dof,) or np.any(pose < robot.q_min) or np.any(pose > robot.q_max):
        raise ParameterError(
            f"{owner}.pose must be {robot.n_dof} joint positions inside [q_min, q_max]; got "
            f"{pose.tolist()}. Leave it None for zero clipped into the ranges."
        )
    return pose


def _out_and_back(duration: float, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and a path parameter s(t) that runs at unit speed to s_max and back, with cosine speed ramps."""
    t = np.arange(0.0, duration + 0.5 / GRID_HZ, 1.0 / GRID_HZ)
    half = duration / 2.0
    v = np.ones_like(t)
    up = t < ramp
    v[up] = 0.5 * (1.0 - np.cos(np.pi * t[up] / ramp))
    turn = np.abs(t - half) < ramp
    v[turn] = np.cos(np.pi * (t[turn] - (half - ramp)) / (2.0 * ramp))
    v[t >= half + ramp] = -1.0  # the turn ends at -1: a knot exactly at half + ramp belongs to the way back
    down = t > duration - ramp
    v[down] = -0.5 * (1.0 - np.cos(np.pi * (duration - t[down]) / ramp))
    return t, cumulative_trapezoid(v, t, initial=0.0)


def _motor_path(robot, joint, speed, range_fraction, ramp, pose):
    lo, hi = robot.q_min[joint], robot.q_max[joint]
    centre, half_range = 0.5 * (lo + hi), 0.5 * range_fraction * (hi - lo)
    duration = 2.0 * (2.0 * half_range / speed + ramp)
    t, s = _out_and_back(duration, ramp)
    q = np.tile(pose, (t.size, 1))
    q[:, joint] = centre - half_range + speed * s
    return t, q


def motor_experiment(
    robot,
    joint: int,
    *,
    speed: float = 0.25,
    range_fraction: float = 0.4,
    ramp: float = 0.5,
    pose=None,
    limits: JointLimits | None = None,
) -> ExperimentTrajectory:
    """Section 3.1: sweep one joint at constant speed over part of its range and back, the others held.

    The sweep is slow so that the velocity terms of the calibration mass stay small against its
    static load, and it runs forward and back so that friction cancels in the average.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        0-based joint to sweep.
    speed : float
        Sweep speed [rad/s].
    range_fraction : float
        Share of the joint range swept, about its centre, in (0, 1].
    ramp : float
        Length of the cosine speed ramps at the ends and the turn [s].
    pose : array, shape (n_dof,), optional
        Pose of the other joints; default ``home_pose(robot)``. ``choose_motor_pose`` finds one in
        which the calibration mass loads the swept joint.
    limits : JointLimits, optional
        Limits to check against; default the robot's.

    Returns
    -------
    ExperimentTrajectory

    Raises
    ------
    ParameterError
        For a bad joint, speed, fraction, ramp or pose.

    Examples
    --------
    >>> experiment = motor_experiment(robot, 1)  # doctest: +SKIP
    >>> experiment.to_csv("motor_j2.csv", rate=1000.0)  # doctest: +SKIP
    """
    owner = "motor_experiment"
    joint = _check_joint(robot, joint, owner)
    _check_positive(owner, speed=speed, ramp=ramp)
    _check_fraction(owner, "range_fraction", range_fraction)
    t, q = _motor_path(robot, joint, speed, range_fraction, ramp, _pose(robot, pose, owner))
    return verify_experiment("motor", t, q, robot, (joint,), limits)


def choose_motor_pose(
    robot, joint: int, load_torque, rng: np.random.Generator, *, n_candidates: int = 48, range_fraction: float = 0.4
) -> np.ndarray:
    """A pose in which the calibration mass loads ``joint`` strongly all along its sweep (seeded random search).

    Candidates are the home pose and ``n_candidates - 1`` random poses in the middle 60 % of the
    ranges; each is scored by the RMS of the mass's static torque on the joint along the sweep,
    discounted when that torque nearly vanishes somewhere on the sweep.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        0-based joint to sweep.
    load_torque : callable
        ``load_torque(q) -> tau``: joint torques [N m] of the calibration mass held against gravity,
        arrays (n_samples, n_dof) (e.g. ``identification.calibration.payload.payload_static_torque``
        with the robot and mass bound).
    rng : numpy.random.Generator
        Source of the candidate poses.
    n_candidates : int
        Poses tried, >= 1.
    range_fraction : float
        Share of the joint range the sweep covers (as in ``motor_experiment``).

    Returns
    -------
    array, shape (n_dof,)
    """
    owner = "choose_motor_pose"
    joint = _check_joint(robot, joint, owner)
    _check_fraction(owner, "range_fraction", range_fraction)
    if isinstance(n_candidates, bool) or not (isinstance(n_candidates, (int, np.integer)) and n_candidates >= 1):
        raise ParameterError(f"{owner}.n_candidates must be an integer >= 1; got {n_candidates!r}.")
    home = home_pose(robot)
    lo, hi = robot.q_min, robot.q_max
    best, best_score = home, -1.0
    for k in range(n_candidates):
        pose = home if k == 0 else rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
        # scored on about 40 poses of a 0.3 rad/s sweep: the sampling the validated poses were chosen on
        _, q = _motor_path(robot, joint, 0.3, range_fraction, 0.5, pose)
        torque = np.asarray(load_torque(q[:: max(1, q.shape[0] // 40)]))[:, joint]
        evenness = min(1.0, np.abs(torque).min() / (np.abs(torque).max() + 1e-12) + 0.5)
        score = float(np.sqrt(np.mean(torque**2)) * evenness)
        if score > best_score:
            best, best_score = pose, score
    return best


def gravity_experiment(
    robot,
    *,
    duration: float = 120.0,
    speed: float = 0.15,
    range_fraction: float = 0.8,
    joints=None,
    ramp: float = 0.5,
    rng: np.random.Generator | None = None,
    limits: JointLimits | None = None,
) -> ExperimentTrajectory:
    """Section 3.2: jog the joints together at about ``speed`` through their ranges, then back along the same path.

    Each joint follows a rounded triangle wave with its own (random) period, so the poses cover the
    workspace; the second half retraces the first backwards, so forward and reverse currents can
    be averaged and friction cancels. The jog is long and slow: the smallest gravity parameters
    carry torques comparable to the sensor noise.

    Parameters
    ----------
    robot : RobotDescription
    duration : float
        Length of the out-and-back jog [s].
    speed : float
        Approximate joint speed [rad/s].
    range_fraction : float
        Share of each joint range covered, in (0, 1].
    joints : sequence of int, optional
        0-based joints that move (default all); the others hold the home pose.
    ramp : float
        Length of the cosine speed ramps [s].
    rng : numpy.random.Generator, optional
        Source of the periods; ``default_rng(0)`` when omitted.
    limits : JointLimits, optional

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "gravity_experiment"
    _check_positive(owner, duration=duration, speed=speed, ramp=ramp)
    _check_fraction(owner, "range_fraction", range_fraction)
    rng = np.random.default_rng(0) if rng is None else rng
    joints = tuple(range(robot.n_dof)) if joints is None else tuple(_check_joint(robot, j, owner) for j in joints)
    pose = home_pose(robot)
    t, s = _out_and_back(duration, ramp)
    q = np.tile(pose, (t.size, 1))
    for j in joints:
        lo, hi = robot.q_min[j], robot.q_max[j]
        centre, amplitude = 0.5 * (lo + hi), 0.5 * range_fraction * (hi - lo)
        omega = speed * (0.8 + 0.4 * rng.random()) * np.pi / (2.0 * amplitude)
        phase = np.arcsin(np.clip((pose[j] - centre) / amplitude, -0.99, 0.99))
        q[:, j] = centre + amplitude * (2.0 / np.pi) * np.arcsin(0.98 * np.sin(omega * s + phase))
    return verify_experiment("gravity", t, q, robot, joints, limits)


def _segments_path(pieces, start, pose, joint):
    """Knots of segments ``(t, x)`` of one joint's offset from ``pose``, closed at rest at ``start``."""
    t = np.concatenate([p[0] for p in pieces] + [np.array([start])])
    x = np.concatenate([p[1] for p in pieces] + [np.array([0.0])])
    q = np.tile(pose, (t.size, 1))
    q[:, joint] += x
    return t, q


def friction_experiment(
    robot, joint: int, design: FrictionDesign | None = None, *, pose=None, limits: JointLimits | None = None
) -> ExperimentTrajectory:
    """Section 3.3: one joint through the segments of a :class:`FrictionDesign`, the others held.

    Each segment ``q = pose + sign A (1 - cos 2 pi f t)`` starts and ends at rest and moves towards the
    side of the pose with more room; segments are separated by ``design.pause`` seconds at rest.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        0-based joint.
    design : FrictionDesign, optional
        Default ``FrictionDesign()``; ``design.validation()`` gives the second, validation run.
    pose : array, shape (n_dof,), optional
        Default ``home_pose(robot)``.
    limits : JointLimits, optional

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "friction_experiment"
    joint = _check_joint(robot, joint, owner)
    design = FrictionDesign() if design is None else design
    if not isinstance(design, FrictionDesign):
        raise ParameterError(f"{owner}.design must be a FrictionDesign; got {type(design).__name__}.")
    pose = _pose(robot, pose, owner)
    up, down = robot.q_max[joint] - pose[joint], pose[joint] - robot.q_min[joint]
    sign, room = (1.0, up) if up >= down else (-1.0, down)
    pieces, start = [], 0.0
    for amplitude, frequency, periods in design.segments(robot.qd_max[joint], robot.qdd_max[joint], 0.95 * room):
        length = periods / frequency
        tb = np.arange(0.0, length, 1.0 / GRID_HZ)
        pieces.append((start + tb, sign * amplitude * (1.0 - np.cos(2.0 * np.pi * frequency * tb))))
        start += length
        if design.pause > 0:
            tp = np.arange(0.0, design.pause, 1.0 / GRID_HZ)
            pieces.append((start + tp, np.zeros_like(tp)))
            start += design.pause
    t, q = _segments_path(pieces, start, pose, joint)
    return verify_experiment("friction", t, q, robot, (joint,), limits)


def oscillation_experiment(
    robot,
    joint: int,
    *,
    amplitudes=(2e-4, 1e-3, 5e-3, 0.03, 0.15, 0.6),
    speed_fraction: float = 0.6,
    acceleration_fraction: float = 0.9,
    cycles: int = 3,
    min_period: float = 1.0,
    pose=None,
    limits: JointLimits | None = None,
) -> ExperimentTrajectory:
    """One joint through oscillations ``A sin^3(w t)`` of growing amplitude, others held (a quick friction run).

    ``sin^3`` starts and ends each block at rest with zero acceleration, so blocks join smoothly. The
    period of a block is the longest of ``min_period``, the one reaching ``speed_fraction`` of the
    joint speed limit and the one reaching ``acceleration_fraction`` of its acceleration limit (the
    peak acceleration of ``A sin^3(w t)`` is ``3 A w^2``, at the block's turns), so a large amplitude
    is run slower instead of leaving the limits. Coarser than :func:`friction_experiment`: it does not
    resolve ``sigma0``, ``sigma1`` and ``vs`` well.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        0-based joint.
    amplitudes : sequence of float
        [rad], each inside the range about the pose.
    speed_fraction : float
        Peak speed of a block as a fraction of the speed limit, in (0, 1].
    acceleration_fraction : float
        Peak acceleration of a block as a fraction of the acceleration limit, in (0, 1].
    cycles : int
        Periods per block.
    min_period : float
        [s]
    pose : array, shape (n_dof,), optional
    limits : JointLimits, optional

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "oscillation_experiment"
    joint = _check_joint(robot, joint, owner)
    _check_fraction(owner, "speed_fraction", speed_fraction)
    _check_fraction(owner, "acceleration_fraction", acceleration_fraction)
    _check_positive(owner, cycles=cycles, min_period=min_period)
    pose = _pose(robot, pose, owner)
    limit = min(robot.q_max[joint] - pose[joint], pose[joint] - robot.q_min[joint])
    if len(amplitudes) == 0 or min(amplitudes) <= 0 or max(amplitudes) >= limit:
        raise ParameterError(
            f"{owner}.amplitudes must be positive and inside the range of joint {joint + 1} ({limit:.3g} from the "
            f"pose); got {list(amplitudes)}. Lower the largest amplitude."
        )
    pieces, start = [], 0.0
    for amplitude in amplitudes:
        # peak speed of A sin^3(w t) is about 1.155 A w, peak acceleration 3 A w^2
        omega = min(
            2.0 * np.pi / min_period,
            speed_fraction * robot.qd_max[joint] / (1.155 * amplitude),
            np.sqrt(acceleration_fraction * robot.qdd_max[joint] / (3.0 * amplitude)),
        )
        period = 2.0 * np.pi / omega
        tb = np.arange(0.0, cycles * period, 1.0 / GRID_HZ)
        pieces.append((start + tb, amplitude * np.sin(omega * tb) ** 3))
        start += cycles * period
    t, q = _segments_path(pieces, start, pose, joint)
    return verify_experiment("friction", t, q, robot, (joint,), limits)


def _fitted(swing: np.ndarray, up: float, down: float) -> np.ndarray:
    """``swing`` (a motion starting at 0) scaled down, if need be, to stay within ``[-down, up]``: starting from its
    first value, a sum of sines can swing twice its amplitude one way (at ``fraction`` above 0.5 it would leave the
    range). A swing scaled down keeps 0.1 % of the room free, so the spline a controller tracks between the knots
    does not overshoot the limit either."""
    high, low = float(swing.max()) / 0.999, float(-swing.min()) / 0.999
    factor = min(1.0, up / high if high > 0 else 1.0, down / low if low > 0 else 1.0)
    return swing * factor


def sine_experiment(
    robot,
    *,
    duration: float = 30.0,
    rng: np.random.Generator | None = None,
    n_sines: int = 3,
    fraction: float = 0.5,
    limits: JointLimits | None = None,
) -> ExperimentTrajectory:
    """A sum of ``n_sines`` sines per joint (eq. 22) with random frequencies and phases, a stand-in excitation.

    Scaled into ``fraction`` of the position, speed and acceleration limits about ``motion_centre`` (zero, or a
    quarter of the range inside for a joint whose range ends near zero), and scaled down further where the swing
    would leave the range; it starts and ends with a one-second cosine fade. ``trajopt.optimize_excitation`` designs a
    better-conditioned excitation; this one needs no model.

    Parameters
    ----------
    robot : RobotDescription
    duration : float
        [s]
    rng : numpy.random.Generator, optional
        Source of frequencies, phases and weights; ``default_rng(0)`` when omitted.
    n_sines : int
        Sines per joint.
    fraction : float
        Share of each limit used, in (0, 1].
    limits : JointLimits, optional

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "sine_experiment"
    _check_positive(owner, duration=duration, n_sines=n_sines)
    _check_fraction(owner, "fraction", fraction)
    rng = np.random.default_rng(0) if rng is None else rng
    t = np.arange(0.0, duration + 0.5 / GRID_HZ, 1.0 / GRID_HZ)
    fade = np.minimum(1.0, np.minimum(t, duration - t) / 1.0)
    fade = 0.5 * (1.0 - np.cos(np.pi * fade))
    centre = motion_centre(robot)
    q = np.tile(centre, (t.size, 1))
    for j in range(robot.n_dof):
        omega = 2.0 * np.pi * rng.uniform(0.05, 0.5, n_sines)
        phase = rng.uniform(0.0, 2.0 * np.pi, n_sines)
        weight = rng.uniform(0.5, 1.0, n_sines)
        room = min(robot.q_max[j] - centre[j], centre[j] - robot.q_min[j])
        scale = fraction * min(
            room / weight.sum(), robot.qd_max[j] / (weight * omega).sum(), robot.qdd_max[j] / (weight * omega**2).sum()
        )
        x = (scale * weight * np.sin(np.outer(t, omega) + phase)).sum(axis=1)
        q[:, j] = centre[j] + fade * _fitted(x - x[0], robot.q_max[j] - centre[j], centre[j] - robot.q_min[j])
    return verify_experiment("sine", t, q, robot, tuple(range(robot.n_dof)), limits)
