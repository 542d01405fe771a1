"""Nonlinear MPC on the forward dynamics: the multiple-shooting tracking problem, its warm-started step and a plant.

The controller tracks a joint trajectory: states x = (q, qd), controls the joint torques, RK4 on any
CasADi forward dynamics ``(q, qd, tau) -> qdd`` (the PSDM model's, or a peer's, so that they are
compared in the same problem), torque bounds and joint position/velocity bounds. The stage layout
(x0, u0, x1, u1, ..., xN) with the gap constraints in stage order is what fatrop's structure
detection needs; Ipopt solves the same NLP. Build, solve and simulate are separate steps, as in
CasADi's own tools: ``build_mpc`` makes the solver once, ``MPCController.step`` solves one control
interval from the shifted previous solution, and ``simulate_closed_loop`` runs it against a plant
that is independent of the controller model (for instance Pinocchio's aba, integrated more finely).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from psdm_casadi.description import RobotDescription
from psdm_casadi.errors import ParameterError, SolverError
from trajopt.joint_friction import friction_function
from trajopt.mpc_model import INTEGRATORS, build_step_function, expanded, stage_functions

SOLVERS = ("ipopt", "fatrop", "sqpmethod")
# fatrop is also a CasADi QP plugin, but its QP interface prints its matrices and stalled on this problem
QP_SOLVERS = ("hpipm", "qrqp", "osqp")
HESSIANS = ("gauss-newton", "exact", "limited-memory")


@dataclass(frozen=True)
class MPCOptions:
    """Options of the tracking MPC.

    Attributes
    ----------
    horizon : int
        Shooting intervals N.
    dt : float
        Control interval [s]; one step of ``dt / rk4_steps`` is taken ``rk4_steps`` times per interval.
    rk4_steps : int
    integrator : {"rk4", "euler"}
        The controller's discretisation: classical RK4, or semi-implicit Euler (``qd += h qdd``, then
        ``q += h qd``; one forward dynamics per step, the discretisation of Crocoddyl's
        ``IntegratedActionModelEuler``).
    solver : {"ipopt", "fatrop", "sqpmethod"}
        The interior-point NLP solvers Ipopt or fatrop, or CasADi's SQP method whose QPs go to
        ``qp_solver`` (with a Gauss-Newton Hessian: the real-time SQP scheme of acados).
    qp_solver : {"hpipm", "qrqp", "osqp"}
        QP solver of ``sqpmethod``; hpipm (the QP solver of acados) exploits the stage structure (Riccati).
    hessian : {"gauss-newton", "exact", "limited-memory"}
        Gauss-Newton (the constant Hessian of the least-squares cost, no constraint curvature: the
        usual choice of real-time NMPC; Ipopt and sqpmethod), the exact Lagrangian Hessian by CasADi's
        AD (the only one fatrop takes here), or L-BFGS (Ipopt and sqpmethod).
    max_iter : int
        Iteration cap per control step: the real-time scheme applies the iterate reached within it
        (warm started from the shifted previous solution) even when the tolerance is not met yet.
    tol : float
    jit : bool
        Compile the NLP's functions with the C compiler (CasADi ``jit`` with gcc, -O3 -march=native):
        with the Gauss-Newton or L-BFGS Hessian they hold the stage model and its Jacobian once;
        with the exact Hessian the whole SX NLP, a far larger compile. SX dynamics only.
    position_weight, velocity_weight, torque_weight : float
        Stage cost ``wq |q - q_ref|^2 + wv |qd - qd_ref|^2 + wu |tau / tau_scale|^2``.
    """

    horizon: int = 20
    dt: float = 0.01
    rk4_steps: int = 1
    integrator: str = "rk4"
    solver: str = "ipopt"
    qp_solver: str = "hpipm"
    hessian: str = "gauss-newton"
    max_iter: int = 10
    tol: float = 1e-6
    jit: bool = False
    position_weight: float = 1e4
    velocity_weight: float = 10.0
    torque_weight: float = 1e-4

    def __post_init__(self):
        for name in ("horizon", "rk4_steps", "max_iter"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ParameterError(f"MPCOptions.{name} must be a positive integer; got {value!r}. Pass e.g. 10.")
        for name in ("dt", "tol", "position_weight", "velocity_weight", "torque_weight"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ParameterError(f"MPCOptions.{name} must be a positive finite number; got {value!r}.")
        if self.solver not in SOLVERS:
            raise ParameterError(f"MPCOptions.solver must be one of {SOLVERS}; got {self.solver!r}.")
        if self.integrator not in INTEGRATORS:
            raise ParameterError(f"MPCOptions.integrator must be one of {INTEGRATORS}; got {self.integrator!r}.")
        if self.qp_solver not in QP_SOLVERS:
            raise ParameterError(f"MPCOptions.qp_solver must be one of {QP_SOLVERS}; got {self.qp_solver!r}.")
        if self.hessian not in HESSIANS:
            raise ParameterError(f"MPCOptions.hessian must be one of {HESSIANS}; got {self.hessian!r}.")
        if self.solver == "fatrop" and self.hessian != "exact":
            raise ParameterError(
                f"MPCOptions.hessian must be 'exact' with solver='fatrop'; got {self.hessian!r}. Use solver='ipopt'."
            )


@dataclass
class MPCController:
    """A built tracking MPC: the NLP solver and the warm start it carries from one step to the next.

    Attributes
    ----------
    solver : casadi.Function
        The nlpsol; parameters ``p`` = the reference (2 n_dof, N + 1) column-major; x0 enters by equal bounds.
    step_function : casadi.Function
        ``(x, u) -> x_next``: the controller's discrete model (RK4).
    options : MPCOptions
    n_dof : int
    bounds : dict
        ``lbx``, ``ubx``, ``lbg``, ``ubg`` of the NLP.
    """

    solver: ca.Function
    step_function: ca.Function
    options: MPCOptions
    n_dof: int
    bounds: dict
    _guess: np.ndarray | None = field(default=None, repr=False)
    _multipliers: np.ndarray | None = field(default=None, repr=False)

    def initialize(self, states, torques) -> None:
        """Set the first guess: states (N + 1, 2 n_dof) and torques (N, n_dof)."""
        states, torques = np.asarray(states, dtype=float), np.asarray(torques, dtype=float)
        n, horizon = self.n_dof, self.options.horizon
        if states.shape != (horizon + 1, 2 * n) or torques.shape != (horizon, n):
            raise ParameterError(
                f"MPCController.initialize needs states ({horizon + 1}, {2 * n}) and torques ({horizon}, {n}); "
                f"got {states.shape} and {torques.shape}."
            )
        stages = np.hstack([states[:-1], torques]).ravel()
        self._guess = np.concatenate([stages, states[-1]])
        self._multipliers = None

    def step(self, state, reference) -> tuple[np.ndarray, dict]:
        """Solve one control interval; returns the first torque (n_dof,) and the solver's stats.

        ``reference`` is (N + 1, 2 n_dof): (q_ref, qd_ref) at the N + 1 nodes from now. The solution,
        shifted by one interval, is kept as the next step's start (primal and constraint multipliers).
        Real-time scheme: when the iteration cap stops the solver, its iterate is applied and the
        stats say so (``return_status``); only a non-finite iterate raises.

        Raises
        ------
        ParameterError
            On a state or reference of the wrong shape, or before ``initialize``.
        SolverError
            When the solver returns non-finite numbers.
        """
        n = self.n_dof
        state, reference = step_arguments("MPCController", n, self.options.horizon, state, reference, self._guess)
        lbx, ubx = self.bounds["lbx"].copy(), self.bounds["ubx"].copy()
        lbx[: 2 * n] = ubx[: 2 * n] = state
        args = dict(self.bounds, lbx=lbx, ubx=ubx, x0=self._guess, p=reference.ravel())
        if self._multipliers is not None:
            args["lam_g0"] = self._multipliers
        start, start_cpu = time.perf_counter(), time.process_time()
        result = self.solver(**args)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        stats = dict(self.solver.stats(), time_s=elapsed, cpu_time_s=cpu)
        w = np.asarray(result["x"]).ravel()
        if not np.all(np.isfinite(w)):
            raise SolverError(
                f"MPC step: {self.options.solver} returned non-finite values (status {stats.get('return_status')}); "
                "check the state against the limits and the reference.",
                status=stats.get("return_status"),
                iterations=stats.get("iter_count"),
            )
        self._guess = _shift_primal(w, n)
        self._multipliers = _shift_multipliers(np.asarray(result["lam_g"]).ravel(), n)
        return w[2 * n : 3 * n].copy(), stats


def step_arguments(controller: str, n_dof: int, horizon: int, state, reference, guess) -> tuple:
    """(state, reference) as float arrays, checked for a controller's ``step``: the state (q, qd) of shape
    (2 n_dof,), the reference (N + 1, 2 n_dof), and a first guess already given (``initialize``).

    Raises ParameterError naming ``<controller>.step``, the argument and the shape it needs.
    """
    reference, state = np.asarray(reference, dtype=float), np.asarray(state, dtype=float)
    if state.shape != (2 * n_dof,):
        raise ParameterError(f"{controller}.step state must be (q, qd) of shape ({2 * n_dof},); got {state.shape}.")
    if reference.shape != (horizon + 1, 2 * n_dof):
        raise ParameterError(
            f"{controller}.step reference must have shape ({horizon + 1}, {2 * n_dof}); got {reference.shape}."
        )
    if guess is None:
        raise ParameterError(f"{controller}.step needs a first guess; call initialize(states, torques) first.")
    return state, reference


def _shift_primal(w, n_dof):
    """Shift a solution (x0, u0, ..., x_N) by one interval: (x1, u1, ..., x_N, u_{N-1}, x_N)."""
    stage, tail = 3 * n_dof, 2 * n_dof
    stages = w[:-tail].reshape(-1, stage)[1:]
    last = np.concatenate([w[-tail:], stages[-1, tail:] if len(stages) else w[tail:stage]])
    return np.concatenate([stages.ravel(), last, w[-tail:]])


def _shift_multipliers(lam, n_dof):
    """Shift the gap multipliers by one interval, repeating the last gap's."""
    gaps = lam.reshape(-1, 2 * n_dof)
    return np.concatenate([gaps[1:].ravel(), gaps[-1]])


def _solver_options(options: MPCOptions, n_constraints: int) -> dict:
    common = {"print_time": False, "error_on_fail": False}
    if options.solver == "fatrop":
        return dict(
            common,
            structure_detection="auto",
            equality=[True] * n_constraints,
            fatrop={"print_level": 0, "max_iter": options.max_iter, "tol": options.tol, "mu_init": 1e-2},
        )
    if options.solver == "sqpmethod":
        quiet = {"print_header": False, "print_iteration": False, "print_status": False}
        return dict(
            common,
            **quiet,
            qpsol=options.qp_solver,
            qpsol_options=_qp_options(options.qp_solver),
            hessian_approximation="limited-memory" if options.hessian == "limited-memory" else "exact",
            max_iter=options.max_iter,
            tol_pr=options.tol,
            tol_du=options.tol,
        )
    ipopt = {
        "print_level": 0,
        "sb": "yes",
        "max_iter": options.max_iter,
        "tol": options.tol,
        "hessian_approximation": "limited-memory" if options.hessian == "limited-memory" else "exact",
        "warm_start_init_point": "yes",
        "mu_init": 1e-3,
    }
    return dict(common, ipopt=ipopt)


def _qp_options(name: str) -> dict:
    quiet = {"qrqp": {"print_iter": False, "print_header": False}, "osqp": {"osqp": {"verbose": False}}}
    return dict({"error_on_fail": False, "print_time": False}, **quiet.get(name, {}))


def build_mpc(
    robot: RobotDescription,
    forward_dynamics: ca.Function,
    options: MPCOptions | None = None,
    *,
    friction=True,
    forward_dynamics_jacobian: ca.Function | None = None,
) -> MPCController:
    """Build the tracking MPC of a robot on a forward-dynamics function.

    Parameters
    ----------
    robot : RobotDescription
        Gives the joint position, velocity and torque limits and (``friction=True``) the drives.
    forward_dynamics : casadi.Function
        ``(q, qd, tau) -> qdd`` [rad, rad/s, N m -> rad/s^2] of the controller's model.
    options : MPCOptions, optional
    friction : bool
        Subtract the drives' smooth friction from the torque before the dynamics.
    forward_dynamics_jacobian : casadi.Function, optional
        ``(q, qd, tau) -> (d qdd/d q, d qdd/d qd, d qdd/d tau)``, each (n_dof, n_dof): derivatives to use
        instead of CasADi's AD of forward_dynamics, e.g. exported C loaded by ``casadi.external``
        (``codegen.export_c(..., jacobians=True)``). Gauss-Newton or limited-memory Hessian only.

    Returns
    -------
    MPCController
        Call ``initialize`` with a first guess, then ``step`` once per control interval.

    Raises
    ------
    ParameterError
        When forward_dynamics does not map three (n_dof,) inputs to one (n_dof,) output.

    Notes
    -----
    With the Gauss-Newton or limited-memory Hessian the NLP is an MX graph over two per-stage
    functions, the discrete model and its Jacobian (compiled when ``jit``), and the constraint
    Jacobian is assembled from the stage blocks; with the exact Hessian the whole NLP is one SX graph.
    """
    options = options or MPCOptions()
    n, horizon = robot.n_dof, options.horizon
    if forward_dynamics.n_in() != 3 or any(forward_dynamics.size_in(i) != (n, 1) for i in range(3)):
        raise ParameterError(
            f"build_mpc forward_dynamics must take (q, qd, tau) of shape ({n}, 1) each for {robot.name}; "
            f"got inputs {[forward_dynamics.size_in(i) for i in range(forward_dynamics.n_in())]}."
        )
    forward_dynamics = expanded(forward_dynamics)
    friction_law = friction_function(robot) if friction else None
    step = build_step_function(forward_dynamics, n, options.dt, options.rk4_steps, friction_law, options.integrator)
    exact = options.hessian == "exact"
    sx_model = forward_dynamics.is_a("SXFunction") and (
        forward_dynamics_jacobian is None or forward_dynamics_jacobian.is_a("SXFunction")
    )
    if exact and forward_dynamics_jacobian is not None:
        raise ParameterError(
            "build_mpc forward_dynamics_jacobian needs hessian='gauss-newton' or 'limited-memory'; got 'exact'."
        )
    if exact and not sx_model:
        raise ParameterError(
            f"MPCOptions.hessian='exact' needs SX forward dynamics; {forward_dynamics.name()} has no SX form. "
            "Use hessian='gauss-newton' or 'limited-memory'."
        )
    symbol = ca.SX if exact else ca.MX
    # compiled: the NLP's own functions (with the exact Hessian: the whole SX NLP, which is large)
    compiled = _jit_options(options.jit and sx_model)  # an external's code is not linked into the jit
    w = symbol.sym("w", 3 * n * horizon + 2 * n)
    p = symbol.sym("p", 2 * n * (horizon + 1))
    states = ca.horzcat(*[w[3 * n * k : 3 * n * k + 2 * n] for k in range(horizon + 1)])
    torques = ca.horzcat(*[w[3 * n * k + 2 * n : 3 * n * (k + 1)] for k in range(horizon)])
    model, model_jacobian = (
        (step, None)
        if exact
        else stage_functions(
            forward_dynamics,
            n,
            options.dt,
            options.rk4_steps,
            friction_law,
            forward_dynamics_jacobian,
            options.integrator,
        )
    )
    gaps = states[:, 1:] - model.map(horizon)(states[:, :-1], torques)
    constraints = ca.vec(gaps)  # stage by stage; x0 is fixed through equal bounds, as structured QP solvers want
    cost = tracking_cost(robot, options, states, torques, p)
    nlp = {"x": w, "p": p, "f": cost, "g": constraints}
    functions = {}
    if not exact:
        jac_g = constraint_jacobian(w, states, torques, model_jacobian, n)
        if options.solver == "sqpmethod":
            functions["jac_fg"] = ca.Function(
                "nlp_jac_fg",
                [w, p],
                [cost, ca.gradient(cost, w), constraints, jac_g],
                ["x", "p"],
                ["f", "grad_f_x", "g", "jac_g_x"],
                compiled,
            )
        else:
            functions["jac_g"] = ca.Function(
                "nlp_jac_g", [w, p], [constraints, jac_g], ["x", "p"], ["g", "jac_g_x"], compiled
            )
    if options.hessian == "gauss-newton":
        functions["hess_lag"] = _gauss_newton_hessian(w, p, cost, constraints)
    solver_options = dict(_solver_options(options, constraints.numel()), **compiled)
    if not exact:  # the multipliers' gradient would need second-order AD through the model
        solver_options.update(no_nlp_grad=True, calc_lam_p=False)
    solver = ca.nlpsol("mpc", options.solver, nlp, dict(solver_options, **functions))
    return MPCController(solver, step, options, n, variable_bounds(robot, horizon))


def _jit_options(enabled: bool) -> dict:
    if not enabled:
        return {}
    return {
        "jit": True,
        "compiler": "shell",
        "jit_options": {"flags": ["-O3", "-march=native"], "verbose": False},
    }


def tracking_cost(robot: RobotDescription, options: MPCOptions, states, torques, reference):
    """``wq |q - q_ref|^2 + wv |qd - qd_ref|^2 + wu |tau / tau_max|^2`` over the nodes 1..N and the N torques.

    states (2 n_dof, N + 1), torques (n_dof, N), reference (2 n_dof (N + 1),) column-major: the one
    objective of every MPC of this package (the full solve, the real-time iteration, the peers).
    """
    n, horizon = robot.n_dof, options.horizon
    error = states[:, 1:] - ca.reshape(reference, 2 * n, horizon + 1)[:, 1:]
    tau_scale = np.where(np.isfinite(robot.tau_max), robot.tau_max, 1.0)
    return (
        options.position_weight * ca.sumsqr(error[:n, :])
        + options.velocity_weight * ca.sumsqr(error[n:, :])
        + options.torque_weight * ca.sumsqr(torques / ca.DM(tau_scale))
    )


def constraint_jacobian(w, states, torques, model_jacobian, n):
    """``dg/dx`` assembled from the stage Jacobians: -[A_k B_k] and the identity per gap."""
    horizon = torques.shape[1]
    n_w = w.numel()
    _, blocks = model_jacobian.map(horizon)(states[:, :-1], torques)
    rows = []
    for k in range(horizon):
        start = 3 * n * k
        rows.append(
            ca.horzcat(
                ca.MX(2 * n, start),
                -blocks[:, start : start + 3 * n],
                ca.MX.eye(2 * n),
                ca.MX(2 * n, n_w - start - 5 * n),
            )
        )
    return ca.vertcat(*rows)


def _gauss_newton_hessian(w, p, cost, constraints):
    """``(x, p, lam_f, lam_g) -> lam_f triu(d2 cost / dw2)``: the cost is quadratic, so its Hessian is constant."""
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", constraints.numel())
    hessian = ca.DM(ca.evalf(ca.hessian(cost, w)[0]) if isinstance(w, ca.SX) else _constant_hessian(w, p, cost))
    x, p_in = ca.MX.sym("x", w.numel()), ca.MX.sym("p", p.numel())
    return ca.Function(
        "nlp_hess_l",
        [x, p_in, lam_f, lam_g],
        [lam_f * ca.triu(ca.MX(hessian))],
        ["x", "p", "lam_f", "lam_g"],
        ["triu_hess_gamma_x_x"],
    )


def _constant_hessian(w, p, cost):
    evaluate = ca.Function("cost_hessian", [w, p], [ca.hessian(cost, w)[0]])
    return evaluate(np.zeros(w.numel()), np.zeros(p.numel()))


def variable_bounds(robot: RobotDescription, horizon: int) -> dict:
    """Variable bounds in stage order: x0 (set to the measured state at each step), then the joint and torque limits."""
    x_low = np.concatenate([robot.q_min, -robot.qd_max])
    x_high = np.concatenate([robot.q_max, robot.qd_max])
    free = np.full(2 * robot.n_dof, np.inf)
    low = [np.concatenate([-free, -robot.tau_max])]
    high = [np.concatenate([free, robot.tau_max])]
    for _ in range(1, horizon):
        low.append(np.concatenate([x_low, -robot.tau_max]))
        high.append(np.concatenate([x_high, robot.tau_max]))
    low.append(x_low)
    high.append(x_high)
    zeros = np.zeros(2 * robot.n_dof * horizon)
    return {"lbx": np.concatenate(low), "ubx": np.concatenate(high), "lbg": zeros, "ubg": zeros}
