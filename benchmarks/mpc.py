"""Time of one MPC step: the compiled real-time iteration, the full solve, and Crocoddyl, on one task.

For the Denso and the Panda (fingers locked) a nonlinear tracking MPC (multiple shooting, torque
and joint position/velocity bounds, RK4 or semi-implicit Euler per ``--integrator``) runs in
closed loop against Pinocchio's aba integrated by RK4 with 4 substeps per interval
(``mpc_rows``: the same reference, horizon, interval, weights, limits and plant for every row):

- ``psdm_rti``: ours, the real-time iteration (``trajopt.mpc_rti``): one Gauss-Newton SQP step per
  interval from the shifted solution, the PSDM dynamics and their derivatives through the inverse
  dynamics, all one code-generated C function compiled with -O3 -march=native. The QP per
  ``--qp-solver``: ``riccati`` (the default; ``trajopt.riccati_qp``, this package's C for the stage
  structure: the exact solution by one Riccati recursion when no bound is active, else an interior
  point of at most ``--qp-iterations``), or ``hpipm`` (Riccati interior point, at most
  ``--qp-iterations``, linking the HPIPM and BLASFEO built for this CPU by ``make hpipm`` or named by
  ``$PSDM_HPIPM_DIR``, else CasADi's portable copies; the JSON's ``hpipm_blasfeo`` says which);
- ``psdm_sqp``: the previous path, CasADi's sqpmethod re-solving the NLP each interval (HPIPM QPs,
  at most ``--max-iter`` iterations, jit-compiled functions, Python around the solver);
- ``crocoddyl_box_fddp``, ``crocoddyl_fddp`` (Panda): Crocoddyl's BoxFDDP (torque bounds) and FDDP
  with Pinocchio's analytical derivatives, ``--crocoddyl-iterations`` per interval from the shifted
  solution, one thread; the same cost term by term (``trajopt.mpc_crocoddyl``). Run by
  ``--crocoddyl-python`` (``mpc_crocoddyl_rows.py``), since Crocoddyl's wheels need the Pinocchio
  they were built for; skipped with the reason when that Python has none that works;
- ``--dynamics-peers``: the full solve on other dynamics (``psdm_ad``, ``psdm_external``,
  ``casadi_rnea``, ``casadi_rnea_id_derivatives``, ``pinocchio_callback``, ``pinocchio_casadi``).

``--model MODEL.json``: ``psdm_rti`` and ``psdm_sqp`` run on a calibrated model written by ``psdm identify``
(its rigid body, friction and offsets, as ``psdm validate`` predicts; ``examples/mpc_rti_calibrated.py``)
instead of the robot file's parameters; the plant stays the robot file's.

Per row: mean and worst wall time of a step, mean CPU time of the process (the honest figure on a
shared machine), iterations, RMS tracking error of the plant and the largest limit violation.
``rate_hz`` is 1 / mean step wall time of ``psdm_rti`` (``rate_hz_cpu``: of its CPU time);
``speedup_vs_crocoddyl`` the fastest Crocoddyl row's mean step over ours (wall; ``_cpu`` for CPU
time), measured in the same run.
Targets (issue 29, Panda): >= 1 kHz, faster than Crocoddyl at equal (within 0.1 %) or better
tracking RMSE, no limit violation.

Usage::

    python benchmarks/mpc.py [--robots denso panda] [--steps 200] [--horizon 20] [--integrator rk4]
                             [--qp-solver riccati] [--qp-iterations 4] [--crocoddyl-python PATH]
                             [--dynamics-peers] [--json]
                             [--model MODEL.json]  # ours on a calibrated model (psdm identify) instead

Exit code 0 when the targets are met, 1 otherwise, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_support import DENSO_FILE, load_panda, print_json, print_table, show_progress
from mpc_rows import CONTROL_DT, closed_loop_figures

from codegen.build import build_library
from codegen.calibrated import build_calibrated_functions
from codegen.export import export_c
from codegen.peers.pinocchio_callback import PinocchioAba
from codegen.peers.rnea_sx import build_rnea_functions
from identification.calibration.calibrated_model import read_calibrated_model
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from trajopt.hpipm_c import hpipm_folders
from trajopt.mpc import MPCOptions, build_mpc
from trajopt.mpc_model import build_forward_dynamics_jacobian
from trajopt.mpc_rti import QP_MODES, RTI_QP_SOLVERS, build_rti, compile_rti

LOG = logging.getLogger("benchmarks.mpc")
TARGET_RATE_HZ = 1000.0
# tracking RMSEs within 0.1 % count as equal (the same task converges to the same closed loop: 4 digits agree)
RMSE_EQUAL = 1e-3
HERE = Path(__file__).resolve().parent


def pinocchio_casadi_dynamics(oracle):
    """``(q, qd, tau) -> qdd`` from ``pinocchio.casadi``, or the reason it cannot be built here."""
    try:
        import pinocchio.casadi as cpin
    except ImportError as error:
        return None, (
            f"import pinocchio.casadi failed ({error}): the pip 'pin' wheel is built without CasADi support "
            "(it ships the C++ header pinocchio/autodiff/casadi.hpp but no Python binding); conda-forge's "
            "pinocchio has it"
        )
    import casadi as ca

    model = cpin.Model(oracle.model)
    data = model.createData()
    q, qd, tau = (ca.SX.sym(name, oracle.model.nv) for name in ("q", "qd", "tau"))
    qdd = cpin.aba(model, data, q, qd, tau)
    return ca.Function("forward_dynamics", [q, qd, tau], [qdd], ["q", "qd", "tau"], ["qdd"]), None


def exported_dynamics(forward_dynamics, folder):
    """The forward dynamics and its Jacobians as exported C, compiled and loaded by ``casadi.external``."""
    library = build_library(
        export_c([forward_dynamics], Path(folder) / "c", jacobians=True),
        build_dir=Path(folder) / "build",
        flags=("-O3", "-march=native"),
    )
    return library.function("psdm_forward_dynamics"), library.function("psdm_forward_dynamics_jac")


def dynamics_peers(robot, ours, folder):
    """Other forward dynamics for the full solve, by name: (casadi.Function or None, Jacobian or None, reason)."""
    oracle = PinocchioOracle(robot)
    cpin, reason = pinocchio_casadi_dynamics(oracle)
    rnea = build_rnea_functions(oracle.model)
    psdm = ours.forward_dynamics
    return {
        "psdm_ad": (psdm, None, None),
        "psdm_external": (*exported_dynamics(psdm, folder), None),
        "casadi_rnea": (rnea.forward_dynamics, None, None),
        "casadi_rnea_id_derivatives": (
            rnea.forward_dynamics,
            build_forward_dynamics_jacobian(rnea.forward_dynamics, rnea.inverse_dynamics, rnea.mass_matrix),
            None,
        ),
        "pinocchio_casadi": (cpin, None, reason),
        "pinocchio_callback": (PinocchioAba(oracle.model), None, None),
    }


def calibrated_functions(model_file, robot):
    """The calibrated model's Functions (rigid body, friction, offsets: what ``psdm validate`` predicts with)."""
    loaded = read_calibrated_model(model_file)
    if loaded.robot.n_dof != robot.n_dof:
        raise ParameterError(
            f"benchmarks/mpc.py --model must be identified for the robot of --robots ({robot.n_dof} joints); "
            f"{model_file} holds {loaded.robot.n_dof}. Pass that robot's model file."
        )
    return build_calibrated_functions(loaded.calibrated, loaded.model, loaded.robot)


def timed_build(build):
    start = time.perf_counter()
    controller = build()
    return controller, time.perf_counter() - start


def crocoddyl_rows(name, args) -> dict:
    """Crocoddyl's rows from ``mpc_crocoddyl_rows.py`` run by ``--crocoddyl-python``; or the reason they are missing."""
    command = [args.crocoddyl_python, str(HERE / "mpc_crocoddyl_rows.py"), "--robot", name, "--steps", str(args.steps),
               "--horizon", str(args.horizon), "--integrator", args.integrator,
               "--iterations", str(args.crocoddyl_iterations)]  # fmt: skip
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=os.pathsep.join([str(HERE.parent), str(HERE)]))
    result = subprocess.run(command, capture_output=True, text=True, env=env)
    lines = [line for line in result.stdout.splitlines() if line.startswith("{")]
    if result.returncode != 0 or not lines:
        tail = " ".join(result.stderr.strip().splitlines()[-3:])
        return {"error": f"{args.crocoddyl_python} could not run the Crocoddyl rows: {tail}"}
    return json.loads(lines[-1])


def run_robot(name, robot, args):
    dt = CONTROL_DT[name]
    options = MPCOptions(horizon=args.horizon, dt=dt, integrator=args.integrator, rk4_steps=args.substeps,
                         solver="sqpmethod",
                         qp_solver="hpipm", max_iter=args.max_iter, jit=True)  # fmt: skip
    rti_options = dataclasses.replace(options, max_iter=args.qp_iterations, tol=args.qp_tol)
    start = time.perf_counter()
    model = derive_psdm(robot)
    ours = build_recursive_functions(model, robot, model.base_parameters(robot.nominal_dynamic_parameters()))
    LOG.info("%s: PSDM model derived in %.1f s", name, time.perf_counter() - start)
    dynamics, friction = (ours, True) if args.model is None else (calibrated_functions(args.model, robot), False)
    jacobian = build_forward_dynamics_jacobian(
        dynamics.forward_dynamics, dynamics.inverse_dynamics, dynamics.mass_matrix
    )
    rows, skipped = {}, {}
    with tempfile.TemporaryDirectory(prefix="psdm-mpc-") as folder:
        LOG.info("%s: compiling the RTI step", name)
        rti, build_s = timed_build(
            lambda: compile_rti(
                build_rti(
                    robot,
                    dynamics.forward_dynamics,
                    rti_options,
                    friction=friction,
                    forward_dynamics_jacobian=jacobian,
                    qp_mode=args.qp_mode,
                    qp_solver=args.qp_solver,
                ),  # fmt: skip
                Path(folder) / "rti",
            )
        )
        rows["psdm_rti"] = dict(closed_loop_figures(robot, rti, args.steps), build_s=build_s)
        LOG.info("%s: the full solve (sqpmethod)", name)
        sqp, build_s = timed_build(
            lambda: build_mpc(
                robot, dynamics.forward_dynamics, options, friction=friction, forward_dynamics_jacobian=jacobian
            )
        )
        rows["psdm_sqp"] = dict(closed_loop_figures(robot, sqp, args.steps), build_s=build_s)
        if args.dynamics_peers:
            for peer, (dynamics, peer_jacobian, reason) in dynamics_peers(robot, ours, folder).items():
                if dynamics is None:
                    skipped[peer] = reason
                    continue
                LOG.info("%s: the full solve with %s dynamics", name, peer)
                controller, build_s = timed_build(
                    lambda d=dynamics, j=peer_jacobian: build_mpc(robot, d, options, forward_dynamics_jacobian=j)
                )
                rows[peer] = dict(closed_loop_figures(robot, controller, args.steps), build_s=build_s)
    versions = None
    if name == "panda":
        LOG.info("%s: Crocoddyl (%s)", name, args.crocoddyl_python)
        croc = crocoddyl_rows(name, args)
        rows.update(croc.get("rows", {}))
        versions = croc.get("versions")
        if "error" in croc:
            skipped["crocoddyl"] = croc["error"]
    else:
        skipped["crocoddyl"] = (
            "Panda only: Crocoddyl's free forward dynamics has no model of the Denso's drive friction"
        )
    return summary(rows, skipped, rti_options, args, dt, versions)


def summary(rows, skipped, rti_options, args, dt, versions) -> dict:
    ours = rows["psdm_rti"]
    croc = {k: r for k, r in rows.items() if k.startswith("crocoddyl") and r["limit_violation"] == 0.0}
    fastest = min(croc, key=lambda k: croc[k]["mean_step_ms"]) if croc else None
    return dict(
        rate_hz=1e3 / ours["mean_step_ms"],
        rate_hz_cpu=1e3 / ours["mean_step_cpu_ms"],
        tracking_rmse=ours["tracking_rmse"],
        limit_violation=ours["limit_violation"],
        speedup_vs_crocoddyl=croc[fastest]["mean_step_ms"] / ours["mean_step_ms"] if fastest else None,
        speedup_vs_crocoddyl_cpu=croc[fastest]["mean_step_cpu_ms"] / ours["mean_step_cpu_ms"] if fastest else None,
        fastest_crocoddyl=fastest,
        crocoddyl_versions=versions,
        rti=(
            f"Riccati (exact when no bound is active, else interior point of {rti_options.max_iter} iterations at "
            f"most, tolerance {rti_options.tol:g})"
            if args.qp_solver == "riccati"
            else f"HPIPM {args.qp_mode}, {rti_options.max_iter} iterations at most, tolerance {rti_options.tol:g}"
        ),
        qp_solver=args.qp_solver,
        full_solve=f"sqpmethod (hpipm QPs), Gauss-Newton Hessian, max {args.max_iter} iterations per step, jit",
        controller_model=(
            "the robot file's nominal parameters and drive friction"
            if args.model is None
            else f"calibrated model {args.model} (rigid body, friction, offsets; friction=False)"
        ),
        hpipm_blasfeo=str(hpipm_folders()[1]) if args.qp_solver == "hpipm" else None,
        integrator=args.integrator,
        substeps=args.substeps,
        horizon=args.horizon,
        dt=dt,
        n_steps=args.steps,
        load_average=os.getloadavg()[0],
        rows=rows,
        skipped=skipped,
    )


COLUMNS = [
    "mean_step_ms",
    "max_step_ms",
    "mean_step_cpu_ms",
    "mean_iterations",
    "tracking_rmse",
    "max_abs_error",
    "limit_violation",
    "build_s",
]


def print_results(results) -> None:
    for name, r in results.items():
        steps = f"{r['integrator']} x {r['substeps']}, {r['n_steps']} closed-loop steps"
        print(f"\n{name}: N={r['horizon']}, dt={r['dt'] * 1e3:.0f} ms, {steps}; ours on {r['controller_model']}")
        print_table([dict(row=k, **{c: v.get(c) for c in COLUMNS}) for k, v in r["rows"].items()], ["row", *COLUMNS])
        for row, reason in r["skipped"].items():
            print(f"  {row}: not run: {reason}")
        speedup = r["speedup_vs_crocoddyl"]
        print(
            f"  psdm_rti: {r['rti']}; rate {r['rate_hz']:.0f} Hz wall, {r['rate_hz_cpu']:.0f} Hz CPU "
            f"(target {TARGET_RATE_HZ:.0f} Hz on the Panda)"
            + (
                f"; {speedup:.2f}x {r['fastest_crocoddyl']} wall, {r['speedup_vs_crocoddyl_cpu']:.2f}x CPU"
                if speedup
                else ""
            )
        )
        if r["crocoddyl_versions"]:
            print(f"  {r['crocoddyl_versions']}")
        load = f"load average {r['load_average']:.1f} on {os.cpu_count()} cores"
        blasfeo = f"; HPIPM/BLASFEO from {r['hpipm_blasfeo']}" if r["hpipm_blasfeo"] else ""
        print(f"  {load}: wall times include waiting for other jobs{blasfeo}")


def missed_targets(results) -> list:
    missed = []
    for name, r in results.items():
        if r["limit_violation"] > 0:
            missed.append(f"{name}: psdm_rti violates a limit by {r['limit_violation']:.3g}")
        if name != "panda":
            continue
        if r["rate_hz"] < TARGET_RATE_HZ:
            missed.append(f"panda: {r['rate_hz']:.0f} Hz < {TARGET_RATE_HZ:.0f} Hz")
        fastest = r["fastest_crocoddyl"]
        if fastest is None:
            missed.append("panda: no Crocoddyl row to compare with")
        elif r["speedup_vs_crocoddyl"] <= 1.0:
            missed.append(f"panda: {fastest} faster per step ({r['speedup_vs_crocoddyl']:.2f}x)")
        elif r["tracking_rmse"] > (1 + RMSE_EQUAL) * r["rows"][fastest]["tracking_rmse"]:
            missed.append(f"panda: {fastest} tracks better")
    return missed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"], choices=["denso", "panda"])
    parser.add_argument("--steps", type=int, default=200, help="closed-loop control steps per row")
    parser.add_argument("--horizon", type=int, default=20)
    parser.add_argument("--integrator", default="rk4", choices=["rk4", "euler"])
    parser.add_argument("--qp-iterations", type=int, default=4, help="interior-point iteration cap of the RTI step")
    parser.add_argument("--qp-solver", default="riccati", choices=RTI_QP_SOLVERS, help="the RTI step's QP solver")
    parser.add_argument("--qp-mode", default="speed_abs", choices=QP_MODES, help="HPIPM's preset in the RTI step")
    parser.add_argument("--qp-tol", type=float, default=1e-3, help="QP residual tolerance of the RTI step")
    parser.add_argument("--max-iter", type=int, default=3, help="SQP iteration cap of the full solve per step")
    parser.add_argument("--crocoddyl-python", default=os.environ.get("PSDM_CROCODDYL_PYTHON", sys.executable))
    parser.add_argument("--crocoddyl-iterations", type=int, default=1, help="FDDP iterations per step")
    parser.add_argument("--dynamics-peers", action="store_true", help="also the full solve on other dynamics")
    parser.add_argument("--model", help="calibrated-model file (psdm identify --out) for psdm_rti and psdm_sqp")
    substeps = "integrator steps per interval of psdm_rti and psdm_sqp (Crocoddyl keeps one); 4 at 5 ms for a "
    substeps += "calibrated model, whose identified friction is steeper than the robot file's law"
    parser.add_argument("--substeps", type=int, default=1, help=substeps)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    for flag in ("steps", "horizon", "max_iter", "qp_iterations", "crocoddyl_iterations", "substeps"):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag.replace('_', '-')} must be a positive integer; got {getattr(args, flag)}.")
    if args.model is not None and len(args.robots) != 1:
        parser.error(f"--model needs one robot in --robots (the one it was identified for); got {args.robots}.")
    show_progress()
    loaders = {"denso": lambda: load_robot(DENSO_FILE), "panda": load_panda}
    try:
        results = {name: run_robot(name, loaders[name](), args) for name in args.robots}
    except ParameterError as error:  # a model file that does not read or fit the robot
        print(f"error: {error}", file=sys.stderr)
        return 2
    if args.json:
        print_json({"robots": results})
    else:
        print_results(results)
    missed = missed_targets(results)
    for line in missed:
        print(f"target missed: {line}", file=sys.stderr)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
