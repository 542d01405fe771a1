"""The MPC benchmark's task and figures, shared by benchmarks/mpc.py and its Crocoddyl worker (another Python).

One task for every row: the reference, the control interval per robot, the first guess, the
closed loop against Pinocchio's aba (RK4, 4 substeps per interval) and the figures of a run.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.oracle import PinocchioOracle
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop

# control interval [s] per robot: the Denso's friction is stiff near zero speed (smoothing 0.2 rad/s on
# a light wrist), so its RK4 needs the shorter interval
CONTROL_DT = {"denso": 0.005, "panda": 0.01}


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


def closed_loop_figures(robot, controller, n_steps, *, friction=True) -> dict:
    """Run a controller (``initialize``/``step``) against the plant; per-step times, tracking and limits."""
    reference = reference_for(robot)
    plant = build_pinocchio_plant(robot, friction=friction)
    guess = PinocchioOracle(robot).gravity(reference(0.0)[0])
    result = simulate_closed_loop(controller, plant, reference, n_steps, torque_guess=guess)
    skip = 1 if n_steps > 1 else 0  # the first step starts cold
    times, cpu = result.step_time_s[skip:], result.step_cpu_s[skip:]
    return {
        "mean_step_ms": float(np.mean(times) * 1e3),
        "max_step_ms": float(np.max(times) * 1e3),
        "mean_step_cpu_ms": float(np.mean(cpu) * 1e3),
        "mean_iterations": float(np.mean(result.iterations)),
        "tracking_rmse": result.tracking_rmse,
        "max_abs_error": float(np.max(np.abs(result.q - result.q_ref))),
        "limit_violation": result.limit_violation(robot),
    }
