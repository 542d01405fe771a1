"""The physically consistent step of the recordings-route fit: Ipopt over log-Cholesky links (and flange bodies).

:func:`consistent_fit` minimises the weighted residual of the normal equations of
``trajectory_fit`` over standard parameters in the log-Cholesky chart (``pseudo_inertia``), so every
link, and every unknown payload fixed to the flange (``payload_fit``), has a positive-definite
pseudo-inertia; friction and drive inertias are bounded below by zero, and a pull towards the robot file's
parameters, a Gaussian prior weighed against the data's independent samples (``prior_pull``), settles what the
data hardly fix. It is solved twice, the second time weighted by the first consistent fit's own residual.

In the chart the problem is not convex, and where the data push a link towards a degenerate pseudo-inertia its optimum
lies at infinity: Ipopt regularises and creeps (the heavy arm's fits ran to the iteration cap, their answer set by
the cap). Each pass is therefore first solved as the convex problem it is, in the standard parameters along a
log-det barrier path (``barrier_path``); the chart solve is kept as the fallback from the path's last point.

With ``TrajectoryOptions.envelope`` (the default) each link also stays inside its physical envelope
(``envelope``): the density condition of its bounding ellipsoid and its centre of mass's reach, its mass within
``mass_ratio`` of the robot file's, the drive inertias within ``drive_inertia_ratio`` of the file's where it gives
them, and its spread about its centre of mass above its floor (``inertia_floor``: the cone of ``J - m diag(F, 0)``, in
the chart and the barrier) (:func:`fit_bounds`). The envelope is per body (``FitBounds.envelopes``, one ellipsoid or
None per link); a flange payload has none. The bounds come back with the data's pressure on each, so that a report
can say which ones the data pushed against (``envelope_report``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from identification.calibration.envelope import density_weights, link_envelopes, reach_weights
from identification.calibration.inertia_floor import link_floors
from identification.calibration.prior_pull import PriorPull
from identification.calibration.pseudo_inertia import (
    CONSISTENCY_MARGIN,
    LINK_PARAMETER_COUNT,
    lifted_link,
    link_from_log_cholesky,
    link_from_pseudo_inertia,
    log_cholesky_from_link,
    pseudo_inertia,
    semidefinite_links,
)
from psdm_casadi.errors import SolverError
from psdm_casadi.ipopt_progress import progress_options

__all__ = [
    "IPOPT_OPTIONS",
    "ROTOR",
    "FitBounds",
    "consistent_fit",
    "drive_lower_bounds",
    "fit_bounds",
    "held_rotors",
    "held_standard",
    "lifted_links",
    "link_is_free",
    "residual_sigma",
]

logger = logging.getLogger(__name__)

ROTOR = LINK_PARAMETER_COUNT  # column of the drive inertia in a joint's 11 standard parameters
# When the data ask for an inconsistent link, the optimum lies on the boundary of the chart, at
# infinity in its log-diagonal: the objective then creeps down without its gradient vanishing.
# Ipopt stops when the objective has stopped changing (acceptable_obj_change_tol, relative).
IPOPT_OPTIONS = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.tol": 1e-9,
                 "ipopt.acceptable_tol": 1e-2, "ipopt.acceptable_obj_change_tol": 1e-9,
                 "ipopt.acceptable_iter": 10, "ipopt.max_iter": 2000}  # fmt: skip
FIRST_PASS_MAX_ITER = 2000  # a lower cap makes the second pass depend on round-off (where the creep stopped)


@dataclass(frozen=True, eq=False)
class FitBounds:
    """What the consistent fit held each joint's link and drive to (inf / -inf / None: no bound).

    Attributes
    ----------
    envelopes : tuple
        Per joint, the link's ``LinkEnvelope`` or None (not bounded, or not a free link).
    mass_lower, mass_upper : array, shape (n_dof,)
        [kg]
    rotor_lower, rotor_upper : array, shape (n_dof,)
        [kg m^2] of the drive inertias (in the base parameters or a column ``Ia<j>`` of their own).
    pressure : array, shape (n_dof, 3)
        After the fit: per joint, how hard the data press on the link's envelope, its mass bounds and the drive
        inertia's bounds (``_pressure``: the weighted squared residual, in noise variances, that the bound costs
        to first order); zeros before it.
    prior : PriorPull or None
        After the fit: how strongly it was pulled towards the robot file (``prior_pull``).
    floors : tuple
        Per joint, the link's inertia floor (``inertia_floor.link_floors``: 3 x 3, per unit mass) or None; empty:
        none.
    held_rotors : tuple
        The joints (0-based) whose drive inertia is held at the robot's with the links it carries
        (:func:`held_rotors`): its bounds meet there, and the data pushing on them is no finding.
    """

    envelopes: tuple
    mass_lower: np.ndarray
    mass_upper: np.ndarray
    rotor_lower: np.ndarray
    rotor_upper: np.ndarray
    pressure: np.ndarray | None = None
    prior: PriorPull | None = None
    floors: tuple = ()
    held_rotors: tuple = ()

    def floor(self, i: int):
        """The inertia floor ``F`` of link ``i`` (``inertia_floor``), or None."""
        return self.floors[i] if i < len(self.floors) else None


def residual_sigma(equations, x) -> np.ndarray:
    """Per joint, the residual standard deviation [N m] of the parameters ``x`` (never below 1e-9 x torque RMS)."""
    dof = np.maximum(equations.count - equations.n_columns / equations.n_dof, 1.0)
    rms = np.sqrt(equations.energy / np.maximum(equations.count, 1))
    return np.maximum(np.sqrt(np.maximum(equations.residual_sum(x), 0.0) / dof), 1e-9 * np.maximum(rms, 1e-12))


def fit_bounds(robot, model, options) -> FitBounds:
    """The bounds of ``options`` (``envelope``, ``mass_ratio``, ``drive_inertia_ratio``) for ``robot``'s links."""
    n = robot.n_dof
    none = np.full(n, np.inf)
    if not options.envelope or robot.links is None:
        return _holding_rotors(FitBounds((None,) * n, np.zeros(n), none, np.zeros(n), none.copy()), robot, options)
    free = [i for i in range(n) if link_is_free(model, i)]
    mass = np.array([link.mass for link in robot.links], dtype=float)
    rotor = np.asarray(robot.rotor_inertia, dtype=float)
    low, high = options.mass_ratio
    given = mass > 0
    rotor_low, rotor_high = options.drive_inertia_ratio
    with_rotor = rotor > 0
    bounds = FitBounds(
        envelopes=link_envelopes(robot, free),
        mass_lower=np.where(given, low * mass, 0.0),
        mass_upper=np.where(given, high * mass, np.inf),
        rotor_lower=np.where(with_rotor, rotor_low * rotor, 0.0),
        rotor_upper=np.where(with_rotor, rotor_high * rotor, np.inf),
        floors=link_floors(robot, free),
    )
    return _holding_rotors(bounds, robot, options)


def held_rotors(robot, held_links) -> tuple:
    """The joints (0-based) whose drive inertia the fit holds with the ``held_links`` (``TrajectoryOptions``): each
    joint whose every carried link (its own to the flange) is held, at ``robot``'s rotor inertia (the file's, or the
    reference ``merged_rotors`` holds a merged one to); none where that is 0, nothing to hold it at.

    In a serial chain a joint's torque is that of the links it carries and of its own rotor (``Ia_j qdd_j``, on that
    joint alone). Once those links are the file's, the rotor is the joint's last inertia the fit can move, and
    fitted it takes what the links took (a heavy arm with every link held kept joint 2 worse than the robot file on
    the held-out motion, its rotor fitted above the file's): held with them, the joint predicts what the robot
    file's rigid body predicts, the baseline ``worse_joint_hold`` judges it against. A joint whose later links stay
    free keeps its rotor fitted: its own link held with its rotor can bring the joint within its margin of the file
    while the free links after it take what the data ask of the joint (the same arm, another seed: link 2 heavier
    than the file's and a spring kept on joint 3, which has none), where the step that holds every link it carries
    would have come next.
    """
    if robot.links is None or not held_links:
        return ()
    n, held = robot.n_dof, set(int(i) for i in held_links)
    rotor = np.asarray(robot.rotor_inertia, dtype=float)
    return tuple(j for j in range(n) if rotor[j] > 0 and held >= set(range(j, n)))


def _holding_rotors(bounds: FitBounds, robot, options) -> FitBounds:
    """``bounds`` with the drive inertia of each of :func:`held_rotors` at the robot file's (lower = upper bound)."""
    held = list(held_rotors(robot, options.held_links))
    if not held:
        return bounds
    lower, upper = bounds.rotor_lower.copy(), bounds.rotor_upper.copy()
    lower[held] = upper[held] = np.asarray(robot.rotor_inertia, dtype=float)[held]
    return replace(bounds, rotor_lower=lower, rotor_upper=upper, held_rotors=tuple(held))


def prior_standard(robot):
    """The robot file's standard parameters, or a unit mass per link with a small inertia (a consistent start)."""
    if robot.links is not None:
        return robot.nominal_dynamic_parameters()
    standard = np.zeros((robot.n_dof, LINK_PARAMETER_COUNT + 1))
    standard[:, 0] = 1.0
    standard[:, [4, 6, 9]] = 0.01
    return standard


def lifted_links(robot, links=None, model=None) -> tuple:
    """The links (0-based, ascending) of ``links`` (default: every link) that a fit holding them holds lifted
    (:func:`held_standard`): those the robot file states semi-definite (``pseudo_inertia.semidefinite_links`` of
    :func:`prior_standard`: a point mass, a thin rod) and, given ``model``, free in it (:func:`link_is_free`: a link
    the model lacks, massless, is neither fitted nor held). The consistent fit lifts these of its held links, and
    identify's hold of the worse joints names them lifted (``worse_joint_hold``)."""
    semidefinite = set(semidefinite_links(prior_standard(robot)))
    chosen = range(robot.n_dof) if links is None else {int(k) for k in links}
    return tuple(i for i in sorted(chosen) if i in semidefinite and (model is None or link_is_free(model, i)))


def held_standard(robot, held_links=(), margin: float = CONSISTENCY_MARGIN, model=None) -> np.ndarray:
    """:func:`prior_standard` with each of ``held_links`` (0-based, ``TrajectoryOptions.held_links``) that the robot
    file states semi-definite (:func:`lifted_links`: a point mass; given ``model``, one free in it) lifted by
    ``margin`` [kg m^2], the fit's own (``pseudo_inertia.lifted_link``): the values the fit holds those links at. Held
    at the file's own, such a link fails the consistency check of the model (its pseudo-inertia eigenvalue 0, its mass
    matrix singular where no other inertia acts about its joint) and nothing is written; lifted it is as near the file
    as consistency allows, and no nearer than every link the fit identifies stays."""
    standard = np.array(prior_standard(robot), dtype=float)
    for i in lifted_links(robot, held_links, model):
        standard[i, :LINK_PARAMETER_COUNT] = lifted_link(standard[i, :LINK_PARAMETER_COUNT], margin)
    return standard


def link_is_free(model, link: int) -> bool:
    """Whether any of the link's 10 inertial parameters reaches the base parameters."""
    block = model.parameter_map[:, link * (LINK_PARAMETER_COUNT + 1) : link * (LINK_PARAMETER_COUNT + 1) + 10]
    return bool(np.any(block))


def _solve(problem, start, bounds, final=True, warn=True):
    """Ipopt from ``start`` within ``bounds`` ``(lbx, ubx, lbg, ubg)``: (solution, status).

    The first of the two passes only sets the second's weights: a stop at ``FIRST_PASS_MAX_ITER`` iterations there
    is not warned about (a link pressed against its envelope creeps towards the chart's boundary for long), nor
    anywhere when ``warn`` is off (a fit that only judges, such as the diagnosis's ``envelope_check``).
    """
    cap = IPOPT_OPTIONS["ipopt.max_iter"] if final else min(FIRST_PASS_MAX_ITER, IPOPT_OPTIONS["ipopt.max_iter"])
    lbx, ubx, lbg, ubg = bounds
    sizes = (problem["x"].numel(), problem["g"].numel(), 0)
    bar, callback = progress_options("consistent_fit_progress", sizes, cap, "identify: consistent fit (Ipopt)",
                                     logger, lbg, ubg)  # fmt: skip
    solver = ca.nlpsol("consistent_fit", "ipopt", problem, {**IPOPT_OPTIONS, "ipopt.max_iter": cap, **bar})
    solution = solver(x0=np.clip(start, lbx, ubx), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    if callback is not None:
        callback.close()
    status = solver.stats()["return_status"]
    if status == "Maximum_Iterations_Exceeded" and not (final and warn):
        logger.debug("identify: the first pass of the consistent fit stopped at %s iterations", cap)
    elif status == "Maximum_Iterations_Exceeded":  # every iterate of the chart is consistent: keep it, marked
        logger.warning(
            "identify: the consistent fit stopped at Ipopt's iteration cap (%s) with the objective still "
            "creeping towards the boundary of physical consistency; the model is consistent but not proven "
            "optimal (solver_status says so). Compare its validation RMSE with --no-consistency.",
            IPOPT_OPTIONS["ipopt.max_iter"],
        )
    elif not solver.stats()["success"]:
        fix = "try --no-consistency to see the unconstrained estimate, or record a better-exciting trajectory."
        raise SolverError(f"the consistent fit did not converge ({status}); {fix}", status=status)
    return solution, status


def _link_constraints(rows, links, prior, bounds):
    """Envelope (``tr(J Q_hat) >= 0``, and the centre of mass within its reach where the link has one) and mass bounds
    of the free links, each scaled by the link's mass.

    The reach's row is in masses times metres (``reach_weights`` times its limit: its coefficients those of the
    centre's distance along the link; in masses alone the SCARA's path with a spring on joint 1 stalled where the
    reach was not even active).

    Returns the constraints, their bounds, and per constraint ``(link, column of the pressure, size)``: the size
    the envelope's row gives way by (1, or the reach's limit), None for a mass bound (its value).
    """
    g, lower, upper, owner = [], [], [], []
    for i in links:
        scale, envelope = max(prior[i, 0], 0.1), bounds.envelopes[i]
        if envelope is not None:
            reach = (reach_weights(envelope), None if envelope.reach is None else envelope.reach.limit)
            for weights, size in ((density_weights(envelope), 1.0), reach):
                if weights is not None:
                    g.append(ca.dot(ca.DM(weights * size), rows[i][:LINK_PARAMETER_COUNT]) / scale)
                    lower.append(0.0)
                    upper.append(np.inf)
                    owner.append((i, 0, size))
        if np.isfinite(bounds.mass_upper[i]) or bounds.mass_lower[i] > 0:
            g.append(rows[i][0] / scale)
            lower.append(bounds.mass_lower[i] / scale)
            upper.append(bounds.mass_upper[i] / scale)
            owner.append((i, 1, None))
    return g, np.array(lower), np.array(upper), owner


def _pressure(solution, owner, names, bounds, count, n_phi):
    """Per joint, how hard the data press on its (envelope, mass, drive inertia) bounds (``FitBounds.pressure``).

    Ipopt's multiplier of a bound is the objective's derivative with respect to it; times the number of samples
    and the bound's own size it is the first-order drop of the weighted squared residual (in noise variances)
    if the bound gave way by its whole size: the envelope by its size (the constraint is scaled by the mass),
    a mass or drive inertia bound by its value.
    """
    n = bounds.mass_lower.size
    out = np.zeros((n, 3))
    lam_g = np.abs(np.asarray(solution["lam_g"]).reshape(-1))
    values = np.asarray(solution["g"]).reshape(-1)
    for (i, column, size), lam, value in zip(owner, lam_g, values):
        out[i, column] += count * lam * (abs(value) if size is None else size)
    lam_x = np.abs(np.asarray(solution["lam_x"]).reshape(-1))
    x = np.asarray(solution["x"]).reshape(-1)
    out[:, 2] = count * lam_x[n_phi : n_phi + n] * np.abs(x[n_phi : n_phi + n])
    for k, name in enumerate(names):
        if name.startswith("Ia") and name[2:].isdigit():
            index = n_phi + n + k
            out[int(name[2:]) - 1, 2] += count * lam_x[index] * abs(x[index])
    return out


def _variable_bounds(n_phi, names, drive_lower, bounds):
    """Bounds of (phi, rotor, drive): the chart is free, drive inertias in theirs, drive terms from ``drive_lower``."""
    upper_drive = np.full(len(names), np.inf)
    lower_drive = np.array(drive_lower, dtype=float)
    for k, name in enumerate(names):
        if name.startswith("Ia") and name[2:].isdigit():
            j = int(name[2:]) - 1
            lower_drive[k], upper_drive[k] = max(lower_drive[k], bounds.rotor_lower[j]), bounds.rotor_upper[j]
    lower = np.concatenate([np.full(n_phi, -np.inf), bounds.rotor_lower, lower_drive])
    upper = np.concatenate([np.full(n_phi, np.inf), bounds.rotor_upper, upper_drive])
    return lower, upper


def consistent_fit(
    robot, model, equations, sigma, names, options, drive_lower, payload_prior=None, bounds=None, warn=True, *,
    correlation=None,
):  # fmt: skip
    """(standard (n_dof, 11), drive, payloads (k, 10), Ipopt status, bounds): the consistent step (module docstring).

    ``equations`` hold the columns ``[base, drive (names), payload_1 (10), ..., payload_k (10)]``;
    ``payload_prior`` (k, 10) are the unknown payloads' start and pull targets (consistent bodies); ``bounds``
    (``FitBounds``, default :func:`fit_bounds` of ``options``) hold the links in their envelopes and come back
    with the data's ``pressure`` on each and the ``prior`` pull used. ``correlation`` (per joint, samples) is the
    residual's correlation time that sets the pull's weight (``prior_pull``; None: independent samples).
    ``warn=False`` logs a stop at Ipopt's iteration cap at DEBUG only.
    """
    n = robot.n_dof
    bounds = fit_bounds(robot, model, options) if bounds is None else bounds
    payload_prior = np.zeros((0, 10)) if payload_prior is None else np.asarray(payload_prior, dtype=float)
    prior = held_standard(robot, options.held_links, options.margin, model)  # held: the file's (semi-definite lifted)
    links = [i for i in range(n) if link_is_free(model, i) and i not in options.held_links]
    phi = ca.SX.sym("phi", LINK_PARAMETER_COUNT * len(links))
    psi = ca.SX.sym("psi", 10 * len(payload_prior))
    rotor, drive = ca.SX.sym("rotor", n), ca.SX.sym("drive", len(names))
    rows = []
    for i in range(n):
        k = links.index(i) if i in links else None
        link = None if k is None else link_from_log_cholesky(phi[k * 10 : k * 10 + 10], options.margin, bounds.floor(i))
        rows.append(ca.vertcat(link if link is not None else ca.DM(prior[i, :10]), rotor[i]))
    standard = ca.vertcat(*rows)
    bodies = [
        link_from_log_cholesky(psi[k * 10 : k * 10 + 10], margin=options.margin) for k in range(len(payload_prior))
    ]
    payloads = ca.vertcat(*bodies) if bodies else ca.DM.zeros(0, 1)
    x = ca.vertcat(ca.mtimes(ca.DM(model.parameter_map), standard), drive, payloads)
    count = float(equations.count.sum())
    pull = PriorPull.of(options, equations.count, correlation)
    logger.debug("consistent fit: %s", pull.describe())  # identify's report states it once (IdentifyResult)
    prior_term = pull.expression(standard, prior, payloads, payload_prior)
    variables = ca.vertcat(phi, rotor, drive, psi)
    start = np.concatenate([*(chart_start(prior[i, :10], options.margin, bounds.floor(i)) for i in links),
                            np.maximum(prior[:, ROTOR], 0.0), np.zeros(len(names)),
                            *(chart_start(body, options.margin) for body in payload_prior)])  # fmt: skip
    lower, upper = _variable_bounds(phi.numel(), names, drive_lower, bounds)
    lower, upper = (np.concatenate([v, np.full(psi.numel(), sign * np.inf)]) for v, sign in ((lower, -1), (upper, 1)))
    g, g_lower, g_upper, owner = _link_constraints(rows, links, prior, bounds)
    evaluate = ca.Function("standard", [variables], [standard, x, payloads])
    plain = _standard_form(model, prior, links, payload_prior, len(names), bounds, pull)
    x_opt, w, centre = start, 1.0 / sigma**2, None
    for final in (False, True):  # then once more weighted by the consistent fit's own residuals (module docstring)
        gram, moment, energy = equations.weighted(w)
        residual = (ca.bilin(ca.DM(gram), x, x) - 2 * ca.dot(ca.DM(moment), x) + energy) / count
        problem = {
            "x": variables,
            "f": residual + prior_term,
            "g": ca.vertcat(*g) if g else ca.SX(0, 1),
        }
        convex, x_opt = _convex_solve(plain, evaluate, x_opt, (gram, moment, energy, count), (lower, upper),
                                      options.margin, (links, len(payload_prior), n), centre)  # fmt: skip
        centre = None if convex is None else convex.first  # where the next pass's path starts (barrier_path)
        if convex is not None and convex.complete:  # the convex problem solved: the chart has nothing to add
            solution, status, offset = convex.solution, convex.status, 10 * (len(links) + len(payload_prior))
        else:  # the chart from the path's last point (or from the last pass's solution)
            solution, status = _solve(problem, x_opt, (lower, upper, g_lower, g_upper), final, warn)
            x_opt, offset = np.clip(np.asarray(solution["x"]).reshape(-1), lower, upper), phi.numel()  # a hair out
        w = 1.0 / residual_sigma(equations, np.asarray(evaluate(x_opt)[1]).reshape(-1)) ** 2
    values, _, bodies_opt = (np.asarray(v) for v in evaluate(x_opt))
    drive_opt = x_opt[phi.numel() + n : phi.numel() + n + len(names)]
    bounds = replace(bounds, pressure=_pressure(solution, owner, names, bounds, count, offset), prior=pull)
    return values.reshape(n, -1), drive_opt, bodies_opt.reshape(-1, 10), status, bounds


def centred_residual(gram, moment, energy, count, x):
    """The weighted squared residual per sample ``(x' G x - 2 m' x + e) / count`` of the regression vector ``x``
    (CasADi), written around the least-squares minimum ``x_ls``: ``((x - x_ls)' G (x - x_ls) - 2 r' (x - x_ls) + e_ls)
    / count`` with ``r = m - G x_ls`` (round-off) and ``e_ls`` the value there; the same quadratic for any ``x_ls``.

    Its gradient ``2 (G (x - x_ls) - r) / count`` is then of the size of the distance from the least squares, not the
    difference of ``G x`` and ``m``, each of size ``|G| |x|``: that difference carried a round-off of
    ``eps |G| |x| / count``, about 1e-10 on the virtual Denso's gravity columns, which is Ipopt's ``tol`` for the
    barrier path (``barrier_path.BARRIER_OPTIONS``); whether a solve reached it was chance.
    """
    centre = np.linalg.lstsq(gram, moment, rcond=None)[0]
    rest = moment - gram @ centre
    level = energy - 2.0 * moment @ centre + centre @ gram @ centre
    d = x - ca.DM(centre)
    return (ca.bilin(ca.DM(gram), d, d) - 2 * ca.dot(ca.DM(rest), d) + level) / count


def chart_start(link, margin, floor=None):
    """Chart coordinates of a link with the margin and its inertia floor ``floor`` (``m diag(floor, 0)``, or None)
    taken off (projected if inconsistent)."""
    matrix = pseudo_inertia(link) - margin * np.eye(4)
    if floor is not None:
        matrix[:3, :3] -= float(link[0]) * np.asarray(floor)
    return log_cholesky_from_link(link_from_pseudo_inertia(matrix), floor=max(margin, 1e-9))


def drive_lower_bounds(names):
    """0 for friction and drive inertias, none for torque offsets."""
    return np.array([-np.inf if name.startswith("offset") else 0.0 for name in names])


def _standard_form(model, prior, links, flange, n_drive, bounds, pull) -> dict:
    """The consistent fit's pieces with the standard parameters themselves as the variables (``barrier_path``): the
    variables (free links' ten, flange bodies' ten, rotors, drive terms), the regression vector ``x``, the ``pull``
    (``PriorPull``, as in ``consistent_fit``), the link constraints and their bounds, and each body's size (its
    pseudo-inertia's trace at the prior); ``pull``: the pull without its weight, and the weight (``shared_barrier``)."""
    n, n_bodies = prior.shape[0], len(flange)
    links_v, bodies_v = ca.SX.sym("s", 10 * len(links)), ca.SX.sym("b", 10 * n_bodies)
    rotor, drive = ca.SX.sym("rotor", n), ca.SX.sym("drive", n_drive)
    rows = []
    for i in range(n):
        k = links.index(i) if i in links else None
        rows.append(ca.vertcat(ca.DM(prior[i, :10]) if k is None else links_v[10 * k : 10 * k + 10], rotor[i]))
    standard = ca.vertcat(*rows)
    g, g_lower, g_upper, _ = _link_constraints(rows, links, prior, bounds)
    sizes = [max(float(np.trace(pseudo_inertia(body))), 1e-6) for body in [*prior[links, :10], *flange]]
    unweighted = pull.pull(standard, prior, bodies_v, flange)
    return {
        "variables": ca.vertcat(links_v, bodies_v, rotor, drive),
        "sizes": sizes,
        "floors": [bounds.floor(i) for i in links] + [None] * n_bodies,
        "x": ca.vertcat(ca.mtimes(ca.DM(model.parameter_map), standard), drive, bodies_v),
        "f_extra": pull.weight * unweighted,
        "pull": (unweighted, pull.weight),
        "g": ca.vertcat(*g) if g else ca.SX(0, 1),
        "g_bounds": (g_lower, g_upper),
    }


def _convex_solve(plain, evaluate, chart, normal, chart_bounds, margin, counts, centre=None) -> tuple:
    """(``barrier_path.BarrierResult`` or None, chart coordinates of its point, or ``chart`` without one): the convex
    problem (``_standard_form``) solved along the barrier path from the chart point ``chart``, or from ``centre``
    (the standard form's variables: the last pass's point of the path's first weight, ``BarrierResult.first``; a
    second pass starts there, not at the last pass's end, ``barrier_path``). Inside ``shared_barrier.shared_solvers``
    by the structure's shared solver, and by one of its own when that stops short of the path's end."""
    from identification.calibration.barrier_path import barrier_solution
    from identification.calibration.shared_barrier import shared_problem

    gram, moment, energy, count = normal
    free, n_bodies, n = counts
    values, _, bodies = (np.asarray(v) for v in evaluate(chart))
    values, bodies = values.reshape(n, -1), bodies.reshape(-1, 10)
    n_phi, n_psi = 10 * len(free), 10 * n_bodies
    rest = chart[n_phi : chart.size - n_psi]  # rotors and drive terms: the same in both forms
    start = np.concatenate([values[free, :10].reshape(-1), bodies.reshape(-1), rest]) if centre is None else centre
    lower, upper = chart_bounds
    lbx = np.concatenate([np.full(n_phi + n_psi, -np.inf), lower[n_phi : lower.size - n_psi]])
    ubx = np.concatenate([np.full(n_phi + n_psi, np.inf), upper[n_phi : upper.size - n_psi]])
    bounds = (lbx, ubx, *plain["g_bounds"])
    problem, shared = shared_problem(plain, normal, margin)  # inside ``shared_solvers``: the data as parameters
    floors = plain["floors"]
    solved = None if shared is None else barrier_solution(problem, plain["sizes"], start, bounds, margin, shared,
                                                          floors)  # fmt: skip
    if shared is None or solved is None or not solved.complete:  # a shared solver that stopped: solved as alone
        if shared is not None:
            logger.debug("consistent fit: the shared barrier-path solver stopped (%s); this fit's own solver",
                         "at its first weight" if solved is None else solved.status)  # fmt: skip
        residual = centred_residual(gram, moment, energy, count, plain["x"])
        problem = {"x": plain["variables"], "f": residual + plain["f_extra"], "g": plain["g"]}
        solved = barrier_solution(problem, plain["sizes"], start, bounds, margin, floors=floors)
    if solved is None:
        return None, chart
    links = [chart_start(body, margin, floor) for body, floor in zip(solved.x[:n_phi].reshape(-1, 10), floors)]
    flange = [chart_start(body, margin) for body in solved.x[n_phi : n_phi + n_psi].reshape(-1, 10)]
    return solved, np.concatenate([*links, solved.x[n_phi + n_psi :], *flange])
