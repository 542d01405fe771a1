"""Checks run before any fit of ``diagnose``: every joint moves in both recordings, the training recording's torque is
of the robot file's magnitude (``plausibility.check_torque_magnitude``: a torque constant without its gear ratio
otherwise gives findings that explain a torque a hundred times too small), and the nominal model's free columns are well
conditioned on the training recording (a still or dithering joint otherwise gives noise-fitted findings);
``validation_recordings`` and ``training_recordings`` check the recording arguments."""

from __future__ import annotations

import numpy as np

from identification.data.excitation_check import ExcitationThresholds, check_joint_motion
from identification.data.plausibility import check_torque_magnitude
from identification.data.recording import Recording
from identification.data.regressor_check import base_parameter_joints, check_regressor
from identification.diagnosis.columns import row_chunks
from identification.diagnosis.context import check_preprocessed
from identification.diagnosis.held_links import held_links
from identification.diagnosis.nominal import friction_feature_names, joint_friction_columns
from identification.metrics import rms
from psdm_casadi.errors import ParameterError

RECORD_FIX = (
    "Record training and validation runs that move {joints} over a large part of the range, with speed and "
    "acceleration (psdm excite, or psdm simulate --experiment sine)."
)


def check_motion(robot, train, validation, options) -> None:
    """Every joint moves in the training and the validation recording (``DiagnosisOptions.excitation``).

    Recordings given preprocessed (``options.preprocess=False``) must hold qd and qdd first.
    """
    for role, rec in (("training", train), ("validation", validation)):
        if not options.preprocess:
            check_preprocessed(rec)
        check_joint_motion(
            rec,
            range(robot.n_dof),
            robot=robot,
            purpose=f"the diagnosis ({role} recording)",
            fix=RECORD_FIX,
            thresholds=options.excitation,
        )


def check_nominal_columns(robot, model, problem, options) -> None:
    """The nominal model's free columns on the training recording, each joint weighted by its torque RMS as the
    selection weights it, must have full rank and a bounded condition number (``check_regressor``); before that, the
    training recording's torque must be on the robot file's scale (``check_torque_magnitude``)."""
    ctx = problem.ctx_t
    recording = Recording(t=ctx.t, q=ctx.q, tau=ctx.tau, qd=ctx.qd, qdd=ctx.qdd, name=ctx.name)
    check_torque_magnitude(recording, robot, currents=ctx.torque_constants is not None)
    n = robot.n_dof
    names = friction_feature_names(options.friction, n)
    per = len(names) // n
    joints = [(k // per,) for k in range(len(names))]
    if options.friction == "lugre" and robot.drives is not None:  # the bristle dynamics of the LuGre prior
        names += [f"lugre_dynamics_{j + 1}" for j in range(n)]
        joints += [(j,) for j in range(n)]
    held = held_links(model, robot, options.held_links) if options.rigid_body == "identified" else None
    if held is not None:  # the free links' directions of the base parameters (``held_links``)
        names += [f"free_rigid_body_{k + 1}" for k in range(held.basis.shape[1])]
        joints += [tuple(range(n))] * held.basis.shape[1]
    elif options.rigid_body == "identified":
        names += list(model.base_names)
        joints += list(base_parameter_joints(model))
    torque_rms = rms(problem.ctx_t.tau)
    sigma = np.maximum(torque_rms, 1e-6 * max(float(np.max(torque_rms)), 1e-12))
    thresholds = options.excitation if options.excitation is not None else ExcitationThresholds()
    if len(row_chunks(problem.base_t.n_samples)) == 1:
        matrix, weights = (
            problem.base_t.dense().reshape(-1, problem.base_t.n_columns),
            np.tile(1.0 / sigma**2, problem.ctx_t.n_samples),
        )
    else:  # the same singular values and column norms, from a chunked QR of the weighted rows
        matrix, weights = problem.base_t.weighted_r(sigma), None
    held = {c for j in options.held_friction.joints for c in joint_friction_columns(robot, options.friction, j)}
    if options.file_friction is not None:  # a model file's joints without a Stribeck hump or bristle column
        held |= set(options.file_friction.zero_columns())
    free = [c for c in range(len(names)) if c not in held]  # a held joint's friction is no column of the fit
    source = f"{problem.ctx_t.name or 'the training recording'} (the nominal model's friction" + (
        " and base parameters)" if options.rigid_body == "identified" else ")"
    )

    def check(columns):
        check_regressor(matrix[:, columns], weights, names=[names[c] for c in columns],
                        column_joints=[joints[c] for c in columns], owner="diagnose", source=source, fix=RECORD_FIX,
                        max_condition=thresholds.max_condition, robot=robot)  # fmt: skip

    if not free:  # every joint's friction held at a model file's values and the rigid body fixed: no fit
        return
    try:
        check(free)
    except ParameterError as exc:
        hump = [c for c in free if names[c].startswith("fs_minus_fc_")]
        if not hump:
            raise
        try:  # without the Stribeck hump's columns: then a joint that never slows down is the only trouble
            check([c for c in free if c not in hump])
        except ParameterError:
            raise exc from None
        raise ParameterError(
            f"{exc} The nominal friction's Stribeck hump ({options.friction}, seen only below a joint's Stribeck "
            "velocity) is the only trouble: a joint that never slows down that far does not show it. Pass "
            "--friction coulomb_viscous (no hump; DiagnosisOptions(friction='coulomb_viscous')) to diagnose these "
            "recordings as they are."
        ) from None


def validation_recordings(validation) -> tuple:
    """``validation`` (a Recording or a non-empty sequence of them) as a tuple of Recordings.

    Raises
    ------
    ParameterError
        When it is empty or holds something else than Recordings.
    """
    return _recordings(validation, "validation")


def training_recordings(train) -> tuple:
    """``train`` (a Recording or a non-empty sequence of them, pooled by ``diagnose``) as a tuple of Recordings.

    Raises
    ------
    ParameterError
        When it is empty or holds something else than Recordings.
    """
    return _recordings(train, "train")


def _recordings(value, argument: str) -> tuple:
    """``value``, diagnose's ``argument`` (a Recording or a non-empty sequence of them), as a tuple of Recordings."""
    from identification.data.recording import Recording

    try:
        items = (value,) if isinstance(value, Recording) else () if value is None else tuple(value)
    except TypeError:  # not a sequence
        items = ()
    if not items or not all(isinstance(r, Recording) for r in items):
        raise ParameterError(
            f"diagnose {argument} must be a Recording or a non-empty list of Recordings; got "
            f"{type(value).__name__}. Pass {argument}=[recording_a, recording_b]."
        )
    return items
