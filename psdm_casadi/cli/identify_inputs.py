"""``psdm identify``'s inputs on the recordings route, read and refused before any work: the output files, the
recordings (joint side, timed, ``--holdout`` cut) with the loads they state and the joints without torque, and the
numbers of the options (the fit's settings).

Everything here can refuse (exit 2) with a message naming the option or the file; nothing here fits.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from psdm_casadi.cli.checks import check_not_input, check_suffix, output_file
from psdm_casadi.cli.holdout import cut_training, holdout_fraction
from psdm_casadi.errors import ParameterError

__all__ = ["TrainingInputs", "check_outputs", "coulomb_velocity_option", "fit_settings", "read_training"]


@dataclass(frozen=True)
class TrainingInputs:
    """The recordings identify fits and judges: ``paths`` and ``configurations`` (the load each states) of the
    training recordings, ``recordings`` and ``validation`` read (joints without torque marked), ``explicit`` the
    ``--validate`` paths as given (before a ``--holdout`` part joins them), ``missing`` the validation's sentences on
    joints without torque."""

    paths: list
    configurations: list
    recordings: list
    validation: list
    explicit: list
    missing: list


def read_training(args, robot, layout) -> TrainingInputs:
    """The ``--data`` and ``--validate`` recordings read as the robot reads them (``args.validate`` becomes their
    paths), each checked before deriving and fitting (units, joint order, motion; with ``--friction lugre``, that
    every joint reverses)."""
    from identification.data.robot_recordings import recording_paths
    from psdm_casadi.cli.checks import check_recordings_first

    paths, configurations = _configurations(args.data, robot)
    args.validate = recording_paths(args.validate, robot)
    recordings, validation, explicit = _loaded(args, robot, layout, paths)  # joint side, timed; --holdout cut
    recordings, validation, missing = _missing_torque(args, robot, paths, recordings, validation)
    check_recordings_first(robot, recordings, validation)  # units, joint order, motion: before deriving and fitting
    if args.friction == "lugre":
        _check_reversals(recordings, paths)
    return TrainingInputs(paths, configurations, recordings, validation, explicit, missing)


def coulomb_velocity_option(text, n_dof: int):
    """``--coulomb-velocity``: None (chosen from the data), one width [rad/s] for every joint, or ``n_dof`` widths
    separated by commas (a tuple, one per joint).

    Raises
    ------
    ParameterError
        Naming the option and the fix, for a value that is not one or ``n_dof`` velocities > 0.
    """
    if text is None:
        return None
    try:
        values = [float(v) for v in str(text).split(",")]
    except ValueError:
        values = []
    if len(values) not in (1, n_dof) or not all(np.isfinite(v) and v > 0 for v in values):
        raise ParameterError(f"--coulomb-velocity must be a velocity > 0 [rad/s], e.g. 0.02, or {n_dof} of them, one "
                             f"per joint separated by commas (e.g. {','.join(['0.02'] * n_dof)}); got {text!r}. Leave "
                             "it out to choose it from the data.")  # fmt: skip
    return values[0] if len(values) == 1 else tuple(values)


def fit_settings(args, n_dof: int) -> tuple:
    """``(ColumnRequest, TrajectoryOptions)`` of the options for a robot of ``n_dof`` joints, each number refused where
    no fit can use it."""
    from identification.calibration.column_choice import ColumnRequest
    from identification.calibration.envelope import check_ratio
    from identification.calibration.trajectory_fit import TrajectoryOptions

    for flag, value in (("--mass-bounds", args.mass_bounds), ("--drive-inertia-bounds", args.drive_inertia_bounds)):
        check_ratio(flag, value)
    request = ColumnRequest(friction=args.friction, offset=args.offset, drive_inertia=args.drive_inertia,
                            drive_loss=args.drive_loss,
                            coulomb_velocity=coulomb_velocity_option(args.coulomb_velocity, n_dof))  # fmt: skip
    if args.prior_uncertainty is not None and not (np.isfinite(args.prior_uncertainty) and args.prior_uncertainty > 0):
        raise ParameterError(f"--prior-uncertainty must be > 0 (a multiple of each parameter's size, e.g. 3); got "
                             f"{args.prior_uncertainty!r}.")  # fmt: skip
    options = TrajectoryOptions(consistency=not args.no_consistency, cutoff_hz=args.cutoff,
                                envelope=not args.no_envelope, mass_ratio=tuple(args.mass_bounds),
                                drive_inertia_ratio=tuple(args.drive_inertia_bounds))  # fmt: skip
    if args.prior_uncertainty is not None:
        options = replace(options, prior_uncertainty=args.prior_uncertainty)
    return request, options


def check_outputs(args):
    """--out must be a new .json file (or, with --overwrite, any file but an input); --plots has no folder here."""
    if args.plots:
        raise ParameterError(
            "identify --plots writes the four-step route's plots into its --out folder; the recordings route writes "
            "one model file. Drop --plots, and plot with 'psdm validate MODEL.json RECORDING.csv --plots DIR'."
        )
    inputs = [("ROBOT", args.robot), ("--model", args.model)]
    inputs += [("--data", path) for path in args.data] + [("--validate", path) for path in args.validate]
    check_not_input(args.out, "--out", inputs, example=f"{Path(args.out).stem}_model.json")
    check_suffix(args.out, "--out", (".json",), "one calibrated-model file (JSON)")
    args.holdout = holdout_fraction(args)  # refused before any work too
    return output_file(args.out, "--out", args.overwrite)


def _loaded(args, robot, layout, paths) -> tuple:
    """(training, validation recordings, the ``--validate`` paths), read joint side and timed. With ``--holdout``, each
    training recording is cut on its raw samples (each part prepared on its own, as the model file says) and its last
    part validates after the ``--validate`` recordings: ``args.validate`` then names every validation recording's
    file, ``args.held_out`` the parts (``data.holdout.HeldOutPart``)."""
    from identification.data.robot_recordings import load_robot_recording

    recordings = [load_robot_recording(path, robot, args.topic, layout) for path in paths]
    validation = [load_robot_recording(path, robot, args.topic, layout) for path in args.validate]
    explicit, args.held_out = list(args.validate), []
    if args.holdout is not None:
        recordings, held, args.held_out = cut_training(recordings, paths, args.holdout, args.cutoff)
        validation, args.validate = [*validation, *held], [*explicit, *map(str, paths)]
    return recordings, validation, explicit


def _missing_torque(args, robot, paths, recordings, validation) -> tuple:
    """(training, validation recordings with their joints without torque marked, the validation's sentences): the
    ``--missing-torque`` statements and the columns found empty (``missing_torque``); the fit names its own."""
    from identification.data.missing_torque import (
        find_missing_torque,
        missing_torque_messages,
        parse_missing_torque,
        stated_missing_torque,
    )

    stated = parse_missing_torque(args.missing_torque, robot.joint_names)
    unknown = sorted(set(stated) - {Path(p).name for p in (*paths, *args.validate)})
    if unknown:
        raise ParameterError(
            f"--missing-torque names {unknown}, which is not among the --data or --validate recordings; name one of "
            "those files (FILE:JOINTS)."
        )
    marked = [
        [find_missing_torque(stated_missing_torque(r, p, stated)) for r, p in zip(group, names)]
        for group, names in ((recordings, paths), (validation, args.validate))
    ]
    if args.friction == "lugre" and any(r.missing_torque for group in marked for r in group):
        raise ParameterError(
            "--friction lugre fits every joint's friction along its whole series; a recording misses a joint's "
            "torque. Leave that recording out, or identify with --friction stribeck."
        )
    return marked[0], marked[1], missing_torque_messages(marked[1], robot.joint_names, "validation")


def _configurations(data, robot) -> tuple:
    """(recording paths, one PayloadConfiguration each) of --data: manifests expanded, sidecars read, the files
    of a split recording named once (by their folder, ``robot_recordings.recording_paths``)."""
    from identification.data.configuration import recordings_with_configurations
    from identification.data.robot_recordings import recording_paths

    merged = {}
    for path, configuration in zip(*recordings_with_configurations(data)):
        merged.setdefault(recording_paths([path], robot)[0], configuration)
    return list(merged), list(merged.values())


def _check_reversals(recordings, paths) -> None:
    """Refuse, before any work, a recording in which a joint does not slide both ways: LuGre friction is fitted
    along the reversals (``friction.models.check_slides_both_ways`` on the velocity of the recorded positions)."""
    from identification.friction.models import check_slides_both_ways
    from psdm_casadi.errors import InsufficientExcitationError

    for recording, path in zip(recordings, paths):
        qd = np.gradient(recording.q, recording.t, axis=0)
        for j in range(recording.n_dof):
            try:
                check_slides_both_ways(qd[:, j], owner=f"{path} joint {j + 1}")
            except InsufficientExcitationError as exc:
                raise InsufficientExcitationError(
                    f"--friction lugre: {exc} LuGre friction is fitted along the reversals of every joint; or "
                    "pass --friction stribeck."
                ) from None
