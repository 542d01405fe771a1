"""The paper's LuGre fit (section 3.3): trust-region eq. 20, then Nelder-Mead over a simulation of the whole record.

The peer of our multiple shooting (:mod:`identification.friction.shooting`) in
``benchmarks/calibration.py`` and ``benchmarks/identification_friction.py``: the same data and
starting point (:mod:`identification.friction.start`), scipy's Nelder-Mead in place of Matlab's
``fminsearch``, and as the cost's simulator either a general stiff ODE solver (scipy LSODA,
:func:`simulate_lugre_ode`, the paper's setting) or our exponential integrator
(:func:`identification.friction.simulation.simulate_lugre`).
"""

from __future__ import annotations

import bisect
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize

from identification.friction.models import LUGRE_PARAMETER_NAMES, LuGreParameters, check_friction_data
from identification.friction.simulation import lugre_torque, simulated_mse
from identification.friction.start import check_initial
from psdm_casadi.errors import ParameterError, SolverError

__all__ = ["BaselineResult", "paper_friction_fit", "simulate_lugre_ode"]


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


_FREE_SETS = {
    "presliding": ("fs", "vs", "sigma0", "sigma1"),
    "all": LUGRE_PARAMETER_NAMES,
}


def simulate_lugre_ode(parameters, t, qd, rtol=1e-6):
    """LuGre torque from a general-purpose stiff ODE solver (scipy LSODA), as a Matlab ``ode15s`` cost would.

    The velocity is interpolated linearly between samples; the step is capped at one sample
    period; the bristle state starts at zero. The right-hand side is scalar Python (``math``), the
    cheapest form for scipy's solvers. Much slower than
    :func:`identification.friction.simulation.simulate_lugre`; it reproduces the paper's "simulate
    the LuGre equations" cost.

    Parameters
    ----------
    parameters : LuGreParameters
    t, qd : array, shape (n_samples,)
        Times [s] and joint velocity [rad/s].
    rtol : float
        Relative tolerance of LSODA (absolute tolerance 1e-12 rad).

    Returns
    -------
    tau : ndarray, shape (n_samples,)
        Friction torque [N m].

    Raises
    ------
    SolverError
        When LSODA fails.
    """
    p = parameters
    t, qd = check_friction_data(t, qd, owner="simulate_lugre_ode")
    times, speeds = t.tolist(), qd.tolist()
    last = len(times) - 2
    fc, dfs, inv_vs, sigma0 = p.fc, p.fs - p.fc, 1.0 / p.vs, p.sigma0
    exp = math.exp

    def rhs(time_, z):
        k = min(max(bisect.bisect_right(times, time_) - 1, 0), last)
        w = (time_ - times[k]) / (times[k + 1] - times[k])
        v = speeds[k] + w * (speeds[k + 1] - speeds[k])
        x = v * inv_vs
        g = fc + dfs * exp(-x * x)
        return [v - sigma0 * abs(v) * z[0] / g]

    sol = solve_ivp(
        rhs, (t[0], t[-1]), [0.0], method="LSODA", t_eval=t, rtol=rtol, atol=1e-12, max_step=float(np.min(np.diff(t)))
    )
    if not sol.success:
        raise SolverError(f"simulate_lugre_ode: LSODA failed: {sol.message}", status=str(sol.status))
    return lugre_torque(p, qd, p.sigma0 * sol.y[0])


def paper_friction_fit(
    t, qd, tau_friction, initial, free="presliding", max_evaluations=None, substeps=1, simulator="exponential"
):
    """The paper's LuGre fit: Nelder-Mead over a LuGre simulation of the whole record (section 3.3).

    Starting from ``initial`` (whose ``fc, fv, dv`` come from the trust-region fit of eq. 20),
    scipy's Nelder-Mead -- the counterpart of Matlab's ``fminsearch`` -- minimises the sum of
    squared errors between the measured torque and
    :func:`identification.friction.simulation.simulate_lugre` over the parameters in
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
        The cost's LuGre simulation: our stiff-safe
        :func:`identification.friction.simulation.simulate_lugre` or the generic stiff ODE solver
        :func:`simulate_lugre_ode` (the paper's setting, much slower).

    Returns
    -------
    BaselineResult
    """
    t, qd, tau = check_friction_data(t, qd, tau_friction, owner="paper_friction_fit")
    check_initial(initial, "paper_friction_fit")
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
        return tau.size * simulated_mse(parameters_of(x), t, qd, tau, substeps)

    start = time.perf_counter()
    sol = minimize(
        cost,
        np.zeros(len(names)),
        method="Nelder-Mead",
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
