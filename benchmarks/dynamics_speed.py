"""Speed of the exported PSDM C code against Pinocchio and a direct CasADi SX Newton-Euler model.

For each robot, one C++ program (one process) is generated and compiled with -O3 -march=native. It
times, on the same 10^6 pre-generated random states (median of repeats):

- PSDM inverse dynamics (theta baked in) vs ``pinocchio::rnea``,
- PSDM forward dynamics vs ``pinocchio::aba``,
- PSDM regressor Y vs ``pinocchio::computeJointTorqueRegressor``,
- PSDM inverse/forward dynamics vs a CasADi SX rnea model code-generated the same way.

"PSDM" is the exported recursive form (``psdm_casadi.recursive``); the paper's sum form
(``psdm_casadi.symbolic``) is timed beside it when the model has at most 5000 functions. Both are
exported by ``codegen.export_c`` with the inlined sin/cos, like the CasADi peer.

Targets (issue 3): id >= 8x, fd >= 6x, regressor >= 10x faster than Pinocchio; faster than the
CasADi rnea in both. Usage::

    python benchmarks/dynamics_speed.py [--robots denso panda] [--samples 1000000] [--repeats 5] [--json]

Needs a C/C++ compiler, Eigen (``pip install cmeel-eigen`` or Debian's ``libeigen3-dev``) and the Pinocchio/Boost
headers of the ``pin`` wheel (cmeel prefix). Exit code 0 when every target is met, 1 otherwise,
2 when a prerequisite is missing.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

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
}
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
            f"states, median of {r['repeats']}; times in us)"
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
        errors = ", ".join(f"{k}={v:.1e}" for k, v in r["max_abs_error"].items())
        print(f"max |error| vs Pinocchio on 1000 states: {errors}")
    print(
        "\nPSDM: the exported recursive form (Newton-Euler on the base parameters' sparse standard preimage); "
        f"PSDM sum: the paper's pseudo-symbolic sum (not timed when p > {SUM_FORM_MAX_FUNCTIONS:d})."
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
                robot, base / key, n_samples=args.samples, repeats=args.repeats, log=log, key=key
            )
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    missed = missed_targets(results)
    if args.json:
        print(json.dumps({"robots": results, "targets": TARGETS, "targets_met": not missed, "targets_missed": missed}))
    else:
        print_table(results)
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
