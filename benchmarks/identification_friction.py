"""Benchmark: LuGre friction identification, our multiple shooting vs the paper's Nelder-Mead.

For every joint of the virtual Denso (robots/denso_vs6556g.toml, paper Table 2 friction) a
friction experiment (``trajopt.friction_design.tuned_friction_signal``) is simulated with a fine-step LuGre reference
(32 sub-steps per sample) plus white torque noise. Both methods start from the same eq. 20
trust-region fit and the same data-driven initial guess; we report parameter relative errors,
R^2 on a separate validation experiment, wall time and the speed-up.

    python benchmarks/identification_friction.py [--joints 1 2] [--noise 0.02] [--free all] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from bench_support import show_progress

from identification.friction.baseline import paper_friction_fit, simulate_lugre_ode
from identification.friction.models import LUGRE_PARAMETER_NAMES, LuGreParameters
from identification.friction.shooting import ShootingOptions, fit_lugre_multiple_shooting
from identification.friction.simulation import simulate_lugre
from identification.friction.start import fit_high_speed, initial_lugre_guess
from identification.metrics import r2
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot
from trajopt.friction_design import tuned_friction_signal

ROBOT = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
TOLERANCE = {"fc": 0.05, "fs": 0.05, "fv": 0.05, "vs": 0.10, "dv": 0.10, "sigma0": 0.25, "sigma1": 0.25}


def run_joint(robot, joint, noise, free, rng, substeps=1, interval=10, nm_simulator="exponential"):
    truth = LuGreParameters.from_drive(robot.drives[joint])
    t, _, qd = tuned_friction_signal(truth, robot.qd_max[joint])
    tau_true, _ = simulate_lugre(truth, t, qd, substeps=32)
    sigma = noise * truth.fc
    tau = tau_true + sigma * rng.standard_normal(t.size)
    tv, _, qdv = tuned_friction_signal(truth, robot.qd_max[joint], frequency_scale=1.3)
    tau_v, _ = simulate_lugre(truth, tv, qdv, substeps=32)
    tau_v = tau_v + sigma * rng.standard_normal(tv.size)

    t0 = time.perf_counter()
    high_speed = fit_high_speed(qd, tau)
    initial = initial_lugre_guess(t, qd, tau, high_speed)
    init_seconds = time.perf_counter() - t0

    cpu = time.process_time()
    ours = fit_lugre_multiple_shooting(t, qd, tau, initial, ShootingOptions(substeps=substeps, interval=interval))
    ours_cpu = time.process_time() - cpu
    cpu = time.process_time()
    paper = paper_friction_fit(t, qd, tau, initial, free=free, simulator=nm_simulator)
    paper_cpu = time.process_time() - cpu
    # the paper's cost simulates LuGre with a generic ODE solver: time one such evaluation
    cpu = time.process_time()
    simulate_lugre_ode(initial, t, qd)
    ode_eval_cpu = time.process_time() - cpu
    rows = {}
    for name, params, seconds, cpu_seconds in (
        ("shooting", ours.parameters, ours.seconds, ours_cpu),
        ("nelder_mead", paper.parameters, paper.seconds, paper_cpu),
    ):
        pred, _ = simulate_lugre(params, tv, qdv)
        rows[name] = {
            "parameters": params.as_dict(),
            "relative_error": params.relative_error(truth),
            "validation_r2": r2(tau_v, pred),
            "seconds": seconds,
            "cpu_seconds": cpu_seconds,
            "within_tolerance": all(params.relative_error(truth)[k] <= TOLERANCE[k] for k in LUGRE_PARAMETER_NAMES),
        }
    rows["shooting"].update(iterations=ours.iterations, status=ours.status, solve_seconds=ours.solve_seconds)
    rows["nelder_mead"].update(evaluations=paper.evaluations, converged=paper.converged)
    return {
        "joint": joint + 1,
        "n_samples": int(t.size),
        "duration": float(t[-1] - t[0]),
        "noise_std": sigma,
        "initial_seconds": init_seconds,
        "truth": truth.as_dict(),
        "speedup": paper.seconds / ours.seconds,
        "speedup_cpu": paper_cpu / ours_cpu,
        "nm_simulator": nm_simulator,
        "ode_evaluation_cpu_seconds": ode_eval_cpu,
        "nm_with_ode_estimated_cpu_seconds": paper.evaluations * ode_eval_cpu,
        "speedup_cpu_vs_nm_with_ode_estimated": paper.evaluations * ode_eval_cpu / ours_cpu,
        **rows,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--joints", type=int, nargs="*", default=[1, 2, 3, 4, 5, 6])
    parser.add_argument("--noise", type=float, default=0.02, help="torque noise std as a fraction of fc")
    parser.add_argument("--free", choices=["presliding", "all"], default="presliding")
    parser.add_argument("--substeps", type=int, default=1)
    parser.add_argument("--interval", type=int, default=10)
    parser.add_argument(
        "--nm-simulator",
        choices=["exponential", "ode"],
        default="exponential",
        help="LuGre simulation inside the Nelder-Mead cost ('ode' is the paper's, minutes per joint)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    show_progress()
    robot = load_robot(ROBOT)
    rng = np.random.default_rng(args.seed)
    results = [
        run_joint(robot, j - 1, args.noise, args.free, rng, args.substeps, args.interval, args.nm_simulator)
        for j in args.joints
    ]
    if args.json:
        json.dump({"noise": args.noise, "free": args.free, "joints": results}, sys.stdout, indent=2)
        print()
        return 0
    head = "joint method      " + " ".join(f"{n:>7}" for n in LUGRE_PARAMETER_NAMES) + "   R2_val  wall[s]  cpu[s]  ok"
    print(
        f"relative parameter errors [%], noise std {args.noise:g} fc, Nelder-Mead over {args.free}"
        f" with the {args.nm_simulator} simulator; tolerances fc fs fv 5 %, vs dv 10 %, sigma0 sigma1 25 %"
    )
    print(head)
    for r in results:
        for name in ("shooting", "nelder_mead"):
            e = r[name]["relative_error"]
            print(
                f"{r['joint']:>5} {name:<11} "
                + " ".join(f"{100 * e[n]:7.2f}" for n in LUGRE_PARAMETER_NAMES)
                + f"  {r[name]['validation_r2']:.5f} {r[name]['seconds']:8.2f} {r[name]['cpu_seconds']:7.2f}"
                + f"  {'yes' if r[name]['within_tolerance'] else 'NO'}"
            )
        print(
            f"      speed-up {r['speedup']:.2f}x wall, {r['speedup_cpu']:.2f}x cpu"
            f"  (shared eq. 20 fit + initial guess {r['initial_seconds']:.2f} s, not counted)"
        )
        print(
            f"      Nelder-Mead with an ODE-solver cost (paper): {r['ode_evaluation_cpu_seconds']:.2f} s per evaluation"
            f" x {r['nelder_mead']['evaluations']} = {r['nm_with_ode_estimated_cpu_seconds']:.0f} s cpu (estimate),"
            f" {r['speedup_cpu_vs_nm_with_ode_estimated']:.0f}x our cpu"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
