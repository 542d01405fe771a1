"""Speed of the exported PSDM C code against Pinocchio and a direct CasADi SX Newton-Euler model.

For each robot, one C++ program (one process) is generated and compiled with -O3 -march=native. It
times (thread CPU time, so that other processes on a shared machine do not count), on the same 10^6
pre-generated random states (median of repeats):

- PSDM inverse dynamics (theta baked in) vs ``pinocchio::rnea``,
- PSDM forward dynamics vs ``pinocchio::aba``,
- PSDM regressor Y vs ``pinocchio::computeJointTorqueRegressor``,
- PSDM inverse/forward dynamics vs a CasADi SX rnea model code-generated the same way,
- the same three vs Pinocchio's own code generation with CppADCodeGen (``codegen.peers.cppadcg``),
- the exported PSDM derivatives (``codegen.derivatives``: tau and d(tau)/d(q, qd, qdd); qdd and
  d(qdd)/d(q, qd, tau); the rows' reverse sweeps in vector lanes, ``codegen.lane_derivatives``) vs
  ``pinocchio::computeRNEADerivatives`` / ``computeABADerivatives`` and vs the fastest CppADCodeGen route
  (the Jacobian of the generated rnea/aba, or the generated analytical derivatives).

"PSDM" is the exported recursive form (``psdm_casadi.recursive``); the paper's sum form
(``psdm_casadi.symbolic``) is timed beside it when the model has at most 5000 functions. Both are
exported by ``codegen.export_c`` with the inlined sin/cos, like the CasADi peer.

Targets (issues 3 and 18): id >= 8x, fd >= 6x, regressor >= 10x faster than Pinocchio; faster than the
CasADi rnea in both; each >= 2x faster than CppADCodeGen; derivatives >= 5x faster than Pinocchio's
analytical ones and >= 2x faster than CppADCodeGen's. When the CppADCodeGen peer cannot be built, its ratios
are null and ``cppadcg_error`` says why. Usage::

    python benchmarks/dynamics_speed.py [--robots denso panda] [--samples 1000000] [--repeats 5] [--json]

Needs a C/C++ compiler, Eigen (``pip install cmeel-eigen`` or Debian's ``libeigen3-dev``) and the Pinocchio/Boost
headers of the ``pin`` wheel (cmeel prefix); the CppADCodeGen peer needs the ``cmeel-cppad`` and
``cmeel-cppadcodegen`` wheels (``pip install -e '.[bench]'``). Exit code 0 when every target is met, 1 otherwise,
2 when a prerequisite is missing.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

from codegen.peers.batch_speed import measure_batch_speed
from codegen.peers.speed import SPEED_ROWS, SUM_FORM_MAX_FUNCTIONS, cmeel_prefix, find_prerequisites, measure_speed
from psdm_casadi.errors import SolverError
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, from_urdf, load_robot

REPO = Path(__file__).resolve().parents[1]

TARGETS = {
    "id_speedup_vs_pinocchio": 8.0,
    "fd_speedup_vs_pinocchio": 6.0,
    "regressor_speedup_vs_pinocchio": 10.0,
    "id_speedup_vs_casadi_rnea": 1.0,
    "fd_speedup_vs_casadi_rnea": 1.0,
    "id_speedup_vs_cppadcg": 2.0,
    "fd_speedup_vs_cppadcg": 2.0,
    "regressor_speedup_vs_cppadcg": 2.0,
    "id_derivatives_speedup_vs_pinocchio": 5.0,
    "fd_derivatives_speedup_vs_pinocchio": 5.0,
    "id_derivatives_speedup_vs_cppadcg": 2.0,
    "fd_derivatives_speedup_vs_cppadcg": 2.0,
    "batch_speedup_vs_best_cpu_peer": 2.0,
}
# (label, our key, Pinocchio key, CppADCodeGen keys) of the table against the strongest peers.
PEER_ROWS = (
    ("inverse dynamics", "psdm_id", "pinocchio_rnea", ("cppadcg_rnea",)),
    ("forward dynamics", "psdm_fd", "pinocchio_aba", ("cppadcg_aba",)),
    ("regressor Y", "psdm_regressor", "pinocchio_regressor", ("cppadcg_regressor",)),
    (
        "ID derivatives",
        "psdm_id_derivatives",
        "pinocchio_rnea_derivatives",
        ("cppadcg_rnea_jacobian", "cppadcg_rnea_derivatives"),
    ),
    (
        "FD derivatives",
        "psdm_fd_derivatives",
        "pinocchio_aba_derivatives",
        ("cppadcg_aba_jacobian", "cppadcg_aba_derivatives"),
    ),
)
PANDA_LOCKED = ("panda_finger_joint1", "panda_finger_joint2")


def robots():
    """The benchmark robots by short name: the Denso VS-6556G and the 7-DOF Panda (fingers locked)."""
    panda = cmeel_prefix() / "share" / "example-robot-data" / "robots" / "panda_description" / "urdf" / "panda.urdf"
    return {
        "denso": lambda: load_robot(BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"),
        "panda": lambda: from_urdf(panda, locked_joints=PANDA_LOCKED, name="panda"),
    }


def _us(ns: dict, key) -> float:
    return ns[key] / 1e3 if key and key in ns else float("nan")


def print_table(results) -> None:
    for r in results.values():
        ns = r["ns"]
        print(
            f"\n{r['robot']} (n_dof={r['n_dof']}, p={r['n_functions']}, l={r['n_base']}; {r['n_samples']} random "
            f"states, median of {r['repeats']}; thread CPU time in us)"
        )
        print(
            f"{'function':18s} {'PSDM':>8s} {'PSDM sum':>9s} {'Pinocchio':>10s} {'CasADi NE':>10s} "
            f"{'vs Pinocchio':>13s} {'vs CasADi NE':>13s} {'sum vs Pinocchio':>17s}"
        )
        for label, suffix, pin_key, peer_key in SPEED_ROWS:
            ours, summed = _us(ns, f"psdm_{suffix}"), _us(ns, f"psdm_sum_{suffix}")
            pin_t, peer_t = _us(ns, pin_key), _us(ns, peer_key)
            print(
                f"{label:18s} {ours:8.3f} {summed:9.3f} {pin_t:10.3f} {peer_t:10.3f} {pin_t / ours:12.1f}x "
                f"{peer_t / ours:12.2f}x {pin_t / summed:16.1f}x"
            )
        ops = {**r.get("n_operations", {}), **r["casadi_rnea_n_operations"]}
        print("arithmetic operations: " + ", ".join(f"{k}={v}" for k, v in ops.items()))
        lanes = r.get("lane_operations", {})
        if lanes:
            print(
                "derivatives in vector lanes (scalar + vector instructions): "
                + ", ".join(f"{k}={v['scalar']}+{v['vector']}" for k, v in lanes.items())
            )
        print_peer_table(r)
        errors = ", ".join(f"{k}={v:.1e}" for k, v in r["max_abs_error"].items())
        print(f"max |error| vs Pinocchio on 1000 states: {errors}")
    print(
        "\nPSDM: the exported recursive form (Newton-Euler on the base parameters' sparse standard preimage); "
        f"PSDM sum: the paper's pseudo-symbolic sum (not timed when p > {SUM_FORM_MAX_FUNCTIONS:d})."
    )


def print_peer_table(r) -> None:
    """Per call and derivatives against Pinocchio and its CppADCodeGen code (the fastest of its routes)."""
    ns = r["ns"]
    print(
        f"\n{'against the strongest peers':28s} {'PSDM':>8s} {'Pinocchio':>10s} {'CppADCodeGen':>13s} "
        f"{'vs Pinocchio':>13s} {'vs CppADCodeGen':>16s}  CppADCodeGen route"
    )
    for label, ours_key, pin_key, cg_keys in PEER_ROWS:
        ours, pin_t = _us(ns, ours_key), _us(ns, pin_key)
        timed = [k for k in cg_keys if k in ns]
        cg_key = min(timed, key=lambda k: ns[k]) if timed else None
        cg_t = _us(ns, cg_key)
        print(
            f"{label:28s} {ours:8.3f} {pin_t:10.3f} {cg_t:13.3f} {pin_t / ours:12.1f}x {cg_t / ours:15.2f}x  "
            f"{cg_key or 'not built'}"
        )
    if r.get("casadi_pinocchio_error"):
        print(f"Pinocchio on CasADi SX peer {r['casadi_pinocchio_error']}")
    if r.get("cppadcg_error"):
        print(f"CppADCodeGen peer not built: {r['cppadcg_error']}")
    else:
        print(
            "CppADCodeGen times, all routes: "
            + ", ".join(f"{k}={v / 1e3:.3f}" for k, v in ns.items() if "cppadcg" in k)
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"], choices=sorted(robots()))
    parser.add_argument("--samples", type=int, default=1_000_000, help="random states per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--keep", type=Path, default=None, help="build folder to keep (default: a temp folder)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with per-robot entries")
    args = parser.parse_args(argv)
    try:
        find_prerequisites()
    except SolverError as exc:
        sys.exit(f"dynamics_speed: {exc}")

    def log(message):
        print(message, file=sys.stderr, flush=True)

    base = args.keep if args.keep is not None else Path(tempfile.mkdtemp(prefix="psdm_bench_"))
    results = {}
    try:
        for key in args.robots:
            robot = robots()[key]()
            results[key] = measure_speed(
                robot,
                base / key,
                n_samples=args.samples,
                repeats=args.repeats,
                log=log,
                key=key,
                cppadcg_cache=base / "cppadcg_generator",
            )
            results[key].update(  # issue 18, item 3: batches of states (reuses the CppADCodeGen generator)
                measure_batch_speed(robot, base / f"{key}_batch", cppadcg_cache=base / "cppadcg_generator", log=log)
            )
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    missed = missed_targets(results)
    if args.json:
        print(json.dumps({"robots": results, "targets": TARGETS, "targets_met": not missed, "targets_missed": missed}))
    else:
        print_table(results)
        from batch_speed import print_batch_table  # beside this script

        for key, r in results.items():
            print_batch_table(key, r)
        print("\ntargets: " + ", ".join(f"{k} >= {v:g}" for k, v in TARGETS.items()))
        print("all met" if not missed else "NOT met: " + "; ".join(missed))
    return 0 if not missed else 1


def missed_targets(results) -> list:
    """``["panda regressor_speedup_vs_pinocchio 9.50 < 10", ...]``: every robot's ratio below its target (or
    missing)."""
    missed = []
    for key, r in results.items():
        for name, target in TARGETS.items():
            value = r.get(name)
            value = float("nan") if value is None else float(value)
            if not value >= target:
                missed.append(f"{key} {name} {value:.2f} < {target:g}")
    return missed


if __name__ == "__main__":
    sys.exit(main())
