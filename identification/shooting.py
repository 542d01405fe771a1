"""LuGre friction identification: high-speed fit (eq. 20) and the multiple-shooting NLP solved by Ipopt.

Takes one joint's friction experiment as plain arrays (``t, qd, tau_friction``, paper eq. 19)
and returns :class:`identification.friction.LuGreParameters`. The pipeline is

1. :func:`fit_high_speed` -- eq. 20 on samples with ``|qd| >> vs`` (scipy trust-region least squares);
2. :func:`initial_lugre_guess` -- cheap data-driven starting values for ``fs, vs, sigma0, sigma1``;
3. :func:`fit_lugre_multiple_shooting` -- all seven parameters at once: the bristle force at the
   shooting nodes (every ``ShootingOptions.interval``-th sample) is a decision variable, each
   interval is integrated sample by sample with the exponential integrator of
   :mod:`identification.friction` (stiff-safe at any ``sigma0``), continuity is an equality
   constraint, parameters are optimised as logarithms of their ratio to the initial guess
   (positive and well scaled), and Ipopt gets exact first and second derivatives from CasADi.
   The NLP is built from one small SX Function per interval, mapped over the intervals; its
   exact Lagrangian Hessian is assembled from per-interval 8 x 8 blocks (CasADi's generic
   Hessian of the whole graph scales quadratically here, because the seven parameters couple
   every sample).

:func:`paper_friction_fit` is the paper's method (trust-region eq. 20, then Nelder-Mead over a
LuGre simulation of the whole data set), kept as the peer in ``benchmarks/identification_friction.py``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.optimize import least_squares, minimize

from psdm_casadi.errors import NotFittedError, ParameterError, SolverError
from identification.friction import (
    LUGRE_PARAMETER_NAMES,
    CoulombViscous,
    LuGreParameters,
    _phi12_casadi,
    _substep_layout,
    check_friction_data,
    simulate_lugre,
)

__all__ = [
    "ShootingOptions",
    "ShootingResult",
    "BaselineResult",
    "fit_high_speed",
    "initial_lugre_guess",
    "fit_lugre_multiple_shooting",
    "paper_friction_fit",
    "simulate_lugre_ode",
    "r2_score",
    "LuGreIdentifier",
]

_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


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

    def __post_init__(self):
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
        Fitted friction torque [N m].
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


@dataclass(frozen=True)
class BaselineResult:
    """Result of :func:`paper_friction_fit` (the paper's trust-region + Nelder-Mead method).

    Attributes
    ----------
    parameters : LuGreParameters
    initial : LuGreParameters
    evaluations : int
        LuGre simulations run by Nelder-Mead.
    converged : bool
        Whether Nelder-Mead met its tolerances before its evaluation limit.
    objective : float
        Mean squared torque residual [N^2 m^2].
    seconds : float
        Wall time of the Nelder-Mead stage [s].
    """

    parameters: LuGreParameters
    initial: LuGreParameters
    evaluations: int
    converged: bool
    objective: float
    seconds: float


def r2_score(tau, tau_pred):
    """Coefficient of determination ``1 - SS_res / SS_tot`` of a torque prediction."""
    tau = np.asarray(tau, dtype=float)
    tau_pred = np.asarray(tau_pred, dtype=float)
    ss_tot = float(np.sum((tau - tau.mean()) ** 2))
    if ss_tot == 0.0:
        raise ParameterError("r2_score.tau must vary; got a constant signal. Pass a real friction record.")
    return 1.0 - float(np.sum((tau - tau_pred) ** 2)) / ss_tot


# ------------------------------------------------------------------------------------------------
# stage 1: high-speed fit (eq. 20) and starting values
# ------------------------------------------------------------------------------------------------
def _high_speed_mask(qd, threshold):
    if threshold is None:
        threshold = 0.25 * float(np.max(np.abs(qd)))
    if not (np.isfinite(threshold) and threshold > 0):
        raise ParameterError(
            f"fit_high_speed.threshold must be finite and > 0; got {threshold}. Pass a speed well above vs [rad/s]."
        )
    mask = np.abs(qd) > threshold
    if mask.sum() < 10:
        raise ParameterError(
            f"fit_high_speed.threshold leaves {int(mask.sum())} samples with |qd| > {threshold:.3g} rad/s; "
            "need at least 10. Lower it or add fast motion to the experiment."
        )
    return mask


def fit_high_speed(qd, tau_friction, threshold=None):
    """Fit the high-speed model of eq. 20, ``(fc + fv |qd|**dv) sign(qd)``, by trust-region least squares.

    Parameters
    ----------
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    tau_friction : array, shape (n_samples,)
        Friction torque [N m].
    threshold : float, optional
        Only samples with ``|qd| > threshold`` [rad/s] are used; default a quarter of ``max |qd|``
        (pre-sliding and Stribeck effects are negligible there when ``threshold >> vs``).

    Returns
    -------
    CoulombViscous

    Raises
    ------
    ParameterError, ShapeError
        Bad arrays or too few fast samples.

    Examples
    --------
    >>> qd = np.linspace(-3, 3, 200)
    >>> fit = fit_high_speed(qd, CoulombViscous(fc=5.0, fv=2.0, dv=0.7).torque(qd))
    >>> round(fit.fc, 6), round(fit.fv, 6), round(fit.dv, 6)
    (5.0, 2.0, 0.7)
    """
    _, qd, tau = check_friction_data(np.arange(len(np.ravel(qd))), qd, tau_friction, owner="fit_high_speed")
    mask = _high_speed_mask(qd, threshold)
    v = np.abs(qd[mask])
    sgn = np.sign(qd[mask])
    y = tau[mask]
    # linear start (dv = 1): y sign = fc + fv |qd|
    a = np.column_stack([np.ones_like(v), v])
    fc0, fv0 = np.linalg.lstsq(a, y * sgn, rcond=None)[0]
    x0 = np.array([max(fc0, 1e-3 * abs(y).mean()), max(fv0, 1e-3 * abs(y).mean() / v.mean()), 1.0])
    log_v = np.log(v)

    def residual(x):
        return (x[0] + x[1] * np.exp(x[2] * log_v)) * sgn - y

    def jacobian(x):
        power = np.exp(x[2] * log_v)
        return np.column_stack([sgn, power * sgn, x[1] * power * log_v * sgn])

    sol = least_squares(
        residual, x0, jac=jacobian, bounds=([0.0, 0.0, 0.05], [np.inf, np.inf, 3.0]), method="trf",
        x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12,
    )
    return CoulombViscous(fc=float(sol.x[0]), fv=float(sol.x[1]), dv=float(sol.x[2]))


def _sse(parameters, t, qd, tau, substeps=1):
    pred, _ = simulate_lugre(parameters, t, qd, substeps=substeps)
    return float(np.mean((pred - tau) ** 2))


def _replace(p, **changes):
    values = p.as_dict()
    values.update(changes)
    return LuGreParameters(**values)


def initial_lugre_guess(t, qd, tau_friction, high_speed):
    """Data-driven starting values for the LuGre fit, cheap and deterministic.

    ``fc, fv, dv`` come from ``high_speed`` (eq. 20). ``sigma0`` is the best of a logarithmic grid
    of break-away displacements ``fc / sigma0`` in [1e-6, 1e-2] rad (one LuGre simulation each);
    ``fs`` and ``vs`` are fitted to the steady-sliding samples (displacement since the last
    reversal beyond ten break-away displacements) by least squares on the Stribeck curve; finally
    ``sigma1`` is picked from a grid ``sigma0 * [1e-5, 1e-2] s``.

    Parameters
    ----------
    t, qd, tau_friction : array, shape (n_samples,)
        Friction experiment [s, rad/s, N m].
    high_speed : CoulombViscous
        Result of :func:`fit_high_speed`.

    Returns
    -------
    LuGreParameters
    """
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="initial_lugre_guess")
    if not isinstance(high_speed, CoulombViscous):
        raise ParameterError(
            f"initial_lugre_guess.high_speed must be a CoulombViscous; got {type(high_speed).__name__}. "
            "Pass fit_high_speed(...)."
        )
    fc = max(high_speed.fc, 1e-6)
    fv = max(high_speed.fv, 1e-9)
    dv = high_speed.dv
    vmax = float(np.max(np.abs(qd)))
    guess = LuGreParameters(fc=fc, fs=1.2 * fc, vs=0.01 * vmax, fv=fv, dv=dv, sigma0=fc / 1e-4, sigma1=1e-4 * fc / 1e-4)
    # sigma0 from a grid of break-away displacements
    candidates = [_replace(guess, sigma0=fc / xb, sigma1=1e-4 * fc / xb) for xb in np.logspace(-6, -2, 17)]
    guess = min(candidates, key=lambda p: _sse(p, t, qd, tau))
    # fs, vs on steady sliding
    q = np.concatenate([[0.0], np.cumsum(0.5 * (qd[1:] + qd[:-1]) * np.diff(t))])
    sgn = np.sign(qd)
    anchor = np.zeros_like(q)
    last = q[0]
    for k in range(1, q.size):  # position at the last sign change
        if sgn[k] != sgn[k - 1]:
            last = q[k]
        anchor[k] = last
    steady = (np.abs(q - anchor) > 10 * guess.fs / guess.sigma0) & (sgn != 0)
    if steady.sum() > 20:
        v = np.abs(qd[steady])
        y = tau[steady] * sgn[steady] - fv * v**dv - fc

        def residual(x):
            return (np.exp(x[0]) - fc) * np.exp(-((v / np.exp(x[1])) ** 2)) - y

        starts = [np.log([1.2 * fc, vs]) for vs in np.quantile(v, [0.05, 0.2, 0.5])]
        best = min((least_squares(residual, x0, method="trf") for x0 in starts), key=lambda s: s.cost)
        fs, vs = np.exp(best.x)
        if np.isfinite(fs) and np.isfinite(vs) and vs > 0:
            guess = _replace(guess, fs=float(fs), vs=float(min(vs, vmax)))
    # sigma1 grid
    candidates = [_replace(guess, sigma1=guess.sigma0 * r) for r in np.logspace(-5, -2, 7)]
    return min(candidates, key=lambda p: _sse(p, t, qd, tau))


# ------------------------------------------------------------------------------------------------
# stage 2: multiple shooting
# ------------------------------------------------------------------------------------------------
def _interval_functions(p0, s_scale, substeps, parts, length):
    """SX Functions of one shooting interval of ``length`` samples, and its exact Hessian block.

    ``log_p`` (7) are the decision parameters, ``p = p0 * exp(log_p)``; ``w = s / s_scale`` is the
    scaled bristle force at the interval's first sample (the shooting node). ``data`` holds, per
    sample, ``[qd, log|qd|, sign(qd), tau, weight]`` (weight 0 pads the last interval) and ``steps``
    holds, per sample interval, ``4 * substeps * parts`` values ``h, qd_a, qd_b, sign`` (``parts`` = 2
    where some step is split at a zero crossing of the velocity, else 1; padding steps have h = 0).

    Returns ``interval(log_p, w, w_next, steps, data) -> (continuity, cost)`` with the continuity
    defect ``s_end / s_scale - w_next`` and ``cost = sum weight * residual**2``, and
    ``hessian(log_p, w, steps, data, lam_f, lam) -> (36,)``: the upper triangle of the 8 x 8
    Hessian of ``lam_f * cost + lam * continuity`` over ``(log_p, w)`` (continuity is linear in
    ``w_next``, which therefore has no second derivatives).
    """
    log_p = ca.SX.sym("log_p", 7)
    p = [float(p0[i]) * ca.exp(log_p[i]) for i in range(7)]
    fc, fs, vs, fv, dv, sigma0, sigma1 = p
    w = ca.SX.sym("w")
    w_next = ca.SX.sym("w_next")
    data = ca.SX.sym("data", 5, length)
    per_step = 4 * substeps * parts
    steps = ca.SX.sym("steps", per_step, length)
    lam_f = ca.SX.sym("lam_f")
    lam = ca.SX.sym("lam")

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
            phi1, phi2 = _phi12_casadi(x)
            s = ca.exp(-x) * s + x * (phi1 * sign * g_a + phi2 * sign * (g_b - g_a))
    con = s / s_scale - w_next

    z = ca.vertcat(log_p, w)
    hess = ca.hessian(lam_f * cost + lam * con, z)[0]
    triu = ca.vertcat(*[hess[i, j] for i, j in zip(*np.triu_indices(8))])
    return (
        ca.Function("interval", [log_p, w, w_next, steps, data], [con, cost]),
        ca.Function("interval_hessian", [log_p, w, steps, data, lam_f, lam], [triu]),
    )


def _scatter(n_nodes, block_node):
    """Sparse map from stacked upper-triangular 8x8 blocks to the upper triangle of the NLP Hessian.

    Block b covers variables ``(0..6, 7 + block_node[b])``. Returns the target sparsity and the
    (nnz x 36 n_blocks) 0/1 matrix that sums block entries into its nonzeros (column-major order).
    """
    import scipy.sparse as sps

    ti, tj = np.triu_indices(8)
    k = np.asarray(block_node)[:, None]
    rows = np.where(ti == 7, 7 + k, ti[None, :])
    cols = np.where(tj == 7, 7 + k, tj[None, :])
    n_var = 7 + n_nodes
    lin = (cols.astype(np.int64) * n_var + rows).ravel()  # column-major linear index, row <= col
    unique, position = np.unique(lin, return_inverse=True)
    scatter = sps.csc_matrix((np.ones(lin.size), (position, np.arange(lin.size))), shape=(unique.size, lin.size))
    sparsity = ca.Sparsity.triplet(n_var, n_var, (unique % n_var).tolist(), (unique // n_var).tolist())
    matrix = ca.DM(
        ca.Sparsity(scatter.shape[0], scatter.shape[1], scatter.indptr.tolist(), scatter.indices.tolist()),
        scatter.data,
    )
    return sparsity, matrix


def _build_nlp(t, qd, tau, p0, s_scale, substeps, mse_scale, interval):
    """Assemble f, g and the exact Lagrangian Hessian of the multiple-shooting NLP.

    Variables: ``log_p`` (7) then the scaled bristle force at the nodes, samples ``0, M, 2M, ...``.
    """
    n = t.size
    m = interval
    n_nodes = (n - 1) // m + 1
    padded = n_nodes * m
    layout = _substep_layout(t, qd, substeps)
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

    x = ca.MX.sym("x", 7 + n_nodes)
    log_p = x[:7]
    w = x[7:].T
    w_next = ca.horzcat(w[:, 1:], ca.MX.zeros(1, 1))  # the last interval has no successor
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", n_nodes - 1)
    lam = ca.horzcat(lam_g.T, ca.MX.zeros(1, 1))
    cons, costs, hessians, order = [], [], [], []
    for parts in (1, 2):
        nodes = np.flatnonzero(interval_crosses == (parts == 2))
        if nodes.size == 0:
            continue
        fun, hess = _interval_functions(p0, s_scale, substeps, parts, m)
        cols = nodes.tolist()
        # a mapped Function takes its r x m matrix inputs side by side: interval-major columns
        samples = (nodes[:, None] * m + np.arange(m)[None, :]).ravel()
        step_in = ca.DM(steps[: half * parts, samples])
        data_in = ca.DM(data[:, samples])
        con, cost = fun.map(nodes.size)(log_p, w[:, cols], w_next[:, cols], step_in, data_in)
        cons.append(con)
        costs.append(cost)
        hessians.append(hess.map(nodes.size)(log_p, w[:, cols], step_in, data_in, lam_f, lam[:, cols]))
        order.append(nodes)
    order = np.concatenate(order)
    permutation = np.argsort(order, kind="stable")
    con_all = ca.horzcat(*cons)[:, permutation.tolist()]
    f = ca.sum2(ca.horzcat(*costs))
    g = con_all[:, : n_nodes - 1].T
    sparsity, scatter = _scatter(n_nodes, order)
    hess = ca.MX(sparsity, ca.mtimes(scatter, ca.vertcat(*[ca.vec(h) for h in hessians])))
    p_sym = ca.MX.sym("p", 0)
    hess_lag = ca.Function(
        "nlp_hess_l", [x, p_sym, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]
    )
    return {"x": x, "f": f, "g": g}, hess_lag, n_nodes


def _check_initial(initial, owner):
    if not isinstance(initial, LuGreParameters):
        raise ParameterError(
            f"{owner}.initial must be a LuGreParameters; got {type(initial).__name__}. "
            "Pass initial_lugre_guess(...) or LuGreParameters(...)."
        )
    for name in ("fv", "sigma1"):
        if getattr(initial, name) <= 0:
            raise ParameterError(
                f"{owner}.initial.{name} must be > 0 for the log-scaled fit; got 0. Pass a small positive guess."
            )


def fit_lugre_multiple_shooting(t, qd, tau_friction, initial, options=None):
    """Fit all seven LuGre parameters by multiple shooting, solved by Ipopt with exact derivatives.

    Decision variables are ``log(p / initial)`` for the seven parameters and the bristle force
    ``s = sigma0 z`` (scaled by ``initial.fs``) at every shooting node. On each interval the
    exponential integrator of :mod:`identification.friction` carries ``s`` from sample to sample;
    its end must equal the next node (continuity). The objective is the mean squared torque
    residual of eq. 14 at every sample.

    Parameters
    ----------
    t : array, shape (n_samples,)
        Strictly increasing times [s].
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    tau_friction : array, shape (n_samples,)
        Measured friction torque [N m] (eq. 19).
    initial : LuGreParameters
        Starting point (e.g. :func:`initial_lugre_guess`); ``fv`` and ``sigma1`` must be > 0.
    options : ShootingOptions, optional

    Returns
    -------
    ShootingResult

    Raises
    ------
    SolverError
        Ipopt did not converge; ``status`` and ``iterations`` are attached.
    ParameterError, ShapeError
        Bad arrays or options.
    """
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="fit_lugre_multiple_shooting")
    _check_initial(initial, "fit_lugre_multiple_shooting")
    options = ShootingOptions() if options is None else options
    if not isinstance(options, ShootingOptions):
        raise ParameterError(
            f"fit_lugre_multiple_shooting.options must be a ShootingOptions; got {type(options).__name__}."
        )
    start = time.perf_counter()
    n = t.size
    p0 = initial.as_array()
    s_scale = max(initial.fs, initial.fc)
    # starting trajectory: simulate the initial guess; its error scales the objective to O(1)
    tau_init, z_init = simulate_lugre(initial, t, qd, substeps=options.substeps)
    mse_scale = max(float(np.mean((tau_init - tau) ** 2)), 1e-12 * float(np.mean(tau**2)), 1e-300)
    nlp, hess_lag, n_nodes = _build_nlp(t, qd, tau, p0, s_scale, options.substeps, mse_scale, options.interval)
    ipopt = {
        "max_iter": int(options.max_iter),
        "tol": float(options.tol),
        "print_level": int(options.print_level),
        "sb": "yes",
        "hessian_approximation": options.hessian,
    }
    ipopt.update(options.ipopt_options)
    solver_options = {"ipopt": ipopt, "print_time": False}
    if options.hessian == "exact":
        solver_options["hess_lag"] = hess_lag
    solver = ca.nlpsol("lugre_shooting", "ipopt", nlp, solver_options)
    w0 = np.concatenate([np.zeros(7), initial.sigma0 * z_init[:: options.interval] / s_scale])
    bound = np.log(options.parameter_range)
    lbx = np.concatenate([np.full(7, -bound), np.full(n_nodes, -np.inf)])
    ubx = np.concatenate([np.full(7, bound), np.full(n_nodes, np.inf)])
    solve_start = time.perf_counter()
    sol = solver(x0=w0, lbx=lbx, ubx=ubx, lbg=0, ubg=0)
    solve_seconds = time.perf_counter() - solve_start
    stats = solver.stats()
    status = str(stats.get("return_status", "unknown"))
    iterations = int(stats.get("iter_count", -1))
    accepted = _SUCCESS if options.accept_acceptable else _SUCCESS[:1]
    if status not in accepted:
        raise SolverError(
            f"fit_lugre_multiple_shooting: Ipopt returned status {status} after {iterations} iterations. "
            "Improve the initial guess, raise ShootingOptions.max_iter or check the data.",
            status=status,
            iterations=iterations,
        )
    x_opt = np.asarray(sol["x"]).ravel()
    parameters = LuGreParameters.from_array(p0 * np.exp(x_opt[:7]))
    tau_fit, z = simulate_lugre(parameters, t, qd, z0=x_opt[7] * s_scale / parameters.sigma0, substeps=options.substeps)
    return ShootingResult(
        parameters=parameters,
        initial=initial,
        z=z,
        tau=tau_fit,
        status=status,
        iterations=iterations,
        objective=float(np.mean((tau_fit - tau) ** 2)),
        seconds=time.perf_counter() - start,
        solve_seconds=solve_seconds,
    )


# ------------------------------------------------------------------------------------------------
# the paper's method (peer for the benchmark)
# ------------------------------------------------------------------------------------------------
_FREE_SETS = {
    "presliding": ("fs", "vs", "sigma0", "sigma1"),
    "all": LUGRE_PARAMETER_NAMES,
}


def simulate_lugre_ode(parameters, t, qd, rtol=1e-6):
    """LuGre torque from a general-purpose stiff ODE solver (scipy LSODA), as a Matlab ``ode15s`` cost would.

    The velocity is interpolated linearly; the step is capped at one sample period. Slower than
    :func:`identification.friction.simulate_lugre` by two orders of magnitude; it reproduces the
    paper's "simulate the LuGre equations" cost for the baseline timing.

    Returns
    -------
    tau : ndarray, shape (n_samples,)
        Friction torque [N m].
    """
    from scipy.integrate import solve_ivp

    p = parameters
    t, qd = check_friction_data(t, qd, owner="simulate_lugre_ode")

    def rhs(time_, z):
        v = np.interp(time_, t, qd)
        g = p.fc + (p.fs - p.fc) * np.exp(-((v / p.vs) ** 2))
        return v - p.sigma0 * abs(v) * z / g

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0], method="LSODA", t_eval=t, rtol=rtol, atol=1e-12,
                    max_step=float(np.min(np.diff(t))))
    if not sol.success:
        raise SolverError(f"simulate_lugre_ode: LSODA failed: {sol.message}", status=str(sol.status))
    from identification.friction import lugre_torque

    return lugre_torque(p, qd, p.sigma0 * sol.y[0])


def paper_friction_fit(t, qd, tau_friction, initial, free="presliding", max_evaluations=None, substeps=1,
                       simulator="exponential"):
    """The paper's LuGre fit: Nelder-Mead over a LuGre simulation of the whole record (section 3.3).

    Starting from ``initial`` (whose ``fc, fv, dv`` come from the trust-region fit of eq. 20),
    scipy's Nelder-Mead -- the counterpart of Matlab's ``fminsearch`` -- minimises the sum of
    squared errors between the measured torque and :func:`simulate_lugre` over the parameters in
    ``free``, with ``fminsearch``'s defaults: a 5 % initial simplex, ``TolFun = 1e-4`` on the sum of
    squares, ``TolX = 1e-4`` and ``200 * n_free`` evaluations. The simplex works on
    ``log(p / initial)`` (positive parameters; ``TolX`` is then relative, which lets it stop
    earlier than on the raw values, where ``sigma0 ~ 1e5`` never meets an absolute 1e-4).

    Parameters
    ----------
    t, qd, tau_friction : array, shape (n_samples,)
        Friction experiment [s, rad/s, N m].
    initial : LuGreParameters
        Starting point, ``fv`` and ``sigma1`` > 0.
    free : {"presliding", "all"}
        ``"presliding"`` fits ``fs, vs, sigma0, sigma1`` (the paper); ``"all"`` all seven.
    max_evaluations : int, optional
        Simulation budget; default ``200 * n_free``.
    substeps : int
        Integrator sub-steps per sample of the simulation.
    simulator : {"exponential", "ode"}
        The cost's LuGre simulation: our stiff-safe :func:`simulate_lugre` (fast) or the generic
        stiff ODE solver :func:`simulate_lugre_ode` (the paper's setting, ~100x slower).

    Returns
    -------
    BaselineResult
    """
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="paper_friction_fit")
    _check_initial(initial, "paper_friction_fit")
    if free not in _FREE_SETS:
        raise ParameterError(f"paper_friction_fit.free must be one of {sorted(_FREE_SETS)}; got {free!r}.")
    names = _FREE_SETS[free]
    if simulator not in ("exponential", "ode"):
        raise ParameterError(
            f"paper_friction_fit.simulator must be 'exponential' or 'ode'; got {simulator!r}. Pass 'exponential'."
        )
    if max_evaluations is None:
        max_evaluations = 200 * len(names)
    if not (isinstance(max_evaluations, (int, np.integer)) and max_evaluations >= 1):
        raise ParameterError(f"paper_friction_fit.max_evaluations must be an integer >= 1; got {max_evaluations!r}.")
    index = [LUGRE_PARAMETER_NAMES.index(name) for name in names]
    p0 = initial.as_array()

    def parameters_of(x):
        values = p0.copy()
        values[index] = p0[index] * np.exp(x)
        return LuGreParameters.from_array(values)

    def cost(x):
        if not np.all(np.abs(x) < 20):
            return np.inf
        if simulator == "ode":
            return float(np.sum((simulate_lugre_ode(parameters_of(x), t, qd) - tau) ** 2))
        return tau.size * _sse(parameters_of(x), t, qd, tau, substeps)

    start = time.perf_counter()
    sol = minimize(
        cost, np.zeros(len(names)), method="Nelder-Mead",
        options={"maxfev": int(max_evaluations), "maxiter": int(max_evaluations), "xatol": 1e-4, "fatol": 1e-4},
    )
    seconds = time.perf_counter() - start
    return BaselineResult(
        parameters=parameters_of(sol.x),
        initial=initial,
        evaluations=int(sol.nfev),
        converged=bool(sol.success),
        objective=float(sol.fun) / tau.size,
        seconds=seconds,
    )


# ------------------------------------------------------------------------------------------------
# estimator
# ------------------------------------------------------------------------------------------------
class LuGreIdentifier:
    """scikit-learn-style LuGre friction identifier for one joint (paper section 3.3, our NLP).

    ``fit`` runs :func:`fit_high_speed` (eq. 20), :func:`initial_lugre_guess` (unless ``initial``
    is given) and :func:`fit_lugre_multiple_shooting`.

    Parameters
    ----------
    high_speed_threshold : float, optional
        Speed [rad/s] above which eq. 20 is fitted; default a quarter of ``max |qd|``.
    options : ShootingOptions, optional
        Options of the multiple-shooting NLP.
    initial : LuGreParameters, optional
        Starting point of the NLP; default from the data.
    substeps : int
        Integrator sub-steps per sample used by :meth:`predict`.

    Attributes
    ----------
    params_ : LuGreParameters
        Identified parameters.
    high_speed_ : CoulombViscous
        The eq. 20 fit.
    initial_ : LuGreParameters
        The NLP's starting point.
    result_ : ShootingResult
        Full NLP result (z trajectory, Ipopt status, seconds).

    Examples
    --------
    >>> est = LuGreIdentifier()          # doctest: +SKIP
    >>> est.fit(t, qd, tau).params_      # doctest: +SKIP
    """

    def __init__(self, high_speed_threshold=None, options=None, initial=None, substeps=1):
        self.high_speed_threshold = high_speed_threshold
        self.options = options
        self.initial = initial
        self.substeps = substeps

    def fit(self, t, qd, tau_friction):
        """Identify the seven LuGre parameters from one joint's friction record; returns ``self``."""
        t, qd, tau = check_friction_data(t, qd, tau_friction, owner="LuGreIdentifier.fit")
        self.high_speed_ = fit_high_speed(qd, tau, self.high_speed_threshold)
        if self.initial is None:
            self.initial_ = initial_lugre_guess(t, qd, tau, self.high_speed_)
        else:
            _check_initial(self.initial, "LuGreIdentifier")
            self.initial_ = self.initial
        self.result_ = fit_lugre_multiple_shooting(t, qd, tau, self.initial_, self.options)
        self.params_ = self.result_.parameters
        return self

    def _check_is_fitted(self):
        if not hasattr(self, "params_"):
            raise NotFittedError(
                "LuGreIdentifier.params_ must be set by fit; got an unfitted estimator. Call fit(t, qd, tau) first."
            )

    def predict(self, t, qd, z0=0.0):
        """Friction torque [N m], shape (n_samples,), simulated along ``qd`` from bristle state ``z0``."""
        self._check_is_fitted()
        tau, _ = simulate_lugre(self.params_, t, qd, z0=z0, substeps=self.substeps)
        return tau

    def score(self, t, qd, tau_friction):
        """Coefficient of determination R^2 of :meth:`predict` against ``tau_friction``."""
        self._check_is_fitted()
        t, qd, tau = check_friction_data(t, qd, tau_friction, owner="LuGreIdentifier.score")
        return r2_score(tau, self.predict(t, qd))
