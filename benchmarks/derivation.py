"""Derivation time and accuracy: Denso (target <= 1 s), 7-DOF Panda (target <= 10 s), and the published counts.

Usage: python benchmarks/derivation.py [--json] [--repeats N]
"""

from __future__ import annotations

import argparse
import sys
import time

from bench_support import DENSO_FILE, load_panda, print_json, print_table

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.samples import kr6, scara, two_link

TARGETS = {"Denso VS-6556G": 1.0, "panda": 10.0}
PUBLISHED = {
    "two-link planar (m, rx, Izz)": (10, 4),
    "two-link planar": (18, 6),
    "SCARA": (69, 8),
    "KUKA KR6 Agilus": (6086, 36),
    "Denso VS-6556G": (1318, 32),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--repeats", type=int, default=3, help="repeats per robot; the median is reported")
    args = parser.parse_args(argv)
    robots = [two_link(reduced=True), two_link(), scara(), kr6(), load_robot(DENSO_FILE), load_panda()]
    rows, ok = [], True
    for robot in robots:
        times = []
        for _ in range(args.repeats):
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
    if args.json:
        print_json({"robots": rows, "all_targets_met": ok})
    else:
        print_table(
            rows,
            [
                "robot",
                "n_dof",
                "p",
                "l",
                "n_gravity",
                "published_p_l",
                "seconds",
                "target_s",
                "max_rel_error_vs_pinocchio",
            ],
        )
        print("all targets met" if ok else "SOME TARGETS MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
