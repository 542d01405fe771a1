"""The ``psdm export-urdf`` subcommand: a calibrated model's identified inertias, friction and drives as a URDF.

``psdm export-urdf model.json robot.urdf`` reads the file ``psdm identify`` wrote and writes
``codegen.urdf_export.render_urdf`` of it: for a URDF robot a copy of its URDF
with the identified bodies, for a DH robot a generated URDF. The output is written atomically and
never replaces a file without ``--overwrite``; a model that is not physically consistent is refused
(exit 1) unless ``--allow-inconsistent``, as ``psdm identify`` does.
"""

from __future__ import annotations

from psdm_casadi.cli.exports import add_export_arguments, read_export_input, write_export
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, print_json, progress

__all__ = ["register"]


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
    add_export_arguments(p, "URDF file to write (.urdf)", _run_export_urdf)


def _run_export_urdf(args) -> int:
    from codegen.target_holds import findings_not_representable, friction_not_representable, offsets_not_representable
    from codegen.urdf_export import render_urdf

    read = read_export_input(args, "export-urdf", ".urdf", "a URDF")
    if read is None:
        return EXIT_CHECK_FAILED
    calibrated, robot = read.calibrated, read.robot
    progress(f"export-urdf: writing the identified inertias of {robot.name} ...", quiet=args.json)
    text = render_urdf(calibrated, robot)
    left_out = (friction_not_representable(calibrated), findings_not_representable(calibrated),
                offsets_not_representable(calibrated))  # fmt: skip
    write_export("export-urdf", read, text, [warning for warning in left_out if warning is not None])
    source = "urdf" if robot.urdf_path is not None else "dh"
    if args.json:
        print_json({"command": "export-urdf", "model": str(args.model), "out": str(args.out), "robot": robot.name,
                    "source": source, "consistent": calibrated.consistent,
                    "min_pseudo_inertia_eigenvalue": read.eigenvalue,
                    "locked_joints": list(robot.locked_joints)})  # fmt: skip
    else:
        kind = "a copy of its URDF" if source == "urdf" else "a URDF generated from its DH table"
        print(f"{robot.name}: identified inertias of {robot.n_dof} links written to {args.out} ({kind})")
    return EXIT_OK
