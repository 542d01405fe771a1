"""Reference trajectories of the paper's calibration experiments (section 3), as plain arrays for the virtual robot.

Each function returns ``(t, q)`` sampled densely and smoothly (C2 up to the resampling), which
``simulate_recording`` interpolates with a cubic spline to get velocities and accelerations:

- ``motor_reference``: one joint swept at constant speed forward and back (run with and without a payload);
- ``gravity_reference``: all joints jogged slowly and simultaneously, then back along the same path;
- ``friction_reference``: one joint through sine-cubed oscillations of growing amplitude (pre-sliding to fast);
- ``sine_reference``: a sum of three sines per joint (eq. 22), a stand-in for an optimised excitation.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from psdm_casadi.errors import ParameterError
from psdm_casadi.robot import RobotDescription

GRID_HZ = 500.0  # density of the returned samples


def home_pose(robot: RobotDescription) -> np.ndarray:
    """Zero clipped into the joint ranges: the pose of the joints an experiment does not move."""
    return np.clip(np.zeros(robot.n_dof), robot.q_min, robot.q_max)


def _check_joint(robot, joint, owner):
    if not (isinstance(joint, (int, np.integer)) and 0 <= joint < robot.n_dof):
        raise ParameterError(f"{owner} joint must be a joint index 0..{robot.n_dof - 1}; got {joint!r}.")


def _out_and_back(duration: float, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and a path parameter s(t) that runs at unit speed to s_max and back, with cosine speed ramps."""
    t = np.arange(0.0, duration + 0.5 / GRID_HZ, 1.0 / GRID_HZ)
    half = duration / 2.0
    v = np.ones_like(t)
    up = t < ramp
    v[up] = 0.5 * (1.0 - np.cos(np.pi * t[up] / ramp))
    turn = np.abs(t - half) < ramp
    v[turn] = np.cos(np.pi * (t[turn] - (half - ramp)) / (2.0 * ramp))
    v[t > half + ramp] = -1.0
    down = t > duration - ramp
    v[down] = -0.5 * (1.0 - np.cos(np.pi * (duration - t[down]) / ramp))
    return t, cumulative_trapezoid(v, t, initial=0.0)


def motor_reference(robot: RobotDescription, joint: int, speed: float = 0.3, range_fraction: float = 0.6,
                    ramp: float = 0.5, pose=None) -> tuple[np.ndarray, np.ndarray]:
    """Sweep one joint at constant ``speed`` [rad/s] over ``range_fraction`` of its range and back (paper 3.1).

    Returns
    -------
    (t, q) : arrays, shapes (n_samples,) and (n_samples, n_dof)
    """
    _check_joint(robot, joint, "motor_reference")
    pose = home_pose(robot) if pose is None else np.asarray(pose, dtype=float)
    lo, hi = robot.q_min[joint], robot.q_max[joint]
    centre, half_range = 0.5 * (lo + hi), 0.5 * range_fraction * (hi - lo)
    duration = 2.0 * (2.0 * half_range / speed + ramp)
    t, s = _out_and_back(duration, ramp)
    q = np.tile(pose, (t.size, 1))
    q[:, joint] = centre - half_range + speed * s
    return t, q


def gravity_reference(robot: RobotDescription, duration: float = 60.0, speed: float = 0.25,
                      range_fraction: float = 0.8, joints=None, ramp: float = 0.5,
                      rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Jog the joints together at about ``speed`` [rad/s] through their ranges, then back (paper 3.2).

    Each joint follows a rounded triangle wave with its own period and phase, so the poses cover the
    workspace; the second half retraces the first backwards, so forward and reverse currents can be averaged.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    joints = range(robot.n_dof) if joints is None else joints
    pose = home_pose(robot)
    t, s = _out_and_back(duration, ramp)
    q = np.tile(pose, (t.size, 1))
    for j in joints:
        _check_joint(robot, j, "gravity_reference")
        lo, hi = robot.q_min[j], robot.q_max[j]
        centre, amplitude = 0.5 * (lo + hi), 0.5 * range_fraction * (hi - lo)
        omega = speed * (0.8 + 0.4 * rng.random()) * np.pi / (2.0 * amplitude)
        phase = np.arcsin(np.clip((pose[j] - centre) / amplitude, -0.99, 0.99))
        q[:, j] = centre + amplitude * (2.0 / np.pi) * np.arcsin(0.98 * np.sin(omega * s + phase))
    return t, q


def friction_reference(robot: RobotDescription, joint: int, amplitudes=(2e-4, 1e-3, 5e-3, 0.03, 0.15, 0.6),
                       speed_fraction: float = 0.6, cycles: int = 3, min_period: float = 1.0,
                       pose=None) -> tuple[np.ndarray, np.ndarray]:
    """One joint through oscillations ``A sin^3(w t)`` of growing amplitude (paper 3.3), others held.

    ``sin^3`` starts and ends each block at rest with zero acceleration, so blocks join smoothly. The
    period of a block is the longer of ``min_period`` and the one reaching ``speed_fraction`` of the
    joint speed limit.
    """
    _check_joint(robot, joint, "friction_reference")
    pose = home_pose(robot) if pose is None else np.asarray(pose, dtype=float)
    limit = min(robot.q_max[joint] - pose[joint], pose[joint] - robot.q_min[joint])
    if max(amplitudes) >= limit:
        raise ParameterError(
            f"friction_reference amplitudes must stay inside the range of joint {joint} ({limit:.3g} from the pose); "
            f"got {max(amplitudes)}. Lower the largest amplitude."
        )
    pieces, start = [], 0.0
    for amplitude in amplitudes:
        # peak speed of A sin^3(w t) is about 1.15 A w
        omega = min(2.0 * np.pi / min_period, speed_fraction * robot.qd_max[joint] / (1.155 * amplitude))
        period = 2.0 * np.pi / omega
        tb = np.arange(0.0, cycles * period, 1.0 / GRID_HZ)
        pieces.append((start + tb, amplitude * np.sin(omega * tb) ** 3))
        start += cycles * period
    t = np.concatenate([p[0] for p in pieces] + [np.array([start])])
    x = np.concatenate([p[1] for p in pieces] + [np.array([0.0])])
    q = np.tile(pose, (t.size, 1))
    q[:, joint] += x
    return t, q


def sine_reference(robot: RobotDescription, duration: float = 30.0, rng: np.random.Generator | None = None,
                   n_sines: int = 3, fraction: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A sum of ``n_sines`` sines per joint (eq. 22) with random frequencies and phases, scaled into
    ``fraction`` of the position, speed and acceleration limits; starts and ends with a cosine fade."""
    rng = np.random.default_rng(0) if rng is None else rng
    t = np.arange(0.0, duration + 0.5 / GRID_HZ, 1.0 / GRID_HZ)
    fade = np.minimum(1.0, np.minimum(t, duration - t) / 1.0)
    fade = 0.5 * (1.0 - np.cos(np.pi * fade))
    centre = home_pose(robot)
    q = np.tile(centre, (t.size, 1))
    for j in range(robot.n_dof):
        omega = 2.0 * np.pi * rng.uniform(0.05, 0.5, n_sines)
        phase = rng.uniform(0.0, 2.0 * np.pi, n_sines)
        weight = rng.uniform(0.5, 1.0, n_sines)
        room = min(robot.q_max[j] - centre[j], centre[j] - robot.q_min[j])
        scale = fraction * min(room / weight.sum(), robot.qd_max[j] / (weight * omega).sum(),
                               robot.qdd_max[j] / (weight * omega**2).sum())
        x = (scale * weight * np.sin(np.outer(t, omega) + phase)).sum(axis=1)
        q[:, j] = centre[j] + fade * (x - x[0])
    return t, q
