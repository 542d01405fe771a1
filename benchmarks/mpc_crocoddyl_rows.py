"""Crocoddyl's rows of benchmarks/mpc.py, run by the Python that has a working crocoddyl; prints JSON.

benchmarks/mpc.py starts this script with ``--crocoddyl-python`` (default: its own interpreter), so
Crocoddyl can live in its own environment when its wheel needs another Pinocchio than the project's
(``trajopt.mpc_crocoddyl.crocoddyl_missing_reason``). Same task, plant and figures as the other rows
(``mpc_rows``).

Usage::

    python benchmarks/mpc_crocoddyl_rows.py --robot panda --steps 200 --horizon 20 --integrator rk4
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from bench_support import DENSO_FILE, load_panda
from mpc_rows import CONTROL_DT, closed_loop_figures

from psdm_casadi import load_robot
from trajopt.mpc import MPCOptions
from trajopt.mpc_crocoddyl import build_crocoddyl_mpc, crocoddyl_missing_reason


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot", default="panda", choices=["denso", "panda"])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--horizon", type=int, default=20)
    parser.add_argument("--integrator", default="rk4", choices=["rk4", "euler"])
    parser.add_argument("--iterations", type=int, default=1, help="solver iterations per control interval")
    args = parser.parse_args(argv)
    reason = crocoddyl_missing_reason()
    if reason:
        print(json.dumps({"error": reason}))
        return 0
    import crocoddyl
    import pinocchio

    robot = load_panda() if args.robot == "panda" else load_robot(DENSO_FILE)
    options = MPCOptions(horizon=args.horizon, dt=CONTROL_DT[args.robot], integrator=args.integrator)
    rows = {}
    for solver in ("box-fddp", "fddp"):
        start = time.perf_counter()
        controller = build_crocoddyl_mpc(robot, options, solver=solver, iterations=args.iterations)
        build_s = time.perf_counter() - start
        figures = closed_loop_figures(robot, controller, args.steps)
        rows[f"crocoddyl_{solver.replace('-', '_')}"] = dict(figures, build_s=build_s)
    versions = f"crocoddyl {crocoddyl.__version__}, pinocchio {pinocchio.__version__}, {sys.executable}"
    print(json.dumps({"rows": rows, "versions": versions, "load_average": os.getloadavg()[0]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
