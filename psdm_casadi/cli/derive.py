"""The ``psdm derive`` subcommand."""

from __future__ import annotations

import time
from pathlib import Path

from psdm_casadi.cli.checks import (
    add_robot_argument,
    check_not_input,
    derive_model,
    load_robot_argument,
    output_file,
)
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, print_json, progress
from psdm_casadi.overwrite_option import add_overwrite_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "derive",
        help="derive the PSDM model of a robot file (.toml DH, .urdf or MJCF .xml)",
        description="Derive the minimal regressor model tau = Y(q, qd, qdd) theta of a robot, check it "
        "against Pinocchio's rnea on random states, and optionally write it to a model file.",
    )
    add_robot_argument(parser)
    parser.add_argument("-o", "--output", help="write the model to this .npz file (.npz is appended when missing)")
    add_overwrite_argument(parser, "overwrite an existing output file", dest="force")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random checks (default 0)")
    parser.add_argument(
        "--form",
        dest="derive_form",
        choices=("auto", "sum", "recursive"),
        default="auto",
        help="sum: the paper's monomial table (E, P; up to 8 revolute joints); recursive: base parameters from the "
        "regressor's column space, no table, any size (trees too); auto (default): sum when affordable",
    )
    parser.add_argument("--equations", action="store_true", help="print the base parameters as equations")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(handler=run_derive)


def model_path(output: str) -> Path:
    """The file ``PSDMModel.save`` writes for ``-o OUTPUT`` (``.npz`` appended when missing)."""
    path = Path(output).expanduser()
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def run_derive(args) -> int:
    if args.output:
        check_not_input(model_path(args.output), "-o/--output", [("ROBOT", args.robot)], "--overwrite")
        output_file(model_path(args.output), "-o/--output", args.force, "--overwrite")
    robot = load_robot_argument(args)
    progress(f"deriving {robot.name} ({robot.n_dof} joints) ...", quiet=args.json)
    start = time.perf_counter()
    model = derive_model(args, robot, seed=args.seed)
    seconds = time.perf_counter() - start
    if args.output:
        path = model.save(model_path(args.output), overwrite=args.force)
        progress(f"model written to {path}", quiet=args.json)
    error = model.metadata["max_rel_error_vs_pinocchio"]
    if args.json:
        print_json(
            {
                "command": "derive",
                "robot": robot.name,
                "n_dof": robot.n_dof,
                "form": "sum" if model.has_monomials else "recursive",
                "p": model.n_functions if model.has_monomials else None,
                "l": model.n_base,
                "n_gravity": model.n_gravity,
                "seconds": round(seconds, 4),
                "max_rel_error_vs_pinocchio": error,
            }
        )
    else:
        from psdm_casadi.derive import MAX_DOF

        terms = (
            f"p = {model.n_functions} functions"
            if model.has_monomials
            else f"{robot.n_dof} joints, recursive form (no monomial table beyond {MAX_DOF} revolute joints)"
        )
        print(
            f"{robot.name}: {terms}, l = {model.n_base} base parameters "
            f"({model.n_gravity} gravity), {seconds:.2f} s, max relative error vs Pinocchio {error:.2e}"
        )
        if args.equations:
            print(model.equations())
    return EXIT_OK if error <= 1e-9 else EXIT_CHECK_FAILED
