"""The ``psdm excite`` and ``psdm experiment`` subcommands."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from psdm_casadi.cli.checks import (
    add_robot_argument,
    check_count,
    check_not_input,
    check_positive,
    check_samples,
    load_robot_argument,
    output_file,
    plain,
    staged,
)
from psdm_casadi.cli.output import EXIT_OK, print_json, progress
from psdm_casadi.errors import ParameterError


def register(subparsers) -> None:
    """Add ``excite`` and ``experiment`` to the ``psdm`` command."""
    _register_excite(subparsers)
    _register_experiment(subparsers)


def _register_excite(subparsers) -> None:
    """The ``psdm excite`` parser: the excitation options, the CSV and the plot."""
    p = subparsers.add_parser(
        "excite",
        help="optimise an excitation trajectory (min cond of the stacked regressor) under joint limits",
        description="Design a periodic Fourier (or the paper's sum-of-sines) excitation trajectory minimising the "
        "condition number of the stacked PSDM regressor with Ipopt, subject to position, velocity and "
        "acceleration limits (and optionally torque limits) on a dense grid, verified on a 10x finer "
        "grid. Writes a CSV with t, q, qd, qdd columns and optionally a plot.",
    )
    add_robot_argument(p)
    p.add_argument("--duration", type=float, default=10.0, help="period / length of the trajectory [s] (10)")
    p.add_argument("--harmonics", type=int, default=5, help="Fourier harmonics per joint (5)")
    p.add_argument(
        "--family",
        choices=("fourier", "sum_of_sines"),
        default="fourier",
        help="trajectory family (fourier: periodic; sum_of_sines: the paper's eq. 22)",
    )
    p.add_argument("--terms", type=int, default=3, help="sines per joint for --family sum_of_sines (3)")
    p.add_argument(
        "--columns",
        choices=("inertial", "all"),
        default="inertial",
        help="regressor columns to excite: inertial (not identified by the gravity step, as in the "
        "paper) or all (default inertial)",
    )
    p.add_argument(
        "--criterion",
        choices=("cond", "logdet"),
        default="cond",
        help="smooth condition-number surrogate or D-optimal log-det (default cond)",
    )
    p.add_argument("--starts", type=int, default=3, help="random starts of Ipopt (3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts (0)")
    p.add_argument("--samples", type=int, default=100, help="objective grid size (100)")
    p.add_argument("--rest-to-rest", action="store_true", help="start and end at zero velocity and acceleration")
    p.add_argument("--limit-scale", type=float, default=1.0, help="use this fraction of the robot's limits (1.0)")
    p.add_argument("--torque-limits", action="store_true", help="also keep |tau| <= tau_max with the nominal model")
    p.add_argument("--time-limit", type=float, default=None, help="start no new Ipopt start after this many seconds")
    p.add_argument("--max-iter", type=int, default=300, help="Ipopt iterations per solve (300)")
    p.add_argument("--out", default="excitation.csv", help="output CSV (t, q1.., qd1.., qdd1..) (excitation.csv)")
    p.add_argument("--rate", type=float, default=100.0, help="CSV sampling rate [Hz] (100)")
    p.add_argument("--periods", type=int, default=1, help="periods written to the CSV (Fourier only) (1)")
    p.add_argument("--plot", default=None, help="also save a PNG of q/qd/qdd per joint with the limits")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--json", action="store_true", help="print one JSON object: cond, worst_limit_margin, seconds")
    p.set_defaults(handler=_run_excite)


def _register_experiment(subparsers) -> None:
    """The ``psdm experiment`` parser: the kind of calibration experiment, its joints and settings, the CSV."""
    e = subparsers.add_parser(
        "experiment",
        help="trajectories of the motor, gravity and friction calibration experiments",
        description="Write the paper's calibration experiments, the designs the identification is validated on "
        "with the virtual robot: motor (constant-speed sweep of one joint forward and back, run with "
        "and without the calibration mass), gravity (slow jog of the joints through their ranges and "
        "back along the same path), friction (one joint from rest to rest through pre-sliding, "
        "break-away, Stribeck and sliding segments). The worst limit margin is reported; a negative "
        "one names the limit the path leaves.",
    )
    e.add_argument("kind", choices=("motor", "gravity", "friction"))
    add_robot_argument(e)
    e.add_argument(
        "--joint",
        type=int,
        action="append",
        default=None,
        help="1-based joint (motor, friction: exactly one; gravity: repeat, default all)",
    )
    e.add_argument(
        "--speed",
        type=float,
        default=None,
        help="sweep (motor, default 0.25) or jog (gravity, default 0.15) speed [rad/s]",
    )
    e.add_argument("--duration", type=float, default=None, help="length of the gravity jog [s] (120)")
    e.add_argument("--quick", action="store_true", help="friction: the shorter design (FrictionDesign.quick)")
    e.add_argument(
        "--validation",
        action="store_true",
        help="friction: the second, validation run (the design at 1.3 times its frequencies)",
    )
    e.add_argument("--seed", type=int, default=0, help="seed of the gravity jog's periods (0)")
    e.add_argument("--out", default=None, help="output CSV (default KIND_experiment.csv)")
    e.add_argument("--rate", type=float, default=100.0, help="CSV sampling rate [Hz] (100)")
    e.add_argument("--plot", default=None, help="also save a PNG with the limits")
    e.add_argument("--overwrite", action="store_true", help="replace existing output files")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.set_defaults(handler=_run_experiment)


def _check_excite(args) -> None:
    """The options of ``psdm excite``, before any work (the CSV is written only after the optimisation)."""
    check_positive(args.duration, "--duration", "Pass the period in seconds, e.g. --duration 10.", " of seconds")
    for option, value, example in (
        ("--harmonics", args.harmonics, 5),
        ("--terms", args.terms, 3),
        ("--starts", args.starts, 3),
        ("--samples", args.samples, 100),
        ("--max-iter", args.max_iter, 300),
        ("--periods", args.periods, 1),
    ):
        check_count(value, option, f"Pass e.g. {option} {example}.")
    if not (math.isfinite(args.limit_scale) and 0 < args.limit_scale <= 1):
        raise ParameterError(
            f"--limit-scale must be in (0, 1] (a fraction of the robot's limits); got {plain(args.limit_scale)}. "
            "Pass e.g. --limit-scale 0.9."
        )
    check_positive(args.time_limit, "--time-limit", "Pass e.g. --time-limit 60, or leave it out.", " of seconds")
    check_positive(args.rate, "--rate", "Pass e.g. --rate 100.", " [Hz]")
    if args.periods > 1 and args.family != "fourier":
        raise ParameterError(
            f"--periods must be 1 for --family {args.family} (not periodic); got {args.periods}. "
            "Drop --periods or use --family fourier."
        )
    check_samples(args.duration * args.periods, args.rate, "--rate", "in the CSV", "Lower --rate or --periods.")


def _outputs(args, csv: str):
    """The checked outputs of a trajectory command: (CSV, plot or None); both refused before any work."""
    if args.plot is not None and Path(args.plot).expanduser().absolute() == Path(csv).expanduser().absolute():
        raise ParameterError(f"--plot must name another file than --out; got {args.plot!r} for both. Rename one.")
    for option, path in (("--out", csv), ("--plot", args.plot)):
        check_not_input(path, option, [("ROBOT", args.robot)])
    return output_file(csv, "--out", args.overwrite), output_file(args.plot, "--plot", args.overwrite)


def _run_excite(args) -> int:
    from psdm_casadi.cli.checks import derive_model
    from psdm_casadi.recursive import build_recursive_functions
    from trajopt.optimize import ExcitationOptions, optimize_excitation
    from trajopt.plot import plot_trajectory

    _check_excite(args)
    outputs = _outputs(args, args.out)
    robot = load_robot_argument(args)
    started = time.perf_counter()
    options = ExcitationOptions(
        family=args.family,
        duration=args.duration,
        harmonics=args.harmonics,
        n_terms=args.terms,
        rest_to_rest=args.rest_to_rest,
        criterion=args.criterion,
        n_samples=args.samples,
        limit_scale=args.limit_scale,
        torque_limits=args.torque_limits,
        n_starts=args.starts,
        max_iter=args.max_iter,
        time_limit=args.time_limit,
    )
    options.build_limits(robot)  # bad limits fail here, before the derivation
    options.build_parametrization(robot.n_dof)
    progress(f"excite: deriving the model of {robot.name} ...")
    model = derive_model(args, robot, seed=args.seed)
    functions = build_recursive_functions(model, robot)  # equal to the sum form, far fewer operations
    if args.columns == "inertial":
        columns = tuple(int(c) for c in np.flatnonzero(~model.gravity_mask))
        if not columns:
            raise ParameterError(
                "--columns inertial selects no column: every base parameter is a gravity one. Use --columns all."
            )
        options = replace(options, columns=columns)
    nominal = None
    if args.torque_limits:
        nominal = model.base_parameters(robot.nominal_dynamic_parameters())
    trajectory = optimize_excitation(robot, functions.regressor, options, seed=args.seed, nominal_parameters=nominal)
    with staged(*outputs) as (csv, plot):
        trajectory.to_csv(csv, rate=args.rate, periods=args.periods, overwrite=True)
        if plot is not None:
            plot_trajectory(trajectory, plot, rate=max(args.rate, 50.0), overwrite=True)
    seconds = time.perf_counter() - started
    if args.json:
        print_json(
            {
                "command": "excite",
                "cond": trajectory.cond,
                "worst_limit_margin": trajectory.worst_margin,
                "seconds": round(seconds, 3),
                "optimize_seconds": round(trajectory.seconds, 3),
                "columns": len(trajectory.columns),
                "status": trajectory.status,
                "out": str(args.out),
            }
        )
    else:
        print(
            f"{robot.name}: cond = {trajectory.cond:.4g} on {len(trajectory.columns)} columns, worst limit margin "
            f"{trajectory.worst_margin:.3g} ({trajectory.worst_limit}), {seconds:.1f} s; wrote {args.out}"
            + (f" and {args.plot}" if args.plot else "")
        )
    return EXIT_OK


def _check_experiment(args) -> None:
    """The options of ``psdm experiment``, before any work."""
    check_positive(args.speed, "--speed", "Pass e.g. --speed 0.25.", " [rad/s]")
    check_positive(args.duration, "--duration", "Pass seconds, e.g. --duration 120.", " of seconds")
    check_positive(args.rate, "--rate", "Pass e.g. --rate 100.", " [Hz]")
    if args.kind != "gravity" and (not args.joint or len(args.joint) != 1):
        raise ParameterError(
            f"--joint must be given exactly once for the {args.kind} experiment; got {args.joint}. Pass e.g. --joint 2."
        )
    if args.kind == "gravity" and args.duration is not None:
        check_samples(args.duration, args.rate, "--duration", "in the CSV", "Shorten --duration or lower --rate.")


def _run_experiment(args) -> int:
    from trajopt.experiments import friction_experiment, gravity_experiment, motor_experiment
    from trajopt.friction_design import FrictionDesign
    from trajopt.plot import plot_trajectory

    out = args.out or f"{args.kind}_experiment.csv"
    _check_experiment(args)
    outputs = _outputs(args, out)
    robot = load_robot_argument(args)
    extra = {} if args.speed is None else {"speed": args.speed}
    joints = None if args.joint is None else [_joint_index(j, robot.n_dof) for j in args.joint]
    if args.kind == "gravity":
        if args.duration is not None:
            extra["duration"] = args.duration
        experiment = gravity_experiment(robot, joints=joints, rng=np.random.default_rng(args.seed), **extra)
    elif args.kind == "motor":
        experiment = motor_experiment(robot, joints[0], **extra)
    else:
        design = FrictionDesign.quick() if args.quick else FrictionDesign()
        experiment = friction_experiment(robot, joints[0], design.validation() if args.validation else design)
    check_samples(experiment.duration, args.rate, "--rate", "in the CSV", "Lower --rate.")
    with staged(*outputs) as (csv, plot):
        experiment.to_csv(csv, rate=args.rate, overwrite=True)
        if plot is not None:
            plot_trajectory(experiment, plot, rate=max(args.rate, 50.0), overwrite=True)
    numbers = [j + 1 for j in experiment.joints]
    if args.json:
        print_json(
            {
                "command": "experiment",
                "kind": args.kind,
                "duration": experiment.duration,
                "worst_limit_margin": experiment.worst_margin,
                "joints": numbers,
                "out": out,
            }
        )
    else:
        print(
            f"{args.kind} experiment: {experiment.duration:.1f} s, joints {numbers}, worst limit "
            f"margin {experiment.worst_margin:.3g}; wrote {out}"
        )
    return EXIT_OK


def _joint_index(number: int, n_dof: int) -> int:
    """0-based index of a 1-based ``--joint`` number."""
    if not 1 <= number <= n_dof:
        raise ParameterError(
            f"--joint must be a joint number 1..{n_dof} (the robot has {n_dof} joints); got {number}. "
            f"Pass e.g. --joint {n_dof}."
        )
    return number - 1
