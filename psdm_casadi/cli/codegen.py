"""The ``psdm codegen`` subcommand: robot, model or calibrated-model file -> exported C folder (optionally compiled)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from codegen.export import export_c
from psdm_casadi.cli.checks import (
    add_lock_argument,
    check_not_input,
    load_locked_robot,
    output_folder,
)
from psdm_casadi.cli.output import EXIT_CHECK_FAILED, EXIT_OK, model_warnings, report_model_warnings
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.overwrite_option import add_overwrite_argument

ROBOT_SUFFIXES = (".toml", ".urdf", ".xml", ".mjcf")
CALIBRATED_SUFFIX = ".json"
FORMS = ("recursive", "sum")
DESCRIPTION = (
    "Export the PSDM dynamics of a robot (.toml/.urdf/.xml MJCF, derived first) or of a saved model (.npz) as a "
    "self-contained C folder: <library>.c/.h, Makefile and an example main.c. Functions taking theta are "
    "exported with theta baked in (from --theta, else the robot's nominal base parameters) and with "
    "theta as a runtime input (suffix _theta). The default recursive form evaluates the model by Newton-Euler "
    "on a sparse standard-parameter preimage of theta (needs the kinematics: a robot file, or --robot with a "
    "model); --form sum writes the paper's pseudo-symbolic sum. A calibrated model (.json, written by "
    "'psdm identify') exports the full torque it reports: the rigid body of its base parameters plus its "
    "drive terms (friction, offsets, drive inertias) and the torque-type findings of 'psdm diagnose MODEL "
    "--apply' (spring, offset, ripple, coupling, asymmetry, rotor inertia, load-dependent friction), every "
    "parameter compiled in; its regressor is the rigid body's. Measurement corrections (delay, elasticity, "
    "backlash) are not a torque and are not exported: 'psdm validate' applies them to recordings, and the "
    "header says which corrected signals the functions expect. The warnings 'psdm identify' stored in the "
    "model file are repeated on stderr, in the header and under 'warnings' with --json. A "
    "calibrated model that is not physically consistent is refused (exit 1) unless --allow-inconsistent, "
    "and so is a --theta whose mass matrix is not positive definite over random configurations in the joint "
    "limits (the error names the eigenvalue and the base parameters to blame)."
)


def register(subparsers) -> None:
    """Add the ``codegen`` subcommand to the ``psdm`` parser."""
    p = subparsers.add_parser(
        "codegen",
        help="export inverse/forward dynamics, regressor and mass matrix as C code",
        description=DESCRIPTION,
    )
    p.add_argument(
        "source",
        metavar="ROBOT_OR_MODEL",
        help="robot file (.toml, .urdf, .xml MJCF), saved model (.npz) or calibrated model (.json, 'psdm identify')",
    )
    p.add_argument("--out", required=True, type=Path, help="output folder (new or empty unless --overwrite)")
    p.add_argument(
        "--theta",
        type=Path,
        default=None,
        help="base parameters to bake in: .npy, .csv or whitespace-separated text with n_base values; refused "
        "(exit 1) unless --allow-inconsistent when their mass matrix is not positive definite",
    )
    p.add_argument(
        "--form",
        choices=FORMS,
        default=None,
        help="recursive (Newton-Euler on the base parameters, fastest; default when the kinematics are known) "
        "or sum (the paper's pseudo-symbolic sum; default for a model file without --robot)",
    )
    p.add_argument(
        "--robot",
        type=Path,
        default=None,
        help="robot file (.toml, .urdf, .xml) a saved model was derived from; enables the recursive form",
    )
    p.add_argument(
        "--allow-inconsistent",
        action="store_true",
        help="export a calibrated model that is not physically consistent (or was not checked), or a --theta whose "
        "mass matrix is not positive definite; the files say so",
    )
    add_lock_argument(p)
    p.add_argument("--jacobians", action="store_true", help="also export the Jacobians (<function>_jac)")
    p.add_argument(
        "--batch",
        action="store_true",
        help="also write <library>_batch.c/.h: inverse/forward dynamics and regressor for N states per call "
        "(<name>_batch, vectorised across states, OpenMP threads; theta baked in)",
    )
    p.add_argument(
        "--derivatives",
        action="store_true",
        help="also export inverse_dynamics_derivatives (tau, dtau/d(q, qd, qdd)), forward_dynamics_derivatives "
        "(qdd, dqdd/d(q, qd, tau)) and regressor_derivatives (dvec(Y)/d(q, qd, qdd)), written for speed",
    )
    p.add_argument(
        "--libm-trig",
        action="store_true",
        help="call libm's sin/cos instead of the inlined psdm_sin/psdm_cos (within a few ulp of libm)",
    )
    p.add_argument("--library", default="psdm_dynamics", help="base name of the .c/.h files (default psdm_dynamics)")
    p.add_argument(
        "--compile",
        action="store_true",
        help="also compile lib<library>.so into --out with the system C compiler (-O3 -march=native)",
    )
    add_overwrite_argument(
        p,
        "replace the files an earlier 'psdm codegen' wrote in --out (listed in its .psdm-manifest.json); a "
        "folder holding anything else, or a file of an output's name that psdm did not write, is refused",
        dest="force",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=_run_codegen)


def read_theta(path: Path) -> np.ndarray:
    """Base parameters from a .npy, .csv or text file, as a flat float array."""
    path = Path(path)
    if not path.exists():
        raise ParameterError(f"codegen --theta must name an existing file; got {str(path)!r}. Check the path.")
    try:
        if path.suffix.lower() == ".npy":
            values = np.load(path, allow_pickle=False)
        else:
            delimiter = "," if path.suffix.lower() == ".csv" else None
            values = np.loadtxt(path, delimiter=delimiter, ndmin=1)
    except (OSError, ValueError) as exc:
        raise ParameterError(
            f"codegen --theta must be a .npy, .csv or text file of numbers; could not read {path.name} ({exc}). "
            "Write it with numpy.save or numpy.savetxt."
        ) from None
    values = np.asarray(values, dtype=float).ravel()
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ParameterError(
            f"codegen --theta must hold finite numbers; got {values[bad[0]]} at value {bad[0] + 1} of {path.name}. "
            "Pass the base parameters the identification wrote."
        )
    return values


def _load_source(args, path: Path, robot_path: Path | None, locks=()):
    """(PSDMModel, RobotDescription or None, nominal theta or None) from a robot file or a saved model."""
    from psdm_casadi.cli.checks import derive_model
    from psdm_casadi.cli.output import progress
    from psdm_casadi.model import load_model
    from psdm_casadi.robot import builtin_robot_names

    if path.suffix.lower() in ROBOT_SUFFIXES or (not path.exists() and str(path) in builtin_robot_names()):
        if robot_path is not None:
            raise ParameterError(
                f"codegen --robot is only for a saved model; got the robot file {path.name} as the source. "
                "Drop --robot."
            )
        robot = load_locked_robot(path, locks)
        progress(f"deriving the PSDM model of {robot.name} ...")
        model = derive_model(args, robot)
        nominal = model.base_parameters(robot.nominal_dynamic_parameters()) if robot.has_inertia else None
        return model, robot, nominal
    if locks and robot_path is None:
        raise ParameterError(
            f"codegen --lock applies to a robot; got the saved model {path.name} without --robot. Pass the robot the "
            "model was derived from (--robot ROBOT --lock ...), or drop --lock."
        )
    robot = load_locked_robot(robot_path, locks) if robot_path is not None else None
    return load_model(path), robot, None


def build_export_functions(model, robot, form: str | None):
    """The DynamicsFunctions to export in the requested form (recursive when the robot is known)."""
    from psdm_casadi.recursive import build_recursive_functions
    from psdm_casadi.symbolic import build_functions

    form = form or ("recursive" if robot is not None or not model.has_monomials else "sum")
    if form == "recursive":
        if robot is None and model.has_monomials:
            raise ParameterError(
                "codegen --form recursive needs the robot's kinematics; got a model file without --robot. "
                "Pass --robot ROBOT_FILE (the file the model was derived from) or --form sum."
            )
        return build_recursive_functions(model, robot), form  # a model without table carries its kinematics
    if not model.has_monomials:
        raise ParameterError(
            f"codegen --form sum needs the model's monomial table; {model.robot_name!r} ({model.n_dof} joints) was "
            "derived without one (the recursive form). Drop --form sum or pass --form recursive."
        )
    return build_functions(model), form


def output_names(library: str) -> tuple:
    """What ``psdm codegen`` writes into --out (and what its Makefile builds there), for ``--overwrite``."""
    batch = (f"{library}_batch.c", f"{library}_batch.h")
    lugre = (f"{library}_lugre.c", f"{library}_lugre.h")  # a LuGre model's bristle step (codegen.calibrated_lugre)
    return (f"{library}.c", f"{library}.h", *batch, *lugre, "main.c", "Makefile", f"lib{library}.so", "example")


def _check_options(args):
    """--library, --theta and --out, before the derivation; returns the checked output folder."""
    library = args.library
    plain_name = library.replace("_", "a")
    if not (plain_name.isascii() and plain_name.isalnum()) or library[0].isdigit():
        raise ParameterError(
            "codegen --library must be a C identifier (letters, digits, underscores, not starting with a digit); "
            f"got {library!r}. Pass e.g. --library robot_dynamics."
        )
    if args.theta is not None and not Path(args.theta).is_file():
        raise ParameterError(f"codegen --theta must name an existing file; got {str(args.theta)!r}. Check the path.")
    inputs = (("ROBOT_OR_MODEL", args.source), ("--robot", args.robot), ("--theta", args.theta))
    folder = output_folder(args.out, output_names(library), args.force, force_option="--overwrite", command="codegen")
    check_not_input(args.out, "--out", inputs, "--overwrite")
    return folder


def _calibrated_functions(args, path: Path, out: Path):
    """(Functions, form, None (no theta to bake), header note, CalibratedModel) of a calibrated-model file, as
    ``_export_functions`` returns them, or None when refused."""
    from codegen.calibrated import build_calibrated_functions, consistency_problem, header_note
    from codegen.motor_torque import add_motor_torque
    from psdm_casadi.cli.checks import read_calibrated_argument
    from psdm_casadi.cli.exports import warn_stiff_links
    from psdm_casadi.cli.output import progress

    given = (("--theta", args.theta), ("--robot", args.robot), ("--lock", getattr(args, "lock", None) or None))
    extra = [option for option, value in given if value is not None]
    if extra:
        raise ParameterError(
            f"codegen {' and '.join(extra)} must not be given with a calibrated model; got {path.name}, which holds "
            f"its robot and parameters. Drop {' and '.join(extra)}."
        )
    loaded = read_calibrated_argument(args, path)  # checked; its robot and model derived once
    calibrated, robot, model = loaded.calibrated, loaded.robot, loaded.model
    report_model_warnings("codegen", path, calibrated)
    stiff = warn_stiff_links("codegen", path, loaded)
    problem = consistency_problem(calibrated)
    if problem is not None and not args.allow_inconsistent:
        print(
            f"psdm codegen: error: {problem}. Nothing was written to {str(out)!r}. Identify it again from "
            "better-exciting recordings, or pass --allow-inconsistent to export it anyway.",
            file=sys.stderr,
        )
        return None
    if problem is not None:
        print(f"psdm codegen: warning: exporting it although {problem}", file=sys.stderr)
    progress("building the CasADi functions (rigid body + drive terms) ...")
    form = args.form or "recursive"
    functions = build_calibrated_functions(calibrated, model, robot, form=form, allow_inconsistent=True)
    functions = add_motor_torque(functions, robot.transmission)  # tau_m = N_q^-T tau, with a [transmission]
    stiff_note = "".join(f"/* WARNING: {sentence}. */\n" for sentence in stiff)  # the forward dynamics' users
    return functions, form, None, header_note(calibrated, source_name=path.name) + stiff_note, calibrated


def _export_functions(args, out: Path):
    """(Functions, form, theta to bake, header note or None, CalibratedModel or None) of the source, or None when
    refused."""
    from psdm_casadi.cli.output import progress

    source = Path(args.source)
    if source.suffix.lower() == CALIBRATED_SUFFIX:
        return _calibrated_functions(args, source, out)
    model, robot, theta = _load_source(args, source, args.robot, args.lock)
    note = None
    if args.theta is not None:
        theta = read_theta(args.theta)
        if theta.size != model.n_base:
            raise ShapeError(
                f"codegen --theta must have {model.n_base} values (the model's n_base); got {theta.size}. "
                "Pass the base parameters of this model."
            )
        checked = _checked_theta(args, model, robot, theta, out)
        if checked is None:
            return None
        note = checked or None
    progress("building the CasADi functions ...")
    functions, form = build_export_functions(model, robot, args.form)
    if robot is not None:
        from codegen.motor_torque import add_motor_torque

        functions = add_motor_torque(functions, robot.transmission)  # tau_m = N_q^-T tau, with a [transmission]
    return functions, form, theta, note, None


def _checked_theta(args, model, robot, theta, out: Path) -> str | None:
    """'' for a --theta whose mass matrix is positive definite, the header warning when it is not and
    --allow-inconsistent is given, else None (refused: the error is printed)."""
    from codegen.theta_check import check_theta
    from psdm_casadi.cli.output import progress

    progress(f"checking the mass matrix of {Path(args.theta).name} over random configurations ...")
    problem = check_theta(model, theta, robot).problem(Path(args.theta).name)
    if problem is None:
        return ""
    if not args.allow_inconsistent:
        print(
            f"psdm codegen: error: {problem}. Nothing was written to {str(out)!r}. Pass the base parameters of a "
            "consistent identification, or --allow-inconsistent to export them anyway (marked in the files).",
            file=sys.stderr,
        )
        return None
    print(f"psdm codegen: warning: exporting it although {problem}", file=sys.stderr)
    return f"/* WARNING: {problem}; exported with --allow-inconsistent. */\n"


def _run_codegen(args) -> int:
    from psdm_casadi.cli.output import progress

    folder = _check_options(args)
    out = folder.target
    built = _export_functions(args, out)
    if built is None:
        return EXIT_CHECK_FAILED
    functions, form, theta, note, calibrated = built
    exporter = export_c
    if getattr(args, "derivatives", False):
        from codegen.derivatives import export_derivatives as exporter
    with folder.staging() as stage:
        export = exporter(
            functions,
            stage,
            theta=theta,
            jacobians=args.jacobians,
            library=args.library,
            fast_trig=not args.libm_trig,
        )
        lugre_source = None
        if note is not None:
            from codegen.calibrated import add_header_note

            add_header_note(export, note)
        if calibrated is not None:
            from codegen.calibrated_lugre import add_lugre_step

            lugre_source = add_lugre_step(export, calibrated, note)  # None unless LuGre
        batch = None
        if getattr(args, "batch", False):
            from codegen.batch import add_batch

            progress("writing the batch functions (N states per call) ...")
            batch = add_batch(export, functions)
        if args.compile:
            from codegen.build import compile_shared

            progress(f"compiling lib{export.library}.so ...")
            sources, openmp = ([export.source], ()) if batch is None else ([export.source, batch.source], ("-fopenmp",))
            sources += [lugre_source] if lugre_source is not None else []
            compile_shared(sources, stage / f"lib{export.library}.so", flags=("-O3", "-march=native", *openmp))
    warnings = [] if calibrated is None else model_warnings(calibrated)
    warnings += [
        line[len("/* WARNING: ") : -len(". */")]
        for line in (note or "").splitlines()
        if line.startswith("/* WARNING: ") and "plausible floor" in line
    ]  # ``warn_stiff_links``'s
    _print_export(args, out, export, form, calibrated=calibrated is not None, batch=batch, warnings=warnings)
    if lugre_source is not None:
        progress(f"LuGre friction: NOT in inverse_dynamics; {lugre_source.name} has psdm_lugre_step(s, qd_prev, "
                 "qd, dt) -> (s_next, tau_friction), the bristle step to carry (see its header)")  # fmt: skip
    return EXIT_OK


def _print_export(args, out: Path, export, form: str, calibrated: bool = False, batch=None, warnings=()) -> None:
    from psdm_casadi.cli.output import print_json

    compiled = bool(args.compile)
    if args.json:
        lanes = export.lane_regressor
        print_json(
            {
                "command": "codegen",
                "out": str(out),
                "form": form,
                "calibrated": calibrated,
                "functions": list(export.function_names),
                "n_instructions": export.n_instructions,
                "compiled": compiled,
                "lane_regressor": None if lanes is None else dataclasses.asdict(lanes),
                "batch_functions": None if batch is None else list(batch.function_names),
                "warnings": list(warnings),
            }
        )
    else:
        print(f"wrote {export.source.name}, {export.header.name}, Makefile and main.c to {out} ({form} form)")
        if calibrated:
            print(
                "calibrated model: inverse/forward dynamics and mass matrix include its drive terms (friction, "
                "offsets, drive inertias) and torque-type findings; the regressor is the rigid body's (see the "
                "header comment)"
            )
        print(f"{'function':40s} {'instructions':>12s} {'operations':>10s} {'trig':>5s}")
        for count in export.operation_counts:
            print(f"{count.name:40s} {count.n_instructions:12d} {count.n_operations:10d} {count.n_trig:5d}")
        if export.lane_regressor is not None:
            lanes = export.lane_regressor
            print(
                f"{lanes.name} runs four joint rows per vector instruction: {lanes.parts.n_operations} scalar "
                f"+ {lanes.n_vector_operations} vector operations (-DPSDM_NO_LANES: CasADi's scalar code above)"
            )
        if not export.theta_baked and not calibrated:
            print("theta not baked in (no --theta and no nominal inertia): only the runtime-theta flavour was written")
        if batch is not None:
            print(
                f"wrote {batch.source.name} and {batch.header.name}: {', '.join(batch.function_names)} "
                f"({batch.lane_width} states per vector instruction, OpenMP threads)"
            )
