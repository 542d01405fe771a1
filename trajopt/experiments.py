"""Calibration experiments of the paper's sections 3.1-3.3 as trajectories inside the joint limits.

* ``motor_experiment`` (3.1): one joint sweeps its range at constant velocity forward and back,
  the others hold a pose.
* ``gravity_experiment`` (3.2): every joint jogs slowly and simultaneously through seeded random
  waypoints spanning the ranges, then the same path is run backwards (so friction averages out).
* ``friction_experiment`` (3.3): one joint runs a series of windowed sines whose amplitudes grow from
  the pre-sliding regime to near the speed limit.

Each returns an ``ExperimentTrajectory`` whose limits were verified on a dense grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ParameterError

from trajopt.constraints import JointLimits, check_same_dof, describe_violation, limit_margins, worst_margin
from trajopt.csvfile import write_trajectory_csv


@dataclass(frozen=True)
class MoveSegment:
    """Synchronised straight-line move ``start -> end`` with a trapezoidal time scaling.

    ``q(t) = start + s(t) (end - start)``, ``s`` rising from 0 to 1 with constant ``s'' = +-accel``
    phases around a constant-velocity cruise ``s' = speed``; a hold when ``start == end``.
    """

    start: np.ndarray
    end: np.ndarray
    speed: float  # 1/s, cruise rate of s
    accel: float  # 1/s^2
    duration: float

    def evaluate(self, tau) -> tuple:
        tau = np.asarray(tau, dtype=float)
        delta = self.end - self.start
        if not np.any(delta) or self.speed == 0:
            zeros = np.zeros((tau.size, self.start.size))
            return self.start[None, :] + zeros, zeros.copy(), zeros.copy()
        ta = self.speed / self.accel
        T = self.duration
        s = np.where(tau < ta, 0.5 * self.accel * tau**2,
                     np.where(tau <= T - ta, 0.5 * self.accel * ta**2 + self.speed * (tau - ta),
                              1.0 - 0.5 * self.accel * (T - tau) ** 2))
        sd = np.where(tau < ta, self.accel * tau, np.where(tau <= T - ta, self.speed, self.accel * (T - tau)))
        sdd = np.where(tau < ta, self.accel, np.where(tau <= T - ta, 0.0, -self.accel))
        return (self.start[None, :] + s[:, None] * delta[None, :], sd[:, None] * delta[None, :],
                sdd[:, None] * delta[None, :])


def _move(start, end, qd_limit, qdd_limit) -> MoveSegment:
    """A synchronised move whose fastest joint uses at most ``qd_limit``/``qdd_limit`` (per joint arrays)."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    delta = np.abs(end - start)
    moving = delta > 0
    if not np.any(moving):
        return MoveSegment(start, end, 0.0, 1.0, 0.0)
    speed = float(np.min(qd_limit[moving] / delta[moving]))
    accel = float(np.min(qdd_limit[moving] / delta[moving]))
    if speed**2 / accel > 1.0:  # triangular profile: never reaches the cruise speed
        speed = math.sqrt(accel)
    duration = 1.0 / speed + speed / accel
    return MoveSegment(start, end, speed, accel, duration)


@dataclass(frozen=True)
class SineSegment:
    """One joint runs ``center + h(t) A sin(w t)`` for whole cycles; ``h`` ramps in and out over one cycle each."""

    center: np.ndarray
    joint: int
    amplitude: float
    frequency: float  # rad/s
    cycles: int

    @property
    def duration(self) -> float:
        return 2 * math.pi * self.cycles / self.frequency

    def evaluate(self, tau) -> tuple:
        tau = np.asarray(tau, dtype=float)
        from trajopt.parametrization import _smoothstep

        ramp = 2 * math.pi / self.frequency
        s1, d1, dd1 = _smoothstep(tau / ramp)
        s2, d2, dd2 = _smoothstep((self.duration - tau) / ramp)
        h = s1 * s2
        dh = d1 / ramp * s2 - s1 * d2 / ramp
        ddh = dd1 / ramp**2 * s2 - 2 * d1 * d2 / ramp**2 + s1 * dd2 / ramp**2
        w, a = self.frequency, self.amplitude
        sin, cos = np.sin(w * tau), np.cos(w * tau)
        x, xd, xdd = a * sin, a * w * cos, -a * w**2 * sin
        q = np.repeat(self.center[None, :], tau.size, axis=0)
        qd, qdd = np.zeros_like(q), np.zeros_like(q)
        q[:, self.joint] += h * x
        qd[:, self.joint] = dh * x + h * xd
        qdd[:, self.joint] = ddh * x + 2 * dh * xd + h * xdd
        return q, qd, qdd


@dataclass(frozen=True)
class ExperimentTrajectory:
    """A calibration experiment: a sequence of segments, verified inside ``limits``.

    Attributes
    ----------
    name : str
        "motor", "gravity" or "friction".
    segments : tuple of MoveSegment or SineSegment
    limits : JointLimits
    joints : tuple of int
        1-based joints the experiment identifies.
    worst_margin : float
        Smallest relative margin to a limit on a 1 kHz grid (>= 0).
    """

    name: str
    segments: tuple
    limits: JointLimits
    joints: tuple
    worst_margin: float = float("nan")

    @property
    def duration(self) -> float:
        return float(sum(seg.duration for seg in self.segments))

    @property
    def n_dof(self) -> int:
        return self.limits.n_dof

    def sample(self, t) -> tuple:
        """q, qd, qdd at times ``t`` in [0, duration] [s], arrays (n_samples, n_dof)."""
        t = np.asarray(t, dtype=float).reshape(-1)
        q, qd, qdd = (np.zeros((t.size, self.n_dof)) for _ in range(3))
        starts = np.cumsum([0.0] + [seg.duration for seg in self.segments])
        index = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segments) - 1)
        for k, seg in enumerate(self.segments):
            mask = index == k
            if np.any(mask):
                q[mask], qd[mask], qdd[mask] = seg.evaluate(np.clip(t[mask] - starts[k], 0.0, seg.duration))
        return q, qd, qdd

    def time_grid(self, rate: float) -> np.ndarray:
        if not (isinstance(rate, (int, float)) and rate > 0):
            raise ParameterError(f"ExperimentTrajectory rate must be a positive sampling rate [Hz]; got {rate!r}.")
        return np.arange(int(math.floor(self.duration * rate + 1e-9)) + 1) / float(rate)

    def to_csv(self, path, rate: float = 100.0, *, overwrite: bool = False):
        """Write ``t, q, qd, qdd`` sampled at ``rate`` Hz (atomic; FileExistsError unless ``overwrite``)."""
        t = self.time_grid(rate)
        comment = f"{self.name} experiment, joints {list(self.joints)}, worst_limit_margin={self.worst_margin:.6g}"
        return write_trajectory_csv(path, t, *self.sample(t), comment=comment, overwrite=overwrite)


def _verified(name, segments, limits, joints) -> ExperimentTrajectory:
    draft = ExperimentTrajectory(name, tuple(segments), limits, tuple(joints))
    t = draft.time_grid(1000.0)
    margins = limit_margins(limits, *draft.sample(t))
    worst = worst_margin(margins)
    if worst < -1e-9:
        raise ParameterError(
            f"{name}_experiment leaves the limits ({describe_violation(margins)}); lower speed_fraction or "
            "range_fraction."
        )
    return ExperimentTrajectory(name, tuple(segments), limits, tuple(joints), worst)


def _fraction(owner, field, value):
    if not (isinstance(value, (int, float)) and 0 < value <= 1):
        raise ParameterError(f"{owner}.{field} must be in (0, 1]; got {value!r}. Use e.g. 0.5.")
    return float(value)


def _joint_index(owner, joint, n_dof) -> int:
    if isinstance(joint, bool) or not isinstance(joint, (int, np.integer)) or not 1 <= joint <= n_dof:
        raise ParameterError(f"{owner}.joint must be a 1-based joint number in 1..{n_dof}; got {joint!r}.")
    return int(joint) - 1


def _limits_and_pose(robot, limits, pose, owner):
    limits = JointLimits.from_robot(robot) if limits is None else limits
    check_same_dof(limits, robot.n_dof)
    pose = limits.center if pose is None else np.asarray(pose, dtype=float).reshape(-1)
    if pose.shape != (robot.n_dof,) or np.any(pose < limits.q_min) or np.any(pose > limits.q_max):
        raise ParameterError(
            f"{owner}.pose must be {robot.n_dof} joint positions inside [q_min, q_max]; got {pose.tolist()}. "
            "Leave it None for the centre of the ranges."
        )
    return limits, pose


def motor_experiment(robot, joint: int, *, pose=None, speed_fraction: float = 0.2, accel_fraction: float = 0.3,
                     range_fraction: float = 0.9, sweeps: int = 1, limits: JointLimits | None = None
                     ) -> ExperimentTrajectory:
    """Section 3.1: sweep one joint through its range at constant velocity, forward and back.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        1-based joint to sweep.
    pose : array, shape (n_dof,), optional
        Pose of the other joints (default: centre of the ranges); chosen so the calibration mass
        loads the swept joint.
    speed_fraction, accel_fraction : float
        Cruise velocity and acceleration as fractions of the limits (low, to keep inertia negligible).
    range_fraction : float
        Fraction of the joint range swept, about its centre.
    sweeps : int
        Forward-and-back repetitions.
    limits : JointLimits, optional
        Default: the robot's.

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "motor_experiment"
    i = _joint_index(owner, joint, robot.n_dof)
    limits, pose = _limits_and_pose(robot, limits, pose, owner)
    speed, accel, span = (_fraction(owner, f, v) for f, v in (("speed_fraction", speed_fraction),
                                                              ("accel_fraction", accel_fraction),
                                                              ("range_fraction", range_fraction)))
    if isinstance(sweeps, bool) or not isinstance(sweeps, int) or sweeps < 1:
        raise ParameterError(f"{owner}.sweeps must be an integer >= 1; got {sweeps!r}.")
    low, high = pose.copy(), pose.copy()
    low[i] = limits.center[i] - span * limits.half_range[i]
    high[i] = limits.center[i] + span * limits.half_range[i]
    qd_lim, qdd_lim = speed * limits.qd_max, accel * limits.qdd_max
    segments = [_move(pose, low, qd_lim, qdd_lim)]
    for _ in range(sweeps):
        segments += [_move(low, high, qd_lim, qdd_lim), _move(high, low, qd_lim, qdd_lim)]
    segments.append(_move(low, pose, qd_lim, qdd_lim))
    return _verified("motor", segments, limits, (joint,))


def gravity_experiment(robot, joints=None, *, n_waypoints: int = 12, speed_fraction: float = 0.1,
                       accel_fraction: float = 0.2, range_fraction: float = 0.9, pose=None,
                       limits: JointLimits | None = None, seed: int | None = 0,
                       rng: np.random.Generator | None = None) -> ExperimentTrajectory:
    """Section 3.2: jog the chosen joints slowly and together through random waypoints, then back along the same path.

    Parameters
    ----------
    robot : RobotDescription
    joints : sequence of int, optional
        1-based joints that move (default: all); the others hold ``pose``. The paper ran joints
        1-3 and 4-5 separately.
    n_waypoints : int
        Seeded random waypoints; each joint alternates between the lower and upper part of its range
        (40-100 % of the way to each end), so every move crosses the range and the joints' speeds
        stay within a factor of about 2.5 of the slowest joint's cruise speed.
    speed_fraction, accel_fraction, range_fraction : float
        Slow cruise speed, acceleration and swept range as fractions of the limits.
    seed : int, optional
    rng : numpy.random.Generator, optional

    Returns
    -------
    ExperimentTrajectory
        Duration is twice the forward path (forward then reversed).
    """
    owner = "gravity_experiment"
    limits, pose = _limits_and_pose(robot, limits, pose, owner)
    joints = tuple(range(1, robot.n_dof + 1)) if joints is None else tuple(joints)
    index = [_joint_index(owner, j, robot.n_dof) for j in joints]
    speed, accel, span = (_fraction(owner, f, v) for f, v in (("speed_fraction", speed_fraction),
                                                              ("accel_fraction", accel_fraction),
                                                              ("range_fraction", range_fraction)))
    if isinstance(n_waypoints, bool) or not isinstance(n_waypoints, int) or n_waypoints < 2:
        raise ParameterError(f"{owner}.n_waypoints must be an integer >= 2; got {n_waypoints!r}.")
    generator = rng if rng is not None else np.random.default_rng(seed)
    waypoints = [pose]
    first_side = np.where(generator.random(len(index)) < 0.5, 1.0, -1.0)  # each joint alternates from here
    for k in range(n_waypoints):
        point = pose.copy()
        fraction = generator.uniform(0.4, 1.0, len(index)) * first_side * (-1.0) ** k
        point[index] = limits.center[index] + span * fraction * limits.half_range[index]
        waypoints.append(point)
    waypoints.append(pose)
    qd_lim, qdd_lim = speed * limits.qd_max, accel * limits.qdd_max
    forward = [_move(a, b, qd_lim, qdd_lim) for a, b in zip(waypoints[:-1], waypoints[1:])]
    backward = [_move(b, a, qd_lim, qdd_lim) for a, b in reversed(list(zip(waypoints[:-1], waypoints[1:])))]
    return _verified("gravity", forward + backward, limits, joints)


def friction_experiment(robot, joint: int, *, amplitudes=None, peak_speeds=None, n_levels: int = 8,
                        amplitude_min: float | None = None, speed_fraction: float = 0.9, accel_fraction: float = 0.8,
                        range_fraction: float = 0.8, frequency_max: float = 4 * math.pi, cycles: int = 4, pose=None,
                        limits: JointLimits | None = None) -> ExperimentTrajectory:
    """Section 3.3: one joint runs sines from pre-sliding amplitudes up to near its speed limit.

    Parameters
    ----------
    robot : RobotDescription
    joint : int
        1-based joint.
    amplitudes : sequence of float, optional
        Amplitudes [rad]; default ``n_levels`` geometric steps from ``amplitude_min`` to the
        largest amplitude that fits ``range_fraction`` of the range.
    peak_speeds : sequence of float, optional
        Peak velocity of each level [rad/s]; default geometric up to ``speed_fraction * qd_max``.
        Each level's frequency is ``peak_speed / amplitude``, lowered if the acceleration limit
        demands it.
    amplitude_min : float, optional
        Smallest amplitude [rad]; default ``3 fc / sigma0`` of the joint's drive (a few times the
        LuGre pre-sliding deflection) or 1e-4 rad without drive data.
    frequency_max : float
        Highest sine frequency [rad/s] (default 2 Hz), which bounds the small-amplitude levels.
    cycles : int
        Full cycles per level (one ramps in, one ramps out).

    Returns
    -------
    ExperimentTrajectory
    """
    owner = "friction_experiment"
    i = _joint_index(owner, joint, robot.n_dof)
    limits, pose = _limits_and_pose(robot, limits, pose, owner)
    speed, accel, span = (_fraction(owner, f, v) for f, v in (("speed_fraction", speed_fraction),
                                                              ("accel_fraction", accel_fraction),
                                                              ("range_fraction", range_fraction)))
    if not (isinstance(frequency_max, (int, float)) and frequency_max > 0):
        raise ParameterError(f"{owner}.frequency_max must be a positive frequency [rad/s]; got {frequency_max!r}.")
    if isinstance(cycles, bool) or not isinstance(cycles, int) or cycles < 2:
        raise ParameterError(f"{owner}.cycles must be an integer >= 2 (one ramps in, one out); got {cycles!r}.")
    room = span * min(pose[i] - limits.q_min[i], limits.q_max[i] - pose[i])
    if amplitudes is None:
        if amplitude_min is None:
            drive = robot.drives[i] if robot.drives is not None else None
            amplitude_min = 3 * drive.fc / drive.sigma0 if drive is not None and drive.sigma0 > 0 else 1e-4
        if not (0 < amplitude_min < room):
            raise ParameterError(
                f"{owner}.amplitude_min must be in (0, {room:.4g}) rad for joint {joint}; got {amplitude_min!r}."
            )
        amplitudes = np.geomspace(amplitude_min, room, n_levels)
    amplitudes = np.asarray(amplitudes, dtype=float).reshape(-1)
    if amplitudes.size == 0 or np.any(amplitudes <= 0) or np.any(amplitudes > room + 1e-12):
        raise ParameterError(
            f"{owner}.amplitudes must be positive and at most {room:.4g} rad (range_fraction of the room about the "
            f"pose); got {amplitudes.tolist()}."
        )
    v_max, a_max = speed * limits.qd_max[i], accel * limits.qdd_max[i]
    if peak_speeds is None:
        peak_speeds = np.geomspace(v_max / 50, v_max, amplitudes.size)
    peak_speeds = np.asarray(peak_speeds, dtype=float).reshape(-1)
    if peak_speeds.shape != amplitudes.shape or np.any(peak_speeds <= 0):
        raise ParameterError(
            f"{owner}.peak_speeds must be {amplitudes.size} positive speeds [rad/s], one per amplitude; "
            f"got {peak_speeds.tolist()}."
        )
    segments = []
    for amp, v in zip(amplitudes, np.minimum(peak_speeds, v_max)):
        w = min(v / amp, math.sqrt(a_max / amp), frequency_max)
        segment = SineSegment(pose.copy(), i, float(amp), float(w), cycles)
        _, qd, qdd = segment.evaluate(np.linspace(0, segment.duration, 400 * cycles))
        usage = max(np.abs(qd[:, i]).max() / limits.qd_max[i], np.abs(qdd[:, i]).max() / limits.qdd_max[i])
        if usage > 0.99:  # the window's derivative adds a little; slow this level down
            segment = SineSegment(pose.copy(), i, float(amp), float(w * 0.99 / usage), cycles)
        segments.append(segment)
    return _verified("friction", segments, limits, (joint,))
