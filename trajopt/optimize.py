"""optimize_excitation(): multi-start Ipopt on the excitation NLP -> ExcitationTrajectory (verified limits).

Each start is a random trajectory of the family scaled into the limits; Ipopt then minimises the
smooth criterion, continuing the sharpness of the condition-number surrogate. Every candidate is
checked on a grid ten times finer than the constraint grid (and repaired by shrinking a joint's
oscillation if a limit is grazed between samples); the best true condition number wins.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ExcitationWarning, ParameterError, SolverError
from psdm_casadi.ipopt_progress import shows_progress_bars
from trajopt.constraints import (
    JointLimits,
    KeepOut,
    check_same_dof,
    describe_violation,
    fine_grid,
    scale_into_limits,
    verify_limits,
)
from trajopt.criteria import check_columns, condition_number, nominal_column_scale, stack_regressor
from trajopt.excitation import FAMILIES, ExcitationOptions, ExcitationTrajectory
from trajopt.problem import build_excitation_problem, build_torque_function, check_regressor

__all__ = ["FAMILIES", "ExcitationOptions", "ExcitationTrajectory", "optimize_excitation", "random_feasible_parameters"]

_ACCEPTED = (
    "Solve_Succeeded",
    "Solved_To_Acceptable_Level",
    "Maximum_Iterations_Exceeded",
    "User_Requested_Stop",
    "Maximum_WallTime_Exceeded",
    "Maximum_CpuTime_Exceeded",
    "Search_Direction_Becomes_Too_Small",
)
_CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")

logger = logging.getLogger(__name__)


def random_feasible_parameters(
    parametrization, limits: JointLimits, rng: np.random.Generator, t, fill: float = 0.7
) -> np.ndarray:
    """A random trajectory of the family scaled so that q, qd, qdd use at most ``fill`` of the limits on ``t``."""
    x = parametrization.random_parameters(rng, limits.center)
    return scale_into_limits(parametrization, x, limits, t, fill=fill)


def _rng(seed, rng) -> np.random.Generator:
    if rng is not None:
        if not isinstance(rng, np.random.Generator):
            raise ParameterError(
                f"rng must be a numpy Generator; got {type(rng).__name__}. Use np.random.default_rng(0)."
            )
        return rng
    return np.random.default_rng(0 if seed is None else seed)


def optimize_excitation(
    robot,
    regressor,
    options: ExcitationOptions | None = None,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    nominal_parameters=None,
    keep_out: KeepOut | None = None,
) -> ExcitationTrajectory:
    """Design an excitation trajectory minimising the condition number of the stacked regressor (eq. 23).

    Parameters
    ----------
    robot : RobotDescription
        Supplies n_dof and limits (unless ``options.limits``).
    regressor : casadi.Function
        ``q, qd, qdd -> Y`` (n_dof x n_base), e.g. ``build_recursive_functions(model, robot).regressor``.
    options : ExcitationOptions, optional
    seed : int, optional
        Seed of the random starts (default 0); ignored when ``rng`` is given.
    rng : numpy.random.Generator, optional
    nominal_parameters : array, shape (n_base,), optional
        Base parameters for the torque limit (``options.torque_limits``).
    keep_out : KeepOut, optional
        A point of the robot to keep on one side of a plane.

    Returns
    -------
    ExcitationTrajectory

    Raises
    ------
    ParameterError
        Invalid options or limits, or limits that no trajectory of the family can meet.
    SolverError
        When every start fails in Ipopt (status and iterations attached).

    Examples
    --------
    >>> options = ExcitationOptions(duration=10, harmonics=5)  # doctest: +SKIP
    >>> traj = optimize_excitation(robot, functions.regressor, options)  # doctest: +SKIP
    >>> traj.to_csv("traj.csv", rate=100)  # doctest: +SKIP
    """
    started = time.perf_counter()
    options = ExcitationOptions() if options is None else options
    if not isinstance(options, ExcitationOptions):
        raise ParameterError(f"options must be ExcitationOptions; got {type(options).__name__}.")
    generator = _rng(seed, rng)
    limits, parametrization, columns, torque_function = _checked_inputs(robot, regressor, options, nominal_parameters)
    tight = limits.shrunk(options.limit_backoff)
    starts = [
        random_feasible_parameters(
            parametrization, tight, generator, fine_grid(parametrization, 200, 1), options.start_fill
        )
        for _ in range(options.n_starts)
    ]
    column_scale = None
    if options.column_scaling:
        t_obj = parametrization.default_grid(options.n_samples)
        column_scale = nominal_column_scale(regressor, *parametrization.evaluate(t_obj, starts[0]), columns)
    _report(
        options,
        f"excite: building the NLP ({parametrization.__class__.__name__}, "
        f"{parametrization.n_parameters} parameters, {columns.size} columns, {options.n_samples} samples)",
    )
    problem = build_excitation_problem(
        parametrization,
        regressor,
        limits,
        columns=columns,
        criterion=options.criterion,
        n_samples=options.n_samples,
        n_constraint_samples=options.n_constraint_samples,
        backoff=options.limit_backoff,
        column_scale=column_scale,
        torque_function=torque_function,
        keep_out=keep_out,
        max_iter=options.max_iter,
        ipopt_options=options.ipopt_options,
    )
    search = _run_starts(problem, starts, options, started)
    if search.best is None and search.rank_deficient:
        raise ParameterError(
            "ExcitationOptions.columns must be identifiable: the stacked regressor of the selected columns is rank "
            "deficient on every start (a column is zero or a combination of others along any trajectory). Select "
            "base-parameter columns only, e.g. ~model.gravity_mask, or None for all."
        )
    if search.best is None:
        _raise_failure(search.statuses, problem.limits)
    if search.status not in _CONVERGED:
        warnings.warn(
            f"optimize_excitation: the best start stopped with Ipopt status {search.status}; its limits are "
            "verified but the criterion may improve with a larger max_iter or time_limit.",
            ExcitationWarning,
            stacklevel=2,
        )
    cond_scaled = None
    if column_scale is not None:
        y = stack_regressor(regressor, *parametrization.evaluate(problem.t_objective, search.best), columns)
        cond_scaled = condition_number(y * column_scale)
    seconds = time.perf_counter() - started
    return ExcitationTrajectory(
        parametrization=parametrization,
        parameters=search.best,
        cond=search.cond,
        worst_margin=search.margins["worst"],
        worst_limit=describe_violation(search.margins),
        seconds=seconds,
        columns=tuple(int(c) for c in columns),
        limits=problem.limits,
        cond_scaled=cond_scaled,
        status=search.status,
        start_conds=search.start_conds,
    )


def _report(options: ExcitationOptions, message: str, progress: tuple | None = None) -> None:
    """A progress line on this module's logger, unless ``options.quiet``; ``progress`` is (done, total) starts,
    which the command line draws as a bar on a terminal."""
    if not options.quiet:
        logger.info(message, extra=None if progress is None else {"progress": progress})


def _checked_inputs(robot, regressor, options: ExcitationOptions, nominal_parameters) -> tuple:
    """Validate the inputs of ``optimize_excitation``: (limits, parametrization, columns, torque function or None)."""
    n_dof = robot.n_dof
    check_regressor(regressor, n_dof)
    limits = options.build_limits(robot)
    check_same_dof(limits, n_dof)
    parametrization = options.build_parametrization(n_dof)
    columns = check_columns(options.columns, regressor.size2_out(0))
    torque_function = None
    if limits.tau_max is not None:
        if nominal_parameters is None:
            raise ParameterError(
                "nominal_parameters must be given when ExcitationOptions.torque_limits is True; got None. "
                "Pass nominal_parameters=model.base_parameters(robot.nominal_dynamic_parameters())."
            )
        torque_function = build_torque_function(regressor, nominal_parameters)
    return limits, parametrization, columns, torque_function


@dataclass(frozen=True)
class _Search:
    """Outcome of the multi-start search: the best verified start (None if none) and every start's record."""

    best: np.ndarray | None
    cond: float
    margins: dict | None
    status: str
    statuses: tuple
    start_conds: tuple
    rank_deficient: bool


def _solve_stages(problem, x0, sharpness, options: ExcitationOptions, started: float, label: str) -> tuple:
    """Ipopt on one start through the sharpness continuation, each stage warm-started from the last.

    Returns (x, Ipopt status, total iterations); x is the last accepted iterate.
    """
    x, status, iterations, multipliers = np.asarray(x0, dtype=float), "", 0, {}
    for stage, p in enumerate(sharpness):
        if stage > 0 and options.time_limit is not None and time.perf_counter() - started > options.time_limit:
            break
        solver = problem.solver if stage == 0 else problem.warm_solver
        if options.time_limit is not None:
            problem.monitor.deadline = started + options.time_limit
        solution = _solve_interruptibly(solver, problem, label, p=p, x0=x, **multipliers)
        stats = solver.stats()
        status, iterations = stats.get("return_status", "unknown"), iterations + int(stats.get("iter_count", 0))
        _report(
            options,
            f"excite: start {label}, stage {stage + 1}/{len(sharpness)} (p={p:g}): "
            f"criterion {float(solution['f']):.4g}, {status}, {int(stats.get('iter_count', 0))} "
            f"iterations, {time.perf_counter() - started:.1f} s",
        )
        if status not in _ACCEPTED:
            break
        x = np.asarray(solution["x"], dtype=float).reshape(-1)
        multipliers = {"lam_x0": solution["lam_x"], "lam_g0": solution["lam_g"]}
    return x, status, iterations


@contextmanager
def _interrupts_recorded(monitor):
    """A list that receives the SIGINTs of the block, each of which asks the running Ipopt solve to stop.

    The handler raises nothing: a KeyboardInterrupt raised inside CasADi's Python callbacks would be
    printed there as a traceback and turned into a solver failure. It moves the iteration monitor's
    deadline to the past instead, so Ipopt stops at its next iteration, and the caller raises.
    """
    received = []
    previous = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or previous in (signal.SIG_IGN, None):
        yield received
        return

    def record(signum, frame):
        received.append(signum)
        monitor.deadline = -math.inf

    signal.signal(signal.SIGINT, record)
    try:
        yield received
    finally:
        signal.signal(signal.SIGINT, previous)


def _solve_interruptibly(solver, problem, label: str, **arguments):
    """One Ipopt solve; a Ctrl-C during it raises KeyboardInterrupt (the user asked to stop, not this start)."""
    deadline, monitor = problem.monitor.deadline, problem.monitor
    monitor.show, monitor.label = shows_progress_bars(logger), f"excite: start {label} (Ipopt)"
    monitor.set_bounds(problem.lbg, problem.ubg)
    with _interrupts_recorded(problem.monitor) as interrupts:
        try:
            solution = solver(lbx=problem.lbx, ubx=problem.ubx, lbg=problem.lbg, ubg=problem.ubg, **arguments)
        except Exception:
            if interrupts:
                raise KeyboardInterrupt(f"excite: start {label} interrupted") from None
            raise
        finally:
            monitor.close()
    status = solver.stats().get("return_status", "unknown")
    # User_Requested_Stop before the deadline of the time limit: Ipopt's own handling of SIGINT
    own_stop = status == "User_Requested_Stop" and time.perf_counter() < deadline
    if interrupts or own_stop:
        raise KeyboardInterrupt(f"excite: start {label} interrupted (Ipopt status {status})")
    return solution


def _run_starts(problem, starts, options: ExcitationOptions, started: float) -> _Search:
    """Solve every start (until the time limit), verify it on the fine grid and keep the best true ``cond``."""
    parametrization, columns = problem.parametrization, problem.columns
    sharpness = options.sharpness if options.criterion == "cond" else (options.sharpness[-1],)
    best, best_cond, best_margins, best_status = None, math.inf, None, ""
    statuses, start_conds, rank_deficient = [], [], False
    for k, x0 in enumerate(starts):
        label = f"{k + 1}/{len(starts)}"
        elapsed = time.perf_counter() - started
        if options.time_limit is not None and elapsed > options.time_limit and best is not None:
            _report(options, f"excite: time limit reached after {k} starts")
            break
        x, status, iterations = _solve_stages(problem, x0, sharpness, options, started, label)
        statuses.append((status, iterations))
        if status not in _ACCEPTED:
            start_conds.append(math.inf)
            _report(options, f"excite: start {label} failed ({status}, {iterations} iterations)", (k + 1, len(starts)))
            continue
        x, margins = _verified(problem, x)
        if margins["worst"] < 0:
            start_conds.append(math.inf)
            _report(
                options,
                f"excite: start {label} discarded: {describe_violation(margins)} after repair",
                (k + 1, len(starts)),
            )
            continue
        cond = condition_number(
            stack_regressor(problem.regressor, *parametrization.evaluate(problem.t_objective, x), columns)
        )
        start_conds.append(cond)
        if not math.isfinite(cond):
            rank_deficient = True
            _report(options, f"excite: start {label}: the stacked regressor is rank deficient", (k + 1, len(starts)))
            continue
        _report(
            options,
            f"excite: start {label}: cond {cond:.4g}, worst margin {margins['worst']:.3g} "
            f"({status}, {iterations} iterations, {time.perf_counter() - started:.1f} s)",
            (k + 1, len(starts)),
        )
        if cond < best_cond:
            best, best_cond, best_margins, best_status = x, cond, margins, status
    return _Search(
        best=best,
        cond=best_cond,
        margins=best_margins,
        status=best_status,
        statuses=tuple(statuses),
        start_conds=tuple(start_conds),
        rank_deficient=rank_deficient,
    )


def _verified(problem, x) -> tuple:
    """Verify x on the 10x finer grid; if a kinematic limit is grazed between samples, shrink that joint."""
    parametrization, limits = problem.parametrization, problem.limits
    n_con = problem.n_constraint_samples
    margins = verify_limits(
        parametrization, x, limits, n_con, torque_function=problem.torque_function, keep_out=problem.keep_out
    )
    if margins["worst"] < 0 and min(margins["q"], margins["qd"], margins["qdd"]) < 0:
        x = scale_into_limits(parametrization, x, limits, fine_grid(parametrization, n_con), fill=1 - 1e-9)
        margins = verify_limits(
            parametrization, x, limits, n_con, torque_function=problem.torque_function, keep_out=problem.keep_out
        )
    return x, margins


def _raise_failure(statuses, limits) -> None:
    infeasible = [s for s, _ in statuses if s == "Infeasible_Problem_Detected"]
    if statuses and len(infeasible) == len(statuses):
        extra = "tau_max, " if limits.tau_max is not None else ""
        raise ParameterError(
            f"JointLimits ({extra}q_min/q_max, qd_max, qdd_max and any keep-out plane) cannot be met by any trajectory "
            "of the family: Ipopt proved every start infeasible. Relax the torque limit or keep-out plane, or use "
            "rest_to_rest=False."
        )
    status, iterations = statuses[-1] if statuses else ("no start", 0)
    raise SolverError(
        f"optimize_excitation: every start failed in Ipopt (last status {status} after {iterations} iterations). "
        "Try more n_starts, a smaller limit_backoff, or criterion='logdet'.",
        status=status,
        iterations=iterations,
    )
