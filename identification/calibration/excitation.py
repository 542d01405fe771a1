"""What each calibration step needs its recordings to excite: ``data.excitation_check`` and ``regressor_check``.

Every step refuses, before it fits, data in which what it identifies does not move
(:class:`~psdm_casadi.errors.InsufficientExcitationError`, naming the recording, the joints and what to
record instead); :func:`check_calibration_data` runs the per-joint checks on every raw recording of a
data directory before step 1, so a still excitation is refused before minutes of friction fitting.

=========================  ==================================  ============================================
step                       joints that must move               also
=========================  ==================================  ============================================
motor (Kt)                 the swept joint, both sweeps        (its regression is one column per joint)
gravity                    the joints with a gravity torque    rank and condition of the weighted regressor
friction                   the oscillating joint               sliding both ways above the Stribeck range
inertial                   every joint                         rank and condition of the weighted regressor
refinement                 (its rows come from the above)      rank and condition of the freed parameters
=========================  ==================================  ============================================

The thresholds are :class:`~identification.data.excitation_check.ExcitationThresholds` (the steps'
``excitation`` hyper-parameter, ``PipelineOptions.excitation``); their defaults and why are documented there.
"""

from __future__ import annotations

import numpy as np

from identification.data.excitation_check import ExcitationThresholds, check_joint_motion, check_sliding
from identification.data.plausibility import check_plausible_recording
from identification.data.regressor_check import base_parameter_joints, check_regressor
from psdm_casadi.errors import ParameterError

__all__ = [
    "MOTOR_FIX",
    "GRAVITY_FIX",
    "FRICTION_FIX",
    "EXCITATION_FIX",
    "thresholds_of",
    "check_motor_experiments",
    "check_gravity_design",
    "check_friction_experiment",
    "check_inertial_design",
    "check_calibration_data",
]

MOTOR_FIX = (
    "Record the motor_j{k}_nominal and motor_j{k}_payload sweeps again with {joints} running at constant speed "
    "over a good part of its range and back, the other joints held (psdm experiment motor --joint {k})."
)
GRAVITY_FIX = (
    "Record a slow out-and-back jog (gravity.csv) that moves {joints} through most of their ranges and back along "
    "the same path (psdm experiment gravity)."
)
FRICTION_FIX = (
    "Record friction_j{k} again with {joints} oscillating in both directions, from pre-sliding amplitudes up to "
    "sliding speeds near its speed limit, the other joints held (psdm experiment friction --joint {k})."
)
EXCITATION_FIX = (
    "Record an exciting trajectory (excitation.csv) that moves {joints} over a large part of the range, with speed "
    "and acceleration (psdm excite, or psdm simulate --experiment sine)."
)


def thresholds_of(owner: str, value) -> ExcitationThresholds:
    """``value`` (an estimator's ``excitation`` hyper-parameter) as ExcitationThresholds; None gives the defaults."""
    if value is None:
        return ExcitationThresholds()
    if not isinstance(value, ExcitationThresholds):
        raise ParameterError(
            f"{owner}.excitation must be an ExcitationThresholds or None; got {type(value).__name__}. "
            "Pass identification.data.excitation_check.ExcitationThresholds(...)."
        )
    return value


def _sources(recordings) -> str:
    return ", ".join(dict.fromkeys(r.name or "a recording" for r in recordings))


def check_motor_experiments(experiments, robot, thresholds: ExcitationThresholds) -> None:
    """The swept joint of every MotorExperiment moves in both sweeps (range and speed)."""
    for e in experiments:
        for rec in (e.nominal, e.loaded):
            check_joint_motion(
                rec,
                [e.joint],
                robot=robot,
                purpose="the motor step (Kt, eqs. 16-17)",
                fix=MOTOR_FIX,
                thresholds=thresholds,
            )


def _gravity_joints(design) -> list:
    """Joints with a non-zero gravity row somewhere in the design (the others carry no rows)."""
    return [int(j) for j in np.unique(design.joint) if np.any(design.matrix[design.joint == j] != 0)]


def check_gravity_design(model, recordings, design, robot, thresholds: ExcitationThresholds) -> None:
    """The joints with a gravity torque move in every jog; the weighted gravity regressor is well conditioned."""
    joints = _gravity_joints(design)
    for rec in recordings:
        check_joint_motion(
            rec, joints, robot=robot, purpose="the gravity step (eq. 18)", fix=GRAVITY_FIX, thresholds=thresholds
        )
    _check_base_columns(model, model.gravity_mask, design, recordings, "GravityIdentifier", GRAVITY_FIX, thresholds,
                        robot)  # fmt: skip


def check_friction_experiment(experiment, robot, thresholds: ExcitationThresholds) -> None:
    """The joint of a FrictionExperiment moves and slides in both directions above the Stribeck range."""
    rec, joint = experiment.recording, experiment.joint
    purpose = "the friction step (eqs. 19-20, LuGre)"
    check_joint_motion(rec, [joint], robot=robot, purpose=purpose, fix=FRICTION_FIX, thresholds=thresholds)
    check_sliding(rec, joint, robot=robot, fix=FRICTION_FIX, thresholds=thresholds)


def check_inertial_design(model, recordings, design, robot, thresholds: ExcitationThresholds) -> None:
    """Every joint moves in every excitation; the regressor of the inertial (non-gravity) columns is well-posed."""
    for rec in recordings:
        check_joint_motion(
            rec,
            range(rec.n_dof),
            robot=robot,
            purpose="the inertial step (eq. 21)",
            fix=EXCITATION_FIX,
            thresholds=thresholds,
        )
    _check_base_columns(model, ~model.gravity_mask, design, recordings, "InertialIdentifier", EXCITATION_FIX,
                        thresholds, robot)  # fmt: skip


def _check_base_columns(model, mask, design, recordings, owner, fix, thresholds, robot) -> None:
    """The weighted regressor of the base parameters ``mask`` selects must be excited (``check_regressor``)."""
    owners = base_parameter_joints(model)
    check_regressor(
        design.matrix,
        design.weights,
        names=[name for name, keep in zip(model.base_names, mask) if keep],
        column_joints=[j for j, keep in zip(owners, mask) if keep],
        owner=owner,
        source=_sources(recordings),
        fix=fix,
        max_condition=thresholds.max_condition,
        robot=robot,
    )


def _gravity_rows(model, rec, every: int = 10) -> list:
    """Joints whose gravity row is non-zero somewhere along ``rec`` (every ``every``-th sample)."""
    y = model.gravity_regressor(rec.q[::every])
    return [int(j) for j in np.flatnonzero(np.any(np.abs(y) > 0, axis=(0, 2)))]


def check_calibration_data(robot, model, data, thresholds: ExcitationThresholds | None = None) -> None:
    """Per-joint checks of every raw recording of a CalibrationData, before any step runs.

    Motor sweeps: the swept joint; gravity jogs: the joints with a gravity torque; friction experiments
    (and their validation runs): the joint, sliding both ways; excitations: every joint.

    Every recording must first be plausible for ``robot`` (``plausibility.check_plausible_recording``: positions
    near the limits, speeds below them, time in seconds).

    Raises
    ------
    RecordingError
        For a recording in the wrong units (degrees, milliseconds) or of other joints, naming it and the column.
    InsufficientExcitationError
        For the first recording that fails, naming it, the joints and what to record instead.
    """
    thresholds = thresholds_of("PipelineOptions", thresholds)
    motor = [rec for _, nominal, loaded in data.motor for rec in (nominal, loaded)]
    friction = [rec for _, rec in tuple(data.friction) + tuple(data.friction_validation)]
    for rec in (*motor, *data.gravity, *friction, *data.excitation):
        check_plausible_recording(rec, robot)
    for joint, nominal, loaded in data.motor:
        for rec in (nominal, loaded):
            check_joint_motion(
                rec,
                [joint],
                robot=robot,
                purpose="the motor step (Kt, eqs. 16-17)",
                fix=MOTOR_FIX,
                thresholds=thresholds,
            )
    for rec in data.gravity:
        check_joint_motion(
            rec,
            _gravity_rows(model, rec),
            robot=robot,
            purpose="the gravity step (eq. 18)",
            fix=GRAVITY_FIX,
            thresholds=thresholds,
        )
    for joint, rec in tuple(data.friction) + tuple(data.friction_validation):
        purpose = "the friction step (eqs. 19-20, LuGre)"
        check_joint_motion(rec, [joint], robot=robot, purpose=purpose, fix=FRICTION_FIX, thresholds=thresholds)
        check_sliding(rec, joint, robot=robot, fix=FRICTION_FIX, thresholds=thresholds)
    for rec in data.excitation:
        check_joint_motion(
            rec,
            range(rec.n_dof),
            robot=robot,
            purpose="the inertial step (eq. 21) and the validation",
            fix=EXCITATION_FIX,
            thresholds=thresholds,
        )
