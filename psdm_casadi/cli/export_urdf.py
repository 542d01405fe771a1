"""The ``psdm export-urdf`` subcommand: a calibrated model's identified inertias, friction and drives as a URDF.

``psdm export-urdf model.json robot.urdf`` reads the file ``psdm identify`` wrote and writes
``codegen.urdf_export.render_urdf`` of it: for a URDF robot a copy of its URDF
with the identified bodies, for a DH robot a generated URDF. The output is written atomically and
never replaces a file without ``--overwrite``; a model that is not physically consistent is refused
(exit 1) unless ``--allow-inconsistent``, as ``psdm identify`` does.
"""

from __future__ import annotations

import sys
from pathlib import Path

from psdm_casadi.cli.checks import check_not_input, check_suffix, output_file
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, print_json, progress, report_model_warnings

__all__ = ["check_not_robot_file", "register"]


def register(subparsers) -> None:
    """Add ``export-urdf`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "export-urdf",
        help="write the identified inertias, friction and drive inertias of a calibrated model into a URDF",
        description=(
            "Read a calibrated-model file written by 'psdm identify' and write a URDF with its identified "
            "inertias: for a URDF robot a copy of its URDF in which each moving link carries the identified body "
            "of its joint (links merged into that body by fixed or locked joints get mass 0), for a DH robot a "
            "generated chain of links. Each inertial is given in its link frame about the centre of mass; joints "
            "get <dynamics damping=fv friction=fc>; drive inertias (armature) are written as comments, since "
            "URDF has no field for them and Pinocchio's URDF parser does not read one. Friction shapes and findings "
            "URDF cannot hold (Stribeck, LuGre, the torque terms and measurement corrections of 'psdm diagnose "
            "--apply') are left out with a warning, their parameters in comments."
        ),
    )
    p.add_argument("model", help="calibrated-model file (.json) written by 'psdm identify'")
    p.add_argument("out", help="URDF file to write (.urdf)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing output file (never MODEL, nor the robot file MODEL was identified from)",
    )
    p.add_argument(
        "--allow-inconsistent",
        action="store_true",
        help="write a model that is not physically consistent (marked as such in the file)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=_run_export_urdf)


def check_not_robot_file(args, calibrated) -> None:
    """OUT must not replace the robot file MODEL was identified from (its text is stored in MODEL, not its path):
    an existing OUT named as one of those files, or holding the same text, is refused even with --overwrite."""

    from psdm_casadi.errors import ParameterError

    files = (calibrated.document.get("robot") or {}).get("files") or {}
    path = Path(args.out).expanduser()
    if not path.is_file():
        return
    same_name = path.name in files
    if not same_name and path.stat().st_size > 10_000_000:
        return
    if same_name or path.read_text(errors="replace") in files.values():
        raise ParameterError(
            f"OUT {str(args.out)!r} is (or shares its name with) the robot file {args.model!r} was identified from; "
            f"--overwrite never replaces an input. Name another file, e.g. {path.stem}_identified{path.suffix}."
        )


def _run_export_urdf(args) -> int:
    from codegen.target_holds import findings_not_representable, friction_not_representable
    from codegen.urdf_export import render_urdf
    from psdm_casadi.cli.checks import read_calibrated_argument

    check_not_input(args.out, "OUT", [("MODEL", args.model)], example=f"{Path(args.model).stem}.urdf")
    check_suffix(args.out, "OUT", (".urdf",), "a URDF")
    out = output_file(args.out, "OUT", args.overwrite)
    loaded = read_calibrated_argument(args, args.model)
    calibrated = loaded.calibrated
    report_model_warnings("export-urdf", args.model, calibrated)
    check_not_robot_file(args, calibrated)
    eigenvalue = calibrated.document["standard"]["min_pseudo_inertia_eigenvalue"]
    checked = calibrated.document["standard"].get("checked", True)
    if checked and not calibrated.consistent and not args.allow_inconsistent:
        print(
            f"psdm export-urdf: error: the calibrated model {args.model!r} is not physically consistent (smallest "
            f"pseudo-inertia eigenvalue {eigenvalue}). Nothing was written to {args.out!r}. Re-identify it, or pass "
            "--allow-inconsistent to write it marked as inconsistent.",
            file=sys.stderr,
        )
        return EXIT_CHECK_FAILED
    robot = loaded.robot
    progress(f"export-urdf: writing the identified inertias of {robot.name} ...", quiet=args.json)
    text = render_urdf(calibrated, robot)
    if not calibrated.consistent:
        print("psdm export-urdf: warning: writing an INCONSISTENT model (marked in the file)", file=sys.stderr)
    for left_out in (friction_not_representable(calibrated), findings_not_representable(calibrated)):
        if left_out is not None:
            print(f"psdm export-urdf: warning: {left_out}", file=sys.stderr)
    with out.staging() as stage:
        stage.write_text(text)
    source = "urdf" if robot.urdf_path is not None else "dh"
    if args.json:
        print_json({"command": "export-urdf", "model": str(args.model), "out": str(args.out), "robot": robot.name,
                    "source": source, "consistent": calibrated.consistent, "min_pseudo_inertia_eigenvalue": eigenvalue,
                    "locked_joints": list(robot.locked_joints)})  # fmt: skip
    else:
        kind = "a copy of its URDF" if source == "urdf" else "a URDF generated from its DH table"
        print(f"{robot.name}: identified inertias of {robot.n_dof} links written to {args.out} ({kind})")
    return EXIT_OK
