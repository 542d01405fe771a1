"""The ``psdm export-mjcf`` subcommand: a calibrated model's identified inertias, drives and friction as MJCF.

``psdm export-mjcf model.json robot.xml`` reads the file ``psdm identify`` wrote and writes
``codegen.mjcf_export.render_mjcf`` of it, for MuJoCo. The output is written atomically and never replaces a
file without ``--overwrite`` (nor ever an input); a model that is not physically consistent is refused (exit 1)
unless ``--allow-inconsistent``, as ``psdm export-urdf`` does.
"""

from __future__ import annotations

from pathlib import Path

from psdm_casadi.cli.exports import add_export_arguments, read_export_input, write_export
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, print_json, progress

__all__ = ["register"]


def register(subparsers) -> None:
    """Add ``export-mjcf`` to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "export-mjcf",
        help="write the identified inertias, drive inertias, friction and springs of a calibrated model as MJCF",
        description=(
            "Read a calibrated-model file written by 'psdm identify' and write an MJCF file for MuJoCo: each moving "
            "body carries the identified rigid body of its joint (fullinertia, exact floats), each joint its range, "
            "armature (the drive inertia), damping (viscous friction), frictionloss (Coulomb friction, a constraint "
            "in MuJoCo) and, for a linear spring finding, stiffness and springref; the robot's gravity is the "
            "option gravity. What MJCF cannot hold (torque offsets, Stribeck and LuGre friction shapes, other "
            "findings, measurement corrections) is named in a warning and written as comments with its values."
        ),
    )
    add_export_arguments(p, "MJCF file to write (.xml)", _run_export_mjcf)


def _run_export_mjcf(args) -> int:
    from codegen.mjcf_export import render_mjcf
    from codegen.target_holds import (
        MJCF,
        findings_not_representable,
        friction_not_representable,
        offsets_not_representable,
    )
    from psdm_casadi.mjcf import MJCF_SUFFIXES

    read = read_export_input(args, "export-mjcf", ".xml", "MJCF")
    if read is None:
        return EXIT_CHECK_FAILED
    calibrated, robot = read.calibrated, read.robot
    progress(f"export-mjcf: writing the identified model of {robot.name} ...", quiet=args.json)
    text = render_mjcf(calibrated, robot)
    left_out = (friction_not_representable(calibrated, MJCF), findings_not_representable(calibrated, MJCF),
                offsets_not_representable(calibrated, MJCF))  # fmt: skip
    left_out = [warning for warning in left_out if warning is not None]
    write_export("export-mjcf", read, text, left_out)
    copied = robot.urdf_path is not None and Path(robot.urdf_path).suffix.lower() in MJCF_SUFFIXES
    source = "a copy of its MJCF" if copied else "generated from its kinematics"
    if args.json:
        print_json({"command": "export-mjcf", "model": str(args.model), "out": str(args.out), "robot": robot.name,
                    "source": "mjcf" if copied else "generated", "consistent": calibrated.consistent,
                    "min_pseudo_inertia_eigenvalue": read.eigenvalue, "left_out": left_out})  # fmt: skip
    else:
        print(f"{robot.name}: identified model of {robot.n_dof} joints written to {args.out} (MJCF, {source})")
    return EXIT_OK
