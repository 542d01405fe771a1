"""A minimum-torque point-to-point motion of the Denso with CasADi Opti and the PSDM inverse dynamics.

Decision variables are q, qd, qdd on a grid (trapezoidal integration); the torque comes from the
PSDM inverse dynamics with the robot file's nominal parameters, so CasADi supplies exact
derivatives. The result is checked against Pinocchio's rnea at the end.

Run: python examples/min_torque_motion.py
"""

import casadi as ca
import numpy as np

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

ROBOT_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"


def solve(n_intervals: int = 30, duration: float = 1.5):
    robot = load_robot(ROBOT_FILE)
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    dynamics = build_recursive_functions(model, robot, theta)  # recursive form, parameters compiled in

    n = robot.n_dof
    start = np.array([0.0, 0.3, 0.2, 0.0, 0.4, 0.0])
    goal = np.array([1.0, -0.2, 0.6, 0.8, -0.3, 0.5])
    h = duration / n_intervals

    opti = ca.Opti()
    q = opti.variable(n, n_intervals + 1)
    qd = opti.variable(n, n_intervals + 1)
    qdd = opti.variable(n, n_intervals + 1)
    effort = 0
    for k in range(n_intervals + 1):
        tau = dynamics.inverse_dynamics(q[:, k], qd[:, k], qdd[:, k])
        weight = 0.5 if k in (0, n_intervals) else 1.0
        effort += weight * h * ca.sumsqr(tau / robot.tau_max)
        opti.subject_to(opti.bounded(-robot.tau_max, tau, robot.tau_max))
    for k in range(n_intervals):  # trapezoidal integration of qd and q
        opti.subject_to(qd[:, k + 1] == qd[:, k] + 0.5 * h * (qdd[:, k] + qdd[:, k + 1]))
        opti.subject_to(q[:, k + 1] == q[:, k] + 0.5 * h * (qd[:, k] + qd[:, k + 1]))
    opti.subject_to(opti.bounded(robot.q_min, q, robot.q_max))
    opti.subject_to(opti.bounded(-robot.qd_max, qd, robot.qd_max))
    opti.subject_to(opti.bounded(-robot.qdd_max, qdd, robot.qdd_max))
    opti.subject_to([q[:, 0] == start, q[:, -1] == goal, qd[:, 0] == 0, qd[:, -1] == 0])
    opti.minimize(effort)
    for k in range(n_intervals + 1):  # straight-line initial guess
        opti.set_initial(q[:, k], start + (goal - start) * k / n_intervals)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "max_iter": 300})
    solution = opti.solve()
    return robot, solution.value(q).T, solution.value(qd).T, solution.value(qdd).T, dynamics


def main():
    robot, q, qd, qdd, dynamics = solve()
    tau = np.array([np.array(dynamics.inverse_dynamics(a, b, c)).ravel() for a, b, c in zip(q, qd, qdd)])
    reference = PinocchioOracle(robot).rnea(q, qd, qdd)
    error = np.abs(tau - reference).max()
    print(f"peak |tau| per joint [N m]: {np.round(np.abs(tau).max(axis=0), 2)}")
    print(f"PSDM torque vs Pinocchio rnea on the optimal motion: max error {error:.2e} N m")
    assert error < 1e-9 * max(1.0, np.abs(reference).max())
    assert np.allclose(q[-1], [1.0, -0.2, 0.6, 0.8, -0.3, 0.5], atol=1e-6)
    assert np.all(np.abs(tau) <= robot.tau_max + 1e-6)


if __name__ == "__main__":
    main()
