"""ExcitationProblem: the Ipopt NLP of eq. 23 built with CasADi (built here, solved in optimize.py).

Decision variables are the parameters of a trajectory family. The objective is a smooth criterion
(``criteria.py``) of the information matrix ``F = sum_j Ys_j^T Ys_j / N`` accumulated over an
objective grid by mapping the regressor Function (``Function.map`` with a reduced output, so the
stacked regressor is never formed in the graph). Joint limits are imposed on every sample of a
constraint grid, tightened by a small back-off so that they also hold between samples (what is
grazed between samples is caught by the 10x finer verification in optimize.py); the optional torque
limit goes through the regressor with nominal base parameters and the optional
keep-out plane through a forward-kinematics Function.

Ipopt runs with a limited-memory Hessian (the criterion is a Callback with an exact gradient and
no Hessian; this is also much faster than an exact Hessian through the mapped regressor). For a
Fourier family every limit is linear in the parameters, so the constraint Jacobian is declared
constant. The later stages of the sharpness continuation use ``warm_solver``, which restarts from
the previous primal-dual point with a small barrier parameter.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.ipopt_progress import IpoptProgress
from trajopt.constraints import JointLimits, KeepOut, check_same_dof
from trajopt.criteria import CriterionCallback, build_information_function, check_columns
from trajopt.parametrization import FourierTrajectory

logger = logging.getLogger(__name__)

DEFAULT_IPOPT = {
    "hessian_approximation": "limited-memory",
    "limited_memory_max_history": 6,
    "print_level": 0,
    "sb": "yes",
    "tol": 1e-4,
    "acceptable_tol": 1e-3,
    "acceptable_iter": 5,
    "mu_strategy": "monotone",
}


WARM_START_IPOPT = {
    "warm_start_init_point": "yes",
    "mu_strategy": "monotone",
    "mu_init": 1e-4,
    "warm_start_bound_push": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
}


class IpoptMonitor(IpoptProgress):
    """Ipopt iteration callback that stops the solve once ``deadline`` (a ``time.perf_counter`` value) passes.

    The optimiser sets ``deadline`` before each solve; a stopped solve returns ``User_Requested_Stop``
    with its current iterate, which is then verified like any other. With ``show`` set (a terminal:
    ``ipopt_progress.shows_progress_bars``) each iteration also moves a progress bar (``IpoptProgress``).
    """

    def __init__(self, name: str, n_x: int, n_g: int, n_p: int, max_iter: int = 300):
        super().__init__(name, (n_x, n_g, n_p), max_iter, "excite: trajectory optimisation (Ipopt)", logger)
        self.deadline = float("inf")
        self.show = False

    def eval(self, arg):
        if self.show:
            super().eval(arg)
        else:
            self.iterations += 1
        return [1 if time.perf_counter() > self.deadline else 0]


def default_constraint_samples(parametrization, samples_per_period: int = 12, minimum: int = 50) -> int:
    """Enough constraint samples that the fastest component is sampled ``samples_per_period`` times per period."""
    cycles = parametrization.duration * parametrization.max_frequency / (2 * np.pi)
    return int(max(minimum, np.ceil(samples_per_period * cycles)))


def build_torque_function(regressor: ca.Function, nominal_parameters) -> ca.Function:
    """``q, qd, qdd -> tau = Y(q, qd, qdd) theta`` with fixed nominal base parameters ``theta`` (n_base,)."""
    n_dof, n_base = regressor.size1_out(0), regressor.size2_out(0)
    theta = np.asarray(nominal_parameters, dtype=float).reshape(-1)
    if theta.shape != (n_base,) or not np.all(np.isfinite(theta)):
        raise ShapeError(
            f"nominal_parameters must be {n_base} finite base parameters (theta); got shape {theta.shape}. "
            "Pass model.base_parameters(robot.nominal_dynamic_parameters())."
        )
    q, qd, qdd = (ca.SX.sym(name, n_dof) for name in ("q", "qd", "qdd"))
    tau = ca.mtimes(regressor(q, qd, qdd), ca.DM(theta))
    return ca.Function("torque", [q, qd, qdd], [tau], ["q", "qd", "qdd"], ["tau"])


def check_regressor(regressor, n_dof: int) -> None:
    """The regressor must be a casadi.Function q, qd, qdd -> Y (n_dof x n_base)."""
    if not isinstance(regressor, ca.Function) or regressor.n_in() != 3 or regressor.n_out() < 1:
        raise ParameterError(
            f"regressor must be a casadi.Function (q, qd, qdd) -> Y; got {type(regressor).__name__}. "
            "Pass build_recursive_functions(derive_psdm(robot), robot).regressor."
        )
    sizes = [regressor.numel_in(i) for i in range(3)]
    if sizes != [n_dof] * 3 or regressor.size1_out(0) != n_dof:
        raise ShapeError(
            f"regressor inputs must have n_dof={n_dof} entries and Y {n_dof} rows; got inputs {sizes} and "
            f"{regressor.size1_out(0)} rows. Derive the model from the same robot."
        )


@dataclass(frozen=True)
class ExcitationProblem:
    """A built (not solved) excitation NLP with its bounds and grids.

    Attributes
    ----------
    solver : casadi.Function
        ``nlpsol`` over ``x`` with parameter ``p`` (the sharpness of the ``cond`` surrogate).
    monitor : IpoptMonitor
        Iteration callback of both solvers; set ``monitor.deadline`` to stop a solve at a wall time.
    warm_solver : casadi.Function
        The same NLP with Ipopt set up to continue from a previous primal-dual solution
        (``lam_x0``, ``lam_g0``), used for the later stages of the sharpness continuation.
    lbx, ubx, lbg, ubg : arrays
        Bounds on the decision vector and on the constraints.
    t_objective, t_constraint : arrays
        Objective and constraint grids [s].
    limits : JointLimits
        The limits the trajectory must satisfy (before back-off).
    """

    parametrization: object
    regressor: ca.Function
    limits: JointLimits
    columns: np.ndarray
    criterion: str
    solver: ca.Function
    warm_solver: ca.Function
    monitor: IpoptMonitor
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    t_objective: np.ndarray
    t_constraint: np.ndarray
    backoff: float
    torque_function: ca.Function | None = None
    keep_out: KeepOut | None = None
    column_scale: np.ndarray | None = None
    objective_function: ca.Function | None = None
    _keepalive: tuple = field(default=(), repr=False)

    @property
    def n_constraint_samples(self) -> int:
        return self.t_constraint.shape[0]


def build_excitation_problem(
    parametrization,
    regressor: ca.Function,
    limits: JointLimits,
    *,
    columns=None,
    criterion: str = "cond",
    n_samples: int = 100,
    n_constraint_samples=None,
    backoff: float = 0.02,
    column_scale=None,
    torque_function=None,
    keep_out=None,
    max_iter: int = 300,
    max_wall_time=None,
    ipopt_options=None,
) -> ExcitationProblem:
    """Build the NLP of excitation design (eq. 23 with a smooth criterion); nothing is solved.

    Parameters
    ----------
    parametrization : FourierTrajectory or SumOfSinesTrajectory
    regressor : casadi.Function
        ``q, qd, qdd -> Y`` (n_dof x n_base).
    limits : JointLimits
    columns : array of int or bool mask, optional
        Regressor columns to excite (default all).
    criterion : {"cond", "logdet"}
    n_samples : int
        Objective grid size.
    n_constraint_samples : int, optional
        Constraint grid size (default: 12 samples per period of the fastest component, at least 50; limits
        grazed between samples are caught by the 10x finer verification and repaired).
    backoff : float
        Fraction by which limits are tightened on the constraint grid, in [0, 0.5).
    column_scale : array, optional
        Multiplies the selected columns in the objective.
    torque_function : casadi.Function, optional
        ``q, qd, qdd -> tau`` with nominal parameters; constrains ``|tau| <= limits.tau_max``.
    keep_out : KeepOut, optional
    max_iter : int
        Ipopt iteration limit.
    max_wall_time : float, optional
        Ipopt wall-time limit [s].
    ipopt_options : dict, optional
        Raw Ipopt options, passed through unchanged (override the defaults).

    Returns
    -------
    ExcitationProblem
    """
    cols = _checked_problem_inputs(
        parametrization, regressor, limits, columns, n_samples, backoff, torque_function, keep_out
    )
    if n_constraint_samples is None:
        n_constraint_samples = default_constraint_samples(parametrization)

    x = ca.MX.sym("x", parametrization.n_parameters)
    sharpness = ca.MX.sym("p")
    t_obj = parametrization.default_grid(n_samples)
    objective, keepalive = _objective(parametrization, regressor, x, sharpness, t_obj, cols, criterion, column_scale)
    tight = limits.shrunk(backoff)
    t_con = parametrization.default_grid(n_constraint_samples)
    g, lbg, ubg, linear = _constraints(parametrization, x, t_con, tight, torque_function, keep_out)

    nlp = {"x": x, "p": sharpness, "f": objective, "g": g}
    monitor = IpoptMonitor("monitor", x.numel(), g.numel(), 1, max_iter)
    solver, warm_solver = _ipopt_solvers(nlp, monitor, linear, max_iter, max_wall_time, ipopt_options)
    lbx, ubx = parametrization.bounds(tight.q_min, tight.q_max)
    objective_function = ca.Function("objective", [x, sharpness], [objective], ["x", "p"], ["f"])
    return ExcitationProblem(
        parametrization=parametrization,
        regressor=regressor,
        limits=limits,
        columns=cols,
        criterion=criterion,
        solver=solver,
        warm_solver=warm_solver,
        monitor=monitor,
        lbx=lbx,
        ubx=ubx,
        lbg=lbg,
        ubg=ubg,
        t_objective=t_obj,
        t_constraint=t_con,
        backoff=float(backoff),
        torque_function=torque_function,
        keep_out=keep_out,
        column_scale=None if column_scale is None else np.asarray(column_scale, dtype=float),
        objective_function=objective_function,
        _keepalive=keepalive,
    )


def _checked_problem_inputs(
    parametrization, regressor, limits, columns, n_samples, backoff, torque_function, keep_out
) -> np.ndarray:
    """Validate the inputs of ``build_excitation_problem``; the selected columns as indices."""
    n_dof = parametrization.n_dof
    check_same_dof(limits, n_dof)
    check_regressor(regressor, n_dof)
    cols = check_columns(columns, regressor.size2_out(0))
    if not (isinstance(backoff, (int, float)) and 0 <= backoff < 0.5):
        raise ParameterError(f"ExcitationOptions.limit_backoff must be in [0, 0.5); got {backoff!r}. Use e.g. 0.02.")
    if not (isinstance(n_samples, (int, np.integer)) and n_samples * n_dof >= cols.size):
        raise ParameterError(
            f"ExcitationOptions.n_samples must be an integer with n_samples * n_dof >= {cols.size} columns; "
            f"got {n_samples!r}. Use e.g. 100."
        )
    if limits.tau_max is not None and torque_function is None:
        raise ParameterError(
            "nominal_parameters must be given when JointLimits.tau_max is set (the torque limit goes through the "
            "model). Pass nominal_parameters=model.base_parameters(robot.nominal_dynamic_parameters())."
        )
    if keep_out is not None and keep_out.point.numel_in(0) != n_dof:
        raise ShapeError(
            f"KeepOut.point must take q with n_dof={n_dof} entries; got {keep_out.point.numel_in(0)}. "
            "Build it from the same robot."
        )
    return cols


def _objective(parametrization, regressor, x, sharpness, t_obj, cols, criterion, column_scale) -> tuple:
    """The criterion of the mean information matrix over the objective grid, and the objects it needs alive.

    The regressor Function is mapped with a reduced (summed) output, so the stacked regressor is
    never formed in the graph.
    """
    n_samples = t_obj.shape[0]
    q, qd, qdd = parametrization.symbolic(x, t_obj)
    info = build_information_function(regressor, cols, column_scale)
    info_sum = info.map("information_sum", "serial", int(n_samples), [], [0])
    information = info_sum(q.T, qd.T, qdd.T) / n_samples
    criterion_fn = CriterionCallback(criterion, cols.size)
    return criterion_fn(information, sharpness), (criterion_fn, info, info_sum)


def _constraints(parametrization, x, t_con, tight: JointLimits, torque_function, keep_out) -> tuple:
    """Limits on every constraint sample, the family's equalities: (g, lbg, ubg, whether g is linear in x)."""
    n_con = t_con.shape[0]
    qc, qdc, qddc = parametrization.symbolic(x, t_con)
    blocks = [ca.vec(qc), ca.vec(qdc), ca.vec(qddc)]  # joint-major: all samples of joint 1, then joint 2...
    lbg = [np.repeat(tight.q_min, n_con), np.repeat(-tight.qd_max, n_con), np.repeat(-tight.qdd_max, n_con)]
    ubg = [np.repeat(tight.q_max, n_con), np.repeat(tight.qd_max, n_con), np.repeat(tight.qdd_max, n_con)]
    linear = isinstance(parametrization, FourierTrajectory)  # its q, qd, qdd are linear in x
    if tight.tau_max is not None:
        tau = torque_function.map(n_con)(qc.T, qdc.T, qddc.T)  # (n_dof, n_con)
        blocks.append(ca.vec(tau))
        lbg.append(np.tile(-tight.tau_max, n_con))
        ubg.append(np.tile(tight.tau_max, n_con))
        linear = False
    if keep_out is not None:
        points = keep_out.point.map(n_con)(qc.T)  # (3, n_con)
        blocks.append((ca.mtimes(ca.DM(keep_out.normal).T, points) - keep_out.offset).T)
        lbg.append(np.full(n_con, keep_out.margin))
        ubg.append(np.full(n_con, np.inf))
        linear = False
    equality = parametrization.equality(x)
    blocks.append(equality)
    lbg.append(np.zeros(equality.shape[0]))
    ubg.append(np.zeros(equality.shape[0]))
    return ca.vertcat(*blocks), np.concatenate(lbg), np.concatenate(ubg), linear


def _ipopt_solvers(nlp: dict, monitor: IpoptMonitor, linear: bool, max_iter, max_wall_time, ipopt_options) -> tuple:
    """The cold-start and warm-start Ipopt solvers of the NLP; raw ``ipopt_options`` override the defaults."""
    options = dict(DEFAULT_IPOPT)
    options["max_iter"] = int(max_iter)
    if max_wall_time is not None:
        options["max_wall_time"] = float(max_wall_time)
    if linear:
        options["jac_c_constant"] = "yes"
        options["jac_d_constant"] = "yes"
    options.update(ipopt_options or {})
    common = {"print_time": False, "error_on_fail": False, "iteration_callback": monitor}
    solver = ca.nlpsol("excitation", "ipopt", nlp, {"ipopt": options, **common})
    warm = {**options, **WARM_START_IPOPT, **(ipopt_options or {})}
    warm_solver = ca.nlpsol("excitation_warm", "ipopt", nlp, {"ipopt": warm, **common})
    return solver, warm_solver
