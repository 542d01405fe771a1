"""Excitation benchmark: our multi-start Ipopt vs differential evolution (5x our time) vs 100 random trajectories.

For the Denso VS-6556G and the Franka Panda, on the inertial columns of the PSDM regressor (those
not identified by the gravity step, as in the paper's eq. 23), over the same Fourier
parametrisation and the same limits:

* ours: ``optimize_excitation`` (smooth condition-number surrogate, Ipopt, multi-start);
* DE: ``scipy.optimize.differential_evolution`` on the true condition number with a penalty for
  limit violations (``--de-mode repair``: every candidate is scaled into the limits instead),
  stopped after ``--de-factor`` (5) times our wall time, then repaired into the
  limits like ours;
* random: the best of 100 random trajectories scaled into the limits.

Every reported condition number is the true one on the same objective grid, and every trajectory's
limits are checked on a grid 10x finer than the constraint grid.

Usage: python benchmarks/excitation.py [--json] [--robots denso panda] [--harmonics 8] [--de-factor 5]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from bench_support import show_progress
from scipy.optimize import differential_evolution

from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ExcitationWarning
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, from_urdf, load_robot
from trajopt.constraints import JointLimits, fine_grid, limit_margins, scale_into_limits, verify_limits
from trajopt.criteria import condition_number, stack_regressor
from trajopt.optimize import ExcitationOptions, optimize_excitation, random_feasible_parameters
from trajopt.problem import default_constraint_samples

ROOT = Path(__file__).resolve().parents[1]
PANDA = (
    Path(sys.prefix)
    / "lib"
    / f"python{sys.version_info.major}.{sys.version_info.minor}"
    / "site-packages"
    / "cmeel.prefix"
    / "share"
    / "example-robot-data"
    / "robots"
    / "panda_description"
    / "urdf"
    / "panda.urdf"
)


def load(name):
    if name == "denso":
        return load_robot(BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml")
    if name == "panda":
        return from_urdf(PANDA, locked_joints=["panda_finger_joint1", "panda_finger_joint2"])
    raise SystemExit(f"unknown robot {name!r}; use denso or panda")


def run_robot(name, args, log):
    robot = load(name)
    model = derive_psdm(robot, seed=0)
    regressor = build_recursive_functions(model, robot).regressor
    columns = tuple(int(c) for c in np.flatnonzero(~model.gravity_mask))
    options = ExcitationOptions(
        duration=args.duration,
        harmonics=args.harmonics,
        n_starts=args.starts,
        columns=columns,
        time_limit=args.time_limit,
        quiet=args.json,
    )
    limits = JointLimits.from_robot(robot)

    # --- ours ---
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        ours = optimize_excitation(robot, regressor, options, seed=args.seed)
    par = ours.parametrization
    t_obj = par.default_grid(options.n_samples)
    n_con = default_constraint_samples(par)
    t_fine = fine_grid(par, n_con)

    def cond_of(x):
        return condition_number(stack_regressor(regressor, *par.evaluate(t_obj, x), columns))

    def verified(x):
        return verify_limits(par, x, limits, n_con)["worst"]

    log(f"{name}: ours cond {ours.cond:.4g} in {ours.seconds:.1f} s")

    # --- best of 100 random feasible trajectories ---
    rng = np.random.default_rng(args.seed + 1)
    random_conds, t0 = [], time.perf_counter()
    for _ in range(args.n_random):
        x = random_feasible_parameters(par, limits, rng, t_fine, fill=1.0 - 1e-9)
        if verified(x) >= 0:
            random_conds.append(cond_of(x))
    random_seconds = time.perf_counter() - t0
    log(f"{name}: best random cond {min(random_conds):.4g} of {len(random_conds)}")

    # --- differential evolution over the same parametrisation, 5x our wall time ---
    t_con = par.default_grid(n_con)
    lb, ub = par.bounds(limits.q_min, limits.q_max)
    coef = par.n_per_joint
    lb, ub = lb.reshape(-1, coef), ub.reshape(-1, coef)
    lb[:, :-1] = -limits.qd_max[:, None]
    ub[:, :-1] = limits.qd_max[:, None]
    bounds = list(zip(lb.ravel(), ub.ravel()))

    def repaired(x):  # decode every candidate into the limits (a stronger evolutionary baseline)
        return min(cond_of(scale_into_limits(par, x, limits, t_con, fill=1.0 - args.backoff)), 1e6)

    def penalised(x):
        m = limit_margins(limits, *par.evaluate(t_con, x))
        violation = -min(0.0, m["q"], m["qd"], m["qdd"])
        if violation > 0:
            return 1e6 * (1.0 + violation)
        return min(cond_of(x), 1e6)

    budget = args.de_factor * ours.seconds
    start = time.perf_counter()
    state = {"evaluations": 0}

    def stop(*_args, **_kwargs):
        state["evaluations"] += 1
        return time.perf_counter() - start > budget

    de = differential_evolution(
        penalised if args.de_mode == "penalty" else repaired,
        bounds,
        seed=args.seed,
        maxiter=100000,
        popsize=args.de_popsize,
        polish=False,
        tol=0,
        callback=stop,
        init="latinhypercube",
    )
    de_seconds = time.perf_counter() - start
    x_de = de.x if args.de_mode == "penalty" else scale_into_limits(par, de.x, limits, t_con, fill=1.0 - args.backoff)
    x_de = scale_into_limits(par, x_de, limits, t_fine, fill=1.0 - 1e-9)  # the same final repair ours gets
    cond_de = cond_of(x_de)
    log(f"{name}: DE cond {cond_de:.4g} after {de_seconds:.1f} s ({de.nfev} evaluations)")

    worst = min(verified(ours.parameters), verified(x_de))
    return {
        "robot": robot.name,
        "n_columns": len(columns),
        "de_mode": args.de_mode,
        "cond_ours": ours.cond,
        "cond_de": cond_de,
        "cond_random_best": min(random_conds),
        "worst_limit_margin": ours.worst_margin,
        "worst_limit_margin_all": worst,
        "seconds": ours.seconds,
        "seconds_de": de_seconds,
        "seconds_random": random_seconds,
        "de_evaluations": int(de.nfev),
        "n_random_feasible": len(random_conds),
        "ratio_de_over_ours": cond_de / ours.cond,
        "ratio_random_over_ours": min(random_conds) / ours.cond,
        "start_conds": list(ours.start_conds),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--harmonics", type=int, default=8)
    parser.add_argument("--starts", type=int, default=3)
    parser.add_argument("--time-limit", type=float, default=50.0, help="wall-time budget of ours [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--de-factor", type=float, default=5.0)
    parser.add_argument("--de-popsize", type=int, default=15)
    parser.add_argument("--n-random", type=int, default=100)
    parser.add_argument(
        "--de-mode",
        choices=("penalty", "repair"),
        default="penalty",
        help="DE handles limits by a penalty (the paper's GA) or by scaling each candidate into them",
    )
    parser.add_argument("--backoff", type=float, default=0.02, help="limit back-off of DE's repair decoding")
    args = parser.parse_args(argv)
    show_progress()

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    results = {name: run_robot(name, args, log) for name in args.robots}
    checks = {
        name: {
            "beats_de": r["cond_ours"] < r["cond_de"],
            "3x_better_than_random": r["ratio_random_over_ours"] >= 3,
            "limits_hold": r["worst_limit_margin_all"] >= 0,
            "within_60s": r["seconds"] <= 60 if name == "denso" else True,
        }
        for name, r in results.items()
    }
    if args.json:
        print(json.dumps({"results": results, "checks": checks}, default=float))
    else:
        head = (
            f"{'robot':8} {'cols':>4} {'cond ours':>10} {'cond DE(5x)':>12} {'best random':>12} {'rand/ours':>9} "
            f"{'margin':>8} {'ours s':>7} {'DE s':>7}"
        )
        print(head)
        for name, r in results.items():
            print(
                f"{name:8} {r['n_columns']:4d} {r['cond_ours']:10.4g} {r['cond_de']:12.4g} "
                f"{r['cond_random_best']:12.4g} "
                f"{r['ratio_random_over_ours']:9.2f} {r['worst_limit_margin']:8.3g} {r['seconds']:7.1f} "
                f"{r['seconds_de']:7.1f}"
            )
        print("checks:", json.dumps(checks))
    return 0 if all(all(c.values()) for c in checks.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
