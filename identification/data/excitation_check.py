"""Excitation checks: refuse recordings that cannot identify what is fitted to them, before any fit.

Every estimator (the calibration steps, the refinement, the diagnosis) solves for parameters that only
motion makes visible: gravity needs poses, friction sliding, inertia acceleration. On a robot that stood
still (or dithered, or drifted at noise level) least squares fits noise: a 37 kg payload, a mass matrix
with eigenvalue -7e12, a viscous friction of 4.5e41. These checks raise instead an
:class:`~psdm_casadi.errors.InsufficientExcitationError` naming the recording, the joints (or the
parameters) that were not excited and what to record instead. They only refuse: a recording that
passes is fitted exactly as without them.

Three checks, each on the data a step actually fits (the third in :mod:`identification.data.regressor_check`):

- :func:`check_joint_motion`: the joints a step identifies must move over a range and at a speed
  (thresholds relative to the joint's limits and to the encoder resolution, :class:`ExcitationThresholds`);
- :func:`check_sliding`: the moving joint of a friction experiment must slide in both directions at
  speeds above the Stribeck range, for long enough to be motion rather than noise (and
  :func:`check_reversals`, its counterpart on exciting trajectories: a share of the samples each way);
- :func:`~identification.data.regressor_check.check_regressor`: the weighted, column-scaled regressor of
  the parameters being identified must have full rank and a condition number below a bound; otherwise
  the error names the columns that span its weak directions and the joints that would excite them.

The thresholds separate an experiment from no experiment; they do not grade a design (the
condition number of an optimised excitation is the job of ``trajopt``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.data.recording import Recording
from psdm_casadi.errors import InsufficientExcitationError, ParameterError

__all__ = [
    "ExcitationThresholds",
    "JointMotion",
    "joint_motion",
    "estimate_resolution",
    "check_joint_motion",
    "check_sliding",
    "check_reversals",
    "one_way_joints",
    "one_way_velocities",
    "joint_label",
    "joint_labels",
    "format_fix",
]

SPEED_PERCENTILE = 95.0  # the "speed" of a joint: this percentile of its windowed speed (robust to spikes)


@dataclass(frozen=True)
class ExcitationThresholds:
    """Thresholds of the excitation checks (module docstring); every value must be finite and >= 0.

    The defaults refuse what is not an experiment and pass every designed one by a wide margin: the
    calibration plan sweeps 15 to 40 % of a joint's range at 0.25 rad/s or more (motor), jogs at
    0.15-0.3 rad/s over 80 % of the ranges (gravity), slides at 10 to 90 % of ``qd_max`` (friction),
    and an excitation spans tens of percent of the ranges and speed limits; a joint that is held,
    dithers or drifts moves by less than a thousandth of its range.

    Parameters
    ----------
    min_range_fraction : float
        Least range of motion (max - min of q) as a fraction of ``q_max - q_min`` (default 0.01, i.e.
        0.04 to 0.13 rad on the Denso). Below it, ``sin q`` and ``cos q`` (gravity, kinematics) barely
        change, so their columns are nearly constant and collinear with each other and with any offset.
    min_range_steps : float
        Least range in encoder steps (``resolution``; default 100): the position's quantisation noise
        (``step / sqrt(12)``) then stays below 0.3 % of the motion, and the velocity and acceleration
        differentiated from it are not quantisation noise. Matters for coarse encoders and robots
        whose limits are unknown.
    min_speed_fraction : float
        Least speed (the 95th percentile of the speed over ``speed_window``) as a fraction of
        ``qd_max`` (default 0.005, i.e. 0.016 to 0.04 rad/s on the Denso): slower, the velocity terms
        (friction, Coriolis) are below noise and the "motion" is drift. A speed of one encoder step
        per ``speed_window`` is always required.
    speed_window : float
        Time [s] over which the speed is measured from positions (default 0.02 s), so position noise
        and single-sample glitches do not count as motion.
    min_sliding_fraction : float
        Friction experiments: least sliding speed as a fraction of ``qd_max`` (default 0.05, i.e. 0.16
        to 0.4 rad/s on the Denso, ten times or more its Stribeck velocities of 0.01 to 0.03 rad/s):
        the high-speed fit of eq. 20 uses samples faster than a quarter of the peak speed, which must
        lie beyond the Stribeck range for fc, fv and dv to separate from fs and vs.
    min_sliding_time : float
        Friction experiments: the joint must slide above that speed for at least this long [s] without
        interruption, in each direction (default 0.05 s): both signs are needed to separate Coulomb
        friction from a torque offset, and a stroke of 0.05 s at 0.16 rad/s or more covers 8 mrad, tens of
        break-away displacements ``fs / sigma0``, so the bristles reach steady sliding. It is 2.5 speed
        windows: a glitch or noise does not slide that long (the quick designs slide 0.2 s and more).
    max_condition : float
        Largest condition number of the weighted regressor after scaling its columns to unit norm
        (default 1e8). The least squares compute the covariance from ``A^T A``, whose condition is the
        square, 1e16 at the bound: the reciprocal of double precision (2.2e-16), where the standard
        errors lose their last digit. Statistically, the weakest direction is then moved 1e8 times more
        by torque noise than the best: noise of 0.1 % of the torques becomes a 1e5-fold error. The virtual
        robot's calibration and diagnosis recordings give 2 to 40.
    resolution : float or None
        Encoder step [rad or m]; None (default) estimates it per joint from the data as the smallest
        gap between distinct recorded positions (the step of quantised data, ~0 for unquantised data).

    Raises
    ------
    ParameterError
        For a negative or non-finite value, or ``max_condition`` below 1.
    """

    min_range_fraction: float = 0.01
    min_range_steps: float = 100.0
    min_speed_fraction: float = 0.005
    speed_window: float = 0.02
    min_sliding_fraction: float = 0.05
    min_sliding_time: float = 0.05
    max_condition: float = 1e8
    resolution: float | None = None

    def __post_init__(self):
        for name in (
            "min_range_fraction",
            "min_range_steps",
            "min_speed_fraction",
            "speed_window",
            "min_sliding_fraction",
            "min_sliding_time",
            "max_condition",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.number)) and np.isfinite(value) and value >= 0):
                raise ParameterError(f"ExcitationThresholds.{name} must be finite and >= 0; got {value!r}.")
        if self.max_condition < 1:
            raise ParameterError(
                f"ExcitationThresholds.max_condition must be >= 1; got {self.max_condition!r}. Use e.g. 1e8."
            )
        if self.resolution is not None and not (np.isfinite(self.resolution) and self.resolution >= 0):
            raise ParameterError(
                f"ExcitationThresholds.resolution must be >= 0 [rad or m] or None; got {self.resolution!r}."
            )


@dataclass(frozen=True, eq=False)
class JointMotion:
    """How much each joint of a recording moved, shapes (n_dof,).

    Attributes
    ----------
    range : array
        max - min of q [rad or m].
    speed : array
        95th percentile of ``|q(t + w) - q(t)| / w`` with ``w`` the speed window [rad/s or m/s].
    resolution : array
        Encoder step [rad or m] (given or estimated; 0 when unknown).
    window : float
        Window the speed was measured over [s] (``speed_window``, at least one sample step).
    """

    range: np.ndarray
    speed: np.ndarray
    resolution: np.ndarray
    window: float


def joint_label(joint: int, robot=None) -> str:
    """``"joint 3 (J3)"``: the 1-based joint number, with the robot's name for it when it differs."""
    label = f"joint {joint + 1}"
    names = getattr(robot, "joint_names", None)
    if names is not None and joint < len(names) and str(names[joint]) not in (label, str(joint + 1)):
        label += f" ({names[joint]})"
    return label


def joint_labels(joints, robot=None) -> str:
    """``"joint 1 (J1), joint 3 (J3)"``: the labels of ``joints`` (0-based), comma-separated."""
    return ", ".join(joint_label(j, robot) for j in joints)


def format_fix(fix: str, joints, robot=None) -> str:
    """``fix`` with ``{joints}`` replaced by the joints' labels and ``{k}`` by their 1-based numbers."""
    return fix.format(joints=joint_labels(joints, robot), k=",".join(str(j + 1) for j in joints))


def _thresholds(thresholds) -> ExcitationThresholds:
    if thresholds is None:
        return ExcitationThresholds()
    if not isinstance(thresholds, ExcitationThresholds):
        raise ParameterError(
            f"excitation thresholds must be an ExcitationThresholds; got {type(thresholds).__name__}. "
            "Pass ExcitationThresholds(...) or None."
        )
    return thresholds


def estimate_resolution(q) -> np.ndarray:
    """Per column, the smallest gap between distinct values of ``q`` (n_samples, n_dof): the encoder step of
    quantised positions; gaps at floating-point rounding level are ignored; 0 when there are none."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.zeros(q.shape[1])
    for j in range(q.shape[1]):
        values = np.unique(q[:, j])
        gaps = np.diff(values)
        gaps = gaps[gaps > 1e-12 * max(float(np.abs(values).max()), 1.0)]
        out[j] = float(gaps.min()) if gaps.size else 0.0
    return out


def _windowed_velocity(t, q, window) -> tuple[np.ndarray, float]:
    """``(q(t_k + w) - q(t_k)) / w`` per sample (n_samples - m, n_dof) and the mean window ``w`` [s]."""
    n = t.size
    dt = float(np.median(np.diff(t)))
    m = min(max(1, int(round(window / dt))), n - 1)
    span = t[m:] - t[:-m]
    return (q[m:] - q[:-m]) / span[:, None], float(np.mean(span))


def joint_motion(recording: Recording, thresholds: ExcitationThresholds | None = None) -> JointMotion:
    """Range, speed and encoder step of every joint of ``recording`` (see :class:`JointMotion`)."""
    thresholds = _thresholds(thresholds)
    q = recording.q
    velocity, window = _windowed_velocity(recording.t, q, thresholds.speed_window)
    if thresholds.resolution is None:
        resolution = estimate_resolution(q)
    else:
        resolution = np.full(recording.n_dof, float(thresholds.resolution))
    return JointMotion(
        range=np.ptp(q, axis=0),
        speed=np.percentile(np.abs(velocity), SPEED_PERCENTILE, axis=0),
        resolution=resolution,
        window=window,
    )


def _limit(robot, name, n_dof):
    value = getattr(robot, name, None) if robot is not None else None
    if value is None:
        return None
    value = np.asarray(value, dtype=float).reshape(-1)
    return value if value.shape == (n_dof,) else None


def _needed(motion: JointMotion, robot, thresholds: ExcitationThresholds, n_dof: int):
    """Least range [rad] and speed [rad/s] per joint."""
    q_min, q_max, qd_max = (_limit(robot, name, n_dof) for name in ("q_min", "q_max", "qd_max"))
    need_range = thresholds.min_range_steps * motion.resolution
    need_speed = motion.resolution / motion.window
    if q_min is not None and q_max is not None:  # an unlimited (infinite) range sets no threshold
        span = np.where(np.isfinite(q_max - q_min), q_max - q_min, 0.0)
        need_range = np.maximum(need_range, thresholds.min_range_fraction * span)
    if qd_max is not None:
        need_speed = np.maximum(need_speed, thresholds.min_speed_fraction * np.where(np.isfinite(qd_max), qd_max, 0.0))
    return need_range, need_speed


def check_joint_motion(
    recording: Recording, joints, *, robot=None, purpose: str, fix: str, thresholds=None
) -> JointMotion:
    """Raise unless every joint of ``joints`` moves over the least range and at the least speed.

    Parameters
    ----------
    recording : Recording
        Any recording (raw or preprocessed; only ``t`` and ``q`` are read); its ``name`` is the source in messages.
    joints : sequence of int
        Joints (0-based) the fit needs moving.
    robot : RobotDescription, optional
        Its ``q_min``, ``q_max`` and ``qd_max`` set the limit-relative thresholds and ``joint_names`` the
        labels; without it only the resolution-relative thresholds apply.
    purpose : str
        What the motion is for, e.g. ``"the inertial step (eq. 21)"``.
    fix : str
        What to record instead; ``{joints}`` is replaced by the failing joints' labels, ``{k}`` by their numbers.
    thresholds : ExcitationThresholds, optional

    Returns
    -------
    JointMotion

    Raises
    ------
    InsufficientExcitationError
        Naming the recording, every failing joint with its range and speed against the thresholds, and ``fix``.

    Examples
    --------
    >>> t = np.linspace(0.0, 2.0, 201)
    >>> rec = Recording(t=t, q=np.column_stack([np.sin(t), 0 * t]), tau=np.zeros((201, 2)), name="run.csv")
    >>> check_joint_motion(rec, [0], purpose="a test", fix="Move it.").range.round(3).tolist()
    [1.0, 0.0]
    """
    thresholds = _thresholds(thresholds)
    motion = joint_motion(recording, thresholds)
    need_range, need_speed = _needed(motion, robot, thresholds, recording.n_dof)
    failing, details = [], []
    for j in sorted({int(j) for j in joints}):
        too_short = not (motion.range[j] >= need_range[j] and motion.range[j] > 0)
        too_slow = not (motion.speed[j] >= need_speed[j] and motion.speed[j] > 0)
        if too_short or too_slow:
            failing.append(j)
            details.append(
                f"{joint_label(j, robot)}: range {motion.range[j]:.3g} rad (needs >= {need_range[j]:.3g}), "
                f"speed {motion.speed[j]:.3g} rad/s (needs >= {need_speed[j]:.3g})"
            )
    if failing:
        source = recording.name or "the recording"
        every = len(failing) == recording.n_dof > 1
        raise InsufficientExcitationError(
            f"Recording {source}: {'every joint' if every else joint_labels(failing, robot)} must move for {purpose} "
            "(range of motion >= "
            f"{thresholds.min_range_fraction:.3g} of the joint range and >= {thresholds.min_range_steps:.3g} encoder "
            f"steps, {SPEED_PERCENTILE:.0f}th-percentile speed >= {thresholds.min_speed_fraction:.3g} of qd_max); got "
            + "; ".join(details)
            + ". "
            + (fix.format(joints="every joint", k="<k>") if every else format_fix(fix, failing, robot)),
            joints=failing,
        )
    return motion


def _longest_run(flags: np.ndarray) -> int:
    """Length of the longest run of True in a 1-D boolean array."""
    if not flags.any():
        return 0
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return int(np.max(edges[1::2] - edges[::2]))


def check_sliding(recording: Recording, joint: int, *, robot=None, fix: str, thresholds=None) -> float:
    """Raise unless ``joint`` slides in both directions above the sliding speed for ``min_sliding_time``.

    The sliding speed is ``min_sliding_fraction * qd_max`` (with ``robot``) and at least the least speed of
    :func:`check_joint_motion`; the speed is measured over ``speed_window`` from the positions.

    Parameters
    ----------
    recording : Recording
        The friction experiment (raw or preprocessed).
    joint : int
        The moving joint, 0-based.
    robot : RobotDescription, optional
    fix : str
        What to record instead (``{joints}`` is replaced by the joint's label, ``{k}`` by its number).
    thresholds : ExcitationThresholds, optional

    Returns
    -------
    float
        The sliding speed used [rad/s].

    Raises
    ------
    InsufficientExcitationError
        Naming the recording, the joint, the direction(s) missing, the speeds and ``fix``.
    """
    thresholds = _thresholds(thresholds)
    motion = joint_motion(recording, thresholds)
    _, need_speed = _needed(motion, robot, thresholds, recording.n_dof)
    velocity, _ = _windowed_velocity(recording.t, recording.q, thresholds.speed_window)
    v = velocity[:, joint]
    qd_max = _limit(robot, "qd_max", recording.n_dof)
    speed = float(need_speed[joint])
    if qd_max is not None and np.isfinite(qd_max[joint]):
        speed = max(speed, thresholds.min_sliding_fraction * float(qd_max[joint]))
    dt = float(np.median(np.diff(recording.t)))
    runs = {"positive": _longest_run(v > speed) * dt, "negative": _longest_run(v < -speed) * dt}
    missing = [side for side, seconds in runs.items() if not (seconds >= thresholds.min_sliding_time and seconds > 0)]
    if missing:
        source = recording.name or "the recording"
        label = joint_label(joint, robot)
        raise InsufficientExcitationError(
            f"Recording {source}: {label} must slide in both directions at more than {speed:.3g} rad/s for at "
            f"least {thresholds.min_sliding_time:.3g} s each way (above the Stribeck range, as eq. 20 and the "
            f"LuGre fit need); got {runs['positive']:.3g} s positive and {runs['negative']:.3g} s negative "
            f"(peak speeds {max(0.0, float(v.max())):.3g} and {max(0.0, float(-v.min())):.3g} rad/s). "
            + format_fix(fix, [joint], robot),
            joints=[joint],
        )
    return speed


def _pooled_velocity(recordings) -> np.ndarray:
    """The recordings' joint velocities, pooled: ``qd`` where recorded (prepared recordings), else central
    differences of ``q``."""
    return np.concatenate([r.qd if r.qd is not None else np.gradient(r.q, r.t, axis=0) for r in recordings])


def one_way_joints(recordings, joints, *, speed, min_fraction: float) -> list:
    """The joints of ``joints`` (0-based, sorted) that do not move faster than ``speed`` [rad/s] (one, or one per
    joint) both ways on
    ``min_fraction`` of the pooled samples of ``recordings``: their Coulomb friction is a constant there, which a
    torque offset or the rigid body's gravity takes as well."""
    return one_way_velocities(_pooled_velocity(list(recordings)), joints, speed=speed, min_fraction=min_fraction)


def one_way_velocities(qd: np.ndarray, joints, *, speed, min_fraction: float) -> list:
    """The joints of ``joints`` (0-based, sorted) whose velocity ``qd`` (n_samples, n_dof) [rad/s] is not above
    ``speed`` (one, or one per joint) both ways on ``min_fraction`` of the samples (``one_way_joints``' rule on one
    velocity array)."""
    qd = np.asarray(qd, dtype=float)
    speeds = np.broadcast_to(np.asarray(speed, dtype=float), qd.shape[1:])
    return [j for j in sorted({int(j) for j in joints})
            if min(np.mean(qd[:, j] > speeds[j]), np.mean(qd[:, j] < -speeds[j])) < min_fraction]  # fmt: skip


def _speed_text(speeds) -> str:
    """``"0.05"``, or ``"0.02, 0.085"`` where the failing joints' speeds differ."""
    return ", ".join(dict.fromkeys(f"{v:.3g}" for v in speeds))


def check_reversals(recordings, joints, *, speed, min_fraction: float, robot=None, purpose: str, fix: str):
    """Raise unless every joint of ``joints`` moves faster than ``speed`` both ways on ``min_fraction`` of the samples.

    The samples of all ``recordings`` are pooled (a fit pools their rows): a joint that reverses in one of
    them passes. Velocities are the recordings' ``qd`` (prepared recordings), or central differences of ``q``.

    Parameters
    ----------
    recordings : sequence of Recording
    joints : sequence of int
        Joints (0-based) whose friction must be told apart from a constant (a torque offset).
    speed : float or array of float
        [rad/s] A sample counts for a direction when the joint moves faster than this that way (one speed, or one per
        joint of the recordings).
    min_fraction : float
        Least share of the pooled samples in each direction.
    robot : RobotDescription, optional
        Joint names for the message.
    purpose : str
        Why both directions are needed, e.g. ``"to tell Coulomb friction from a torque offset"``.
    fix : str
        What to do instead (``{joints}`` and ``{k}`` are replaced by the failing joints' labels and numbers).

    Raises
    ------
    InsufficientExcitationError
        Naming the recordings, every failing joint with its share of samples each way and its velocity range, and
        ``fix``.
    """
    recordings = list(recordings)
    qd = _pooled_velocity(recordings)
    failing = one_way_joints(recordings, joints, speed=speed, min_fraction=min_fraction)
    details, speeds = [], np.broadcast_to(np.asarray(speed, dtype=float), qd.shape[1:])  # one, or one per joint
    for j in failing:
        shares = (float(np.mean(qd[:, j] > speeds[j])), float(np.mean(qd[:, j] < -speeds[j])))
        details.append(
            f"{joint_label(j, robot)}: {100 * shares[0]:.3g} % of the samples positive, {100 * shares[1]:.3g} % "
            f"negative (qd{j + 1} from {qd[:, j].min():.3g} to {qd[:, j].max():.3g} rad/s)"
        )
    if failing:
        source = ", ".join(dict.fromkeys(r.name or "a recording" for r in recordings))
        raise InsufficientExcitationError(
            f"Recording {source}: {joint_labels(failing, robot)} must move both ways {purpose} (faster than "
            f"{_speed_text(speeds[failing])} rad/s on at least {100 * min_fraction:.3g} % of the samples each way); "
            "got " + "; ".join(details) + ". " + format_fix(fix, failing, robot),
            joints=failing,
        )
