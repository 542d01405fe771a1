"""Time of one MPC step with the PSDM dynamics and with each peer's dynamics in the same problem.

For the Denso and the Panda (fingers locked) a nonlinear tracking MPC (``trajopt.mpc``: multiple
shooting, RK4 on the forward dynamics, torque and joint position/velocity bounds) runs in closed
loop against Pinocchio's aba integrated by RK4 with finer steps. Only the forward dynamics in the
problem change between the rows:

- ``psdm``: the PSDM recursive forward dynamics (SX) with its derivatives through the PSDM inverse
  dynamics (``trajopt.mpc_model.build_forward_dynamics_jacobian``), compiled with the NLP functions
  (CasADi jit, gcc -O3 -march=native);
- variants of ours, not peers: ``psdm_ad`` (CasADi's AD of the forward dynamics instead) and
  ``psdm_external`` (forward dynamics and AD Jacobians exported by ``codegen.export_c``, compiled with
  -O3 -march=native and loaded by ``casadi.external``);
- ``casadi_rnea``: the CasADi SX Newton-Euler peer (``codegen.peers.rnea_sx``) with CasADi's AD, compiled
  the same way, and ``casadi_rnea_id_derivatives``: the same peer given the inverse-dynamics derivatives;
- ``pinocchio_callback``: ``pinocchio.aba`` in a CasADi callback with ``computeABADerivatives`` as its
  Jacobian (Python, not compilable, first derivatives only);
- ``pinocchio_casadi``: Pinocchio templated on CasADi SX, when ``import pinocchio.casadi`` works; the
  reason is printed when it does not.

Per step the table gives the mean and worst wall time of the solve, the mean CPU time of the process
(the honest figure on a machine shared with other jobs), the iterations and the RMS tracking error
of the plant. ``rate_hz`` is 1 / mean step wall time of the PSDM row. Target (issue 18): PSDM the
fastest row, and above 100 Hz for the 20-step horizon on the Panda.

Usage::

    python benchmarks/mpc.py [--robots denso panda] [--steps 100] [--horizon 20] [--solver sqpmethod]
                             [--qp-solver hpipm] [--max-iter 3] [--no-jit] [--json]

Exit code 0 when the targets are met, 1 otherwise, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_support import DENSO_FILE, load_panda, print_json, print_table, show_progress

from codegen.build import build_library
from codegen.export import export_c
from codegen.peers.pinocchio_callback import PinocchioAba
from codegen.peers.rnea_sx import build_rnea_functions
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from trajopt.mpc import QP_SOLVERS, SOLVERS, MPCOptions, build_mpc
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop
from trajopt.mpc_model import build_forward_dynamics_jacobian

LOG = logging.getLogger("benchmarks.mpc")
# control interval [s] per robot: the Denso's friction is stiff near zero speed (smoothing 0.2 rad/s on
# a light wrist), so its RK4 needs the shorter interval
CONTROL_DT = {"denso": 0.005, "panda": 0.01}
TARGET_RATE_HZ = 100.0


def reference_for(robot):
    """A smooth joint reference inside the limits: sines of 0.5 Hz about the middle of each joint's range."""
    middle = (robot.q_min + robot.q_max) / 2
    amplitude = np.minimum(0.3, 0.2 * (robot.q_max - robot.q_min))
    omega = 2 * np.pi * 0.5
    phase = np.linspace(0, np.pi / 2, robot.n_dof)

    def reference(t):
        return middle + amplitude * np.sin(omega * t + phase) - amplitude * np.sin(phase), amplitude * omega * np.cos(
            omega * t + phase
        )

    return reference


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


def dynamics_rows(robot, folder):
    """Forward dynamics to compare, by name: (casadi.Function or None, its Jacobian function or None, reason)."""
    start = time.perf_counter()
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    ours = build_recursive_functions(model, robot, theta)
    psdm = ours.forward_dynamics
    LOG.info("%s: PSDM model derived in %.1f s", robot.name, time.perf_counter() - start)
    oracle = PinocchioOracle(robot)
    cpin, reason = pinocchio_casadi_dynamics(oracle)
    rnea = build_rnea_functions(oracle.model)
    return {
        "psdm": (psdm, build_forward_dynamics_jacobian(psdm, ours.inverse_dynamics, ours.mass_matrix), None),
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


def run_row(robot, dynamics, jacobian, options, n_steps, reference):
    """Build the MPC on these dynamics and run it closed loop; returns the figures of one row."""
    start = time.perf_counter()
    controller = build_mpc(robot, dynamics, options, forward_dynamics_jacobian=jacobian)
    build_s = time.perf_counter() - start
    plant = build_pinocchio_plant(robot)
    q0 = reference(0.0)[0]
    guess = PinocchioOracle(robot).gravity(q0)
    result = simulate_closed_loop(controller, plant, reference, n_steps, torque_guess=guess)
    times = result.step_time_s[1:] if n_steps > 1 else result.step_time_s  # the first solve starts cold
    return {
        "mean_step_ms": float(np.mean(times) * 1e3),
        "max_step_ms": float(np.max(times) * 1e3),
        "mean_step_cpu_ms": float(np.mean(result.step_cpu_s[1:] if n_steps > 1 else result.step_cpu_s) * 1e3),
        "mean_iterations": float(np.mean(result.iterations)),
        "tracking_rmse": result.tracking_rmse,
        "max_abs_error": float(np.max(np.abs(result.q - result.q_ref))),
        "limit_violation": result.limit_violation(robot),
        "build_s": build_s,
    }


def run_robot(name, robot, args):
    dt = CONTROL_DT[name]
    options = MPCOptions(
        horizon=args.horizon,
        dt=dt,
        solver=args.solver,
        qp_solver=args.qp_solver,
        hessian="exact" if args.solver == "fatrop" else "gauss-newton",
        max_iter=args.max_iter,
        jit=not args.no_jit,
    )
    reference = reference_for(robot)
    peers = {}
    with tempfile.TemporaryDirectory(prefix="psdm-mpc-") as folder:
        for peer, (dynamics, jacobian, reason) in dynamics_rows(robot, folder).items():
            if dynamics is None:
                peers[peer] = {"mean_step_ms": None, "max_step_ms": None, "tracking_rmse": None, "error": reason}
                continue
            opts = options
            if options.hessian == "exact" and (jacobian is not None or isinstance(dynamics, PinocchioAba)):
                # the exact Hessian needs second derivatives: these rows take the Gauss-Newton one
                opts = MPCOptions(**{**options.__dict__, "solver": "ipopt", "hessian": "gauss-newton"})
            LOG.info("%s: MPC with %s dynamics", name, peer)
            peers[peer] = run_row(robot, dynamics, jacobian, opts, args.steps, reference)
    ours = peers.pop("psdm")
    variants = {key: peers.pop(key) for key in ("psdm_ad", "psdm_external")}
    solver = f"{options.solver}" + (f" ({options.qp_solver} QPs)" if options.solver == "sqpmethod" else "")
    return dict(
        ours,
        rate_hz=1e3 / ours["mean_step_ms"],
        solver=f"{solver}, {options.hessian} Hessian, max {options.max_iter} iterations per step"
        + (", jit" if options.jit else ""),
        horizon=options.horizon,
        dt=dt,
        n_steps=args.steps,
        load_average=os.getloadavg()[0],
        variants=variants,
        peers=peers,
    )


def print_results(results) -> None:
    for name, r in results.items():
        print(f"\n{name}: N={r['horizon']}, dt={r['dt'] * 1e3:.0f} ms, {r['n_steps']} closed-loop steps; {r['solver']}")
        rows = [dict(dynamics="psdm", **{k: v for k, v in r.items() if k in COLUMNS})]
        for peer, figures in {**r["variants"], **r["peers"]}.items():
            rows.append(dict(dynamics=peer, **{k: v for k, v in figures.items() if k in COLUMNS}))
        print_table(rows, ["dynamics", *COLUMNS])
        for peer, figures in r["peers"].items():
            if figures.get("error"):
                print(f"  {peer}: not built: {figures['error']}")
        print(
            f"  rate {r['rate_hz']:.0f} Hz (target {TARGET_RATE_HZ:.0f} Hz on the Panda); load average "
            f"{r['load_average']:.1f} on {os.cpu_count()} cores: wall times include waiting for other jobs"
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


def missed_targets(results) -> list:
    missed = []
    for name, r in results.items():
        timed = {p: f["mean_step_ms"] for p, f in r["peers"].items() if f.get("mean_step_ms") is not None}
        faster = [p for p, t in timed.items() if t < r["mean_step_ms"]]
        if faster:
            missed.append(f"{name}: {', '.join(faster)} faster per step than psdm")
        if name == "panda" and r["rate_hz"] < TARGET_RATE_HZ:
            missed.append(f"panda: {r['rate_hz']:.0f} Hz < {TARGET_RATE_HZ:.0f} Hz")
    return missed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", nargs="+", default=["denso", "panda"], choices=["denso", "panda"])
    parser.add_argument("--steps", type=int, default=100, help="closed-loop control steps per row")
    parser.add_argument("--horizon", type=int, default=20)
    parser.add_argument("--solver", default="sqpmethod", choices=SOLVERS)
    parser.add_argument("--qp-solver", default="hpipm", choices=QP_SOLVERS)
    parser.add_argument("--max-iter", type=int, default=3, help="iteration cap per control step")
    parser.add_argument("--no-jit", action="store_true", help="do not compile the NLP functions")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    for flag in ("steps", "horizon", "max_iter"):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag.replace('_', '-')} must be a positive integer; got {getattr(args, flag)}.")
    show_progress()
    loaders = {"denso": lambda: load_robot(DENSO_FILE), "panda": load_panda}
    results = {name: run_robot(name, loaders[name](), args) for name in args.robots}
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
