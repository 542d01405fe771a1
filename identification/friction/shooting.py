"""The multiple-shooting LuGre fit of one joint's friction experiment, solved by Ipopt (our NLP).

Takes one joint's friction experiment as plain arrays (``t, qd, tau_friction``, paper eq. 19) and
a starting point from :mod:`identification.friction.start` (stage 1: eq. 20 and a data-driven
guess), and returns :class:`identification.friction.models.LuGreParameters`.

:func:`fit_lugre_multiple_shooting` fits all seven parameters at once: the bristle force at the
shooting nodes (every ``ShootingOptions.interval``-th sample) is a decision variable, each interval
is integrated sample by sample with the exponential integrator of
:mod:`identification.friction.lugre_step` (stiff-safe at any ``sigma0``), continuity is an equality
constraint, parameters are optimised as logarithms of their ratio to the initial guess (positive
and well scaled), and Ipopt gets exact first and second derivatives from CasADi. The NLP is built
from one small SX Function per interval and assembled by :mod:`identification.friction.shooting_nlp`.
With ``ShootingOptions(measurement="central-difference")`` each interval carries instead the
measurement model of :mod:`identification.friction.measurement` (bristles driven by the encoder's
displacement, torque averaged as held commands and central differences measure it).

The pipeline's friction step (:class:`identification.calibration.friction_step.FrictionIdentifier`)
runs this fit per joint. The paper's method (trust-region eq. 20, then Nelder-Mead over a LuGre
simulation of the whole data set), the peer of the benchmarks, lives in
:mod:`identification.friction.baseline`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from identification.friction.lugre_step import phi_function_expressions, substep_layout
from identification.friction.measurement import build_measured_interval, measured_layout, simulate_lugre_measured
from identification.friction.models import (
    LUGRE_PARAMETER_NAMES,
    LuGreParameters,
    check_friction_data,
    check_slides_both_ways,
)
from identification.friction.shooting_nlp import assemble_shooting_nlp, build_shooting_interval
from identification.friction.simulation import simulate_lugre
from identification.friction.start import check_initial
from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.ipopt_progress import progress_options

logger = logging.getLogger(__name__)

__all__ = ["ShootingOptions", "ShootingResult", "fit_lugre_multiple_shooting"]

_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
MEASUREMENTS = ("sample", "central-difference")


@dataclass(frozen=True)
class ShootingOptions:
    """Options of :func:`fit_lugre_multiple_shooting`.

    Parameters
    ----------
    interval : int
        Samples per shooting interval, >= 1. The bristle force at every ``interval``-th sample is a
        decision variable; inside an interval it is propagated sample by sample by the integrator
        and the interval's end must meet the next node (continuity). 1 is full multiple shooting
        (every sample a variable); longer intervals shrink the KKT system, and stay well
        conditioned because the integrator is contractive (``|decay| <= 1``).
    substeps : int
        Integrator steps per sample interval, >= 1 (second-order scheme; 1 is accurate at 1 kHz).
    hessian : {"exact", "limited-memory"}
        Exact CasADi Hessian of the Lagrangian, or Ipopt's L-BFGS approximation.
    max_iter : int
        Ipopt iteration limit, >= 1.
    tol : float
        Ipopt convergence tolerance, > 0.
    parameter_range : float
        Each parameter is kept within ``[initial / parameter_range, initial * parameter_range]``, > 1.
    accept_acceptable : bool
        Treat Ipopt's ``Solved_To_Acceptable_Level`` as success.
    print_level : int
        Ipopt verbosity 0..12.
    ipopt_options : dict
        Raw Ipopt options passed through unchanged (the only free-form dict).
    measurement : {"sample", "central-difference"}
        What each torque sample is compared with. ``"sample"``: the friction at the sample instant,
        along the velocity interpolated linearly between samples. ``"central-difference"``: the
        friction averaged as a torque measured from held commands and the central second
        difference of the encoder sees it, along the encoder's displacement between samples
        (:mod:`identification.friction.measurement`; needs ``q``; exact on each sample interval, so
        ``substeps`` is not used). The friction step uses it at full rate: on joints that ring on
        their bristles after a stick, ``"sample"`` biases sigma1.
    fixed : tuple of str
        Parameters (of ``LUGRE_PARAMETER_NAMES``) held at their initial value, e.g. ``("dv",)`` for
        linear viscous friction (the recordings route, whose viscous term is linear).
    """

    interval: int = 10
    substeps: int = 1
    hessian: str = "exact"
    max_iter: int = 200
    tol: float = 1e-8
    parameter_range: float = 1e3
    accept_acceptable: bool = False
    print_level: int = 0
    ipopt_options: dict = field(default_factory=dict)
    measurement: str = "sample"
    fixed: tuple = ()

    def __post_init__(self):
        unknown = [name for name in self.fixed if name not in LUGRE_PARAMETER_NAMES]
        if unknown:
            raise ParameterError(
                f"ShootingOptions.fixed must name parameters of {LUGRE_PARAMETER_NAMES}; got {unknown!r}."
            )
        if self.measurement not in MEASUREMENTS:
            raise ParameterError(
                f"ShootingOptions.measurement must be one of {MEASUREMENTS}; got "
                f"{self.measurement!r}. Pass 'central-difference' with positions q."
            )
        for name in ("interval", "substeps", "max_iter"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 1):
                raise ParameterError(f"ShootingOptions.{name} must be an integer >= 1; got {value!r}. Pass e.g. 1.")
        if self.hessian not in ("exact", "limited-memory"):
            raise ParameterError(
                f"ShootingOptions.hessian must be 'exact' or 'limited-memory'; got {self.hessian!r}. Pass 'exact'."
            )
        if not (np.isfinite(self.tol) and self.tol > 0):
            raise ParameterError(f"ShootingOptions.tol must be finite and > 0; got {self.tol}. Pass e.g. 1e-8.")
        if not (np.isfinite(self.parameter_range) and self.parameter_range > 1):
            raise ParameterError(
                f"ShootingOptions.parameter_range must be finite and > 1; got {self.parameter_range}. Pass e.g. 1e3."
            )
        if not (isinstance(self.print_level, (int, np.integer)) and 0 <= self.print_level <= 12):
            raise ParameterError(f"ShootingOptions.print_level must be an integer in 0..12; got {self.print_level!r}.")
        if not isinstance(self.ipopt_options, dict):
            raise ParameterError(
                f"ShootingOptions.ipopt_options must be a dict; got {type(self.ipopt_options).__name__}. Pass {{}}."
            )


@dataclass(frozen=True)
class ShootingResult:
    """Result of :func:`fit_lugre_multiple_shooting`.

    Attributes
    ----------
    parameters : LuGreParameters
        Identified parameters.
    initial : LuGreParameters
        The starting point.
    z : ndarray, shape (n_samples,)
        Bristle deflection trajectory [rad] at the optimum.
    tau : ndarray, shape (n_samples,)
        Fitted friction torque [N m] (with ``measurement="central-difference"``: as measured, the
        triangle-weighted mean around each sample).
    status : str
        Ipopt return status.
    iterations : int
        Ipopt iterations.
    objective : float
        Mean squared torque residual [N^2 m^2].
    seconds : float
        Wall time of build and solve [s].
    solve_seconds : float
        Wall time of the Ipopt solve alone [s].
    """

    parameters: LuGreParameters
    initial: LuGreParameters
    z: np.ndarray
    tau: np.ndarray
    status: str
    iterations: int
    objective: float
    seconds: float
    solve_seconds: float


# ------------------------------------------------------------------------------------------------
# the NLP of the friction at the samples (measurement="sample")
# ------------------------------------------------------------------------------------------------
def _interval_functions(p0, s_scale, substeps, parts, length):
    """SX Functions of one shooting interval of ``length`` samples, and its exact Hessian block.

    ``log_p`` (7) are the decision parameters, ``p = p0 * exp(log_p)``; ``w = s / s_scale`` is the
    scaled bristle force at the interval's first sample (the shooting node). ``data`` holds, per
    sample, ``[qd, log|qd|, sign(qd), tau, weight]`` (weight 0 pads the last interval) and ``steps``
    holds, per sample interval, ``4 * substeps * parts`` values ``h, qd_a, qd_b, sign`` (``parts`` = 2
    where some step is split at a zero crossing of the velocity, else 1; padding steps have h = 0).

    Returns the pair of :func:`identification.friction.shooting_nlp.build_shooting_interval`, with
    the continuity defect ``s_end / s_scale - w_next`` and ``cost = sum weight * residual**2``.
    """
    log_p = ca.SX.sym("log_p", 7)
    p = [float(p0[i]) * ca.exp(log_p[i]) for i in range(7)]
    fc, fs, vs, fv, dv, sigma0, sigma1 = p
    w = ca.SX.sym("w")
    w_next = ca.SX.sym("w_next")
    data = ca.SX.sym("data", 5, length)
    per_step = 4 * substeps * parts
    steps = ca.SX.sym("steps", per_step, length)

    s = s_scale * w
    cost = 0
    for i in range(length):
        qd = data[0, i]
        g = fc + (fs - fc) * ca.exp(-((qd / vs) ** 2))
        tau = s + sigma1 * (qd - ca.fabs(qd) * s / g) + fv * ca.exp(dv * data[1, i]) * data[2, i]
        cost = cost + data[4, i] * (tau - data[3, i]) ** 2
        for j in range(substeps * parts):
            h, qa, qb, sign = (steps[4 * j + r, i] for r in range(4))
            g_a = fc + (fs - fc) * ca.exp(-((qa / vs) ** 2))
            g_b = fc + (fs - fc) * ca.exp(-((qb / vs) ** 2))
            x = 0.5 * sigma0 * h * (ca.fabs(qa) / g_a + ca.fabs(qb) / g_b)
            phi1, phi2 = phi_function_expressions(x)
            s = ca.exp(-x) * s + x * (phi1 * sign * g_a + phi2 * sign * (g_b - g_a))
    return build_shooting_interval("interval", log_p, w, w_next, steps, data, s / s_scale - w_next, cost)


def _build_nlp(t, qd, tau, p0, s_scale, substeps, mse_scale, interval):
    """The NLP of the friction at the samples: ``nlp, hess_lag, n_nodes`` (see ``shooting_nlp``).

    Variables: ``log_p`` (7) then the scaled bristle force at the nodes, samples ``0, M, 2M, ...``.
    """
    n = t.size
    m = interval
    n_nodes = (n - 1) // m + 1
    padded = n_nodes * m
    layout = substep_layout(t, qd, substeps)
    # per-sample data, padded with zero-weight samples
    moving = qd != 0
    data = np.zeros((5, padded))
    data[:, :n] = np.vstack([qd, np.where(moving, np.log(np.abs(qd) + ~moving), 0.0), np.sign(qd), tau, np.ones(n)])
    data[4, :n] /= n * mse_scale
    # per-step data for both parts, padded with h = 0 (identity) steps
    step_rows = []
    for part in range(2):
        for j in range(substeps):
            step_rows += [layout.h[part, j], layout.qd_a[part, j], layout.qd_b[part, j], layout.sign[part, j]]
    steps = np.zeros((len(step_rows), padded))
    steps[:, : n - 1] = np.vstack(step_rows)
    crossing = np.zeros(padded, dtype=bool)
    crossing[: n - 1] = layout.crossing
    interval_crosses = crossing.reshape(n_nodes, m).any(axis=1)
    half = 4 * substeps

    groups = []
    for parts in (1, 2):
        nodes = np.flatnonzero(interval_crosses == (parts == 2))
        if nodes.size == 0:
            continue
        fun, hess = _interval_functions(p0, s_scale, substeps, parts, m)
        # a mapped Function takes its r x m matrix inputs side by side: interval-major columns
        samples = (nodes[:, None] * m + np.arange(m)[None, :]).ravel()
        groups.append((nodes, fun, hess, steps[: half * parts, samples], data[:, samples]))
    return (*assemble_shooting_nlp(n_nodes, groups), n_nodes)


def _build_measured_nlp(t, q, tau, p0, s_scale, mse_scale, interval):
    """The NLP of the central-difference measurement model (:mod:`identification.friction.measurement`)."""
    n_nodes = (t.size - 1) // interval + 1
    fun, hess = build_measured_interval(p0, s_scale, interval)
    steps, data = measured_layout(t, q, tau, n_nodes, interval, mse_scale)
    return (*assemble_shooting_nlp(n_nodes, [(np.arange(n_nodes), fun, hess, steps, data)]), n_nodes)


# ------------------------------------------------------------------------------------------------
# the fit
# ------------------------------------------------------------------------------------------------
def fit_lugre_multiple_shooting(t, qd, tau_friction, initial, options=None, q=None):
    """Fit all seven LuGre parameters by multiple shooting, solved by Ipopt with exact derivatives.

    Decision variables are ``log(p / initial)`` for the seven parameters and the bristle force
    ``s = sigma0 z`` (scaled by ``initial.fs``) at every shooting node. On each interval the
    exponential integrator of :mod:`identification.friction.lugre_step` carries ``s`` from sample
    to sample; its end must equal the next node (continuity). The objective is the mean squared
    torque residual of eq. 14 at every sample (with ``measurement="central-difference"``: of the
    measurement model of :mod:`identification.friction.measurement` at the interior samples, the
    bristle force following the positions ``q``).

    Parameters
    ----------
    t : array, shape (n_samples,)
        Strictly increasing times [s].
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    tau_friction : array, shape (n_samples,)
        Measured friction torque [N m] (eq. 19).
    initial : LuGreParameters
        Starting point (e.g. :func:`identification.friction.start.initial_lugre_guess`); ``fv`` and
        ``sigma1`` must be > 0.
    options : ShootingOptions, optional
    q : array, shape (n_samples,), optional
        Recorded joint positions [rad]; required by ``options.measurement="central-difference"``.

    Returns
    -------
    ShootingResult

    Raises
    ------
    SolverError
        Ipopt did not converge; ``status`` and ``iterations`` are attached.
    ParameterError, ShapeError
        Bad arrays or options.
    InsufficientExcitationError
        When ``qd`` does not slide in both directions (``models.check_slides_both_ways``).

    Examples
    --------
    >>> from identification.friction.start import fit_high_speed, initial_lugre_guess
    >>> initial = initial_lugre_guess(t, qd, tau, fit_high_speed(qd, tau))   # doctest: +SKIP
    >>> fit_lugre_multiple_shooting(t, qd, tau, initial).parameters          # doctest: +SKIP
    """
    t, qd, tau, q, options = _checked_inputs(t, qd, tau_friction, initial, options, q)
    measured = options.measurement == "central-difference"
    start = time.perf_counter()
    n = t.size
    p0 = initial.as_array()
    s_scale = max(initial.fs, initial.fc)
    # starting trajectory: simulate the initial guess; its error scales the objective to O(1)
    tau_init, z_init = _simulate(initial, t, qd, q, options)
    inner = slice(1, n - 1) if measured else slice(None)
    mse_scale = max(float(np.mean((tau_init - tau)[inner] ** 2)), 1e-12 * float(np.mean(tau**2)), 1e-300)
    if measured:
        nlp, hess_lag, n_nodes = _build_measured_nlp(t, q, tau, p0, s_scale, mse_scale, options.interval)
    else:
        nlp, hess_lag, n_nodes = _build_nlp(t, qd, tau, p0, s_scale, options.substeps, mse_scale, options.interval)
    w0 = np.concatenate([np.zeros(7), initial.sigma0 * z_init[:: options.interval] / s_scale])
    x_opt, status, iterations, solve_seconds = _solve(nlp, hess_lag, w0, n_nodes, options)
    parameters = LuGreParameters.from_array(p0 * np.exp(x_opt[:7]))
    tau_fit, z = _simulate(parameters, t, qd, q, options, s0=x_opt[7] * s_scale)
    return ShootingResult(
        parameters=parameters,
        initial=initial,
        z=z,
        tau=tau_fit,
        status=status,
        iterations=iterations,
        objective=float(np.mean((tau_fit - tau)[inner] ** 2)),
        seconds=time.perf_counter() - start,
        solve_seconds=solve_seconds,
    )


def _checked_inputs(t, qd, tau_friction, initial, options, q):
    """Validate the arguments of :func:`fit_lugre_multiple_shooting`; return ``t, qd, tau, q, options``."""
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="fit_lugre_multiple_shooting")
    check_initial(initial, "fit_lugre_multiple_shooting")
    options = ShootingOptions() if options is None else options
    if not isinstance(options, ShootingOptions):
        raise ParameterError(
            f"fit_lugre_multiple_shooting.options must be a ShootingOptions; got {type(options).__name__}."
        )
    if options.measurement == "central-difference":
        if q is None:
            raise ParameterError(
                "fit_lugre_multiple_shooting.q is required by ShootingOptions.measurement="
                "'central-difference'; pass the joint's recorded positions or use 'sample'."
            )
        _, q, _ = check_friction_data(t, q, tau, owner="fit_lugre_multiple_shooting", signal="q")
        if t.size < 4:
            raise ParameterError(
                f"fit_lugre_multiple_shooting.t must hold at least 4 samples with "
                f"measurement='central-difference'; got {t.size}."
            )
    check_slides_both_ways(qd, owner="fit_lugre_multiple_shooting")
    return t, qd, tau, q, options


def _simulate(parameters, t, qd, q, options, s0=0.0):
    """Torque and bristle deflection ``z`` of the fit's model from bristle force ``s0`` [N m] at ``t[0]``."""
    if options.measurement == "central-difference":
        tau, s = simulate_lugre_measured(parameters, t, q, s0=s0)
        return tau, s / parameters.sigma0
    return simulate_lugre(parameters, t, qd, z0=s0 / parameters.sigma0, substeps=options.substeps)


def _solve(nlp, hess_lag, w0, n_nodes, options):
    """Solve the shooting NLP with Ipopt from ``w0``; return ``x_opt, status, iterations, solve_seconds``."""
    ipopt = {
        "max_iter": int(options.max_iter),
        "tol": float(options.tol),
        "print_level": int(options.print_level),
        "sb": "yes",
        "hessian_approximation": options.hessian,
    }
    ipopt.update(options.ipopt_options)
    sizes = (nlp["x"].numel(), nlp["g"].numel(), 0)
    bar, callback = progress_options("lugre_progress", sizes, ipopt["max_iter"], "LuGre friction fit (Ipopt)", logger)
    solver_options = {"ipopt": ipopt, "print_time": False, **bar}
    if options.hessian == "exact":
        solver_options["hess_lag"] = hess_lag
    solver = ca.nlpsol("lugre_shooting", "ipopt", nlp, solver_options)
    bound = np.log(options.parameter_range)
    held = np.isin(LUGRE_PARAMETER_NAMES, options.fixed)
    lbx = np.concatenate([np.where(held, 0.0, -bound), np.full(n_nodes, -np.inf)])
    ubx = np.concatenate([np.where(held, 0.0, bound), np.full(n_nodes, np.inf)])
    solve_start = time.perf_counter()
    sol = solver(x0=w0, lbx=lbx, ubx=ubx, lbg=0, ubg=0)
    solve_seconds = time.perf_counter() - solve_start
    if callback is not None:
        callback.close()
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    iterations = int(stats.get("iter_count", -1))
    accepted = _SUCCESS if options.accept_acceptable else _SUCCESS[:1]
    if status not in accepted:
        raise SolverError(
            f"fit_lugre_multiple_shooting: Ipopt returned status {status} after {iterations} iterations. "
            "Start from a better guess (initial), raise ShootingOptions.max_iter, or check the friction series "
            "(a low-pass cutoff well above the motion's frequencies keeps its low-velocity shape).",
            status=status,
            iterations=iterations,
        )
    return np.asarray(sol["x"]).ravel(), status, iterations, solve_seconds
