"""The ``psdm identify`` subcommand: a calibrated model from exciting recordings, or the paper's four steps.

Recording files (``--data A.csv B.csv``) take the everyday route of ``identify_recordings``; a folder
of the paper's calibration experiments (``--data DIR``) runs the four-step pipeline. ``--protocol``
makes the choice explicit.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from psdm_casadi.cli import identify_recordings
from psdm_casadi.cli.checks import add_robot_argument, check_not_input, load_robot_argument, output_folder
from psdm_casadi.cli.holdout import add_holdout_argument
from psdm_casadi.cli.html_report import add_html_argument, refuse_html_option
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, print_json, progress
from psdm_casadi.errors import ParameterError
from psdm_casadi.fileio import atomic_write, markdown_escape
from psdm_casadi.near_names import did_you_mean

__all__ = ["register", "REPORT_FILES"]

#: What ``psdm identify`` writes besides the model files (``--overwrite`` replaces these and nothing else).
REPORT_FILES = ("report.md", "validation_all.png")


def register(subparsers) -> None:
    """Add ``identify`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "identify",
        help="identify a calibrated model from exciting recordings (or the paper's four calibration steps)",
        description=(
            "Recordings (--data A.csv [B.csv ...], joint torques or currents; columns t, q1..qn, tau1..taun or "
            "i1..in): filter them (cutoff min(10 Hz, rate/10), stated), choose from the data the friction shape "
            "(Coulomb-viscous or Stribeck), a torque offset per joint and the drive-inertia columns (stated; "
            "--friction, --offset, --drive-inertia override), fit base parameters, friction, offsets and drive "
            "inertias by weighted least squares, then physically consistent "
            "standard parameters (positive-definite pseudo-inertias), validate on --validate recordings, and "
            "write one calibrated-model file (--out model.json). A folder (--data DIR, or --protocol four-step) "
            "runs the paper's four calibration steps (motor, gravity, friction, inertial) on its experiments "
            "(payload.json, motor_j<k>_nominal/_payload, gravity, friction_j<k>, excitation) into --out DIR. "
            "A model that is not physically consistent is not saved (exit 1) unless --allow-inconsistent. "
            "Recordings logged on the motor side (encoder angles, motor torques or currents, gears and coupled "
            "joints) are mapped to the joints as the robot file's [transmission] and [recording] tables say; a "
            "folder holding the files of its [recording].files is one recording (see examples/staubli_tx40.toml)."
        ),
    )
    add_robot_argument(p)
    p.add_argument(
        "--data",
        "--train",
        dest="data",
        required=True,
        nargs="+",
        metavar="RECORDING",
        help="recordings (.csv, .npz, .mat, ROS 2 bags), or one data directory (--train: the same option, as "
        "'psdm diagnose' names its training recordings). A recording's payload at the flange "
        'is stated beside it in A.payload.json: {"mass": 2.8, "com": [0, 0, 0.05]} (known; optional "inertia" about '
        'the centre of mass), {"unknown": "gripper"} (identified, shared by the files that name it) or {"mass": 0}; '
        "or pass a configurations.toml listing [[configuration]] name, payload, recordings",
    )
    p.add_argument(
        "--protocol",
        choices=("auto", "recordings", "four-step"),
        default="auto",
        help="recordings (exciting trajectories) or four-step (the paper's experiments in a folder); "
        "auto: four-step for one folder, recordings otherwise",
    )
    p.add_argument("--out", required=True, help="calibrated-model file (.json), or a folder for the four-step route")
    p.add_argument("--model", default=None, help="derived PSDM model (.npz from 'psdm derive'); derived when omitted")
    p.add_argument("--no-refine", action="store_true", help="skip the joint refinement")
    p.add_argument(
        "--plots",
        action="store_true",
        help="four-step route: also write observed-vs-predicted plots (PNG) into --out (on recordings use "
        "'psdm validate MODEL RECORDINGS --plots DIR')",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the model file, or the files an earlier 'psdm identify' wrote in the --out folder (listed in "
        "its .psdm-manifest.json); never an input of the command",
    )
    p.add_argument(
        "--allow-inconsistent",
        action="store_true",
        help="save a model that fails the consistency check (mass matrix not positive definite), marked as such",
    )
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    identify_recordings.add_arguments(p)
    add_holdout_argument(p, "identify")
    add_html_argument(p)
    p.set_defaults(handler=_run_identify)


def _not_experiments(folder: Path) -> str:
    """Why a folder given alone is not read: it is not the paper's experiments (no payload.json), and what to pass."""
    files = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
    shown = ", ".join(files[:8]) + (f" and {len(files) - 8} more" if len(files) > 8 else "") if files else "nothing"
    return (f"--data {str(folder)!r} is a folder but not one of the paper's calibration experiments (it has no "
            f"payload.json; it holds {shown}). Pass the recording files themselves (.csv, .npz, .mat, .mcap/.db3: "
            f"--data run1.csv run2.csv), or, for a recording split into one file per signal, state its files in the "
            f"robot file's [recording] table (as examples/staubli_tx40.toml does).")  # fmt: skip


def _protocol(args) -> str:
    from identification.data.rosbag import is_rosbag

    for path in args.data:
        if not Path(path).exists():
            raise FileNotFoundError(
                f"--data {path!r} does not exist. Check the path: pass recording files (.csv, .npz), or the folder "
                f"of the paper's experiments that 'psdm simulate --out' wrote.{did_you_mean(path)}"
            )
    folders = [Path(path).is_dir() and not is_rosbag(path) for path in args.data]  # a bag folder is one recording
    if any(folders):  # so is the folder of a recording the robot file says is split into one file per signal
        from identification.data.robot_recordings import is_split_recording

        robot = load_robot_argument(args)
        folders = [folder and not is_split_recording(path, robot) for folder, path in zip(folders, args.data)]
    protocol = args.protocol
    if protocol == "auto":
        protocol = "four-step" if len(args.data) == 1 and folders[0] else "recordings"
        if protocol == "four-step" and not (Path(args.data[0]) / "payload.json").exists():
            raise FileNotFoundError(_not_experiments(Path(args.data[0])))
    if protocol == "four-step" and not (len(args.data) == 1 and folders[0]):
        raise FileNotFoundError(
            f"--protocol four-step needs one --data folder of the paper's experiments; got {list(args.data)}. "
            "Pass the folder 'psdm simulate --out' wrote, or recording files without --protocol four-step."
        )
    if protocol == "recordings" and any(folders):
        folder = args.data[folders.index(True)]
        raise FileNotFoundError(
            f"--data {folder!r} is a folder; the recordings route takes recording files (.csv, .npz). "
            "Name the files, or pass --protocol four-step for a folder of the paper's experiments."
        )
    return protocol


def _check_inputs(args):
    """--data and --model must exist and --out must be writable, before the derivation and the fit."""
    from identification.calibration.result import RESULT_FILES

    data = Path(args.data[0])
    if len(args.data) != 1 or not data.is_dir():
        raise FileNotFoundError(
            f"--data {args.data[0]!r} is not a folder of recordings. Check the path (see 'psdm simulate --out')."
        )
    if args.model is not None and not Path(args.model).is_file():
        raise FileNotFoundError(f"--model {args.model!r} does not exist. Check the path, or leave --model out.")
    inputs = (("ROBOT", args.robot), ("--data", args.data[0]), ("--model", args.model))
    folder = output_folder(args.out, RESULT_FILES + REPORT_FILES, args.overwrite, command="identify")
    check_not_input(args.out, "--out", inputs)
    return folder


def _run_identify(args) -> int:
    from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
    from psdm_casadi.cli.checks import derive_model
    from psdm_casadi.model import load_model

    if _protocol(args) == "recordings":
        return identify_recordings.run(args)
    refuse_html_option(args, "the four-step route writes report.md into its --out folder")
    if args.holdout is not None:
        raise ParameterError(
            f"--holdout cuts recording files; {args.data[0]!r} is a folder of the paper's calibration experiments, "
            "which validates on its own excitation experiment. Drop --holdout, or pass recording files."
        )
    folder = _check_inputs(args)
    robot = load_robot_argument(args)
    if args.model:
        model = load_model(args.model)
    else:
        progress("identify: deriving the PSDM model ...", quiet=args.json)
        model = derive_model(args, robot)
    options = PipelineOptions(refine=not args.no_refine, quiet=args.json)
    pipeline = IdentificationPipeline(robot, model, options).fit(args.data[0])
    result = pipeline.result_
    consistent = result.consistency is None or result.consistency.consistent
    if not consistent and not args.allow_inconsistent:
        print(
            f"psdm identify: error: the identified model is not physically consistent: {_inconsistency(result)}. "
            f"Nothing was written to {args.out!r}. Check the recordings (excitation, payload), or pass "
            "--allow-inconsistent to save it marked as inconsistent.",
            file=sys.stderr,
        )
        return EXIT_CHECK_FAILED
    if not consistent:
        result = replace(result, metadata={**result.metadata, "inconsistent": _inconsistency(result)})
        print(f"psdm identify: warning: saving an INCONSISTENT model: {_inconsistency(result)}", file=sys.stderr)
    with folder.staging() as stage:
        result.save(stage)
        text = _report_markdown(robot, result)
        atomic_write(stage / "report.md", lambda handle: handle.write(text))
        plots = [folder.target / Path(p).name for p in pipeline.plot(stage)] if args.plots else []
    _print_summary(args, robot, model, result, pipeline, plots)
    return EXIT_OK


def _inconsistency(result) -> str:
    """One sentence on the failed consistency check."""
    c = result.consistency
    return (
        f"the mass matrix is not positive definite at {c.n_violations} of {c.n_samples} configurations "
        f"(smallest eigenvalue {c.min_eigenvalue:.4g} kg m^2)"
    )


def _report_markdown(robot, result) -> str:
    """report.md: the robot, a loud line when the model is inconsistent, and the validation table (names escaped)."""
    lines = [f"# Identified model: {markdown_escape(robot.name)}", ""]
    if "inconsistent" in result.metadata:
        lines += [
            f"**WARNING: INCONSISTENT MODEL: {result.metadata['inconsistent']}. It was saved only because of "
            "--allow-inconsistent; do not use it to simulate or control the robot.**",
            "",
        ]
    table = replace(result.report, joint_names=tuple(markdown_escape(n) for n in result.report.joint_names))
    return "\n".join(lines) + table.to_markdown() + "\n"


def _print_summary(args, robot, model, result, pipeline, plots) -> None:
    if args.json:
        print_json(
            {
                "command": "identify",
                "robot": robot.name,
                "out": str(args.out),
                "kt": result.kt.tolist(),
                "theta": result.theta.tolist(),
                "base_names": list(model.base_names),
                "lugre": [p.as_dict() for p in result.lugre],
                "report": result.report.to_dict(),
                "consistency": result.consistency.to_dict() if result.consistency is not None else None,
                "inconsistent": "inconsistent" in result.metadata,
                "timings": pipeline.timings_,
                "plots": [str(p) for p in plots],
            }
        )
    else:
        print(result.report.to_markdown())
        print(f"identified model written to {args.out}")
