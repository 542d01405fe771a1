"""Reference trajectories of the paper's calibration experiments (section 3), as plain arrays for the virtual robot.

Each function returns ``(t, q)`` sampled densely and smoothly (C2 up to the resampling), which
``simulate_recording`` interpolates with a cubic spline to get velocities and accelerations:

- ``motor_reference``: one joint swept at constant speed forward and back (run with and without a payload);
- ``gravity_reference``: all joints jogged slowly and simultaneously, then back along the same path;
- ``friction_reference``: one joint through ``A (1 - cos 2 pi f t)`` segments designed by a
  :class:`FrictionDesign` (pre-sliding hysteresis, Stribeck region, sliding), each from rest to rest;
- ``oscillation_reference``: one joint through sine-cubed oscillations of growing amplitude (a short,
  coarse friction experiment for quick runs);
- ``sine_reference``: a sum of three sines per joint (eq. 22), a stand-in for an optimised excitation.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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


def _positive_tuple(owner, name, values):
    values = tuple(float(v) for v in np.atleast_1d(values))
    if not values or not all(np.isfinite(v) and v > 0 for v in values):
        raise ParameterError(f"{owner}.{name} must be a non-empty tuple of positive numbers; got {values!r}.")
    return values


@dataclass(frozen=True)
class FrictionDesign:
    """Content of one joint's friction experiment (paper 3.3), designed without knowing the friction.

    Three groups of ``q = A (1 - cos 2 pi f t)`` segments of the moving joint, each starting and
    ending at rest and followed by ``pause`` seconds at rest (the bristles relax to a new rest state):

    1. pre-sliding (``sigma0``, ``sigma1``): amplitudes ``presliding_amplitudes`` [rad] at
       ``presliding_hz``. Hysteresis loops need amplitudes of 0.3 to 3 break-away displacements
       ``fc / sigma0`` (about 10-100 urad on the Denso's base joints, 0.2-2 mrad on its wrist); a
       logarithmic sweep from 5 urad to 5 mrad covers every joint without knowing ``sigma0``.
    2. break-away (``sigma1``): amplitudes ``breakaway_amplitudes`` [rad] well beyond the break-away
       displacement at ``breakaway_hz``, ``breakaway_periods`` times. Every reversal stops the joint
       at a high deceleration and it sticks: the joint then rings on the bristle stiffness, damped by
       sigma1 (about 80 Hz on the Denso's base joints). Per second these segments carry 10-40 times
       more sigma1 information than the Stribeck and sliding segments; one amplitude (2 mrad) took
       the noise out of sigma1 of the Denso's joint 1 (26 % off on one noise draw without it, 12-14 %
       with it). Larger ones (5 and 10 mrad) stop the joint so hard that, at 1 kHz, the model of the
       measured friction errs at the stick and pulled sigma1 of joint 2 30 % low.
    3. Stribeck region (``fs``, ``vs``): peak speeds ``stribeck_speeds`` [rad/s] at ``stribeck_hz``,
       log-spaced from below the smallest to above the largest plausible ``vs``.
    4. sliding (``fc``, ``fv``, ``dv``): peak speeds ``sliding_fractions`` of the joint speed limit at
       ``sliding_hz`` (raised where the joint range or acceleration limit requires).

    The pre-sliding velocities are about 1e-3 rad/s, so the position must be recorded far below
    1 urad (a motor-side encoder behind the gearbox, see ``SimulationOptions.encoder_resolution``)
    and the data used at the full rate (see ``PipelineOptions.friction_cutoff_hz``).

    Parameters
    ----------
    presliding_amplitudes : tuple of float
        [rad] (or [m]).
    presliding_hz : float
    presliding_periods : int
    breakaway_amplitudes : tuple of float
        [rad] (or [m]); may be empty.
    breakaway_hz : float
    breakaway_periods : int
    stribeck_speeds : tuple of float
        Peak speeds [rad/s].
    stribeck_hz : float
    stribeck_periods : int
    sliding_fractions : tuple of float
        Peak speeds as fractions of ``qd_max``, in (0, 1].
    sliding_hz : float
    sliding_periods : int
    pause : float
        Rest after each segment [s], >= 0.
    frequency_scale : float
        Multiplies every frequency at the same amplitudes (pre-sliding) and peak speeds (others):
        ``validation()`` uses 1.3 for a second, different experiment.

    Examples
    --------
    >>> round(FrictionDesign().duration, 1)
    27.6
    """

    presliding_amplitudes: tuple = tuple(np.round(np.logspace(np.log10(5e-6), np.log10(5e-3), 8), 9))
    presliding_hz: float = 10.0
    presliding_periods: int = 4
    breakaway_amplitudes: tuple = (2e-3,)
    breakaway_hz: float = 10.0
    breakaway_periods: int = 6
    stribeck_speeds: tuple = tuple(np.round(np.logspace(np.log10(3e-3), np.log10(0.5), 6), 5))
    stribeck_hz: float = 1.0
    stribeck_periods: int = 2
    sliding_fractions: tuple = (0.1, 0.3, 0.6, 0.9)
    sliding_hz: float = 0.5
    sliding_periods: int = 1
    pause: float = 0.2
    frequency_scale: float = 1.0

    def __post_init__(self):
        for name in ("presliding_amplitudes", "stribeck_speeds", "sliding_fractions"):
            object.__setattr__(self, name, _positive_tuple("FrictionDesign", name, getattr(self, name)))
        breakaway = tuple(float(v) for v in np.atleast_1d(self.breakaway_amplitudes))
        if breakaway:
            breakaway = _positive_tuple("FrictionDesign", "breakaway_amplitudes", breakaway)
        object.__setattr__(self, "breakaway_amplitudes", breakaway)
        if max(self.sliding_fractions) > 1.0:
            raise ParameterError(f"FrictionDesign.sliding_fractions must be in (0, 1]; got {self.sliding_fractions!r}.")
        for name in ("presliding_hz", "breakaway_hz", "stribeck_hz", "sliding_hz", "frequency_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"FrictionDesign.{name} must be positive; got {value!r}.")
        for name in ("presliding_periods", "breakaway_periods", "stribeck_periods", "sliding_periods"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value >= 1):
                raise ParameterError(f"FrictionDesign.{name} must be an integer >= 1; got {value!r}.")
        if not (np.isfinite(self.pause) and self.pause >= 0):
            raise ParameterError(f"FrictionDesign.pause must be >= 0 [s]; got {self.pause!r}.")

    @classmethod
    def quick(cls) -> "FrictionDesign":
        """A shorter experiment (14 s): fewer segments per group, for demos and tests."""
        return cls(presliding_amplitudes=(1e-5, 6e-5, 3e-4, 1.5e-3), presliding_periods=3,
                   breakaway_amplitudes=(2e-3,), breakaway_periods=4,
                   stribeck_speeds=(0.005, 0.03, 0.2), sliding_fractions=(0.2, 0.8))

    def validation(self) -> "FrictionDesign":
        """The same design at 1.3 times the frequencies: a second experiment for validation."""
        return replace(self, frequency_scale=1.3 * self.frequency_scale)

    @property
    def duration(self) -> float:
        """Length [s] before any frequency raise for range or acceleration limits."""
        s = self.frequency_scale
        return (len(self.presliding_amplitudes) * (self.presliding_periods / (s * self.presliding_hz) + self.pause)
                + len(self.breakaway_amplitudes) * (self.breakaway_periods / (s * self.breakaway_hz) + self.pause)
                + len(self.stribeck_speeds) * (self.stribeck_periods / (s * self.stribeck_hz) + self.pause)
                + len(self.sliding_fractions) * (self.sliding_periods / (s * self.sliding_hz) + self.pause))

    def segments(self, qd_max: float, qdd_max: float, room: float) -> list:
        """``(amplitude, frequency, periods)`` of every segment for a joint with these limits.

        A segment whose travel ``2 A`` exceeds ``room`` or whose peak acceleration ``A (2 pi f)^2``
        exceeds ``0.9 qdd_max`` runs at a higher frequency (same peak speed) or, when both bind, at a
        lower peak speed.
        """
        s = self.frequency_scale
        wanted = [(a, s * self.presliding_hz, self.presliding_periods, None) for a in self.presliding_amplitudes]
        wanted += [(a, s * self.breakaway_hz, self.breakaway_periods, None) for a in self.breakaway_amplitudes]
        wanted += [(None, s * self.stribeck_hz, self.stribeck_periods, v) for v in self.stribeck_speeds]
        wanted += [(None, s * self.sliding_hz, self.sliding_periods, f * qd_max) for f in self.sliding_fractions]
        out = []
        for amplitude, frequency, periods, speed in wanted:
            omega = 2.0 * np.pi * frequency
            if speed is None:
                speed = amplitude * omega
            speed = min(speed, 0.95 * qd_max)
            omega = max(omega, 2.0 * speed / room)  # travel 2 A = 2 v / w within room
            accel = 0.9 * qdd_max
            if speed * omega > accel:  # peak acceleration v w
                omega = accel / speed
                if 2.0 * speed / omega > room:
                    speed = np.sqrt(accel * room / 2.0)
                    omega = accel / speed
            out.append((speed / omega, omega / (2.0 * np.pi), periods))
        return out


def friction_reference(robot: RobotDescription, joint: int, design: FrictionDesign | None = None,
                       pose=None) -> tuple[np.ndarray, np.ndarray]:
    """One joint through the segments of a :class:`FrictionDesign` (paper 3.3), the others held.

    Each segment ``q = pose + sign A (1 - cos 2 pi f t)`` starts and ends at rest and moves towards the
    side of the pose with more room; segments are separated by ``design.pause`` seconds at rest.

    Returns
    -------
    (t, q) : arrays, shapes (n_samples,) and (n_samples, n_dof)
    """
    _check_joint(robot, joint, "friction_reference")
    design = FrictionDesign() if design is None else design
    if not isinstance(design, FrictionDesign):
        raise ParameterError(f"friction_reference design must be a FrictionDesign; got {type(design).__name__}.")
    pose = home_pose(robot) if pose is None else np.asarray(pose, dtype=float)
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
    t = np.concatenate([p[0] for p in pieces] + [np.array([start])])
    x = np.concatenate([p[1] for p in pieces] + [np.array([0.0])])
    q = np.tile(pose, (t.size, 1))
    q[:, joint] += x
    return t, q


def oscillation_reference(robot: RobotDescription, joint: int, amplitudes=(2e-4, 1e-3, 5e-3, 0.03, 0.15, 0.6),
                          speed_fraction: float = 0.6, cycles: int = 3, min_period: float = 1.0,
                          pose=None) -> tuple[np.ndarray, np.ndarray]:
    """One joint through oscillations ``A sin^3(w t)`` of growing amplitude, others held (a quick friction run).

    ``sin^3`` starts and ends each block at rest with zero acceleration, so blocks join smoothly. The
    period of a block is the longer of ``min_period`` and the one reaching ``speed_fraction`` of the
    joint speed limit. Coarser than :func:`friction_reference`: it does not resolve ``sigma0``,
    ``sigma1`` and ``vs`` well.
    """
    _check_joint(robot, joint, "oscillation_reference")
    pose = home_pose(robot) if pose is None else np.asarray(pose, dtype=float)
    limit = min(robot.q_max[joint] - pose[joint], pose[joint] - robot.q_min[joint])
    if max(amplitudes) >= limit:
        raise ParameterError(
            f"oscillation_reference amplitudes must stay inside the range of joint {joint} ({limit:.3g} from the pose); "
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


def tuned_friction_signal(parameters, qd_max, rate=1000.0, frequency_scale=1.0, pause=0.2):
    """A friction experiment tuned with the LuGre parameters known (for testing and benchmarking the fit).

    The blind design the calibration uses is ``FrictionDesign``; this one places its segments at
    multiples of the true ``fc / sigma0``, ``vs`` and ``qd_max``: a series of ``q = A (1 - cos(2 pi f t))``.

    Segments start and end at rest (``qd`` continuous), separated by ``pause`` seconds of rest.

    * pre-sliding: amplitudes 0.3, 0.7, 1.5, 3 times the break-away displacement ``fc / sigma0``
      at 10 Hz, 4 periods each (hysteresis loops; ``sigma0`` and ``sigma1``);
    * Stribeck region: peak speeds 0.5, 1, 2, 4 times ``vs`` at 1 Hz, 2 periods (``fs``, ``vs``);
    * sliding: peak speeds 0.1, 0.3, 0.6, 0.9 of ``qd_max`` at 0.5 Hz, 1 period (``fc, fv, dv``).

    Returns ``t, q, qd`` (n_samples,) [s, rad, rad/s].
    """
    xb = parameters.fc / parameters.sigma0
    segments = [(k * xb, 10.0 * frequency_scale, 4) for k in (0.3, 0.7, 1.5, 3.0)]
    segments += [(v * parameters.vs / (2 * np.pi * frequency_scale), frequency_scale, 2) for v in (0.5, 1, 2, 4)]
    f_slide = 0.5 * frequency_scale
    segments += [(v * qd_max / (2 * np.pi * f_slide), f_slide, 1) for v in (0.1, 0.3, 0.6, 0.9)]
    starts, total = [], 0.0
    for amplitude, frequency, periods in segments:
        starts.append(total)
        total += periods / frequency + pause
    t = np.arange(0.0, total, 1.0 / rate)
    q = np.zeros_like(t)
    qd = np.zeros_like(t)
    for start, (amplitude, frequency, periods) in zip(starts, segments):
        omega = 2 * np.pi * frequency
        m = (t >= start) & (t <= start + periods / frequency)
        q[m] = amplitude * (1 - np.cos(omega * (t[m] - start)))
        qd[m] = amplitude * omega * np.sin(omega * (t[m] - start))
    return t, q, qd
