"""The ``psdm diagnose`` subcommand: nominal model from a training recording, missing physics on training and
validation; with a calibrated model and ``--apply NEW.json``, the findings identified jointly with it.
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path

from psdm_casadi.cli.checks import (
    add_robot_argument,
    add_topic_argument,
    check_count,
    check_not_input,
    check_positive,
    command_model,
    load_robot_argument,
    model_layout,
    output_folder,
)
from psdm_casadi.cli.diagnose_loads import stated_loads, validation_loads
from psdm_casadi.cli.diagnose_train import (
    TRAIN_HELP,
    check_recordings_exist,
    pooled_training,
    read_more_training,
    training_paths,
)
from psdm_casadi.cli.holdout import add_holdout_argument, holdout_fraction
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, print_json, report_model_warnings
from psdm_casadi.cli.recalibration_text import ALONE, adds_nothing, apply_refusal, recalibration_markdown
from psdm_casadi.cli.torque_scale_step import diagnose_torque_scales
from psdm_casadi.errors import ParameterError
from psdm_casadi.log_context import held_back
from psdm_casadi.state_cache import remembering

#: The loggers of identify's fits whose progress lines ("identify: N samples of K recording(s) ...", the Stribeck
#: velocities, the drive inertias inside the base parameters) each of diagnose's refits repeats: not diagnose's lines
#: (its report states the preparation once, and what a refit found).
IDENTIFY_FIT_LOGGERS = ("identification.calibration.trajectory_fit", "identification.calibration.stribeck",
                        "identification.calibration.merged_rotors")  # fmt: skip

VALIDATE_HELP = (
    "validation recording(s) (.csv, .npz, .mat, or a ROS 2 bag); without, the part of --train held out (--holdout, or "
    "the cut of a model identified with --holdout) and the model's other held-out parts. With several, a finding is "
    "kept only if it holds on each (the errors are reported on the first); with one, a block cross-validation of "
    "--train is the second opinion. Findings that flip are listed as unstable, not as missing physics"
)

DESCRIPTION = (
    "Identify the nominal model (the robot file's rigid body + friction) on the training recording, fit "
    "candidate physics terms jointly with it, keep those that lower the validation error enough to earn "
    "their parameters, and report them most important first with per-joint validation RMSE before/after. "
    "Given a calibrated model (.json from 'psdm identify') instead of a robot, the nominal model is the "
    "file's: its kinematics, identified inertia (rigid body fixed), torque offsets and its friction per joint "
    "(Coulomb + viscous or Stribeck with its vs, LuGre with its bristle dynamics; amplitudes refitted); "
    "--apply NEW.json then identifies the model again on its own training recordings (found again by their "
    "content) and every --train with the findings' terms fitted jointly "
    "(signal findings such as a delay correct the recordings; a LuGre model is identified again as 'psdm "
    "identify --friction lugre' does, and takes torque findings only), judges it on --validate as "
    "'psdm validate' does, shows the calibration before and after, and writes the calibrated model with its "
    "findings."
)

ENVELOPE_HELP = (
    "with --rigid-body auto: judge the findings against the free rigid-body recalibration only (by default a finding "
    "it makes unnecessary still stands where a rigid body recalibrated inside its physical envelope, as 'psdm "
    "identify' fits it, needs it: a counterbalance only a link twice as heavy would absorb)"
)


def register(subparsers) -> None:
    """Add ``diagnose`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="find physics missing from the model of a robot (spring, payload, offset, ripple, delay, ...)",
        description=DESCRIPTION,
    )
    add_robot_argument(
        p,
        help="robot file (.toml, .urdf, .xml MJCF), built-in robot name, or calibrated model (.json, 'psdm identify')",
    )
    p.add_argument("--train", required=True, nargs="+", metavar="RECORDING", help=TRAIN_HELP)
    p.add_argument("--validate", nargs="+", metavar="RECORDING", help=VALIDATE_HELP)  # or held out: _held_out
    add_holdout_argument(p, "diagnose")
    add_topic_argument(p)
    p.add_argument(
        "--friction",
        choices=("lugre", "coulomb_viscous", "stribeck"),
        default=None,
        help="nominal friction: steady-state LuGre with the robot file's shape (+ its bristle dynamics "
        "when the file has drives; the default for a robot), Coulomb + viscous, or the steady-state curve alone "
        "(stribeck). A calibrated model's default is its own shape: coulomb_viscous, stribeck (its vs), or lugre "
        "(its identified parameters, bristle dynamics included)",
    )
    p.add_argument(
        "--rigid-body",
        choices=("auto", "prior", "identified"),
        default="auto",
        help="auto (default): a payload or inertia finding must beat a full rigid-body recalibration on the "
        "validation recording, otherwise the base parameters are identified and the report says the robot file's "
        "inertial parameters are off; prior: keep the robot file's inertia; identified: identify them too",
    )
    p.add_argument("--no-envelope", action="store_true", help=ENVELOPE_HELP)
    p.add_argument(
        "--no-sparse",
        action="store_true",
        help="do not look beyond the library (no sparse symbolic term for a residual that stays structured)",
    )
    p.add_argument("--cutoff", type=float, default=None,
                   help="low-pass cut-off of the preprocessing [Hz] (default: a calibrated model's own preparation; "
                   "for a robot file the one 'psdm identify' would choose, min(10 Hz, rate/10))")  # fmt: skip
    p.add_argument(
        "--min-improvement",
        type=float,
        default=0.2,
        help="validation RMSE reduction a joint must show for a term to be kept (default 0.2)",
    )
    p.add_argument("--max-effects", type=int, default=4, help="most effects reported (default 4)")
    p.add_argument(
        "--max-samples",
        type=int,
        default=250_000,
        help="most samples of a recording's diagnosis grid (default 250000: 41 minutes on identify's 100 Hz grid; "
        "longer recordings are decimated further, which bounds memory and time)",
    )
    p.add_argument("--out", default=None, help="folder for report.md, report.json, plots and the augmented model")
    p.add_argument(
        "--apply",
        default=None,
        metavar="NEW_MODEL.json",
        help="with a calibrated model: identify it again with the findings and write the new calibrated model here",
    )
    p.add_argument(
        "--allow-inconsistent",
        action="store_true",
        help="with --apply: write the new model even if it is not physically consistent (marked as such)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --out (and --apply)")
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.set_defaults(handler=_run)


def _held_out(validations) -> list:
    """The validation recordings (``--validate`` and the held-out parts); none is refused naming why and how to have
    one, rather than argparse's "the following arguments are required" (a user with one recording met only that)."""
    if validations:
        return validations
    raise ParameterError(
        "--validate is missing: the diagnosis keeps a finding only if it predicts a recording it was not fitted on. "
        "Pass another recording of the robot, --validate B.csv (a different motion); with one recording only, hold "
        "out its last part: --holdout 0.3 (the first 70 % trains, the rest validates)."
    )


def _run(args) -> int:
    """``psdm diagnose``, its refits' progress lines of ``psdm identify`` held back (``IDENTIFY_FIT_LOGGERS``)."""
    with held_back(*IDENTIFY_FIT_LOGGERS):
        return _run_diagnose(args)


@remembering()  # the recordings' regressors evaluated once across the refits (state_cache)
def _run_diagnose(args) -> int:
    from identification.data.filter_choice import AUTO
    from identification.data.io import not_held_out
    from identification.data.missing_torque import find_missing_torque
    from identification.diagnosis.diagnose import DiagnosisOptions
    from identification.diagnosis.model_file import diagnose_model_prior

    (args.train, args.more_train), args.validate = training_paths(args), list(args.validate or ())
    fraction = _fraction(args)
    _check_numbers(args)
    folder = _out_folder(args)  # refused before any work: an existing report, a file, an unwritable folder
    loaded, apply_out = _calibrated_source(args)
    calibrated = model = robot_file = None
    if loaded is not None:  # the robot here reads and checks the recordings (its kinematics and drives)
        from identification.calibration.calibrated_model import calibrated_robot

        calibrated, robot_file, model = loaded.calibrated, loaded.robot, loaded.model
        robot = calibrated_robot(calibrated, robot_file)
    else:
        robot = load_robot_argument(args)
        check_recordings_exist([args.train, *args.more_train, *args.validate])
    layout = model_layout(args, None if calibrated is None else calibrated.document, "diagnose")  # --columns, --rate
    train, validations, given, held = _recordings(args, robot, calibrated, layout, fraction)  # held: sentences
    if calibrated is not None:  # each validation recording's load: named by the payload check, not twice
        report_model_warnings("diagnose", args.robot, calibrated, args.validate)
    # a dead torque channel: that joint is left out of the diagnosis (``missing_torque.measured_torque``), named
    train, *validations = (find_missing_torque(r) for r in (train, *validations))
    validation = validations[0]
    for warning in not_held_out([args.train, *args.more_train], given, "--train"):
        print(f"psdm diagnose: warning: {warning}", file=sys.stderr)
    preparation = _preparation(args, calibrated, train)
    if loaded is None:  # a torque constant the known payload finds off: the currents read with its value
        robot, scaled = diagnose_torque_scales(args, robot, (train, *validations), preparation.cutoff_hz)
    (train, *validations), stated, checks = stated_loads(args, loaded, robot, (train, *validations), preparation)
    validation = validations[0]
    options = DiagnosisOptions(  # "auto" friction: the robot file's (nominal_friction) or the model file's own shape
        friction=args.friction or AUTO,
        rigid_body=args.rigid_body,
        cutoff_hz=preparation.cutoff_hz,
        rate_hz=preparation.grid_rate_hz,
        edge_periods=preparation.edge_periods,
        min_improvement=args.min_improvement,
        max_effects=args.max_effects,
        max_samples=args.max_samples,
        sparse=not args.no_sparse,
        envelope=not args.no_envelope,
    )
    # progress lines come from the diagnosis loggers, shown on stderr by the handler of ``configure_logging``
    if loaded is None:
        report = _robot_report(args, robot, train, validations, options, scaled)
    else:  # the Python API's diagnosis of a model file (diagnose_model): the same numbers
        refit = _file_refit(args, loaded, robot, layout, train)
        trains = [train, *pooled_training(args, loaded, robot, preparation.cutoff_hz)]  # pooled in the diagnosis
        report, prior = diagnose_model_prior(loaded, trains, validations, options, name=args.robot, refit=refit)
        if prior.note():  # which rigid body the diagnosis started from, and why (also in the rigid-body notes)
            print(f"psdm diagnose: note: {args.robot}: {prior.note()}.", file=sys.stderr)
    report = dataclasses.replace(report, preparation=preparation.text(), held_out=held)
    apply = ApplyRefit()  # --apply's refit
    if apply_out is not None and report.findings and not report.nothing_applied:  # its "after": the model written
        report, apply = _recalibration(args, calibrated, robot_file, model, report, (train, validation), stated[:1])
    loads, temperature = validation_loads(args, calibrated, robot, model, validations, checks)  # each by its file
    judged = "psdm validate" if calibrated is not None else "psdm identify judges its held-out recordings"
    found = tuple(load.sentence() for load in loads if load.load is not None)  # in report.md too, and printed
    report = dataclasses.replace(report, payload_check=found, payload_check_as=judged,
                                 payload_checks=tuple(load.to_dict() for load in loads),
                                 friction_temperature=temperature)  # fmt: skip
    paths = {}
    if folder is not None:
        with folder.staging() as stage:
            paths = {key: folder.target / Path(p).name for key, p in report.save(stage).items()}
    if args.json:
        payload = report.to_dict()
        payload["command"] = "diagnose"
        payload["files"] = {k: str(v) for k, v in paths.items()}
        if apply_out is None:
            print_json(payload)
    else:
        print(report.to_markdown(paths))
    if apply_out is None:
        return 0
    return _apply(args, calibrated, robot_file, apply, apply_out, payload if args.json else None, report)


def _check_numbers(args) -> None:
    """Refuse (exit 2) a count or a cutoff no diagnosis can use, before any work."""
    check_count(args.max_effects, "--max-effects", "Use --max-effects 4 (the default).", minimum=0)
    check_count(args.max_samples, "--max-samples", "Use --max-samples 250000 (the default).", minimum=1000)
    if args.cutoff is not None:
        fix = "Leave --cutoff out (the model's own preparation) or give e.g. --cutoff 10."
        check_positive(args.cutoff, "--cutoff", fix, " [Hz]")


def _fraction(args) -> float | None:
    """The checked ``--holdout``; a robot file without it and without ``--validate`` is refused before any work (a
    model file may hold its own held-out parts)."""
    fraction = holdout_fraction(args)
    if not args.validate and fraction is None and not str(args.robot).lower().endswith(".json"):
        _held_out([])
    return fraction


def _recordings(args, robot, calibrated, layout, fraction) -> tuple:
    """(training recording, validation recordings, the ``--validate`` paths, the report's sentences on the parts held
    out (``holdout.held_out_sentences``)): joint side, timed (the robot file's [recording]); ``--train`` cut at
    ``--holdout`` or where the model file cut it, its held-out part (and without ``--validate`` the model's others)
    after the ``--validate`` recordings. ``args.validate`` then names every validation recording's file,
    ``args.held_parts`` the parts, ``args.more`` the other ``--train`` recordings as (path, raw recording), each cut as
    the first (``holdout.other_training_parts``: then (path, training part, HeldOutPart), its held-out part a
    validation recording of its own)."""
    from identification.data.holdout import diagnose_parts, held_out_sentences, other_training_parts
    from identification.data.robot_recordings import load_robot_recording

    def load(path):
        return load_robot_recording(path, robot, args.topic, layout)

    given = list(args.validate)
    document = None if calibrated is None else calibrated.document
    train, held = diagnose_parts(args.train, load(args.train), document, fraction, load, bool(given), args.robot)
    more = read_more_training(args.more_train, load, robot)  # the refit's other --train recordings, read once
    args.more, others = other_training_parts(more, document, fraction, bool(given), args.robot)
    held += others  # each --train's held-out part validates on its own
    validations = _held_out([*map(load, given), *(recording for _, recording, _ in held)])
    args.validate, args.held_parts = [*given, *(path for path, _, _ in held)], [part for _, _, part in held]
    return train, validations, given, held_out_sentences([args.train, *args.more_train], held)


def _file_refit(args, loaded, robot, layout, train):
    """``model_file.file_refit``: the recordings the model with the findings trains on, the model file's own read as
    ``--train`` is (``refit_training``), ``train`` and the other ``--train`` recordings, found when a finding is
    applied."""
    from identification.data.robot_recordings import load_robot_recording
    from identification.diagnosis.model_file import file_refit

    def load(path):
        return load_robot_recording(path, robot, args.topic, layout)

    return file_refit(loaded, args.robot, train, args.train, load, args.more)


def _robot_report(args, robot, train, validations, options, scaled: str = ""):
    """``diagnose`` of a robot file, the report naming it as its nominal model (``scaled``: the torque constants the
    known payload corrected, ``torque_scale_step``)."""
    from identification.diagnosis.diagnose import diagnose

    report = diagnose(robot, train, validations, options, derive=lambda r: command_model(args, r))
    rigid = "from it" if report.rigid_body == "prior" else "identified"
    return dataclasses.replace(report, nominal_model=f"the robot file {args.robot}: rigid body {rigid}{scaled}")


def _preparation(args, calibrated, train):
    """The preparation of the diagnosis: the model file's own, identify's default for a robot file, or --cutoff."""

    from identification.calibration.model_preparation import (
        SAMPLES_PER_CUTOFF,
        default_preparation,
        model_preparation,
    )

    own = model_preparation(calibrated.document) if calibrated is not None else default_preparation(train)
    if own.note:
        print(f"psdm diagnose: note: {args.robot}: {own.note}", file=sys.stderr)
    if args.cutoff is None:
        return own
    cutoff = float(args.cutoff)
    source = f"--cutoff {cutoff:g}, instead of the {own.source}'s {own.cutoff_hz:g} Hz"
    return dataclasses.replace(own, cutoff_hz=cutoff, grid_rate_hz=SAMPLES_PER_CUTOFF * cutoff, source=source)


def _calibrated_source(args):
    """(LoadedModel or None, checked --apply output or None): a .json source is a calibrated model."""
    from psdm_casadi.cli.checks import check_suffix, output_file, read_calibrated_argument

    if not str(args.robot).lower().endswith(".json"):
        if args.apply is not None:
            raise ParameterError(
                f"diagnose --apply needs a calibrated model (.json from 'psdm identify') as its first argument; got "
                f"{args.robot!r}. Identify the robot first: psdm identify ROBOT --data A.csv --out model.json."
            )
        return None, None  # the recordings are checked once the robot file and its --lock are read (cheap)
    if getattr(args, "lock", None):
        raise ParameterError(
            f"diagnose --lock must not be given with a calibrated model; got {args.robot!r}, which holds its locked "
            "joints. Drop --lock."
        )
    if args.apply is not None:
        check_not_input(args.apply, "--apply", _inputs(args), example=f"{Path(args.apply).stem}_applied.json")
        check_suffix(args.apply, "--apply", (".json",), "a calibrated-model file (JSON)")
    if Path(args.robot).exists():  # cheap errors first: the options, the files, then the model read
        check_recordings_exist([args.train, *args.more_train, *args.validate])
    return read_calibrated_argument(args, args.robot), output_file(args.apply, "--apply", args.overwrite)


@dataclass(frozen=True)
class ApplyRefit:
    """What ``--apply``'s refit gave (``_recalibration``): the ``Recalibration`` (``result``; None without a finding
    to apply), or the sentence refusing the findings (``refusal``, naming the model and the output), which is the
    command's error once the report is out: the report says what was found even when it cannot be applied."""

    result: object = None
    refusal: str = ""

    def raise_refusal(self) -> None:
        """Raise the refusal, if any, as a ``ParameterError`` (exit 2, one line on stderr)."""
        if self.refusal:
            raise ParameterError(self.refusal)


def _recalibration(args, calibrated, robot, model, report, recordings, configurations) -> tuple:
    """(report, :class:`ApplyRefit`) of ``--apply``: the model the report's "after" describes
    (``DiagnosisReport.applied``) judged by the never-worse gate, and the report whose "after" is the model written
    (``with_written_after``); or the report as it is and the refit's refusal of the findings."""
    import warnings

    from identification.calibration.lugre_recordings import LuGreWarning
    from identification.calibration.recalibrate import recalibrate
    from identification.data.torque_constants import recording_kt
    from identification.diagnosis.applied_after import with_written_after

    if report.refit_training is not None:  # the recordings the report's "after" trained on (refit_training)
        recordings = (list(report.refit_training.recordings), recordings[1])
    try:
        with warnings.catch_warnings(record=True) as caught:  # a LuGre model's refit says what it cannot determine
            warnings.simplefilter("always", LuGreWarning)
            result = recalibrate(calibrated, robot, model, report, *recordings, robot_source=None,
                                 configurations=configurations, applied=report.applied)  # fmt: skip
    except ParameterError as exc:  # name the input: the model the findings were to be applied to; after the report
        return report, ApplyRefit(refusal=apply_refusal(exc, args.robot, args.apply))
    for message in dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, LuGreWarning)):
        print(f"psdm diagnose: warning: {message}", file=sys.stderr)
    for w in caught:  # the others as they were
        if not issubclass(w.category, LuGreWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    validation = recordings[1]
    kt = recording_kt(robot, validation)
    written = not adds_nothing(calibrated.document, result.after.document)  # else the report says nothing was written
    report = with_written_after(report, result, model, validation, kt, written)
    return _apply_outcome(args, report, result, written), ApplyRefit(result)


def _apply_outcome(args, report, result, written: bool):
    """``report`` saying whether ``--apply`` writes its file (``apply_file``) or nothing (``apply_refused``), as
    ``_apply`` decides after the report is saved: its page's next step names the file to use."""
    from identification.calibration.recalibrate import consistency_failure

    inconsistent = consistency_failure(result) is not None and not args.allow_inconsistent
    if result.refused is None and written and not inconsistent:
        return dataclasses.replace(report, apply_file=str(args.apply))
    return dataclasses.replace(report, apply_refused=True)


def _apply(args, calibrated, robot, refit: ApplyRefit, out, payload, report) -> int:
    """Gate on consistency, write the new model, show before and after (``refit``: ``_recalibration``'s); the new
    file's training recordings are those its refit trained on (``report``'s)."""
    from identification.calibration.recalibrate import consistency_failure

    refit.raise_refusal()  # the findings refused: said now that the report is out
    result = refit.result
    if result is None:
        why = report.nothing_applied or "no finding"
        print(f"psdm diagnose: nothing to apply: {why}; {args.apply!r} was not written.", file=sys.stderr)
        if payload is not None:
            print_json(payload)
        return 0
    if result.refused is not None:  # the never-worse gate: no subset of the findings keeps every joint (its
        # refit is the model before, which adds nothing: refused, not 'nothing to apply')
        print(f"psdm diagnose: error: {result.refused}. Nothing was written to {args.apply!r}.", file=sys.stderr)
        if payload is not None:
            payload["recalibration"] = {"refused": result.refused, "model": None,
                                        **result.after.document["recalibration"]["never_worse"]}  # fmt: skip
            print_json(payload)
        return EXIT_CHECK_FAILED
    if adds_nothing(calibrated.document, result.after.document):  # a refit with nothing added: the model file stays
        if payload is not None:
            payload["recalibration"] = dict(result.after.document["recalibration"], model=None)
            print_json(payload)
        else:
            trained_on = report.refit_training.short() if report.refit_training is not None else ALONE
            print(recalibration_markdown(result, robot.joint_names, args.apply, args.robot, trained_on))
        return 0
    problem = consistency_failure(result)
    if problem is not None and not args.allow_inconsistent:
        print(
            f"psdm diagnose: error: {problem}. Nothing was written to {args.apply!r}. Pass --allow-inconsistent "
            "to write it marked as such.",
            file=sys.stderr,
        )
        return EXIT_CHECK_FAILED
    read = calibrated.document.get("provenance", {}).get("columns")  # how identify read the recordings: kept
    result.after.document["provenance"].update({} if read is None else {"columns": read})
    refitted = not result.after.document["recalibration"].get("resized_alone")  # else the file's, nothing refitted
    if report.refit_training is not None and refitted:  # a later refit of the new file finds them again
        result.after.document["provenance"]["recordings"] = [dict(e) for e in report.refit_training.entries]
        if report.refit_training.friction_drift is not None:  # trained on the same corrected torques: its refit too
            result.after.document["identification"]["friction_drift"] = report.refit_training.friction_drift
    if args.held_parts:  # the refit trained without them too: validate and diagnose of the new file reuse them
        from identification.data.holdout import holdout_block

        result.after.document["identification"]["holdout"] = holdout_block(args.held_parts)
    with out.staging() as stage:
        result.after.save(stage, overwrite=True, allow_inconsistent=True)
    report_model_warnings("diagnose", args.apply, result.after)  # the refit's, stored in the new file too
    if payload is not None:
        payload["recalibration"] = dict(result.after.document["recalibration"], model=str(args.apply))
        print_json(payload)
    else:
        print(recalibration_markdown(result, robot.joint_names, args.apply))
    return 0


def _out_folder(args):
    """The checked --out folder (None without --out): new, or one holding an earlier diagnosis with --overwrite."""
    from identification.diagnosis.report import REPORT_FILES

    if args.out is None:
        return None
    folder = output_folder(args.out, REPORT_FILES, args.overwrite, command="diagnose")
    check_not_input(args.out, "--out", _inputs(args))
    return folder


def _inputs(args) -> tuple:
    """The files ``psdm diagnose`` reads, which no output may replace."""
    trains = (("--train", path) for path in (args.train, *args.more_train))
    return (("ROBOT", args.robot), *trains, *(("--validate", path) for path in args.validate))
