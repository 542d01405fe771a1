"""The ``psdm simulate`` subcommand: run the virtual robot, or a calibrated model, along a reference or an experiment.

With a robot file, the virtual robot (rigid body, LuGre friction, drives, controller, sensors) tracks
the reference. With a calibrated-model file (``psdm identify --out model.json``), the recording holds
the reference's states and the model's own torques (``identification.calibration.model_simulation``):
what the identified robot would record if the model were exact.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from psdm_casadi.cli.checks import (
    add_robot_argument,
    check_count,
    check_not_input,
    check_positive,
    check_samples,
    load_robot_argument,
    output_folder,
    parse_joints,
)
from psdm_casadi.cli.output import print_json, progress, report_model_warnings
from psdm_casadi.errors import ParameterError

EXPERIMENTS = ("motor", "gravity", "friction", "sine")
MODEL_EXPERIMENTS = ("gravity", "friction", "sine")  # the motor experiment's payload needs the virtual robot
CALIBRATED_SUFFIX = ".json"


def register(subparsers) -> None:
    """Add ``psdm simulate`` to the ``psdm`` parser."""
    _add_simulate(subparsers)


def _add_simulate(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="simulate the virtual robot and write recordings with their true parameters",
        description=(
            "Run the virtual robot (Pinocchio rigid body, LuGre friction, motor constants, PD + feed-forward "
            "controller, sensor noise and quantisation) along a reference and write <name>.csv recordings with "
            "<name>.truth.json / .truth.npz beside them. The reference is a CSV file (columns t,q1..qn[,qd..,qdd..]) "
            "or one of the paper's calibration experiments. With a calibrated model (.json from 'psdm identify') "
            "instead of a robot, write <name>.csv with the reference's states (t, q, qd, qdd) and the model's "
            "torques tau1..taun (its identified parameters, friction and findings), plus --tau-noise."
        ),
    )
    add_robot_argument(
        p,
        help="robot file (.toml or .urdf) with [[link]] and [[drive]] tables, a built-in name, or a calibrated "
        "model (.json from 'psdm identify')",
    )
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--reference", help="CSV with columns t,q1..qn and optional qd1..,qdd1..")
    source.add_argument(
        "--experiment",
        choices=EXPERIMENTS,
        help="a calibration experiment of the paper (section 3), as `psdm experiment` writes it",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated time [s] of --reference, or length of the gravity and sine experiments "
        "(default: the reference's, the experiment's)",
    )
    p.add_argument("--rate", type=float, default=1000.0, help="sample and control rate [Hz] (default 1000)")
    p.add_argument("--substeps", type=int, default=2, help="integration steps per sample (default 2)")
    p.add_argument("--joints", default=None, help="comma-separated 1-based joints for motor/friction (default all)")
    p.add_argument("--payload", type=float, default=2.0, help="calibration mass of the motor experiment [kg]")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise and random experiments")
    p.add_argument("--no-noise", action="store_true", help="no sensor noise and no quantisation")
    p.add_argument(
        "--tau-noise",
        type=float,
        default=0.0,
        help="calibrated model only: standard deviation [N m] of Gaussian noise on the torques (default 0: exact)",
    )
    p.add_argument("--tau", action="store_true", help="also record joint torques tau1..taun")
    p.add_argument("--format", choices=("csv", "npz"), default="csv")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace recordings an earlier 'psdm simulate' wrote in --out (listed in its .psdm-manifest.json; "
        "other files are kept, a user's file of a recording's name is refused)",
    )
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(handler=_run_simulate)


def _read_reference(path: str, n_dof: int):
    """``(t, q[, qd[, qdd]])`` from a trajectory CSV as ``psdm excite`` and ``psdm experiment`` write it.

    The file goes through the recordings' reader (encodings, delimiters, values and time are checked
    there, naming the line and the fix); only the column set differs: a reference has no torques.
    """
    from identification.data.io import read_table, time_column
    from trajopt.csvfile import trajectory_header

    table = read_table(path)
    known = set(trajectory_header(n_dof))
    for name in table.names:
        if name not in known:
            raise ParameterError(
                f"{table.source}: column {name!r} is not a reference column of a {n_dof}-joint robot "
                f"(t, q1..q{n_dof}, qd1.., qdd1..). Remove it."
            )
    if table.n_samples < 2:
        raise ParameterError(f"{table.source}: the reference needs at least 2 rows; got {table.n_samples}.")
    columns = {name: table.data[:, k] for k, name in enumerate(table.names)}
    parts = [time_column(table)]
    for prefix in ("q", "qd", "qdd"):
        names = [f"{prefix}{j + 1}" for j in range(n_dof)]
        present = [n for n in names if n in columns]
        if not present:
            if prefix == "q":
                raise ParameterError(f"{table.source}: columns q1..q{n_dof} are missing. Add joint positions.")
            break
        if len(present) != n_dof:
            missing = next(n for n in names if n not in columns)
            raise ParameterError(f"{table.source}: column {missing} is missing; the robot has n_dof={n_dof}. Add it.")
        parts.append(np.column_stack([columns[n] for n in names]))
    return tuple(parts)


def _experiment_runs(args, robot, joints, rng, base):
    """``(name, reference, SimulationOptions)`` of the chosen calibration experiment (trajopt's designs)."""
    from identification.virtual.calibration import friction_simulation_options
    from identification.virtual.effects import Payload
    from identification.virtual.simulation import SimulationOptions
    from trajopt.experiments import friction_experiment, gravity_experiment, motor_experiment, sine_experiment

    length = {} if args.duration is None else {"duration": args.duration}
    if args.experiment == "motor":
        loaded = SimulationOptions(payload=Payload(mass=args.payload), **base)
        runs = []
        for j in joints:
            ref = motor_experiment(robot, j).reference()
            runs += [
                (f"motor_j{j + 1}_nominal", ref, SimulationOptions(**base)),
                (f"motor_j{j + 1}_payload", ref, loaded),
            ]
        return runs
    if args.experiment == "gravity":
        experiment = gravity_experiment(robot, rng=rng, **length)
        return [("gravity", experiment.reference(), SimulationOptions(**base))]
    if args.experiment == "friction":
        # as in the virtual calibration: no friction feed-forward, fine leapfrog steps
        still = friction_simulation_options(SimulationOptions(**base))
        return [(f"friction_j{j + 1}", friction_experiment(robot, j).reference(), still) for j in joints]
    experiment = sine_experiment(robot, rng=rng, **length)
    return [("sine", experiment.reference(), SimulationOptions(**base))]


def _check_simulate(args) -> None:
    """The options of ``psdm simulate`` that need no robot, before any work."""
    check_positive(args.duration, "--duration", "Pass seconds, e.g. --duration 10.", " of seconds")
    check_positive(args.rate, "--rate", "Pass e.g. --rate 1000.", " [Hz]")
    check_count(args.substeps, "--substeps", "Pass e.g. --substeps 2.")
    check_positive(args.payload, "--payload", "Pass the calibration mass in kg, e.g. --payload 2.", " [kg]")
    if args.duration is not None:
        fix = "Shorten --duration or lower --rate."
        check_samples(args.duration, args.rate, "--duration", "per simulated recording", fix)


def _check_lengths(runs, rate: float) -> None:
    """Every run must stay within the sample bound (the length of a reference or an experiment included)."""
    for name, reference, options in runs:
        t = reference[0]
        duration = options.duration if options.duration is not None else float(t[-1] - t[0])
        fix = "Lower --rate, or shorten --duration or the reference."
        check_samples(duration, rate, "--rate", f"in the recording {name}", fix)


def _recording_names(runs, fmt: str) -> list:
    """The files ``write_recording`` writes for the runs (a recording and its two truth files each)."""
    return [f"{name}{suffix}" for name, _, _ in runs for suffix in (f".{fmt}", ".truth.json", ".truth.npz")]


def _check_not_inputs(args, names) -> None:
    """No recording this run writes may replace the robot, model or --reference file it reads."""
    inputs = (("ROBOT", args.robot), ("--reference", args.reference))
    for name in names:
        check_not_input(Path(args.out) / name, "--out", inputs)


def _run_simulate(args) -> int:
    from identification.virtual.simulation import SimulationOptions

    _check_simulate(args)
    if str(args.robot).lower().endswith(CALIBRATED_SUFFIX):
        return _run_model(args)
    output_folder(args.out, (), args.overwrite, shared=True)  # a file or an unwritable folder: refused first
    robot = load_robot_argument(args)
    n = robot.n_dof
    rng = np.random.default_rng(args.seed)
    joints = parse_joints(args.joints, n)
    base = dict(rate=args.rate, substeps=args.substeps, record_tau=args.tau)
    if args.no_noise:
        base.update(encoder_resolution=None, current_resolution=None, current_noise_std=0.0)
    if args.reference:
        runs = [("reference", _read_reference(args.reference, n), SimulationOptions(duration=args.duration, **base))]
    else:
        runs = _experiment_runs(args, robot, joints, rng, base)
    _check_lengths(runs, args.rate)
    names = _recording_names(runs, args.format)
    _check_not_inputs(args, names)
    folder = output_folder(args.out, names, args.overwrite, shared=True, command="simulate")
    with folder.staging() as stage:
        written, simulated, wall = _simulate_runs(args, robot, runs, rng, stage)
    for entry in written:
        for key in ("recording", "truth", "states"):
            entry[key] = str(folder.target / Path(entry[key]).name)
    if args.json:
        print_json(
            {
                "command": "simulate",
                "robot": robot.name,
                "out": str(args.out),
                "recordings": written,
                "simulated_s": simulated,
                "wall_s": wall,
                "real_time_factor": simulated / max(wall, 1e-9),
            }
        )
    return 0


def _simulate_runs(args, robot, runs, rng, stage: Path) -> tuple:
    """Simulate every run into ``stage``: (summaries, simulated seconds, wall seconds)."""
    from identification.data.motor_side import to_motor_side
    from identification.virtual.simulation import simulate_recording
    from identification.virtual.truth import write_recording

    written, simulated, wall = [], 0.0, 0.0
    for name, ref, options in runs:
        progress(f"simulate: {name} ...", quiet=args.json)
        start = time.perf_counter()
        recording, truth = simulate_recording(robot, ref, options, rng)
        elapsed = time.perf_counter() - start
        # written as the robot's controller logs it (the robot file's [recording].side); the truth stays joint side
        paths = write_recording(to_motor_side(recording, robot), truth, stage, name=name, fmt=args.format)
        simulated += recording.duration
        wall += elapsed
        written.append(
            {
                "name": name,
                "samples": recording.n_samples,
                "duration_s": recording.duration,
                "seconds": elapsed,
                **{k: str(v) for k, v in paths.items()},
            }
        )
        progress(
            f"simulate: {name}: {recording.duration:.1f} s of robot time in {elapsed:.1f} s "
            f"({recording.duration / elapsed:.0f}x real time) -> {Path(args.out) / paths['recording'].name}",
            quiet=args.json,
        )
    return written, simulated, wall


def _run_model(args) -> int:
    """``psdm simulate MODEL.json``: the calibrated model's torques along the reference (module docstring)."""
    from identification.calibration.model_simulation import simulate_calibrated
    from identification.data.io import save_recording
    from identification.data.motor_side import to_motor_side
    from psdm_casadi.cli.checks import read_calibrated_argument

    if not (np.isfinite(args.tau_noise) and args.tau_noise >= 0):
        raise ParameterError(f"--tau-noise must be >= 0 [N m]; got {args.tau_noise!r}. Pass e.g. --tau-noise 0.1.")
    if getattr(args, "lock", None):
        raise ParameterError(
            f"--lock must not be given with a calibrated model; got {args.lock}, but {Path(args.robot).name} holds "
            "its robot's locked joints. Drop --lock, or identify a model with the joints locked."
        )
    if args.experiment == "motor":
        raise ParameterError(
            f"--experiment motor needs the virtual robot (its payload runs); with a calibrated model pass one of "
            f"{', '.join(MODEL_EXPERIMENTS)} or --reference FILE."
        )
    output_folder(args.out, (), args.overwrite, shared=True)
    loaded = read_calibrated_argument(args, args.robot)  # checked; its robot and model derived once
    calibrated, robot, model = loaded.calibrated, loaded.robot, loaded.model
    report_model_warnings("simulate", args.robot, calibrated)
    rng = np.random.default_rng(args.seed)
    if args.reference:
        name, reference = "reference", _read_reference(args.reference, robot.n_dof)
    else:
        name, reference = args.experiment, _model_experiment(args, robot, rng)
    span = float(reference[0][-1] - reference[0][0]) if isinstance(reference, tuple) else reference.duration
    fix = "Lower --rate, or shorten --duration or the reference."
    check_samples(args.duration or span, args.rate, "--rate", f"in the recording {name}", fix)
    _check_not_inputs(args, [f"{name}.{args.format}"])
    folder = output_folder(args.out, [f"{name}.{args.format}"], args.overwrite, shared=True, command="simulate")
    start = time.perf_counter()
    recording = simulate_calibrated(calibrated, model, reference, rate=args.rate, duration=args.duration,
                                    tau_noise_std=args.tau_noise, rng=rng, name=name)  # fmt: skip
    with folder.staging() as stage:
        comment = (
            f"psdm simulate {Path(args.robot).name}: the calibrated model's torques, noise std {args.tau_noise:g} N m"
        )
        save_recording(to_motor_side(recording, robot), stage / f"{name}.{args.format}", comment=comment)
    elapsed = time.perf_counter() - start
    target = folder.target / f"{name}.{args.format}"
    progress(f"simulate: {name}: {recording.duration:.1f} s of the calibrated model -> {target}", quiet=args.json)
    if args.json:
        print_json({"command": "simulate", "model": str(args.robot), "robot": robot.name, "out": str(args.out),
                    "recordings": [{"name": name, "samples": recording.n_samples, "duration_s": recording.duration,
                                    "seconds": elapsed, "recording": str(target)}],
                    "tau_noise_std": args.tau_noise})  # fmt: skip
    return 0


def _model_experiment(args, robot, rng):
    """The experiment's trajectory (it has ``sample(t)``) for a calibrated model's robot."""
    from trajopt.experiments import friction_experiment, gravity_experiment, sine_experiment

    length = {} if args.duration is None else {"duration": args.duration}
    if args.experiment == "gravity":
        return gravity_experiment(robot, rng=rng, **length)
    if args.experiment == "friction":
        joints = parse_joints(args.joints, robot.n_dof)
        if len(joints) != 1:
            raise ParameterError("--experiment friction with a calibrated model needs one joint; pass --joints J.")
        return friction_experiment(robot, joints[0])
    return sine_experiment(robot, rng=rng, **length)
