"""The discovery loop on the four-step calibration: parameter errors with a hidden effect, before and after the loop.

Each scenario simulates the calibration experiments of the virtual Denso (``--plan quick``, the default: the
quick demo's plan, ``psdm_casadi.demo.DemoOptions.quick()`` sizes; ``--plan full``: the experiments of
``benchmarks/calibration.py``, ``CalibrationPlan()`` with its 120 s jog and designed friction experiments, and
the full demo's excitation; noise on) with one hidden effect present during the whole calibration, runs the
four steps (``IdentificationPipeline``, no refinement), diagnoses the excitation recording (first period
trains, last validates), and runs the four steps again with the diagnosis' torque-type findings as known terms
(``ExtraTerms.from_diagnosis``). The same plan without the effect gives the clean-data errors the target is
measured against (issue 16: after within 2x clean). The known terms and the gravity parameters are fitted
jointly on the jog and the excitation, each experiment's rows weighted by its own residual variance
(``identification.calibration.extra_passes``, ``JointGravityIdentifier``); the clean calibration has no terms
and takes its gravity from the jog alone.

Errors against the simulation truth (the robot file): ``kt`` the worst relative Kt error; ``gravity``
and ``inertial`` the worst base-parameter error scaled by max(|truth|, 5 % of the largest parameter
of its kind) (as ``benchmarks/calibration.py``'s ``gravity_max_scaled_err``; parameters below 5 % of
the largest carry torques near the sensor noise). ``loop_parameter_errors`` is the worst over the
scenarios of one seed; its ``after_within_2x_clean`` compares them with that seed's clean errors.

Over several seeds (``--seeds 0 1 2``, :func:`loop_errors_over_seeds`): one seed's clean error is one
draw of the noise, and a lucky one makes a poor reference (the after-errors of that seed are other
draws, from other recordings). So the target is also stated on the distributions:
``after_within_2x_clean_median`` is true when, for Kt, gravity and inertial alike, the median over
the seeds of the worst after-error over the scenarios is at most twice the median over the same
seeds of the clean error (with the same 1e-3 floor as the per-seed test). The worst after-error
over the seeds and the per-seed verdicts are reported beside it, so a seed far off stays visible.

The quick plan's jog lasts 16 s, so each joint travels about 1.2 rad of it: over that travel a linear spring
``k q + c`` is nearly a combination of the joint's gravity torques (sine and cosine of the angle), the jog
alone cannot tell them apart, and the gravity parameters after the loop are as good as the excitation's
estimate of ``k``. The full plan's jog covers 80 % of every joint's range.

    python benchmarks/calibration_loop.py [--json] [--seeds 0 1 2] [--plan quick|full] [--scenarios spring_j4 ...]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from bench_support import DENSO_FILE, print_json, print_table, show_progress

from identification.calibration.extra_terms import ExtraTerms
from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.virtual.calibration import VirtualCalibrationOptions, simulate_calibration
from identification.virtual.effects import Spring, TorqueOffset
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.cli import progress
from psdm_casadi.demo import DemoOptions
from psdm_casadi.errors import ParameterError
from psdm_casadi.recursive import build_recursive_functions
from trajopt.calibration_plan import CalibrationPlan
from trajopt.optimize import ExcitationOptions, optimize_excitation

#: name -> the hidden effect (present in every experiment) and the joint (0-based) it acts on
SCENARIOS = {
    "spring_j4": (Spring(joint=3, stiffness=6.0, q0=0.4), 3),
    "spring_j2": (Spring(joint=1, stiffness=40.0, q0=0.3), 1),
    "offset_j3": (TorqueOffset(offset=(0.0, 0.0, 1.5, 0.0, 0.0, 0.0)), 2),
}


def _scaled(estimate, truth) -> float:
    return float((np.abs(estimate - truth) / np.maximum(np.abs(truth), 0.05 * np.abs(truth).max())).max())


def _within(after: dict, clean: dict) -> bool:
    """Issue 16's test: every error of ``after`` at most twice that of ``clean`` (floored at 1e-3)."""
    return all(after[key] <= 2 * max(clean[key], 1e-3) for key in clean)


def parameter_errors(robot, model, result) -> dict:
    """Worst Kt, gravity and inertial errors of an IdentifiedModel against the robot file (the virtual truth)."""
    kt_true = np.array([d.kt for d in robot.drives])
    truth = model.base_parameters(robot.nominal_dynamic_parameters())
    mask = model.gravity_mask
    return {
        "kt": float(np.abs(result.kt / kt_true - 1).max()),
        "gravity": _scaled(result.theta[mask], truth[mask]),
        "inertial": _scaled(result.theta[~mask], truth[~mask]),
    }


def _excitation(robot, model, options):
    functions = build_recursive_functions(model, robot)
    excitation = optimize_excitation(
        robot,
        functions.regressor,
        ExcitationOptions(
            duration=options.excitation_duration,
            harmonics=options.excitation_harmonics,
            columns=tuple(np.nonzero(~model.gravity_mask)[0]),
            n_starts=options.excitation_starts,
            quiet=True,
        ),
        seed=options.seed,
    )
    t = excitation.time_grid(1000.0, periods=options.excitation_repeats)
    return excitation, (t, *excitation.sample(t))


def _plan(options, plan: str) -> CalibrationPlan:
    """The calibration experiments of ``--plan``: the quick demo's sizes, or ``benchmarks/calibration.py``'s."""
    if plan == "full":
        return CalibrationPlan()
    return CalibrationPlan(gravity_duration=options.gravity_duration, friction_amplitudes=options.friction_amplitudes)


def _scenario(robot, model, options, excitation, reference, extras, plan="quick") -> dict:
    """One calibration with ``extras`` hidden: errors before, the diagnosis, errors after the loop."""
    plan = _plan(options, plan)
    data = simulate_calibration(
        robot,
        plan,
        VirtualCalibrationOptions(quiet=True),
        rng=np.random.default_rng(options.seed),
        excitation=(reference,),
        extras=extras,
    )
    pipeline_options = PipelineOptions(refine=False, quiet=True, seed=options.seed)
    start = time.perf_counter()
    before = IdentificationPipeline(robot, model, pipeline_options).fit(data).result_
    row = {"before": parameter_errors(robot, model, before), "seconds_before": time.perf_counter() - start}
    if not extras:
        return row
    period = excitation.duration
    recording = data.excitation[0]
    report = diagnose(
        robot,
        recording.time_slice(0.0, period),
        recording.time_slice((options.excitation_repeats - 1) * period, np.inf),
        DiagnosisOptions(rigid_body="identified"),
        model=model,
    )
    row["found"] = report.summary()
    try:
        extra = ExtraTerms.from_diagnosis(report)
    except ParameterError:
        row["after"] = row["before"]
        return row
    start = time.perf_counter()
    after = IdentificationPipeline(robot, model, pipeline_options, extra_terms=extra).fit(data).result_
    row["after"] = parameter_errors(robot, model, after)
    row["seconds_after"] = time.perf_counter() - start
    row["terms"] = after.extra_terms.to_dict()
    row["consistent_before"], row["consistent_after"] = (
        bool(before.consistency.consistent),
        bool(after.consistency.consistent),
    )
    return row


def loop_parameter_errors(seed: int = 0, scenarios=tuple(SCENARIOS), plan: str = "quick") -> dict:
    """``{"before": {...}, "after": {...}, "clean": {...}, "scenarios": [...]}``: worst errors over the scenarios."""
    options = DemoOptions.quick(seed=seed) if plan == "quick" else DemoOptions(seed=seed, quiet=True)
    robot = load_robot(DENSO_FILE)
    model = derive_psdm(robot)
    excitation, reference = _excitation(robot, model, options)
    progress("loop benchmark: clean calibration ...")
    clean = _scenario(robot, model, options, excitation, reference, (), plan)["before"]
    rows = []
    for name in scenarios:
        effect, joint = SCENARIOS[name]
        progress(f"loop benchmark: {name} ...")
        row = _scenario(robot, model, options, excitation, reference, (effect,), plan)
        rows.append(dict(row, scenario=name, joint=joint + 1))
    worst = {
        stage: {key: max(r[stage][key] for r in rows) for key in ("kt", "gravity", "inertial")}
        for stage in ("before", "after")
    }
    return dict(worst, clean=clean, after_within_2x_clean=_within(worst["after"], clean), scenarios=rows)


def loop_errors_over_seeds(seeds=(0, 1, 2), scenarios=tuple(SCENARIOS), plan: str = "quick") -> dict:
    """``loop_parameter_errors`` per seed and their comparison across the seeds (module docstring)."""
    per_seed = {int(seed): loop_parameter_errors(int(seed), scenarios, plan) for seed in seeds}
    keys = ("kt", "gravity", "inertial")

    def median(stage):
        return {key: float(np.median([r[stage][key] for r in per_seed.values()])) for key in keys}

    worst_after = {key: max(r["after"][key] for r in per_seed.values()) for key in keys}
    clean, after = median("clean"), median("after")
    return {
        "per_seed": per_seed,
        "clean_median": clean,
        "before_median": median("before"),
        "after_median": after,
        "after_worst": worst_after,
        "after_median_over_clean_median": {key: after[key] / max(clean[key], 1e-3) for key in keys},
        "after_within_2x_clean_median": _within(after, clean),
        "after_within_2x_clean_per_seed": {seed: r["after_within_2x_clean"] for seed, r in per_seed.items()},
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--plan", default="quick", choices=("quick", "full"), help="the calibration experiments")
    args = parser.parse_args(argv)
    show_progress()
    result = loop_errors_over_seeds(tuple(args.seeds), tuple(args.scenarios), args.plan)
    if args.json:
        print_json(
            {"benchmark": "calibration_loop", "seeds": args.seeds, "plan": args.plan, "loop_parameter_errors": result}
        )
        return 0
    table = []
    for seed, r in result["per_seed"].items():
        table.append({"seed": seed, "stage": "clean", **r["clean"]})
        for s in r["scenarios"]:
            for stage in ("before", "after"):
                table.append({"seed": seed, "stage": f"{s['scenario']} {stage}", **s[stage]})
    for name in ("clean_median", "before_median", "after_median", "after_worst"):
        table.append({"seed": "all", "stage": name, **result[name]})
    print_table(table, ["seed", "stage", "kt", "gravity", "inertial"])
    for seed, r in result["per_seed"].items():
        for s in r["scenarios"]:
            print(f"seed {seed} {s['scenario']}: diagnosis found {s['found']}; terms {s.get('terms')}")
        print(f"seed {seed}: after within 2x clean: {r['after_within_2x_clean']}")
    print(f"over seeds {args.seeds}: median after within 2x median clean: {result['after_within_2x_clean_median']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
