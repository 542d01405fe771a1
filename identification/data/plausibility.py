"""Recording plausibility: refuse a recording whose positions, speeds or time stamps no robot of this kind can make.

A recording in the wrong units identifies a "consistent" model that is nonsense: positions in degrees
(a joint at -158 "rad" against limits of +-2.9) fit gravity through ``sin q`` of wrapped angles, and a
time column in milliseconds makes every speed a thousand times too small. Before any fit,
:func:`check_plausible_recording` compares a recording with the robot's limits and raises a
:class:`~psdm_casadi.errors.RecordingError` naming the file, the column, what it reached and the likely
cause (degrees? milliseconds? joint order or the robot file's limits?). Run by the library functions that
read recordings, so the Python API refuses what the command line refuses: the identification from
recordings (``trajectory_data.prepare_recordings``), the calibration data folder
(``excitation.check_calibration_data``), the diagnosis (``diagnose.diagnose``) and the recordings a model is
validated on (``trajectory_checks.check_validation_recording``: ``psdm validate``, ``identify --validate``).

The bounds are loose on purpose (:class:`PlausibilityThresholds`): they separate a unit or mapping
error, which misses by a factor of tens to a thousand, from a real recording that grazes a limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.data.excitation_check import joint_label, joint_motion
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError

__all__ = ["PlausibilityThresholds", "check_plausible_recording", "looks_like_milliseconds"]

DEGREE = np.pi / 180.0
MILLISECOND_RATE = 1000.0  # speeds of a time column in ms are this many times too small


@dataclass(frozen=True)
class PlausibilityThresholds:
    """Bounds of :func:`check_plausible_recording`; every value must be finite and > 0.

    Parameters
    ----------
    limit_margin_fraction : float
        How far [fraction of ``q_max - q_min``] a recorded position may lie beyond a joint limit
        (default 0.1). Real recordings stay within the limits or overshoot by encoder noise and
        controller overshoot; positions in degrees or of another joint miss by many ranges.
    speed_factor : float
        Largest speed (the 95th percentile of the windowed speed of ``excitation_check.joint_motion``)
        as a multiple of ``qd_max`` (default 5). A drive cannot exceed its speed limit several times over;
        a URDF without velocity limits gets 2 rad/s, which a fast joint may pass, hence the wide factor.
        Positions in degrees are 57 times too fast.
    max_millisecond_step : float
        Median time step [s] above which a recording whose every joint is a thousand times too slow is
        taken for a time column in milliseconds (default 0.05: no robot is identified from 20 Hz data).
    """

    limit_margin_fraction: float = 0.1
    speed_factor: float = 5.0
    max_millisecond_step: float = 0.05

    def __post_init__(self):
        for name in ("limit_margin_fraction", "speed_factor", "max_millisecond_step"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.number)) and np.isfinite(value) and value > 0):
                raise ParameterError(f"PlausibilityThresholds.{name} must be finite and > 0; got {value!r}.")


def _limits(robot, n_dof: int):
    """(q_min, q_max, qd_max) of ``robot`` as float arrays (n_dof,), or None when it does not match ``n_dof``."""
    values = [np.asarray(getattr(robot, name, None), dtype=float).reshape(-1) for name in ("q_min", "q_max", "qd_max")]
    return values if all(v.shape == (n_dof,) for v in values) else None


def looks_like_milliseconds(recording: Recording, speed, qd_max, thresholds=None) -> bool:
    """True when the time column looks like milliseconds: a median step of a second or so, every joint at
    least 200 times slower than ``qd_max`` and a thousand times faster, some joint moves at a robot's speeds.

    ``speed`` [rad/s] is each joint's speed as measured with the recorded time stamps (n_dof,).
    """
    thresholds = PlausibilityThresholds() if thresholds is None else thresholds
    if recording.n_samples < 2 or float(np.median(np.diff(recording.t))) < thresholds.max_millisecond_step:
        return False
    speed, qd_max = np.asarray(speed, dtype=float), np.asarray(qd_max, dtype=float)
    scaled = MILLISECOND_RATE * speed
    return bool(
        np.all(speed < 0.005 * qd_max)
        and np.all(scaled <= thresholds.speed_factor * qd_max)
        and np.any(scaled >= 0.05 * qd_max)
    )


def _position_problem(j, q, low, high, fraction, robot) -> str | None:
    margin = fraction * (high - low)
    lowest, highest = float(q.min()), float(q.max())
    if lowest >= low - margin and highest <= high + margin:
        return None
    span = high - low  # degrees miss by ranges, and in radians (x pi/180) they lie within the limits
    far = lowest < low - span or highest > high + span
    in_degrees = far and low - margin <= lowest * DEGREE and highest * DEGREE <= high + margin
    cause = (
        f"in radians (x pi/180) they would lie within: positions in degrees? Convert q{j + 1} to radians or state "
        "the unit (--columns q=PREFIX:deg)"
        if in_degrees
        else f"check the unit of q{j + 1} (rad or m), the joint order and zero offsets, or the robot file's limits"
    )
    return (
        f"column q{j + 1} ({joint_label(j, robot)}) reaches {lowest:.4g} to {highest:.4g}, beyond the joint limits "
        f"[{low:.4g}, {high:.4g}] by more than {margin:.3g} ({100 * fraction:g} % of the range allowed); {cause}"
    )


def _speed_problem(j, speed, qd_max, factor, robot) -> str | None:
    if not speed > factor * qd_max:
        return None
    cause = (
        "positions in degrees? Convert q{k} to radians (x pi/180)"
        if speed * DEGREE <= factor * qd_max
        else "check the time column's unit (seconds), the unit of q{k} and the joint order"
    ).format(k=j + 1)
    return (
        f"column q{j + 1} ({joint_label(j, robot)}) moves at {speed:.4g} rad/s, {speed / qd_max:.3g} times its "
        f"speed limit qd_max = {qd_max:.4g} (at most {factor:g} times allowed); {cause}"
    )


def check_plausible_recording(recording: Recording, robot, thresholds: PlausibilityThresholds | None = None) -> None:
    """Raise unless every joint of ``recording`` stays near ``robot``'s position limits and below its speed limit.

    Parameters
    ----------
    recording : Recording
        Raw or prepared (only ``t`` and ``q`` are read); its ``name`` is the file named in the message.
    robot : RobotDescription
        Its ``q_min``, ``q_max``, ``qd_max`` and joint names. A recording of another joint count is left to
        ``Recording.check_robot``.
    thresholds : PlausibilityThresholds, optional

    Raises
    ------
    RecordingError
        Naming the file, every implausible column with what it reached against the limit, and the likely cause:
        positions in degrees, a time column in milliseconds, the joint order or the robot file's limits.

    Examples
    --------
    >>> from psdm_casadi.robot import load_robot
    >>> robot = load_robot("denso_vs6556g")
    >>> t = np.arange(0.0, 2.0, 0.01)
    >>> q = 0.3 * np.sin(np.outer(t, np.ones(6)))
    >>> check_plausible_recording(Recording(t=t, q=q, tau=0 * q, name="run.csv"), robot)
    >>> check_plausible_recording(Recording(t=t, q=q / DEGREE, tau=0 * q, name="deg.csv"), robot)
    Traceback (most recent call last):
    ...
    psdm_casadi.errors.RecordingError: Recording deg.csv: ... positions in degrees? ...
    """
    thresholds = PlausibilityThresholds() if thresholds is None else thresholds
    limits = _limits(robot, recording.n_dof)
    if limits is None or recording.n_samples < 2:
        return
    q_min, q_max, qd_max = limits
    speed = joint_motion(recording).speed
    source = recording.name or "the recording"
    if looks_like_milliseconds(recording, speed, qd_max, thresholds):
        step = float(np.median(np.diff(recording.t)))
        raise RecordingError(
            f"Recording {source}: the time column t looks like milliseconds: its median step is {step:.4g} and every "
            f"joint then moves at most {float(np.max(speed / qd_max)):.2g} of its speed limit (a thousand times "
            "faster would be a robot's speeds). Write t in seconds (divide it by 1000) or state the unit: "
            "--columns t=NAME:ms."
        )
    problems = []
    for j in range(recording.n_dof):  # one problem per joint: a position beyond the limits says more than its speed
        problem = _position_problem(j, recording.q[:, j], q_min[j], q_max[j], thresholds.limit_margin_fraction, robot)
        if problem is None and np.isfinite(qd_max[j]) and qd_max[j] > 0:
            problem = _speed_problem(j, speed[j], qd_max[j], thresholds.speed_factor, robot)
        problems += [] if problem is None else [problem]
    in_degrees = [p for p in problems if "in radians (x pi/180) they would lie within" in p]
    if len(problems) > 1 and len(in_degrees) == len(problems):  # one cause: say it once
        joints = [p.split()[1] for p in problems]  # "column q3 (...) reaches ..."
        j, others = int(joints[0][1:]) - 1, ", ".join(joints[1:])
        raise RecordingError(
            f"Recording {source}: column q{j + 1} ({joint_label(j, robot)}) reaches {recording.q[:, j].min():.4g} to "
            f"{recording.q[:, j].max():.4g}, beyond the joint limits [{q_min[j]:.4g}, {q_max[j]:.4g}], and {others} "
            "beyond theirs too, every one within them once x pi/180: positions in degrees? Convert "
            f"q{j + 1} to radians, and {others} alike, or state the log's unit: --columns q=PREFIX:deg (e.g. "
            "--columns t=Time,q=Position:deg,tau=Torque)."
        )
    if problems:
        raise RecordingError(
            f"Recording {source}: no {getattr(robot, 'name', 'robot')} can have recorded this; "
            + "; ".join(problems)
            + ". Fix the recording's units (q in rad or m, t in s; a log's own units are stated in --columns, e.g. "
            "q=Position:deg,tau=Torque:mNm,t=Time:ms) or the robot file."
        )
