"""psdm demo: the whole story on the built-in virtual Denso, from robot file to compiled C and a report.

derive -> optimise excitation -> simulate the calibration experiments on a virtual robot that
carries a hidden cable-harness spring on joint 4 -> identify in the paper's four steps ->
diagnose the hidden effect and refit with it -> export and compile C -> report folder.

With the command line, this is the one module that composes every package (each step imports the
package it needs); no library module imports it.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from codegen.peers.speed import SPEED_ROWS
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.fileio import OutputFolder
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

logger = logging.getLogger(__name__)

DENSO_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
REPORT_FORMAT = "psdm-demo-report/1"


@dataclass(frozen=True)
class DemoOptions:
    """Sizes of the demo; ``quick()`` gives the sub-minute version used in tests.

    Parameters
    ----------
    robot_file : Path
    seed : int
        Seeds every random choice (excitation starts, noise, poses): same seed, same report.
    excitation_duration : float
        Period of the optimised Fourier excitation [s].
    excitation_harmonics, excitation_starts : int
    excitation_repeats : int
        Periods recorded (the first for identification and diagnosis training, the last for validation).
    gravity_duration : float
        [s] of the gravity jog.
    friction_amplitudes : tuple of float
        Friction experiment amplitudes [rad].
    spring_joint : int
        0-based joint carrying the hidden spring (3: joint 4, the wrist cable harness).
    spring_stiffness : float
        [N m/rad].
    spring_rest : float
        Rest angle [rad].
    compile_flags : tuple of str
    speed_states : int
        Random states of the C speed comparison with Pinocchio (0: skip it). It runs in a separate
        process on the second core while the experiments are simulated and identified.
    quiet : bool
    refine : bool
        Run the joint Ipopt refinement after the four steps.
    """

    robot_file: Path = DENSO_FILE
    seed: int = 0
    excitation_duration: float = 10.0
    excitation_harmonics: int = 4
    excitation_starts: int = 2
    excitation_repeats: int = 3
    gravity_duration: float = 40.0
    friction_amplitudes: tuple = (2e-4, 1e-3, 5e-3, 0.03, 0.15, 0.6)
    spring_joint: int = 3
    spring_stiffness: float = 6.0
    spring_rest: float = 0.4
    compile_flags: tuple = ("-O2",)
    speed_states: int = 300_000
    quiet: bool = False
    refine: bool = True

    @classmethod
    def quick(cls, **changes) -> DemoOptions:
        """A sub-minute version: short experiments, one excitation start, no refinement."""
        base = cls(
            excitation_duration=6.0,
            excitation_harmonics=3,
            excitation_starts=1,
            excitation_repeats=2,
            gravity_duration=16.0,
            friction_amplitudes=(1e-3, 0.03, 0.3),
            compile_flags=("-O1",),
            speed_states=0,
            refine=False,
        )
        return replace(base, **changes)


@dataclass(frozen=True)
class DemoResult:
    """What the demo measured; ``summary`` is also written as ``summary.json`` in the report folder."""

    folder: Path
    summary: dict = field(default_factory=dict)


#: Everything the demo writes into its report folder (``--force`` replaces these and nothing else).
REPORT_ENTRIES = ("report.md", "speed.md", "summary.json", "excitation.png", "c_code", "diagnosis", "speed")


@dataclass
class _DemoRun:
    """The state one demo run passes from step to step: where it writes, its random stream, what it measured."""

    options: DemoOptions
    stage: Path
    rng: np.random.Generator
    summary: dict
    timings: dict = field(default_factory=dict)

    def say(self, message: str) -> None:
        if not self.options.quiet:
            logger.info("[demo] %s", message)

    def timed(self, name: str, start: float) -> float:
        self.timings[name] = time.perf_counter() - start
        return self.timings[name]


def run_demo(out_dir, options: DemoOptions | None = None, *, overwrite: bool = False) -> DemoResult:
    """Run the whole story and write the report folder.

    The report is built in a staging folder beside ``out_dir`` and moved into place at the end; an
    interrupted or failed run leaves ``out_dir`` as it was (:class:`psdm_casadi.fileio.OutputFolder`).

    Parameters
    ----------
    out_dir : str or Path
        Report folder: new, empty, or (with ``overwrite``) one that holds only a previous demo report.
    options : DemoOptions, optional
    overwrite : bool
        Replace the files of an earlier demo report in ``out_dir``.

    Returns
    -------
    DemoResult

    Raises
    ------
    FileExistsError
        Before any work, when ``out_dir`` may not be written (see ``OutputFolder.check``).
    """
    options = DemoOptions() if options is None else options
    folder = OutputFolder(out_dir, REPORT_ENTRIES)
    folder.check(force=overwrite)
    start_all = time.perf_counter()
    with folder.staging() as stage:
        run = _DemoRun(
            options, stage, np.random.default_rng(options.seed), {"format": REPORT_FORMAT, "seed": options.seed}
        )
        robot, model = _derive(run)
        speed_job = _start_speed_job(options, stage / "speed")
        excitation = _excite(run, robot, model)
        data = _simulate(run, robot, excitation)
        identified = _identify(run, robot, model, data)
        report = _diagnose(run, robot, model, data, excitation)
        _export(run, robot, model, identified.theta, speed_job)
        run.timed("total", start_all)
        run.summary["seconds"] = {k: round(v, 2) for k, v in run.timings.items()}
        (stage / "report.md").write_text(
            _markdown(robot, model, excitation, identified.report.to_markdown(), report, run.summary)
        )
        (stage / "speed.md").write_text(_speed_markdown(run.summary))
        (stage / "summary.json").write_text(json.dumps(run.summary, indent=2, default=float))
    run.say(f"report written to {folder.target}/report.md ({run.timings['total']:.0f} s in all)")
    return DemoResult(folder=folder.target, summary=run.summary)


def _derive(run: _DemoRun):
    start = time.perf_counter()
    robot = load_robot(run.options.robot_file)
    model = derive_psdm(robot)
    seconds = run.timed("derive", start)
    run.say(
        f"derived {robot.name}: p = {model.n_functions}, l = {model.n_base}, {model.n_gravity} gravity "
        f"parameters ({seconds:.1f} s)"
    )
    run.summary["model"] = {
        "p": model.n_functions,
        "l": model.n_base,
        "n_gravity": model.n_gravity,
        "max_rel_error_vs_pinocchio": model.metadata["max_rel_error_vs_pinocchio"],
    }
    return robot, model


def _excite(run: _DemoRun, robot, model):
    """An excitation of the inertial columns, optimised over the recursive form's regressor (the smaller graph)."""
    from trajopt.optimize import ExcitationOptions, optimize_excitation
    from trajopt.plot import plot_trajectory

    o = run.options
    start = time.perf_counter()
    functions = build_recursive_functions(model, robot)
    excitation = optimize_excitation(
        robot,
        functions.regressor,
        ExcitationOptions(
            duration=o.excitation_duration,
            harmonics=o.excitation_harmonics,
            columns=tuple(np.nonzero(~model.gravity_mask)[0]),
            n_starts=o.excitation_starts,
            quiet=o.quiet,
        ),
        seed=o.seed,
    )
    seconds = run.timed("excite", start)
    plot_trajectory(excitation, run.stage / "excitation.png", title="optimised excitation (inertial columns)")
    run.say(
        f"excitation: cond = {excitation.cond:.3g}, worst limit margin = {excitation.worst_margin:.3g} "
        f"({seconds:.1f} s)"
    )
    run.summary["excitation"] = {"cond": excitation.cond, "worst_limit_margin": excitation.worst_margin}
    return excitation


def _simulate(run: _DemoRun, robot, excitation):
    """The calibration experiments on the virtual robot, which carries a spring the model does not know about."""
    from identification.virtual.calibration import VirtualCalibrationOptions, simulate_calibration
    from identification.virtual.effects import Spring
    from trajopt.calibration_plan import CalibrationPlan

    o = run.options
    hidden = Spring(joint=o.spring_joint, stiffness=o.spring_stiffness, q0=o.spring_rest)
    t = excitation.time_grid(1000.0, periods=o.excitation_repeats)
    q, qd, qdd = excitation.sample(t)
    start = time.perf_counter()
    data = simulate_calibration(
        robot,
        CalibrationPlan(gravity_duration=o.gravity_duration, friction_amplitudes=tuple(o.friction_amplitudes)),
        VirtualCalibrationOptions(quiet=o.quiet),
        rng=run.rng,
        excitation=((t, q, qd, qdd),),
        extras=(hidden,),
    )
    run.say(f"simulated the calibration experiments ({run.timed('simulate', start):.1f} s)")
    return data


def _identify(run: _DemoRun, robot, model, data):
    """The paper's four identification steps (and the joint refinement unless --quick)."""
    from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions

    o = run.options
    start = time.perf_counter()
    identified = (
        IdentificationPipeline(robot, model, PipelineOptions(refine=o.refine, seed=o.seed, quiet=o.quiet))
        .fit(data)
        .result_
    )
    seconds = run.timed("identify", start)
    run.say(f"identified (min R^2 'All' = {identified.report.min_r2('all'):.3f}, {seconds:.1f} s)")
    run.summary["identification"] = {"r2_min_all": identified.report.min_r2("all"), "kt": list(identified.kt)}
    return identified


def _diagnose(run: _DemoRun, robot, model, data, excitation):
    """Missing physics on the excitation recording: the first period trains, the last validates."""
    from identification.diagnosis import DiagnosisOptions, diagnose

    o = run.options
    start = time.perf_counter()
    recording = data.excitation[0]
    period = excitation.duration
    train = recording.time_slice(0.0, period)
    validation = recording.time_slice((o.excitation_repeats - 1) * period, np.inf)
    report = diagnose(robot, train, validation, DiagnosisOptions(rigid_body="identified"), model=model)
    run.timed("diagnose", start)
    report.save(run.stage / "diagnosis", plots=True)
    run.summary["diagnosis"] = {
        "hidden": {
            "effect": "spring",
            "joint": o.spring_joint + 1,
            "stiffness": o.spring_stiffness,
            "rest": o.spring_rest,
        },
        "findings": [f.to_dict() for f in report.findings],
        "rmse_before": list(map(float, report.rmse_before)),
        "rmse_after": list(map(float, report.rmse_after)),
    }
    run.say("diagnosis: " + report.summary().splitlines()[0])
    return report


def _export(run: _DemoRun, robot, model, theta, speed_job) -> None:
    """C code of the identified model, compiled and checked against the PSDM sum; then the speed run's result."""
    from codegen.build import build_library
    from codegen.export import export_c

    start = time.perf_counter()
    baked = build_recursive_functions(model, robot, theta)  # the fast form; the sum form checks it below
    export = export_c(baked, run.stage / "c_code", runtime_theta=False, library="denso_dynamics")
    library = build_library(export, build_dir=run.stage / "c_code" / "build", flags=tuple(run.options.compile_flags))
    inverse = library.function(export.function_names[0])
    q_check, qd_check, qdd_check = run.rng.uniform(-1, 1, size=(3, robot.n_dof))
    c_tau = np.array(inverse(q_check, qd_check, qdd_check)).ravel()
    py_tau = model.inverse_dynamics(q_check, qd_check, qdd_check, theta)
    run.say(f"C code of the identified model compiled ({run.timed('codegen', start):.1f} s); waiting for the speed run")
    start = time.perf_counter()
    speed = _finish_speed_job(speed_job)
    run.timed("speed", start)
    run.summary["codegen"] = {
        "functions": list(export.function_names),
        "c_vs_python_max_abs": float(np.abs(c_tau - py_tau).max()),
        "n_instructions": export.n_instructions,
        "speed": speed,
    }
    run.say("speed: " + _speed_sentence(speed))


def _start_speed_job(options, workdir):
    """Start the C-vs-Pinocchio timing in a child process (it compiles Pinocchio, which takes a while)."""
    if options.speed_states <= 0:
        return None
    workdir.mkdir(parents=True, exist_ok=True)
    command = [
        sys.executable,
        "-m",
        "codegen.peers.speed",
        str(options.robot_file),
        "--workdir",
        str(workdir),
        "--samples",
        str(options.speed_states),
        "--repeats",
        "3",
        "--sum-form",
        "no",
    ]
    log = open(workdir / "speed.log", "w")
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=log, text=True), log


def _finish_speed_job(job, timeout=900.0) -> dict:
    if job is None:
        return {"skipped": "not measured in --quick mode; run benchmarks/dynamics_speed.py"}
    process, log = job
    try:
        out, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        return {"error": f"the speed run took more than {timeout:.0f} s"}
    finally:
        log.close()
    lines = out.strip().splitlines()
    try:
        return json.loads(lines[-1]) if lines else {"error": "the speed run printed nothing"}
    except json.JSONDecodeError:
        return {"error": lines[-1][:300]}


def _speed_sentence(speed: dict) -> str:
    if "ns" not in speed:
        return speed.get("skipped") or speed.get("error", "not measured")
    return (
        f"inverse dynamics {speed['id_speedup_vs_pinocchio']:.2f}x Pinocchio rnea, forward dynamics "
        f"{speed['fd_speedup_vs_pinocchio']:.2f}x aba, regressor {speed['regressor_speedup_vs_pinocchio']:.2f}x"
    )


def _speed_table(speed: dict) -> str:
    if "ns" not in speed:
        return "C speed: " + _speed_sentence(speed)
    ns = speed["ns"]
    lines = [
        f"C speed, one C++ process, {speed['n_samples']} random states, median of {speed['repeats']} "
        "(PSDM in the recursive form with the robot file's nominal parameters baked in; -O3 -march=native):",
        "",
        "| function | PSDM [us] | Pinocchio [us] | CasADi Newton-Euler [us] | PSDM speed-up vs Pinocchio |",
        "|---|---|---|---|---|",
    ]
    for label, suffix, pin_key, peer in SPEED_ROWS:
        ours = f"psdm_{suffix}"
        peer_text = f"{ns[peer] / 1e3:.3f}" if peer else "-"
        lines.append(
            f"| {label} | {ns[ours] / 1e3:.3f} | {ns[pin_key] / 1e3:.3f} | {peer_text} | "
            f"{ns[pin_key] / ns[ours]:.2f}x |"
        )
    return "\n".join(lines)


def _markdown(robot, model, excitation, table3, diagnosis, summary) -> str:
    codegen = summary["codegen"]
    lines = [
        f"# psdm demo: {robot.name} (virtual robot, seed {summary['seed']})",
        "",
        "## 1. Derived model",
        "",
        f"p = {model.n_functions} functions, l = {model.n_base} base parameters, {model.n_gravity} of them gravity "
        f"parameters (the paper: 1318, 32, 9). Max relative error against Pinocchio's rnea: "
        f"{summary['model']['max_rel_error_vs_pinocchio']:.1e}.",
        "",
        "## 2. Excitation",
        "",
        f"Fourier series, {excitation.duration:g} s period, inertial columns: condition number "
        f"{excitation.cond:.3g}; worst limit margin on a 10x finer grid {excitation.worst_margin:.3g}.",
        "",
        "![excitation](excitation.png)",
        "",
        "## 3. Identification (the paper's Table 3)",
        "",
        table3,
        "",
        "## 4. Diagnosis of missing physics",
        "",
        f"The virtual robot carries a hidden spring on joint {summary['diagnosis']['hidden']['joint']} "
        f"(k = {summary['diagnosis']['hidden']['stiffness']} N m/rad, "
        f"rest {summary['diagnosis']['hidden']['rest']} rad), "
        "a stand-in for a cable harness; the identification does not model it.",
        "",
        diagnosis.to_markdown(),
        "",
        "## 5. C code",
        "",
        f"Exported {', '.join(codegen['functions'])} in the recursive form (Newton-Euler on the identified base "
        "parameters); the compiled inverse dynamics equals the PSDM sum Y(q, qd, qdd) theta to "
        f"{codegen['c_vs_python_max_abs']:.1e} N m.",
        "",
        "Measured speed against Pinocchio and the step timings: [speed.md](speed.md) (measurements vary from "
        "run to run, so they live outside this file, which is identical for a given seed).",
        "",
    ]
    return "\n".join(lines)


def _speed_markdown(summary) -> str:
    seconds = summary["seconds"]
    return "\n".join(
        [
            "# Speed and timings of this demo run",
            "",
            _speed_table(summary["codegen"]["speed"]),
            "",
            "## Step timings [s]",
            "",
            "| " + " | ".join(seconds) + " |",
            "|" + "---|" * len(seconds),
            "| " + " | ".join(f"{v:.1f}" for v in seconds.values()) + " |",
            "",
        ]
    )


def register(subparsers) -> None:
    """Add ``psdm demo`` to the command line."""
    parser = subparsers.add_parser(
        "demo",
        help="the whole story on the built-in virtual Denso, with a report folder",
        description="Derive the Denso model, optimise an excitation, simulate the calibration experiments on "
        "a virtual robot that hides a cable-harness spring on joint 4, identify it in the paper's "
        "four steps, diagnose the hidden spring and refit, export and compile C, and write a "
        "Markdown report with plots. About 5 minutes; --quick takes under a minute.",
    )
    parser.add_argument("--out", default="demo_report", help="report folder (default demo_report)")
    parser.add_argument("--quick", action="store_true", help="short experiments, no refinement, no speed run")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the files of an earlier demo report in --out (a folder that holds anything else is refused)",
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    parser.set_defaults(handler=_run_demo_command)


def _run_demo_command(args) -> int:
    options = DemoOptions.quick(seed=args.seed) if args.quick else DemoOptions(seed=args.seed)
    result = run_demo(args.out, options, overwrite=args.force)
    if args.json:
        print(json.dumps(result.summary, default=float))
    else:
        print(f"report: {result.folder / 'report.md'}")
    found = any(
        f["effect"] == "spring" and options.spring_joint + 1 in f["joints"]
        for f in result.summary["diagnosis"]["findings"]
    )
    return 0 if found else 1
