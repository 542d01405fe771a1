"""The consistent fit as a convex problem: a log-det barrier path in the standard parameters.

The consistent fit (``consistent_fit``) minimises a convex quadratic of the standard parameters (the weighted
residual and the pull towards the prior) over links whose pseudo-inertia is positive definite and, with the
envelope, inside linear bounds: a convex problem. Solved in the log-Cholesky chart it is not convex any more, and
where the data push a link towards a degenerate pseudo-inertia (a link asked to hold a counterbalance or a payload
it cannot) the optimum lies at infinity in the chart: Ipopt regularises the indefinite Hessian at every step and
creeps along the flat directions for thousands of iterations, stopping wherever its iteration cap falls (the heavy
arm's joint 2 RMSE differed by 40 % between 300 and 2000 iterations).

:func:`barrier_solution` solves the convex problem itself: the standard parameters are the variables, each body's
positive definiteness a barrier ``-mu log det(J - margin 1)`` summed from the pivots of an LDL^T elimination of its
pseudo-inertia (Sylvester: all positive exactly inside the cone), with the pivots also constrained to stay positive so
that Ipopt's fraction-to-the-boundary rule keeps every step inside. Ipopt follows ``mu`` down a path (``MU_PATH``, in
the objective's units, noise variances per sample, to 1e-5), each solve warm-started from the last; the barrier's
duality gap, ``mu`` times four per body, ends far below the noise. On the heavy arm's envelope check the objective it
reaches is within 7e-4 (relative) of the chart's run to convergence (8000 iterations), in about 80 Ipopt iterations
instead of two capped runs of 2000; the chart (``consistent_fit``) stays the fallback from the path's last point when
a solve fails before ``MU_ENOUGH``. A path on to 1e-9 reaches the chart's optimum to 1e-6 (``benchmarks/heavy_arm.py``
3/3 either way); 1e-5 is kept as the tested default.

Each solve stops at Ipopt's ``tol`` (1e-10) or, after ``acceptable_iter`` consecutive iterations within
``acceptable_tol`` (1e-6), at ``Solved_To_Acceptable_Level``: a stall at the round-off floor, which is where links
pressed towards a degenerate pseudo-inertia leave the dual infeasibility (the barrier's curvature ``mu / pivot^2``
grows as ``mu`` falls: 1e-8 to 1e-6 on the virtual Denso with a hidden cam and payload). From 1e-6 down to the tol,
Ipopt's own barrier parameter still has two or three stages to go (``mu^1.5`` down to ``tol / 10``), a few iterations
each: after only 5 acceptable iterations every solve of the Panda's fit stopped one to three iterations short of
converging (its NLP error at 2-7e-10; which solves converged followed the pull's weight by chance). So
``acceptable_iter`` is Ipopt's default 15: acceptable means stalled, not nearly there. The data term is written
around its least-squares minimum (``consistent_fit.centred_residual``) so that its gradient's round-off stays below
the tol where nothing is pressed.

Each solve may take 1000 iterations (``max_iter``): a solve at its cap ends the path and hands the rest to the chart.
With the Panda's joint-5 Stribeck shape refused (Coulomb-viscous) the last solve of the second pass needs 908; at a
cap of 300 the chart then stopped at Solved_To_Acceptable_Level (before the later solves were warm-started as such,
``WARM_OPTIONS``). The cap costs nothing where the path converges.

Each solve after the first starts at the point of the weight before, and Ipopt is told so (``WARM_OPTIONS``): its
start is kept where it is given (``bound_push``, ``bound_frac`` 1e-9, not 1e-2) and its own barrier parameter starts
at a tenth of the path's last weight (``mu_init``, not 0.1). Ipopt's barrier on the pivots' slacks is the path's
barrier over again: at its default start, ten times the path's first weight, every later solve first pulled its start
back from the cone's edge towards the point of that weight, with the pivots' slacks pushed away from pivots near zero
(links pressed towards a degenerate pseudo-inertia or resting on their inertia floors, ``inertia_floor``), its Newton
steps cut back where a pivot turned negative, and then came down again; the smaller the weight, the nearer its start
to the edge and the longer the way back. Where the way back failed, the solve crept at a growing dual infeasibility,
into the restoration phase, to its cap: the Panda's column-check fold fits at the last weight, the virtual Denso's with
a hidden counterbalance or payload, the virtual SCARA with a spring on joint 1 (where the outcome followed the
torque's round-off). A solve so warm-started stays near its start and ends in a few Newton steps per stage of Ipopt's
barrier. The first weight's solve starts off the path (the caller's start, moved inside the cone) and keeps Ipopt's
defaults: from there Ipopt's own barrier finds the way in (with the warm options it stopped at its cap on the virtual
Denso with a hidden cam and payload). A warm-started solve that fails is not tried cold: from a start near the cone's
edge that is the slow way above.

A solve Ipopt stops because its steps became too small to count (``Search_Direction_Becomes_Too_Small``) at an iterate
that is feasible and within ``acceptable_tol`` has stalled at the round-off floor as an acceptable stop does, sooner:
it ends its weight as ``Solved_To_Acceptable_Level`` (:func:`solve_status`), and the path goes on. Counted as failed,
it ended the path, and the chart from the weight before (where the barrier, still weighted, pushes the links out against
their envelopes) failed on a 4-joint arm whose links rest on their inertia floors (``inertia_floor``).

Where a path starts matters: the first weight (``MU_PATH[0]``) wants the bodies well inside the cone, where its
barrier's pull ``mu / pivot`` balances the data's. The consistent fit's second pass (the same problem, reweighted by
the first pass's residuals) started from the first pass's end, the point of the smallest weight, whose pivots are
down to 5e-6 of a body's size on the Panda: at ``mu = 1e-2`` the barrier's gradient there is 2e3 against a data term
of about 1, and Ipopt's Newton steps, cut back at the cone's edge, crawled. The Panda's written fit took 1026
iterations for that path (143 for the first), and a fold fit of the column check on three quarters of the recording
(``column_check``) stopped at the cap at the first weight, its objective rising from 3.3 to 32, and was handed to the
chart. The second pass therefore starts at the first pass's point of the first weight (``BarrierResult.first``): a
point on the central path of a nearby problem. Both passes then take 130-210 iterations on the Panda's fits, and the
end point is the same to 1e-12 (relative) where the old start converged: the barrier problem's optimum is unique.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import casadi as ca
import numpy as np

from identification.calibration.pseudo_inertia import pseudo_inertia
from psdm_casadi.ipopt_progress import progress_options

__all__ = ["MU_ENOUGH", "MU_PATH", "BarrierResult", "barrier_solution", "log_det_barrier", "solve_status"]

logger = logging.getLogger(__name__)

#: The barrier weights, in the objective's units (noise variances per sample), from the first solve to the last.
MU_PATH = (1e-2, 1e-3, 1e-4, 1e-5)
#: The path counts as solved once it has reached this weight (a later solve that fails leaves the point of the last).
MU_ENOUGH = 1e-5
BARRIER_OPTIONS = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.tol": 1e-10,
                   "ipopt.acceptable_tol": 1e-6, "ipopt.acceptable_iter": 15, "ipopt.max_iter": 1000,
                   "show_eval_warnings": False}  # fmt: skip
#: Ipopt's options over ``BARRIER_OPTIONS`` for the solves after the first, each warm-started at the point of the
#: weight before: the start kept where it is given, and Ipopt's own barrier from a tenth of the path's last weight
#: (module docstring).
WARM_OPTIONS = {"ipopt.mu_init": 0.1 * MU_PATH[-1], "ipopt.bound_push": 1e-9, "ipopt.bound_frac": 1e-9}
#: Ipopt's status of a solve whose steps became too small to count (``solve_status``: a stall, acceptable or not).
STALLED = "Search_Direction_Becomes_Too_Small"
#: The largest constraint violation of a stalled solve's last iterate that counts as feasible (the constraints are the
#: links' envelopes and masses, linear, scaled by the mass; and the pivots, of a body's size).
ACCEPTABLE_VIOLATION = 1e-8


def _pseudo(v, margin: float, size: float, floor=None):
    """``(J - margin 1 - m diag(F, 0)) / size`` of ten standard parameters (a CasADi column), as nested lists of
    expressions; ``floor``: the body's ``F`` (``inertia_floor``, 3 x 3 per unit mass) or None (0)."""
    m, mx, my, mz, ixx, ixy, iyy, ixz, iyz, izz = (v[k] for k in range(10))
    half = 0.5 * (ixx + iyy + izz)
    rows = [[half - ixx, -ixy, -ixz, mx], [-ixy, half - iyy, -iyz, my], [-ixz, -iyz, half - izz, mz], [mx, my, mz, m]]
    if floor is not None:
        rows = [[rows[r][c] - (m * float(floor[r][c]) if r < 3 and c < 3 else 0.0) for c in range(4)] for r in range(4)]
    return [[(rows[r][c] - (margin if r == c else 0.0)) / size for c in range(4)] for r in range(4)]


def pivots(v, margin: float, size: float, floor=None) -> list:
    """The four pivots of an LDL^T elimination of ``(J - margin 1 - m diag(F, 0)) / size`` of one body (``floor``:
    its ``F`` or None): all positive exactly inside the cone of positive-definite pseudo-inertias (Sylvester's
    criterion), moved by the body's inertia floor (``inertia_floor``)."""
    a = _pseudo(v, margin, size, floor)
    out = []
    for p in range(4):
        out.append(a[p][p])
        for r in range(p + 1, 4):
            factor = a[r][p] / a[p][p]
            for c in range(p + 1, 4):
                a[r][c] = a[r][c] - factor * a[p][c]
    return out


def log_det_barrier(v, margin: float, size: float, floor=None):
    """``-log det((J - margin 1 - m diag(F, 0)) / size)`` of one body, summed from its ``pivots``: the log of a pivot
    that is not positive is NaN, so a point outside the cone is never accepted (a determinant alone would be positive
    with two negative eigenvalues)."""
    return -sum(ca.log(d) for d in pivots(v, margin, size, floor))


def _inside(body, margin: float, floor=None) -> np.ndarray:
    """A start strictly inside the cone: the body with the eigenvalues of ``J - m diag(F, 0)`` (``floor``: ``F`` or
    None) raised to twice the margin plus a small share of its trace (a prior on the boundary has no barrier value)."""
    from identification.calibration.pseudo_inertia import link_from_pseudo_inertia

    shift = np.zeros((4, 4))
    if floor is not None:
        shift[:3, :3] = floor
    matrix = pseudo_inertia(body)
    matrix = matrix - matrix[3, 3] * shift
    values, vectors = np.linalg.eigh(matrix)
    least = 2.0 * margin + 1e-6 * max(float(np.trace(matrix)), margin)
    raised = (vectors * np.maximum(values, least)) @ vectors.T
    return link_from_pseudo_inertia(raised + raised[3, 3] * shift)


@dataclass(frozen=True, eq=False)
class BarrierResult:
    """Where the barrier path ended: the variables ``x``, Ipopt's last ``solution`` (its multipliers give the
    bounds' pressure), its ``status``, and whether the path reached ``MU_ENOUGH`` (``complete``; otherwise ``x`` is
    the last weight's that was solved, a start for another solver); ``first``: the point of the path's first weight
    (``MU_PATH[0]``), where a path of a slightly different objective starts best (module docstring)."""

    x: np.ndarray
    solution: dict
    status: str
    complete: bool
    first: np.ndarray | None = None


def barrier_solution(problem, bodies, start, bounds, margin: float, shared=None, floors=None):
    """The ``BarrierResult`` of the path ``MU_PATH``, or None when its first solve fails.

    Parameters
    ----------
    problem : dict
        ``x`` (the variables: the ten standard parameters of each body in ``bodies`` first, then the rest), ``f``
        (the objective, in noise variances per sample) and ``g`` (the linear constraints); with ``shared``, ``p``:
        the objective's parameters.
    bodies : list of float
        Per body, the size its pseudo-inertia is measured in (its trace at the prior).
    start : array
        Of the variables; the bodies' parameters are moved inside the cone first.
    bounds : tuple
        ``(lbx, ubx, lbg, ubg)``.
    shared : tuple, optional
        ``(solvers, key, values)`` (``shared_barrier``): the solver of ``problem`` is ``solvers[key]``, built there
        the first time (without a progress bar), with ``problem["p"]`` set to ``values``; ``problem`` is only read
        when the solver is built.
    floors : list, optional
        Per body, its inertia floor ``F`` (``inertia_floor``) or None; the barrier and the pivots are of ``J - margin 1
        - m diag(F, 0)``. None: no body has one.
    """
    floors = [None] * len(bodies) if floors is None else list(floors)
    lbx, ubx, lbg, ubg = bounds
    n_steps = 4 * len(bodies)  # the pivots of each body, constrained >= 0 after the caller's constraints
    lbg, ubg = np.concatenate([lbg, np.zeros(n_steps)]), np.concatenate([ubg, np.full(n_steps, np.inf)])
    if shared is None:
        (solver, callback), values = _solver(problem, (bodies, floors), margin, (lbg, ubg), True), ()
    else:  # a shared solve that fails is solved alone (``consistent_fit``)
        solvers, key, values = shared
        if key not in solvers:
            solvers[key] = _solver(problem, (bodies, floors), margin, (lbg, ubg), False)[0]
        solver, callback = solvers[key], None
    try:
        return _follow_path(solver, (bodies, floors), start, (lbx, ubx, lbg, ubg), margin, (n_steps, values))
    finally:
        if callback is not None:
            callback.close()


def _solver(problem, bodies, margin, g_bounds, progress: bool, extra=None) -> tuple:
    """(``PathSolver``, progress callback or None) of ``problem`` plus ``mu`` times the bodies' barrier, ``mu`` its
    first parameter (then ``problem["p"]``, if any); the pivots also constrained >= 0 (``g_bounds``: with their
    rows); ``bodies``: (sizes, floors); ``extra``: Ipopt options over ``BARRIER_OPTIONS``."""
    x = problem["x"]
    mu = ca.SX.sym("mu")
    bodies = list(zip(*bodies))
    barrier = sum((log_det_barrier(x[10 * k : 10 * k + 10], margin, size, floor)
                   for k, (size, floor) in enumerate(bodies)), 0)  # fmt: skip
    # the pivots also as constraints >= 0: Ipopt's fraction-to-the-boundary rule then keeps its steps inside the
    # cone (without them a Newton step of the small barrier overshoots and is cut back, hundreds of times)
    steps = [d for k, (size, floor) in enumerate(bodies) for d in pivots(x[10 * k : 10 * k + 10], margin, size, floor)]
    g = ca.vertcat(problem["g"], *steps)
    parameters = ca.vertcat(mu, problem["p"]) if "p" in problem else mu
    bar, callback = {}, None
    if progress:
        cap = BARRIER_OPTIONS["ipopt.max_iter"] * len(MU_PATH)  # the bar counts the whole path's iterations
        bar, callback = progress_options("consistent_fit_barrier_progress", (x.numel(), g.numel(), 1), cap,
                                         "identify: consistent fit (Ipopt)", logger, *g_bounds)  # fmt: skip
    nlp = {"x": x, "g": g, "p": parameters, "f": problem["f"] + mu * barrier}
    return PathSolver(nlp, {**(extra or {}), **bar}), callback


class PathSolver:
    """The Ipopt solvers of one barrier path's problem (``nlp``), each built when first used: ``warm=False`` the
    first weight's, from a start off the path (Ipopt's defaults), ``warm=True`` the later weights', each from the
    point of the weight before (``WARM_OPTIONS``); ``options`` over both. ``stats()``: the last solve's."""

    def __init__(self, nlp: dict, options: dict):
        self.nlp, self.options, self.solvers, self.last = nlp, options, {}, None

    def __call__(self, warm: bool = False, **arguments):
        if warm not in self.solvers:
            options = {**BARRIER_OPTIONS, **(WARM_OPTIONS if warm else {}), **self.options}
            self.solvers[warm] = ca.nlpsol("consistent_fit_barrier", "ipopt", self.nlp, options)
        self.last = self.solvers[warm]
        return self.last(**arguments)

    def stats(self) -> dict:
        return self.last.stats()


def _follow_path(solver, bodies, start, bounds, margin, steps):
    """The solves of ``barrier_solution`` along ``MU_PATH``, each from the last (``PathSolver``: the first weight's
    solve cold, the later ones warm-started); ``bodies``: (sizes, floors), ``bounds`` with the pivots' rows,
    ``steps``: (their number, the values of the solver's parameters after ``mu``)."""
    (_, floors), (n_steps, values) = bodies, steps
    lbx, ubx, lbg, ubg = bounds
    current = np.array(start, dtype=float)
    for k, floor in enumerate(floors):
        current[10 * k : 10 * k + 10] = _inside(current[10 * k : 10 * k + 10], margin, floor)
    current, last, iterations, reached, status, first = np.clip(current, lbx, ubx), None, 0, np.inf, "", None
    for weight in MU_PATH:
        p = np.concatenate([[weight], values]) if len(values) else weight
        solution = solver(warm=last is not None, x0=current, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        iterations += stats["iter_count"]
        if solve_status(stats) is None:
            logger.debug("consistent fit: the barrier path stopped at mu %g (%s)", weight, stats["return_status"])
            return None if last is None else BarrierResult(current, last, status, reached <= MU_ENOUGH, first)
        current, last = np.clip(np.asarray(solution["x"]).reshape(-1), lbx, ubx), _without_pivots(solution, n_steps)
        reached, status = weight, solve_status(stats)
        first = current if first is None else first
    logger.debug("consistent fit: barrier path in %d Ipopt iterations", iterations)
    return BarrierResult(current, last, status, True, first)


def solve_status(stats) -> str | None:
    """The status a barrier solve (Ipopt's ``stats``) ends the weight with, or None where it failed.

    ``Solve_Succeeded`` and ``Solved_To_Acceptable_Level`` as Ipopt says; ``Search_Direction_Becomes_Too_Small`` counts
    as ``Solved_To_Acceptable_Level`` where its last iterate is within ``acceptable_tol`` (dual infeasibility) and
    feasible (``ACCEPTABLE_VIOLATION``): the stall at the round-off floor that the acceptable stop waits
    ``acceptable_iter`` iterations for, ended sooner because the steps became too small to count (a link pressed
    on its inertia floor: the barrier's curvature ``mu / pivot^2`` lifts the floor of its gradient's round-off above
    ``tol``). A failed weight ends the path and hands it to the chart from the weight before, far from the optimum.
    """
    status = stats["return_status"]
    if status in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        return status
    record = stats.get("iterations") or {}
    if status != STALLED or not record.get("inf_du"):
        return None
    du, pr = record["inf_du"][-1], record["inf_pr"][-1]
    stalled = du <= BARRIER_OPTIONS["ipopt.acceptable_tol"] and pr <= ACCEPTABLE_VIOLATION
    return "Solved_To_Acceptable_Level" if stalled else None


def _without_pivots(solution, n_steps: int) -> dict:
    """Ipopt's solution with the ``n_steps`` pivot constraints' rows left out of ``g`` and ``lam_g`` (the caller's
    constraints come first)."""
    out = dict(solution)
    n = np.asarray(solution["g"]).size - n_steps
    for key in ("g", "lam_g"):
        out[key] = np.asarray(solution[key]).reshape(-1)[:n]
    return out
