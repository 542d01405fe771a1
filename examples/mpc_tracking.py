"""A nonlinear MPC that tracks a joint trajectory of the Denso with the PSDM forward dynamics.

The controller (``trajopt.mpc``) is multiple shooting with RK4 on the PSDM forward dynamics (its
derivatives taken through the PSDM inverse dynamics) plus the drives' smooth Coulomb-viscous-Stribeck
friction, torque and joint position/velocity bounds, and a real-time SQP scheme: Gauss-Newton
Hessian, structured QPs by hpipm (Riccati), at most a few iterations per control step, warm started
from the shifted previous solution. The plant is independent of that model: Pinocchio's aba with
the same friction, integrated by RK4 with finer steps. The script asserts that the tracking error
stays small and that no limit is crossed.

Set ``JIT = True`` to compile the problem's functions with gcc (a one-off compile of seconds to a
minute; then each step is several times faster), and see ``benchmarks/mpc.py`` for the Panda and
for the same problem on the peers' dynamics.

Run: python examples/mpc_tracking.py
"""

import numpy as np

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR
from trajopt.mpc import MPCOptions, build_mpc
from trajopt.mpc_loop import build_pinocchio_plant, simulate_closed_loop
from trajopt.mpc_model import build_forward_dynamics_jacobian

ROBOT_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
JIT = False
# 5 ms control interval: the smoothed friction is stiff near zero speed on the light wrist, so one RK4
# step per interval must stay short to be stable.
OPTIONS = MPCOptions(horizon=10, dt=0.005, solver="sqpmethod", qp_solver="hpipm", max_iter=3, jit=JIT)


def reference(t):
    q0 = np.array([0.0, 0.3, 0.3, 0.0, 0.5, 0.0])
    amplitude = np.array([0.4, 0.2, 0.3, 0.5, 0.3, 0.6])
    omega = 2 * np.pi * 0.5
    return q0 + amplitude * np.sin(omega * t), amplitude * omega * np.cos(omega * t)


def run(n_steps=30):
    robot = load_robot(ROBOT_FILE)
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    dynamics = build_recursive_functions(model, robot, theta)  # the recursive form: the smallest graph
    # derivatives of the forward dynamics through the (cheap) PSDM inverse dynamics: -M^-1 dID/d(q, qd), M^-1
    jacobian = build_forward_dynamics_jacobian(
        dynamics.forward_dynamics, dynamics.inverse_dynamics, dynamics.mass_matrix
    )
    controller = build_mpc(robot, dynamics.forward_dynamics, OPTIONS, forward_dynamics_jacobian=jacobian)
    plant = build_pinocchio_plant(robot)
    guess = PinocchioOracle(robot).gravity(reference(0.0)[0])  # first torques: hold against gravity
    return robot, simulate_closed_loop(controller, plant, reference, n_steps, torque_guess=guess)


def main():
    robot, result = run()
    errors = np.abs(result.q - result.q_ref).max(axis=1)
    print(
        f"tracking RMSE {result.tracking_rmse * 1e3:.3f} mrad, max {errors.max() * 1e3:.2f} mrad; "
        f"mean solve {result.step_time_s.mean() * 1e3:.1f} ms ({result.iterations.mean():.1f} SQP iterations)"
    )
    assert errors.max() < 0.01, "MPC lost track of the reference"
    assert result.limit_violation(robot) == 0.0, "a joint or torque limit was crossed"


if __name__ == "__main__":
    main()
