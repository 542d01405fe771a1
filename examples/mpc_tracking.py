"""A nonlinear MPC prototype that tracks a joint trajectory of the Denso with the PSDM forward dynamics.

The controller's model is the PSDM forward dynamics plus a smooth Coulomb-viscous-Stribeck friction
per joint (the drive values of the robot file), discretised by RK4 and solved by Ipopt through
multiple shooting. The plant is independent of that model: Pinocchio's aba with the same friction,
integrated with small steps. The script asserts that the tracking error stays small.

Run: python examples/mpc_tracking.py
"""

import casadi as ca
import numpy as np

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

ROBOT_FILE = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
# rad/s: width of the smooth sign in the friction model. Friction slopes near zero speed then reach
# about 10 N m s/rad on the 0.03 kg m^2 wrist: eigenvalues near -340 1/s, so RK4 needs dt <= ~8 ms.
SMOOTHING = 0.2


def friction_casadi(robot, qd):
    """Smooth steady-state friction: (Fc + (Fs - Fc) e^{-(v/vs)^2}) tanh(v/eps) + Fv v (v^2 + eps^2)^((dv-1)/2)."""
    out = []
    for j, drive in enumerate(robot.drives):
        v = qd[j]
        coulomb = (drive.fc + (drive.fs - drive.fc) * ca.exp(-((v / drive.vs) ** 2))) * ca.tanh(v / SMOOTHING)
        viscous = drive.fv * v * (v**2 + SMOOTHING**2) ** ((drive.dv - 1) / 2)
        out.append(coulomb + viscous)
    return ca.vertcat(*out)


def friction_numpy(robot, qd):
    fc = np.array([d.fc for d in robot.drives])
    fs = np.array([d.fs for d in robot.drives])
    vs = np.array([d.vs for d in robot.drives])
    fv = np.array([d.fv for d in robot.drives])
    dv = np.array([d.dv for d in robot.drives])
    return (fc + (fs - fc) * np.exp(-((qd / vs) ** 2))) * np.tanh(qd / SMOOTHING) + fv * qd * (
        qd**2 + SMOOTHING**2
    ) ** ((dv - 1) / 2)


def reference(t):
    q0 = np.array([0.0, 0.3, 0.3, 0.0, 0.5, 0.0])
    amplitude = np.array([0.4, 0.2, 0.3, 0.5, 0.3, 0.6])
    omega = 2 * np.pi * 0.5
    return q0 + amplitude * np.sin(omega * t), amplitude * omega * np.cos(omega * t)


def build_controller(robot, dynamics, horizon=10, dt=0.005):
    n = robot.n_dof
    x = ca.SX.sym("x", 2 * n)
    u = ca.SX.sym("u", n)

    def rhs(state, torque):
        q, qd = state[:n], state[n:]
        return ca.vertcat(qd, dynamics.forward_dynamics(q, qd, torque - friction_casadi(robot, qd)))

    k1 = rhs(x, u)
    k2 = rhs(x + dt / 2 * k1, u)
    k3 = rhs(x + dt / 2 * k2, u)
    k4 = rhs(x + dt * k3, u)
    step = ca.Function("step", [x, u], [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])

    opti = ca.Opti()
    xs, us = opti.variable(2 * n, horizon + 1), opti.variable(n, horizon)
    x0, refs = opti.parameter(2 * n), opti.parameter(2 * n, horizon + 1)
    cost = 0
    for k in range(horizon):
        opti.subject_to(xs[:, k + 1] == step(xs[:, k], us[:, k]))
        opti.subject_to(opti.bounded(-robot.tau_max, us[:, k], robot.tau_max))
        cost += ca.sumsqr(xs[:n, k + 1] - refs[:n, k + 1]) * 1e4 + ca.sumsqr(xs[n:, k + 1] - refs[n:, k + 1]) * 10
        cost += 1e-4 * ca.sumsqr(us[:, k] / robot.tau_max)
    opti.subject_to(xs[:, 0] == x0)
    opti.minimize(cost)
    opti.solver(
        "ipopt",
        {"print_time": False},
        {"print_level": 0, "sb": "yes", "max_iter": 15, "tol": 1e-6, "hessian_approximation": "limited-memory"},
    )
    return opti, xs, us, x0, refs, horizon, dt


def run(n_steps=15):
    robot = load_robot(ROBOT_FILE)
    model = derive_psdm(robot)
    theta = model.base_parameters(robot.nominal_dynamic_parameters())
    dynamics = build_recursive_functions(model, robot, theta)  # the recursive form: the smallest graph
    opti, xs, us, x0, refs, horizon, dt = build_controller(robot, dynamics)
    plant = PinocchioOracle(robot)
    q, qd = reference(0.0)
    opti.set_initial(xs, np.array([np.concatenate(reference(k * dt)) for k in range(horizon + 1)]).T)
    # warm start the torques with the model's inverse dynamics of the reference (plus friction)
    feedforward = []
    for k in range(horizon):
        t_k = k * dt
        q_k, qd_k = reference(t_k)
        qdd_k = (reference(t_k + 1e-4)[1] - reference(t_k - 1e-4)[1]) / 2e-4
        feedforward.append(np.array(dynamics.inverse_dynamics(q_k, qd_k, qdd_k)).ravel() + friction_numpy(robot, qd_k))
    opti.set_initial(us, np.array(feedforward).T)
    errors = []
    for step_index in range(n_steps):
        t = step_index * dt
        targets = np.array([np.concatenate(reference(t + k * dt)) for k in range(horizon + 1)]).T
        opti.set_value(x0, np.concatenate([q, qd]))
        opti.set_value(refs, targets)
        # real-time practice: a bounded number of iterations from a warm start; the iterate is used
        # even when Ipopt has not met its tolerance (the next solve continues from it)
        solution = opti.solve_limited()
        torque = solution.value(us)[:, 0]
        opti.set_initial(xs, solution.value(xs))
        opti.set_initial(us, solution.value(us))
        substeps = 20  # plant: semi-implicit Euler on Pinocchio aba with friction
        for _ in range(substeps):
            qdd = plant.aba(q, qd, torque - friction_numpy(robot, qd))
            qd = qd + dt / substeps * qdd
            q = q + dt / substeps * qd
        errors.append(np.abs(q - reference(t + dt)[0]).max())
    return np.array(errors)


def main():
    errors = run()
    print(f"max tracking error over the run: {errors.max() * 1e3:.2f} mrad; last step: {errors[-1] * 1e3:.2f} mrad")
    assert errors.max() < 0.01, "MPC lost track of the reference"


if __name__ == "__main__":
    main()
