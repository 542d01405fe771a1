"""Batches of states per call: the exported batch C (codegen.batch) against Pinocchio's parallel algorithms.

For each robot, one C++ program (-O3 -march=native, OpenMP) times batches of 1024 states per call with
one thread (per core: states per CPU-second) and all threads (states per wall-clock second):

- PSDM batch inverse dynamics vs ``pinocchio::rneaInParallel`` and Pinocchio's CppADCodeGen rnea in an
  OpenMP loop,
- PSDM batch forward dynamics vs ``pinocchio::abaInParallel`` and the CppADCodeGen aba in an OpenMP loop,
- PSDM batch regressor vs ``computeJointTorqueRegressor`` in an OpenMP loop,

with the single-call exported C in an OpenMP loop beside them, and the inverse dynamics per core as a
ratio to the GPU anchor (GRiD: about 75 M states/s for a 7-DOF arm on an RTX 5090, N = 1024). When the
CppADCodeGen peer cannot be built (``--no-cppadcg``, or missing wheels), ``cppadcg_error`` says why.

Target (issue 18): per core, at least 2x the best CPU peer. Usage::

    python benchmarks/batch_speed.py [--robots denso panda] [--batch 1024] [--batches 64] [--repeats 5] [--json]

``--json`` prints ``{"robots": {name: {...}}}`` with ``batch_states_per_s_per_core``,
``batch_states_per_s_all_cores``, ``batch_speedup_vs_best_cpu_peer``, ``batch_vs_gpu_anchor_per_core`` and
``batch_thread_scaling`` (wall-clock states per second on all threads over one thread, ours and Pinocchio's, per
function; issue 29 asks >= 1.8 on two idle cores), and the machine's load average when it ran.
Exit code 0 when the target is met, 1 otherwise, 2 when a prerequisite is missing.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from codegen.peers.batch_speed import BATCH_ROWS, CPU_PEERS, GPU_ANCHOR_STATES_PER_S, measure_batch_speed
from codegen.peers.speed import find_prerequisites
from psdm_casadi.errors import SolverError

TARGET = 2.0


def print_batch_table(key: str, result: dict) -> None:
    """One robot's rows: M states/s per core and on all cores, ours and Pinocchio's."""
    harness = result["batch"]
    rates, threads = harness["states_per_s"], harness["threads"]
    print(
        f"\n{key}: batches of {harness['batch_size']} states, M states/s (median of {harness['repeats']}; per core = "
        f"1 thread, per CPU-second; all = {threads} threads, per wall-clock second; lanes of {harness['lane_width']})"
    )
    print(
        f"{'function':18s} {'PSDM batch':>11s} {'all cores':>10s} {'PSDM single':>12s} {'Pinocchio':>10s} "
        f"{'all cores':>10s} {'CppADCodeGen':>13s} {'all cores':>10s} {'per core vs best':>17s}"
    )
    for label, ours, _ in BATCH_ROWS:
        mine = rates[f"psdm_batch_{ours}_t1"] / 1e6
        cells = [mine, rates[f"psdm_batch_{ours}_t{threads}"] / 1e6, rates[f"psdm_single_{ours}_t1"] / 1e6]
        for peer in (*CPU_PEERS[ours], None)[:2]:
            cells += [rates.get(f"{peer}_t{t}", float("nan")) / 1e6 for t in (1, threads)]
        best = max(rates[f"{peer}_t1"] for peer in CPU_PEERS[ours] if f"{peer}_t1" in rates) / 1e6
        print(
            f"{label:18s} {cells[0]:11.2f} {cells[1]:10.2f} {cells[2]:12.2f} {cells[3]:10.2f} {cells[4]:10.2f} "
            f"{cells[5]:13.2f} {cells[6]:10.2f} {mine / best:16.1f}x"
        )
    if harness.get("cppadcg_error"):
        print(f"CppADCodeGen not timed: {harness['cppadcg_error'].splitlines()[0]}")
    print(
        f"inverse dynamics per core / GPU anchor (GRiD, RTX 5090, {GPU_ANCHOR_STATES_PER_S / 1e6:.0f} M states/s): "
        f"{result['batch_vs_gpu_anchor_per_core']:.3f}"
    )
    scaling = result["batch_thread_scaling"]
    print(
        f"wall-clock speed-up, {threads} threads over 1 (batch_thread_scaling): "
        + ", ".join(
            f"{label} {scaling['psdm'][key]:.2f}x (Pinocchio {scaling['pinocchio'].get(key, float('nan')):.2f}x)"
            for label, key, _ in BATCH_ROWS
        )
    )
    print("max |error| vs Pinocchio: " + ", ".join(f"{k}={v:.1e}" for k, v in harness["max_abs_error"].items()))


def main(argv=None) -> int:
    from dynamics_speed import robots  # the benchmark robots (Panda with its fingers locked), one definition

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"], choices=sorted(robots()))
    parser.add_argument("--batch", type=int, default=1024, help="states per call")
    parser.add_argument("--batches", type=int, default=64, help="calls per round (distinct states)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=None, help="threads of the all-cores figures (default: all)")
    parser.add_argument("--no-cppadcg", action="store_true", help="do not build the CppADCodeGen peer")
    parser.add_argument(
        "--cppadcg-cache", type=Path, default=None, help="folder of a compiled CppADCodeGen generator to reuse"
    )
    parser.add_argument("--keep", type=Path, default=None, help="build folder to keep (default: a temp folder)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with per-robot entries")
    args = parser.parse_args(argv)
    try:
        find_prerequisites()
    except SolverError as exc:
        print(f"batch_speed: {exc}", file=sys.stderr)
        return 2

    base = args.keep if args.keep is not None else Path(tempfile.mkdtemp(prefix="psdm_batch_bench_"))
    results = {}
    try:
        for key in args.robots:
            results[key] = measure_batch_speed(
                robots()[key](),
                base / key,
                batch=args.batch,
                n_batches=args.batches,
                repeats=args.repeats,
                threads=args.threads,
                cppadcg=not args.no_cppadcg,
                cppadcg_cache=args.cppadcg_cache or base / "cppadcg_generator",
                log=lambda message: print(message, file=sys.stderr, flush=True),
            )
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    missed = [
        f"{key} batch_speedup_vs_best_cpu_peer {r['batch_speedup_vs_best_cpu_peer']:.2f} < {TARGET:g}"
        for key, r in results.items()
        if not r["batch_speedup_vs_best_cpu_peer"] >= TARGET
    ]
    load = os.getloadavg()[0]  # the thread-scaling figure means something only on an idle machine
    if args.json:
        print(
            json.dumps(
                {
                    "robots": results,
                    "target": TARGET,
                    "targets_met": not missed,
                    "targets_missed": missed,
                    "load_average_1min": load,
                }
            )
        )
    else:
        for key, result in results.items():
            print_batch_table(key, result)
        print(f"\nmachine load average (1 min) at the end: {load:.2f} on {os.cpu_count()} cores")
        print(
            f"\ntarget: batch_speedup_vs_best_cpu_peer >= {TARGET:g}: " + ("met" if not missed else "; ".join(missed))
        )
    return 0 if not missed else 1


if __name__ == "__main__":
    sys.exit(main())
