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

The torque is checked too, once the recording is prepared (filtered and differentiated, ``q``, ``qd``, ``qdd``
and the joint torque): :func:`check_torque_magnitude` fits per joint the least-squares scale of the recorded torque
onto the torque the robot file's rigid body predicts for the same motion. A torque constant given without the gear
ratio (the motor's kt), inverted gear ratios or a torque unit scale every joint alike, by 1/100, 1/10000 or 1000;
identify then fitted for half an hour (the counterbalance route tried to explain the missing torque) instead of
saying so. Most joints off by the same large factor is refused, naming the recording, the factor and the likely
causes; a single joint off is a warning naming it. Run by ``trajectory_data.prepare_recordings``, before any fit.

The bounds are loose on purpose (:class:`PlausibilityThresholds`): they separate a unit or mapping
error, which misses by a factor of tens to a thousand, from a real recording that grazes a limit, or a robot file
whose inertias are off by a few times on a link (vendor URDFs), with friction, rotor inertia and a payload on top.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from identification.data.excitation_check import joint_label, joint_motion
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.said_once import SAID, say

__all__ = [
    "PlausibilityThresholds",
    "TorqueMagnitude",
    "check_plausible_recording",
    "check_torque_magnitude",
    "friction_columns",
    "looks_like_milliseconds",
    "percent_of_rated",
    "torque_magnitude",
]

logger = logging.getLogger(__name__)

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
    torque_factor : float
        Recorded over predicted torque (a joint's least-squares scale, :func:`torque_magnitude`) beyond which, or below
        whose inverse, a joint's torque is off (default 10). A vendor URDF off by 2-3x on a link, friction and rotor
        inertia the file lacks, or a payload move a joint's scale by a few times; a forgotten gear ratio by ~100.
    joint_torque_factor : float
        The same for one joint alone, which is warned about (default 30): a joint whose predicted torque is small
        (a wrist, whose vendor inertias are the least known) or that carries a payload the file lacks strays further
        than most joints of a recording can.
    torque_correlation : float
        Least correlation of a joint's recorded with its predicted torque for its scale to be judged (default 0.5):
        a joint whose predicted torque is small next to its friction has no scale to speak of.
    pooled_correlation : float
        The same for the torque of all joints pooled, whose scale decides a refusal (default 0.25): lower, since the
        refusal asks the pooled RMS ratio to agree too, and a heavily geared arm's friction takes much of its torque.
    """

    limit_margin_fraction: float = 0.1
    speed_factor: float = 5.0
    max_millisecond_step: float = 0.05
    torque_factor: float = 10.0
    joint_torque_factor: float = 30.0
    torque_correlation: float = 0.5
    pooled_correlation: float = 0.25

    def __post_init__(self):
        for name in self.__dataclass_fields__:
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
            f"q{j + 1} to radians, and {others} alike, or state the log's unit: --columns q=PREFIX:deg (PREFIX: "
            "the name of its position columns without the joint number)."
        )
    if problems:
        raise RecordingError(
            f"Recording {source}: no {getattr(robot, 'name', 'robot')} can have recorded this; "
            + "; ".join(problems)
            + ". Fix the recording's units (q in rad or m, t in s; a log's own units are stated in --columns, e.g. "
            "q=Position:deg,tau=Torque:mNm,t=Time:ms) or the robot file."
        )


#: Samples of a prepared recording the torque's scale is judged on (evenly spaced; an hour of data is not needed).
TORQUE_SAMPLES = 2000
#: Velocity [rad/s] of the smoothed Coulomb column fitted along with the scale (``friction_columns``).
FRICTION_VELOCITY = 0.01


@dataclass(frozen=True)
class TorqueMagnitude:
    """The recorded torque over the robot file's rigid-body torque for the same motion, per joint and pooled.

    ``scale`` is per joint the least-squares factor ``s`` of ``tau_recorded ~ s tau_file`` (NaN where the file
    predicts no torque or the joint has none recorded) and ``correlation`` the cosine of the two signals (a wrong scale
    keeps it; rotor inertia the file lacks lowers it). ``overall`` and ``overall_correlation`` are the same pooled over
    the joints, so the joints the file predicts most torque for (gravity's, which the file knows best) weigh most;
    ``rms_ratio`` is the pooled RMS of the recorded over the predicted torque. ``predicted_rms`` is each joint's
    predicted RMS [N m]. All of them without the friction columns, when :func:`torque_magnitude` is given them.

    A gross check, for a unit or a mapping (factors of tens to thousands, before any fit); the per-joint torque
    constant within its uncertainty, from a known payload, is ``calibration.torque_scale.TorqueScales``.
    """

    scale: np.ndarray
    correlation: np.ndarray
    predicted_rms: np.ndarray
    overall: float = float("nan")
    overall_correlation: float = float("nan")
    rms_ratio: float = float("nan")

    def judged(self, thresholds: PlausibilityThresholds) -> np.ndarray:
        """The joints (bool, n_dof) whose scale says something: positive and correlated."""
        with np.errstate(invalid="ignore"):
            return np.isfinite(self.scale) & (self.scale > 0) & (self.correlation >= thresholds.torque_correlation)

    def global_factor(self, thresholds: PlausibilityThresholds) -> float | None:
        """The factor every joint's torque is off by (the pooled scale), or None when it is within
        ``torque_factor`` either way, the pooled signals do not correlate, or the RMS ratio disagrees."""
        factor, limit = self.overall, thresholds.torque_factor
        if not (np.isfinite(factor) and factor > 0 and self.overall_correlation >= thresholds.pooled_correlation):
            return None
        low = factor <= 1.0 / limit and self.rms_ratio <= 1.0 / limit
        return factor if low or (factor >= limit and self.rms_ratio >= limit) else None

    def odd_joints(self, thresholds: PlausibilityThresholds) -> np.ndarray:
        """The judged joints (int, 0-based) off by more than ``joint_torque_factor``: too small, or too large where the
        file predicts a torque of some size (a tenth of the largest joint's; on a joint it predicts little for, friction
        and rotor inertia the file lacks make the recorded torque many times the predicted)."""
        judged, limit = self.judged(thresholds), thresholds.joint_torque_factor
        scale = np.where(judged, self.scale, 1.0)
        sizeable = self.predicted_rms >= 0.1 * np.nanmax(self.predicted_rms)
        return np.flatnonzero(judged & ((scale <= 1.0 / limit) | ((scale >= limit) & sizeable)))


def _cosine(x, y) -> float:
    norm = float(np.sqrt((x @ x) * (y @ y)))
    return float(x @ y) / norm if norm > 0 else float("nan")


def friction_columns(qd, velocity: float = FRICTION_VELOCITY) -> np.ndarray:
    """Per joint the columns a drive's friction and offset add to its torque: ``tanh(qd / velocity)``, ``qd`` and 1
    (n_samples, n_dof, 3); the robot file predicts none of them, so the scale is judged without them."""
    qd = np.asarray(qd, dtype=float)
    return np.stack([np.tanh(qd / velocity), qd, np.ones_like(qd)], axis=2)


def _without(columns, signal) -> np.ndarray:
    """``signal`` (n,) less its least-squares fit by ``columns`` (n, k)."""
    coefficients = np.linalg.lstsq(columns, signal, rcond=None)[0]
    return signal - columns @ coefficients


def torque_magnitude(recorded, predicted, nuisance=None) -> TorqueMagnitude:
    """:class:`TorqueMagnitude` of ``recorded`` onto ``predicted`` torques (both (n_samples, n_dof); NaN rows left out).

    ``nuisance`` (n_samples, n_dof, k), e.g. :func:`friction_columns`: per joint, columns fitted along with the scale
    (their share taken out of both signals first), so a friction the file lacks neither inflates nor hides the scale.
    """
    recorded, predicted = np.asarray(recorded, dtype=float), np.asarray(predicted, dtype=float)
    ok = np.isfinite(recorded) & np.isfinite(predicted)
    x, y = np.where(ok, predicted, 0.0), np.where(ok, recorded, 0.0)
    if nuisance is not None:
        for j in np.flatnonzero(ok.sum(axis=0) > np.shape(nuisance)[2]):
            rows = ok[:, j]
            x[rows, j] = _without(nuisance[rows, j], x[rows, j])
            y[rows, j] = _without(nuisance[rows, j], y[rows, j])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.einsum("nj,nj->j", x, y) / np.einsum("nj,nj->j", x, x)
        correlation = np.array([_cosine(x[:, j], y[:, j]) for j in range(x.shape[1])])
        rms = np.sqrt(np.sum(x**2, axis=0) / np.maximum(ok.sum(axis=0), 1))
        overall = float(np.sum(x * y) / np.sum(x * x))
        rms_ratio = float(np.sqrt(np.sum(y * y) / np.sum(x * x)))
    # a joint the file predicts next to no torque for (a massless last link) has no scale: NaN, not 1e15
    scale = np.where((ok.sum(axis=0) >= 3) & (rms > 1e-9 * np.max(rms, initial=0.0)), scale, np.nan)
    return TorqueMagnitude(scale, correlation, rms, overall, _cosine(x.ravel(), y.ravel()), rms_ratio)


def _joint_list(joints) -> str:
    joints = [int(j) + 1 for j in joints]
    consecutive = len(joints) > 2 and joints == list(range(joints[0], joints[-1] + 1))
    return f"{joints[0]}-{joints[-1]}" if consecutive else ", ".join(map(str, joints))


def _scale_causes(factor: float, robot, currents: bool) -> str:
    """The likely causes of every joint's torque being ``factor`` times the robot file's, most likely first."""
    transmission = getattr(robot, "transmission", None)
    ratios = None if transmission is None else np.abs(np.diag(np.asarray(transmission.coupling, dtype=float)))
    causes = ["the torque's unit (state the log's unit: --columns tau=PREFIX:mNm, or convert it to N m)"]
    for unit, size in (("mN m", 1e3), ("kN m", 1e-3)):
        if abs(np.log(factor / size)) <= np.log(2.0):  # a unit's factor, as far as friction and the file allow
            causes[0] = f"torques in {unit}? (N m expected; state the log's unit: --columns tau=PREFIX:mNm)"
    if currents:  # the torque is the currents times the robot file's kt: their unit, not a torque's
        causes[0] = "the current's unit (state the log's unit: --columns i=PREFIX:mA, or convert it to A)"
        if abs(np.log(factor / 1e3)) <= np.log(2.0):
            causes[0] = "currents in mA? (A expected; state the log's unit: --columns i=PREFIX:mA)"
    if factor < 1.0 and ratios is not None and np.median(ratios) < 1.0:
        ratio = float(np.median(ratios))
        causes.insert(0, "inverted gear ratios: [transmission] gear_ratios are motor turns per joint turn (the robot "
                      f"file states {ratio:.3g}; a gearbox reduces, e.g. {1.0 / ratio:.3g})")  # fmt: skip
    elif factor < 1.0 and currents:
        causes.insert(0, "torque constants without the gear ratio: a [[drive]] table's kt is the joint-side constant, "
                      f"gear ratio x the motor's kt; did you give the motor's kt without the gear ratio (about "
                      f"{1.0 / factor:.3g})? Or give motor_kt and gear_ratios in [transmission]")  # fmt: skip
    elif currents:
        causes.append("the torque constants kt (N m/A at the joint) or the gear ratios")
    else:
        causes.append('the torque signal\'s gear ratio (motor-side torque needs [recording] side = { tau = "motor" })')
    causes.append("or the robot file's links are not this robot's (identify bounds the masses around them)")
    return "; ".join(causes)


def percent_of_rated(found: TorqueMagnitude, robot, currents: bool, thresholds: PlausibilityThresholds) -> bool:
    """Whether currents read as amperes are per cent of the rated currents the robot file states (``[transmission]
    rated_current``): the recorded torque is at least twice the file's on most judged joints, and joint by joint as
    ``100 / rated_current`` gives, within 1.5x (a controller's trace read without ``--columns i=PREFIX:%``, whose scale
    alone is within the refusal's tenfold). Not judged without rated currents or on fewer than two joints."""
    rated = getattr(getattr(robot, "transmission", None), "rated_current", None)
    judged = found.judged(thresholds)
    if not currents or rated is None or judged.sum() < 2:
        return False
    as_read = np.abs(np.log(found.scale[judged]))
    as_percent = np.abs(np.log(found.scale[judged] * np.asarray(rated)[judged] / 100.0))
    return bool(np.median(np.log(found.scale[judged])) > np.log(2.0) and np.median(as_percent) < np.log(1.5)
                and np.median(as_percent) < 0.5 * np.median(as_read))  # fmt: skip


def check_torque_magnitude(
    recording: Recording,
    robot,
    currents: bool = False,
    thresholds: PlausibilityThresholds | None = None,
    torque_constants=None,
) -> TorqueMagnitude | None:
    """Refuse a prepared ``recording`` whose torque is off the robot file's by the same large factor on most joints.

    The robot file's rigid body (``PinocchioOracle.rnea``, rotor inertias included) predicts the torque of the
    recorded motion; :func:`torque_magnitude` compares. A pooled scale beyond ``thresholds.torque_factor`` either way
    (the pooled RMS ratio too) is refused; one joint beyond ``thresholds.joint_torque_factor`` is warned about, naming
    it.

    Parameters
    ----------
    recording : Recording
        Prepared (``q``, ``qd``, ``qdd`` and the joint torque ``tau``); its ``name`` is the file named.
    robot : RobotDescription
        Without links (no rigid body to predict with) nothing is checked.
    currents : bool
        The torque was made from currents with the robot file's torque constants (the message names them).
    torque_constants : array (n_dof,), optional
        Per joint the factor [N m/A] that makes the prepared ``tau`` the joint torque, where it is not one already: the
        fleet prepares its currents in amperes (it refits the robot file's kt, ``fleet.session.read_session``) and
        passes the file's kt. NaN on a joint: no torque constant is known, its scale is not judged.

    Returns
    -------
    TorqueMagnitude or None
        The per-joint scales (None: not checked).

    Raises
    ------
    RecordingError
        Naming the recording, the factor, the joints and the likely causes (torque unit, torque constants, gear ratios).
    """
    thresholds = PlausibilityThresholds() if thresholds is None else thresholds
    if getattr(robot, "links", None) is None or recording.tau is None or recording.qdd is None:
        return None
    if recording.n_dof != robot.n_dof or recording.n_samples < 3:
        return None
    from psdm_casadi.oracle import PinocchioOracle

    rows = np.unique(np.linspace(0, recording.n_samples - 1, min(TORQUE_SAMPLES, recording.n_samples)).astype(int))
    predicted = PinocchioOracle(robot).rnea(recording.q[rows], recording.qd[rows], recording.qdd[rows])
    recorded = recording.tau[rows] * (1.0 if torque_constants is None else np.asarray(torque_constants, dtype=float))
    found = torque_magnitude(recorded, predicted, friction_columns(recording.qd[rows]))
    source, factor = recording.name or "the recording", found.global_factor(thresholds)
    if factor is not None:
        shown = np.isfinite(found.scale)
        each = f"{_joint_list(np.flatnonzero(shown))}: " + ", ".join(f"{s:.3g}" for s in found.scale[shown])
        inverse = f" (1/{1.0 / factor:.3g})" if factor < 1.0 else ""
        raise RecordingError(
            f"Recording {source}: the recorded torque is about {factor:.3g} times{inverse} the torque the robot file "
            f"predicts for the same motion (least squares over all joints; per joint {each}); a robot file's inertias "
            "are not that far off. Likely causes: "
            f"{_scale_causes(factor, robot, currents)}. Fix the robot file or the recording and run again."
        )
    if percent_of_rated(found, robot, currents, thresholds):
        rated = robot.transmission.rated_current
        raise RecordingError(
            f"Recording {source}: the currents, read as amperes, give {', '.join(f'{s:.3g}' for s in found.scale)} "
            "times the torque the robot file predicts on joints 1..n, joint by joint as 100 / the rated currents of "
            f"its [transmission] give ({', '.join(f'{100.0 / r:.3g}' for r in rated)}): they look logged in per cent "
            "of each motor's rated current, as industrial controllers trace them. State it: --columns i=PREFIX:% (read "
            "as % / 100 x rated_current), or convert the currents to A."
        )
    for j in found.odd_joints(thresholds):
        message = (
            f"Recording {source}: joint {j + 1} ({joint_label(j, robot)}) records {found.scale[j]:.3g} times the "
            f"torque the robot file predicts for it, more than {thresholds.joint_torque_factor:g} times off where the "
            "others are not: check that joint's torque constant, gear ratio and unit, or the column order"
            + ("; or a load the robot file does not carry (state the payload)." if found.scale[j] > 1 else ".")
        )
        if message not in SAID:
            say(logger, message)
    return found
