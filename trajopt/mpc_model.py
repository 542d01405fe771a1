"""The MPC's discrete model: RK4 on a forward dynamics, its Jacobian chained stage by stage, and FD derivatives.

``trajopt.mpc`` builds its NLP from these: the RK4 step (the exact-Hessian path inlines it into one
SX graph), the stage functions ``(x, u) -> x_next`` and ``(x, u) -> (x_next, d x_next / d(x, u))``
(the Gauss-Newton path), and optionally the forward dynamics' derivatives through the inverse dynamics.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from psdm_casadi.forward import ldl_solve


def rk4(rhs, x, dt: float, steps: int):
    """``steps`` classical Runge-Kutta steps of ``x' = rhs(x)`` over ``dt``: numpy arrays and CasADi symbols alike
    (the controller's discrete model and the closed loop's plant integrate the same way)."""
    h = dt / steps
    for _ in range(steps):
        k1 = rhs(x)
        k2 = rhs(x + h / 2 * k1)
        k3 = rhs(x + h / 2 * k2)
        k4 = rhs(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


INTEGRATORS = ("rk4", "euler")


def semi_implicit_euler(rhs, x, dt: float, steps: int, n_dof: int):
    """``steps`` semi-implicit (symplectic) Euler steps of ``(q, qd)' = rhs(q, qd)`` over dt: ``qd += h qdd``,
    then ``q += h qd`` with the new velocity (Crocoddyl's ``IntegratedActionModelEuler``)."""
    h = dt / steps
    for _ in range(steps):
        qd = x[n_dof:] + h * rhs(x)[n_dof:]
        x = (
            ca.vertcat(x[:n_dof] + h * qd, qd)
            if isinstance(x, (ca.SX, ca.MX))
            else np.concatenate([x[:n_dof] + h * qd, qd])
        )
    return x


def build_step_function(
    forward_dynamics: ca.Function, n_dof: int, dt: float, rk4_steps: int = 1, friction=None, integrator="rk4"
):
    """Discretisation ``(x, u) -> x_next`` of ``qdd = forward_dynamics(q, qd, tau - friction(qd))``: RK4 or
    semi-implicit Euler (``integrator``), ``rk4_steps`` steps per interval.

    The graph is MX (so that any CasADi Function, also a callback, can be the dynamics); it is
    expanded to SX when the dynamics allow it, which is what the solvers evaluate fastest.
    """
    x, u = ca.MX.sym("x", 2 * n_dof), ca.MX.sym("u", n_dof)

    def rhs(state):
        q, qd = state[:n_dof], state[n_dof:]
        tau = u if friction is None else u - friction(qd)
        return ca.vertcat(qd, forward_dynamics(q, qd, tau))

    x_next = rk4(rhs, x, dt, rk4_steps) if integrator == "rk4" else semi_implicit_euler(rhs, x, dt, rk4_steps, n_dof)
    step = ca.Function("step", [x, u], [x_next], ["x", "u"], ["x_next"])
    try:
        return step.expand()
    except RuntimeError:  # a callback or external without an SX form stays MX
        return step


def build_forward_dynamics_jacobian(forward_dynamics, inverse_dynamics, mass_matrix) -> ca.Function:
    """``(q, qd, tau) -> (d qdd/d q, d qdd/d qd, d qdd/d tau)`` through the inverse dynamics.

    Differentiating ``ID(q, qd, FD(q, qd, tau)) = tau`` gives ``d qdd/d(q, qd) = -M^-1 d ID/d(q, qd)``
    at ``qdd = FD`` and ``d qdd/d tau = M^-1``: one Jacobian of the (cheap) inverse dynamics and one
    LDL^T factorisation of M, instead of AD through the factorisation inside the forward dynamics.

    Parameters
    ----------
    forward_dynamics, inverse_dynamics, mass_matrix : casadi.Function
        SX functions ``(q, qd, tau) -> qdd``, ``(q, qd, qdd) -> tau`` and ``q -> M`` of one model.

    Returns
    -------
    casadi.Function
        SX, for ``build_mpc(..., forward_dynamics_jacobian=...)``.
    """
    n = forward_dynamics.size1_in(0)
    q, qd, tau, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "tau", "qdd"))
    torque = inverse_dynamics(q, qd, qdd)
    acceleration = forward_dynamics(q, qd, tau)
    rhs = ca.substitute(ca.horzcat(-ca.jacobian(torque, q), -ca.jacobian(torque, qd)), qdd, acceleration)
    rhs = ca.horzcat(rhs, ca.SX.eye(n))
    solved = ca.horzcat(*[ldl_solve(mass_matrix(q), rhs[:, k]) for k in range(3 * n)])
    return ca.Function(
        "forward_dynamics_jacobian",
        [q, qd, tau],
        [solved[:, :n], solved[:, n : 2 * n], solved[:, 2 * n :]],
        ["q", "qd", "tau"],
        ["dqdd_dq", "dqdd_dqd", "dqdd_dtau"],
        {"cse": True},
    )


def expanded(function: ca.Function) -> ca.Function:
    """The SX form of an MX function when it has one: the fastest to evaluate and to compile."""
    if not function.is_a("MXFunction"):
        return function
    try:
        return function.expand()
    except RuntimeError:  # holds a call without an SX form (an external, a callback)
        return function


def sensitivity_chain(n: int) -> ca.Function:
    """``(d qdd / d(x, u), S) -> d xdot / d(x, u) [S; 0 I]``: a stage point's sensitivity from the state's.

    The right-hand side is ``xdot = (qd, qdd)``, so its Jacobian's top half is the constant ``[0 I 0]``:
    only ``d qdd / d(x, u)`` (n x 3n) multiplies, and the product is one unrolled SX Function (straight-line
    C, about a third of the flops of the sparse product with the whole Jacobian).
    """
    jb, sens = ca.SX.sym("jb", n, 3 * n), ca.SX.sym("s", 2 * n, 3 * n)
    bottom = ca.mtimes(jb[:, : 2 * n], sens) + ca.horzcat(ca.SX(n, 2 * n), jb[:, 2 * n :])
    return ca.Function("sensitivity_chain", [jb, sens], [ca.vertcat(sens[n:, :], bottom)], ["jb", "s"], ["ds"])


def stage_functions(forward_dynamics, n, dt, rk4_steps, friction, fd_jacobian=None, integrator="rk4"):
    """The stage model ``(x, u) -> x_next`` and ``(x, u) -> (x_next, d x_next / d(x, u))``, RK4 or semi-implicit Euler.

    The continuous right-hand side and its Jacobian are two small functions (compiled with the NLP's
    functions when jit); the RK4 sensitivities are chained from them in MX, dk = J(s) [ds; E] at each
    stage point s, so the code to compile holds the right-hand side's Jacobian once, not four times.
    """
    symbol = ca.SX if forward_dynamics.is_a("SXFunction") else ca.MX
    x, u = symbol.sym("x", 2 * n), symbol.sym("u", n)
    tau = u if friction is None else u - friction(x[n:])
    rhs_expr = ca.vertcat(x[n:], forward_dynamics(x[:n], x[n:], tau))
    rhs = ca.Function("rhs", [x, u], [rhs_expr], ["x", "u"], ["xdot"])
    if fd_jacobian is None:
        jac_expr = ca.jacobian(rhs_expr, ca.vertcat(x, u))
    else:  # the given derivatives, chained through the friction: d tau / d qd = -d tau_f / d qd
        d_q, d_qd, d_tau = fd_jacobian(x[:n], x[n:], tau)
        if friction is not None:
            v = ca.SX.sym("qd", n)
            slope = ca.Function("friction_slope", [v], [ca.jacobian(friction(v), v)])
            d_qd = d_qd - ca.mtimes(d_tau, slope(x[n:]))
        top = ca.horzcat(symbol(n, n), symbol.eye(n), symbol(n, n))
        jac_expr = ca.vertcat(top, ca.horzcat(d_q, d_qd, d_tau))
    rhs_jac = ca.Function("rhs_jacobian", [x, u], [rhs_expr, jac_expr], ["x", "u"], ["xdot", "jac"])
    xm, um = ca.MX.sym("x", 2 * n), ca.MX.sym("u", n)
    chain = sensitivity_chain(n)
    h = dt / rk4_steps
    state, sens, state_only = xm, ca.MX(ca.DM(np.hstack([np.eye(2 * n), np.zeros((2 * n, n))]))), xm
    # at the interval's start the sensitivity is [I 0]: there the chain's product is the Jacobian itself
    # (the same numbers; a 7 x 14 x 21 product per stage the Panda's Euler step no longer computes)
    initial = True
    for _ in range(rk4_steps if integrator == "rk4" else 0):
        slopes, slope_sens, plain = [], [], []
        for c in (0.0, 0.5, 0.5, 1.0):
            point = state if not slopes else state + c * h * slopes[-1]
            point_sens = sens if not slopes else sens + c * h * slope_sens[-1]
            value, jac = rhs_jac(point, um)
            slopes.append(value)
            slope_sens.append(jac if initial else chain(jac[n:, :], point_sens))
            initial = False
            plain.append(rhs(state_only if not plain else state_only + c * h * plain[-1], um))
        state = state + h / 6 * (slopes[0] + 2 * slopes[1] + 2 * slopes[2] + slopes[3])
        sens = sens + h / 6 * (slope_sens[0] + 2 * slope_sens[1] + 2 * slope_sens[2] + slope_sens[3])
        state_only = state_only + h / 6 * (plain[0] + 2 * plain[1] + 2 * plain[2] + plain[3])
    for _ in range(rk4_steps if integrator == "euler" else 0):  # qd += h qdd(x, u); q += h qd
        value, jac = rhs_jac(state, um)
        velocity = state[n:] + h * value[n:]
        velocity_sens = sens[n:, :] + h * (jac[n:, :] if initial else chain(jac[n:, :], sens)[n:, :])
        initial = False
        state = ca.vertcat(state[:n] + h * velocity, velocity)
        sens = ca.vertcat(sens[:n, :] + h * velocity_sens, velocity_sens)
        state_only = semi_implicit_euler(lambda s: rhs(s, um), state_only, h, 1, n)
    model = ca.Function("model", [xm, um], [state_only], ["x", "u"], ["x_next"])
    model_jacobian = ca.Function("model_jacobian", [xm, um], [state, sens], ["x", "u"], ["x_next", "jac_x_next_xu"])
    return model, model_jacobian
