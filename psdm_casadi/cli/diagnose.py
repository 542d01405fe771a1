"""The ``psdm diagnose`` subcommand: nominal model from a training recording, missing physics on training and
validation.
"""

from __future__ import annotations

from pathlib import Path

from psdm_casadi.cli.checks import add_robot_argument, add_topic_argument, load_robot_argument, output_folder
from psdm_casadi.cli.output import print_json


def register(subparsers) -> None:
    """Add ``diagnose`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="find physics missing from the model of a robot (spring, payload, offset, ripple, delay, ...)",
        description=(
            "Identify the nominal model (the robot file's rigid body + friction) on the training recording, fit "
            "candidate physics terms jointly with it, keep those that lower the validation error enough to earn "
            "their parameters, and report them most important first with per-joint validation RMSE before/after."
        ),
    )
    add_robot_argument(p)
    p.add_argument("--train", required=True, help="training recording (.csv, .npz, .mat, or a ROS 2 bag)")
    p.add_argument("--validate", required=True, help="validation recording (.csv, .npz, .mat, or a ROS 2 bag)")
    add_topic_argument(p)
    p.add_argument(
        "--friction",
        choices=("lugre", "coulomb_viscous"),
        default="lugre",
        help="nominal friction: steady-state LuGre with the robot file's shape (+ its bristle dynamics "
        "when the file has drives), or Coulomb + viscous",
    )
    p.add_argument(
        "--rigid-body",
        choices=("prior", "identified"),
        default="prior",
        help="keep the robot file's inertia (default) or identify the base parameters too",
    )
    p.add_argument("--cutoff", type=float, default=15.0, help="low-pass cut-off of the preprocessing [Hz]")
    p.add_argument(
        "--min-improvement",
        type=float,
        default=0.2,
        help="validation RMSE reduction a joint must show for a term to be kept (default 0.2)",
    )
    p.add_argument("--max-effects", type=int, default=4, help="most effects reported (default 4)")
    p.add_argument("--out", default=None, help="folder for report.md, report.json, plots and the augmented model")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --out")
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.set_defaults(handler=_run_diagnose)


def _run_diagnose(args) -> int:
    from identification.data.io import load_recording
    from identification.diagnosis.diagnose import DiagnosisOptions, diagnose

    folder = _out_folder(args)  # refused before any work: an existing report, a file, an unwritable folder
    robot = load_robot_argument(args)
    train = load_recording(args.train, robot.n_dof, robot.joint_names, args.topic)
    validation = load_recording(args.validate, robot.n_dof, robot.joint_names, args.topic)
    options = DiagnosisOptions(
        friction=args.friction,
        rigid_body=args.rigid_body,
        cutoff_hz=args.cutoff,
        min_improvement=args.min_improvement,
        max_effects=args.max_effects,
    )
    # progress lines come from the diagnosis loggers, shown on stderr by the handler of ``configure_logging``
    report = diagnose(robot, train, validation, options)
    paths = {}
    if folder is not None:
        with folder.staging() as stage:
            paths = {key: folder.target / Path(p).name for key, p in report.save(stage).items()}
    if args.json:
        payload = report.to_dict()
        payload["command"] = "diagnose"
        payload["files"] = {k: str(v) for k, v in paths.items()}
        print_json(payload)
    else:
        print(report.to_markdown(paths))
    return 0


def _out_folder(args):
    """The checked --out folder (None without --out): new, or one holding an earlier diagnosis with --overwrite."""
    from identification.diagnosis.report import REPORT_FILES

    return None if args.out is None else output_folder(args.out, REPORT_FILES, args.overwrite)
