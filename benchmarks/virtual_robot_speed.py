"""Speed of the virtual robot: simulated seconds per wall second for the Denso, against a bare aba loop.

Usage: python benchmarks/virtual_robot_speed.py [--duration 10] [--json]
The peer is the cost floor of any Python-driven fixed-step simulator: one pinocchio.aba call per step
with no controller, friction or bookkeeping.
"""

import argparse
import json
import time

import numpy as np
import pinocchio as pin
from bench_support import show_progress

from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot
from trajopt.experiments import sine_experiment

ROBOT = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    show_progress()
    robot = load_robot(ROBOT)
    reference = sine_experiment(robot, duration=args.duration).reference()
    rows = []
    oracle = PinocchioOracle(robot)
    q = np.zeros(robot.n_dof)
    for substeps in (1, 2, 4):
        n_steps = int(args.duration * 1000 * substeps)
        start = time.perf_counter()
        for _ in range(n_steps):
            pin.aba(oracle.model, oracle.data, q, q, q)
        floor = time.perf_counter() - start
        start = time.perf_counter()
        simulate_recording(robot, reference, SimulationOptions(substeps=substeps), np.random.default_rng(0))
        wall = time.perf_counter() - start
        rows.append(
            {
                "substeps": substeps,
                "simulated_s": args.duration,
                "wall_s": wall,
                "real_time_factor": args.duration / wall,
                "aba_only_wall_s": floor,
                "ratio_vs_aba_only": wall / floor,
            }
        )
    if args.json:
        print(json.dumps({"benchmark": "virtual_robot_speed", "robot": robot.name, "rate_hz": 1000, "rows": rows}))
        return
    print(f"virtual robot, {robot.name}, 1 kHz, {args.duration:g} s of robot time")
    print(f"{'substeps':>8} {'wall [s]':>9} {'x real time':>12} {'aba-only [s]':>13} {'ratio':>6}")
    for r in rows:
        print(
            f"{r['substeps']:>8} {r['wall_s']:>9.2f} {r['real_time_factor']:>12.1f} {r['aba_only_wall_s']:>13.2f} "
            f"{r['ratio_vs_aba_only']:>6.1f}"
        )


if __name__ == "__main__":
    main()
