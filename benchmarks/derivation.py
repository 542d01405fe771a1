"""Derivation time and accuracy: Denso (target <= 1 s), 7-DOF Panda (target <= 10 s), the published counts, and
the growth with the robot's size.

The scaling part derives ``psdm_casadi.samples.serial_arm(n)`` for n = 4..14 joints and the 2 x 7 + 1
dual-arm torso (examples/dual_arm_torso.toml, a tree) in the recursive form (base parameters from
the regressor's column space; the sum form's 5^n grid is what it replaces), each in a fresh
process: seconds, peak resident memory of that process (VmHWM, imports included: about 130 MB of
it) and the largest relative error against Pinocchio's rnea. Targets: 12 joints and the tree under 60 s and 4 GiB
each, every error under 1e-12; the time's growth exponent in n is the slope of a log-log fit.

Usage: python benchmarks/derivation.py [--json] [--repeats N] [--scaling-only] [--dofs 4 5 ... 14]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
from bench_support import DENSO_FILE, ROOT, load_panda, print_json, print_table

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.samples import kr6, scara, two_link

TARGETS = {"Denso VS-6556G": 1.0, "panda": 10.0}
TREE_FILE = ROOT / "examples" / "dual_arm_torso.toml"
SCALING_DOFS = tuple(range(4, 15))
SCALING_TARGET_DOF = 12
TARGET_SECONDS, TARGET_PEAK_MB, TARGET_ERROR = 60.0, 4096.0, 1e-12
# Run in a fresh process per robot, so that its peak resident memory is that derivation's (plus the imports).
_CHILD = """
import json, sys, time
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.derive import DeriveOptions
from psdm_casadi.samples import serial_arm

def peak_mb():  # this process's peak resident memory (VmHWM: per address space, unlike ru_maxrss kept by exec)
    line = next(x for x in open("/proc/self/status") if x.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024

spec = sys.argv[1]
robot = serial_arm(int(spec)) if spec.isdigit() else load_robot(spec)
imports_mb = peak_mb()
start = time.perf_counter()
model = derive_psdm(robot, DeriveOptions(form="recursive"))
seconds = time.perf_counter() - start
print(json.dumps({"n_dof": robot.n_dof, "seconds": seconds, "l": model.n_base, "n_gravity": model.n_gravity,
    "peak_mb": peak_mb(), "imports_mb": imports_mb,
    "max_rel_error_vs_pinocchio": model.metadata["max_rel_error_vs_pinocchio"]}))
"""
PUBLISHED = {
    "two-link planar (m, rx, Izz)": (10, 4),
    "two-link planar": (18, 6),
    "SCARA": (69, 8),
    "KUKA KR6 Agilus": (6086, 36),
    "Denso VS-6556G": (1318, 32),
}


def measure_in_child(spec: str) -> dict:
    """Derive ``serial_arm(int(spec))`` or the robot file ``spec`` in a fresh Python; its JSON line."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", _CHILD, spec], capture_output=True, text=True, env=env, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def growth_exponent(by_dof: dict) -> float:
    """Slope of log(seconds) against log(n): time grows as n to this power."""
    n = np.array(sorted(by_dof), dtype=float)
    return float(np.polyfit(np.log(n), np.log([by_dof[int(k)] for k in n]), 1)[0])


def scaling(dofs) -> tuple:
    """(rows, JSON part, all targets met) of the recursive derivation by size and of the tree."""
    rows = [{"robot": f"serial arm {n}", **measure_in_child(str(n))} for n in dofs]
    tree = {"robot": "dual_arm_torso (tree)", **measure_in_child(str(TREE_FILE))}
    seconds = {row["n_dof"]: row["seconds"] for row in rows}
    part = {
        "seconds_by_dof": seconds,
        "peak_mb_by_dof": {row["n_dof"]: row["peak_mb"] for row in rows},
        "base_parameters_by_dof": {row["n_dof"]: row["l"] for row in rows},
        "max_rel_error_by_dof": {row["n_dof"]: row["max_rel_error_vs_pinocchio"] for row in rows},
        "time_growth_exponent": growth_exponent(seconds),
        "tree_n_dof": tree["n_dof"],
        "tree_seconds": tree["seconds"],
        "tree_peak_mb": tree["peak_mb"],
        "tree_base_parameters": tree["l"],
        "tree_max_rel_error": tree["max_rel_error_vs_pinocchio"],
    }
    checked = [tree] + [row for row in rows if row["n_dof"] == SCALING_TARGET_DOF]
    ok = all(r["seconds"] < TARGET_SECONDS and r["peak_mb"] < TARGET_PEAK_MB for r in checked)
    ok &= all(r["max_rel_error_vs_pinocchio"] < TARGET_ERROR for r in [tree, *rows])
    return rows + [tree], part, ok


def published(repeats: int) -> tuple:
    """(rows, all targets met) of the published robots, derived as ``derive_psdm`` chooses (the sum form)."""
    robots = [two_link(reduced=True), two_link(), scara(), kr6(), load_robot(DENSO_FILE), load_panda()]
    rows, ok = [], True
    for robot in robots:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            model = derive_psdm(robot)
            times.append(time.perf_counter() - start)
        seconds = sorted(times)[len(times) // 2]
        row = {
            "robot": robot.name,
            "n_dof": robot.n_dof,
            "p": model.n_functions,
            "l": model.n_base,
            "n_gravity": model.n_gravity,
            "seconds": seconds,
            "max_rel_error_vs_pinocchio": model.metadata["max_rel_error_vs_pinocchio"],
        }
        if robot.name in PUBLISHED:
            published_p, published_l = PUBLISHED[robot.name]
            row["published_p_l"] = f"{published_p:d}/{published_l:d}"
            ok &= (model.n_functions, model.n_base) == PUBLISHED[robot.name]
        if robot.name in TARGETS:
            row["target_s"] = TARGETS[robot.name]
            ok &= seconds <= TARGETS[robot.name]
        ok &= row["max_rel_error_vs_pinocchio"] < 1e-9
        rows.append(row)
    return rows, ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per published robot; the median is reported")
    parser.add_argument("--scaling-only", action="store_true", help="skip the published robots")
    parser.add_argument("--dofs", type=int, nargs="+", default=list(SCALING_DOFS), help="serial arm sizes (joints)")
    args = parser.parse_args(argv)
    rows, ok = ([], True) if args.scaling_only else published(args.repeats)
    scale_rows, part, scale_ok = scaling(args.dofs)
    ok &= scale_ok
    if args.json:
        print_json({"robots": rows, **part, "all_targets_met": ok})
        return 0 if ok else 1
    if rows:
        columns = ["robot", "n_dof", "p", "l", "n_gravity", "published_p_l", "seconds", "target_s"]
        print_table(rows, [*columns, "max_rel_error_vs_pinocchio"])
        print()
    print("recursive form (base parameters from the regressor's column space), one fresh process per robot:")
    columns = ["robot", "n_dof", "l", "n_gravity", "seconds", "peak_mb", "imports_mb", "max_rel_error_vs_pinocchio"]
    print_table(scale_rows, columns)
    print(f"time grows as n^{part['time_growth_exponent']:.2f} (log-log fit over {min(args.dofs)}..{max(args.dofs)})")
    print(
        f"targets: {SCALING_TARGET_DOF} joints and the tree < {TARGET_SECONDS:g} s and < {TARGET_PEAK_MB:g} MB, "
        f"errors < {TARGET_ERROR:g}"
    )
    print("all targets met" if ok else "SOME TARGETS MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
