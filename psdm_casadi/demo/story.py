"""The demo's steps: derive, excite, simulate, identify, diagnose, identify again with the finding, export C."""

from __future__ import annotations

import json
import time

import numpy as np

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.demo.markdown import report_markdown
from psdm_casadi.demo.options import REPORT_ENTRIES, REPORT_FORMAT, DemoOptions, DemoResult, DemoRun
from psdm_casadi.demo.speed import finish_speed_job, speed_markdown, speed_sentence, start_speed_job
from psdm_casadi.manifest import ManifestFolder
from psdm_casadi.recursive import build_recursive_functions


def run_demo(out_dir, options: DemoOptions | None = None, *, overwrite: bool = False) -> DemoResult:
    """Run the whole loop and write the report folder.

    The report is built in a staging folder beside ``out_dir`` and moved into place at the end; an
    interrupted or failed run leaves ``out_dir`` as it was (:class:`psdm_casadi.manifest.ManifestFolder`).

    Parameters
    ----------
    out_dir : str or Path
        Report folder: new, empty, or (with ``overwrite``) one that holds only a previous demo report (the
        entries listed in its ``.psdm-manifest.json``).
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
    from psdm_casadi.demo.page import demo_page

    options = DemoOptions() if options is None else options
    folder = ManifestFolder(out_dir, REPORT_ENTRIES, "demo", force_option="--overwrite")
    folder.check(force=overwrite)
    start_all = time.perf_counter()
    with folder.staging() as stage:
        run = DemoRun(
            options, stage, np.random.default_rng(options.seed), {"format": REPORT_FORMAT, "seed": options.seed}
        )
        robot, model = derive(run)
        speed_job = start_speed_job(options, stage / "speed")
        excitation = excite(run, robot, model)
        data = simulate(run, robot, excitation)
        before = identify(run, robot, model, data, "before")
        report = diagnose(run, robot, model, data, excitation)
        after = recalibrate(run, robot, model, data, report, before)
        export(run, robot, after.result_, speed_job)
        run.timed("total", start_all)
        run.summary["seconds"] = {k: round(v, 2) for k, v in run.timings.items()}
        (stage / "report.md").write_text(report_markdown(robot, model, excitation, before, after, report, run.summary))
        demo_page(robot.name, run.summary, stage).write(stage / "report.html")  # summary first, details folded
        (stage / "speed.md").write_text(speed_markdown(run.summary))
        (stage / "summary.json").write_text(json.dumps(run.summary, indent=2, default=float))
    run.say(f"report written to {folder.target}/report.md ({run.timings['total']:.0f} s in all)")
    return DemoResult(folder=folder.target, summary=run.summary)


def derive(run: DemoRun):
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


def excite(run: DemoRun, robot, model):
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


def simulate(run: DemoRun, robot, excitation):
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


def identify(run: DemoRun, robot, model, data, name: str, extra_terms=None):
    """The paper's four identification steps (and the joint refinement unless --quick); ``name`` labels the run."""
    from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
    from identification.calibration.report import plot_observed_predicted

    o = run.options
    start = time.perf_counter()
    pipeline = IdentificationPipeline(
        robot, model, PipelineOptions(refine=o.refine, seed=o.seed, quiet=o.quiet), extra_terms=extra_terms
    ).fit(data)
    seconds = run.timed(f"identify_{name}", start)
    result = pipeline.result_
    t, observed, predicted = pipeline.plot_data_
    plot_observed_predicted(
        t,
        observed,
        predicted,
        run.stage / f"validation_{name}.png",
        title=f"Full model on the excitation validation path ({name} the diagnosis)",
        joint_names=list(robot.joint_names),
    )
    run.summary["identification" if name == "before" else "recalibration"] = calibration_summary(robot, model, result)
    consistency = "consistent" if result.consistency.consistent else "NOT positive definite"
    run.say(
        f"identified ({name} the diagnosis): min R^2 'All' = {result.report.min_r2('all'):.3f}, mass matrix "
        f"{consistency} ({seconds:.1f} s)"
    )
    return pipeline


def calibration_summary(robot, model, result) -> dict:
    """Table 3's worst "All" R^2, consistency, Kt and the errors against the virtual robot's truth (the robot file)."""
    kt_true = np.array([d.kt for d in robot.drives])
    theta_true = model.base_parameters(robot.nominal_dynamic_parameters())
    mask = model.gravity_mask

    def scaled(estimate, truth):
        return float((np.abs(estimate - truth) / np.maximum(np.abs(truth), 0.05 * np.abs(truth).max())).max())

    return {
        "r2_min_all": result.report.min_r2("all"),
        "r2_all": [float(x) for x in result.report["all"].r2],
        "consistent": bool(result.consistency.consistent),
        "min_eigenvalue": float(result.consistency.min_eigenvalue),
        "kt": [float(x) for x in result.kt],
        "kt_rel_err": [float(x) for x in np.abs(result.kt / kt_true - 1.0)],
        "gravity_max_scaled_err": scaled(result.theta[mask], theta_true[mask]),
        "inertial_max_scaled_err": scaled(result.theta[~mask], theta_true[~mask]),
        "extra_terms": None if result.extra_terms is None else result.extra_terms.to_dict(),
    }


def diagnose(run: DemoRun, robot, model, data, excitation):
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


def recalibrate(run: DemoRun, robot, model, data, report, before):
    """The four steps again with the diagnosis' torque-type findings as known terms (the pipeline refits them)."""
    from identification.calibration.extra_terms import ExtraTerms
    from psdm_casadi.errors import ParameterError

    try:
        extra = ExtraTerms.from_diagnosis(report)
    except ParameterError as exc:
        run.warn(f"no recalibration: {exc}")
        run.summary["recalibration"] = dict(run.summary["identification"], skipped=str(exc))
        return before
    run.say(f"identify again with {', '.join(extra.labels)} as known terms ...")
    return identify(run, robot, model, data, "after", extra)


def export(run: DemoRun, robot, result, speed_job) -> None:
    """C code of the corrected model (its whole torque and the rigid body), compiled and checked; then the speed."""
    from codegen.build import build_library
    from codegen.export import export_c

    start = time.perf_counter()
    consistent = bool(result.consistency.consistent)
    run.summary["final_model_consistent"] = consistent
    run.summary["final_min_r2_all"] = result.report.min_r2("all")
    if not consistent:
        run.warn(
            f"the exported model is NOT physically consistent: its mass matrix has eigenvalue "
            f"{result.consistency.min_eigenvalue:.3g} < 0; the C code below computes wrong torques for some states"
        )
    baked = build_recursive_functions(result.model, robot, result.theta)  # the fast form; the sum form checks it
    feedforward = result.build_feedforward(robot)
    functions = [feedforward, baked.inverse_dynamics, baked.forward_dynamics, baked.regressor, baked.mass_matrix]
    folder = run.stage / "c_code"
    structure = getattr(baked, "regressor_structure", None)
    exported = export_c(functions, folder, runtime_theta=False, library="denso_dynamics", regressor_structure=structure)
    library = build_library(exported, build_dir=folder / "build", flags=tuple(run.options.compile_flags))
    q, qd, qdd = run.rng.uniform(-1, 1, size=(3, 64, robot.n_dof))
    c_feedforward, c_inverse = (library.function(f"psdm_{name}") for name in ("feedforward_torque", "inverse_dynamics"))
    c_full = np.array([c_feedforward(*x).full().ravel() for x in zip(q, qd, qdd)])
    casadi_full = np.array([feedforward(*x).full().ravel() for x in zip(q, qd, qdd)])
    c_rigid = np.array([c_inverse(*x).full().ravel() for x in zip(q, qd, qdd)])
    sum_rigid = np.array([result.model.inverse_dynamics(*x, result.theta) for x in zip(q, qd, qdd)])
    run.say(f"C code of the corrected model compiled ({run.timed('codegen', start):.1f} s); waiting for the speed run")
    start = time.perf_counter()
    speed = finish_speed_job(speed_job)
    run.timed("speed", start)
    run.summary["codegen"] = {
        "functions": list(exported.function_names),
        "model": "corrected" if result.extra_terms is not None else "as identified",
        "consistent": consistent,
        "feedforward_c_vs_casadi_max_abs": float(np.abs(c_full - casadi_full).max()),
        "c_vs_python_max_abs": float(np.abs(c_rigid - sum_rigid).max()),
        "n_instructions": exported.n_instructions,
        "speed": speed,
    }
    run.say("speed: " + speed_sentence(speed))
