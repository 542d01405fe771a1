"""The physically consistent step of the recordings-route fit: Ipopt over log-Cholesky links (and flange bodies).

:func:`consistent_fit` minimises the weighted residual of the normal equations of
``trajectory_fit`` over standard parameters in the log-Cholesky chart (``pseudo_inertia``), so every
link, and every unknown payload fixed to the flange (``payload_fit``), has a positive-definite
pseudo-inertia; friction and drive inertias are bounded below by zero, and a small pull
(``prior_weight``) towards the robot file's parameters settles what the data cannot see. It is
solved twice, the second time weighted by the first consistent fit's own residual.
"""

from __future__ import annotations

import logging

import casadi as ca
import numpy as np

from identification.calibration.pseudo_inertia import (
    LINK_PARAMETER_COUNT,
    link_from_log_cholesky,
    link_from_pseudo_inertia,
    log_cholesky_from_link,
    pseudo_inertia,
)
from psdm_casadi.errors import SolverError

__all__ = ["IPOPT_OPTIONS", "consistent_fit", "drive_lower_bounds", "link_is_free", "prior_scale", "residual_sigma"]

logger = logging.getLogger(__name__)

ROTOR = LINK_PARAMETER_COUNT  # column of the drive inertia in a joint's 11 standard parameters
# When the data ask for an inconsistent link, the optimum lies on the boundary of the chart, at
# infinity in its log-diagonal: the objective then creeps down without its gradient vanishing.
# Ipopt stops when the objective has stopped changing (acceptable_obj_change_tol, relative).
IPOPT_OPTIONS = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False, "ipopt.tol": 1e-9,
                 "ipopt.acceptable_tol": 1e-2, "ipopt.acceptable_obj_change_tol": 1e-9,
                 "ipopt.acceptable_iter": 10, "ipopt.max_iter": 2000}  # fmt: skip


def residual_sigma(equations, x) -> np.ndarray:
    """Per joint, the residual standard deviation [N m] of the parameters ``x`` (never below 1e-9 x torque RMS)."""
    dof = np.maximum(equations.count - equations.n_columns / equations.n_dof, 1.0)
    rms = np.sqrt(equations.energy / np.maximum(equations.count, 1))
    return np.maximum(np.sqrt(np.maximum(equations.residual_sum(x), 0.0) / dof), 1e-9 * np.maximum(rms, 1e-12))


def prior_standard(robot):
    """The robot file's standard parameters, or a unit mass per link with a small inertia (a consistent start)."""
    if robot.links is not None:
        return robot.nominal_dynamic_parameters()
    standard = np.zeros((robot.n_dof, LINK_PARAMETER_COUNT + 1))
    standard[:, 0] = 1.0
    standard[:, [4, 6, 9]] = 0.01
    return standard


def link_is_free(model, link: int) -> bool:
    """Whether any of the link's 10 inertial parameters reaches the base parameters."""
    block = model.parameter_map[:, link * (LINK_PARAMETER_COUNT + 1) : link * (LINK_PARAMETER_COUNT + 1) + 10]
    return bool(np.any(block))


def _solve(variables, objective, start, lower, evaluate):
    solver = ca.nlpsol("consistent_fit", "ipopt", {"x": variables, "f": objective}, IPOPT_OPTIONS)
    solution = solver(x0=start, lbx=lower, ubx=np.full(lower.size, np.inf))
    status = solver.stats()["return_status"]
    if status == "Maximum_Iterations_Exceeded":  # every iterate of the chart is consistent: keep it, marked
        logger.warning(
            "identify: the consistent fit stopped at Ipopt's iteration cap (%s) with the objective still "
            "creeping towards the boundary of physical consistency; the model is consistent but not proven "
            "optimal (solver_status says so). Compare its validation RMSE with --no-consistency.",
            IPOPT_OPTIONS["ipopt.max_iter"],
        )
    elif not solver.stats()["success"]:
        fix = "try --no-consistency to see the unconstrained estimate, or record a better-exciting trajectory."
        raise SolverError(f"the consistent fit did not converge ({status}); {fix}", status=status)
    return np.maximum(np.asarray(solution["x"]).reshape(-1), lower), status  # Ipopt may end a hair outside a bound


def consistent_fit(robot, model, equations, sigma, names, options, drive_lower, payload_prior=None):
    """(standard (n_dof, 11), drive, payloads (k, 10), Ipopt status): the consistent step (module docstring).

    ``equations`` hold the columns ``[base, drive (names), payload_1 (10), ..., payload_k (10)]``;
    ``payload_prior`` (k, 10) are the unknown payloads' start and pull targets (consistent bodies).
    """
    n = robot.n_dof
    payload_prior = np.zeros((0, 10)) if payload_prior is None else np.asarray(payload_prior, dtype=float)
    prior = prior_standard(robot)
    links = [i for i in range(n) if link_is_free(model, i)]
    phi = ca.SX.sym("phi", LINK_PARAMETER_COUNT * len(links))
    psi = ca.SX.sym("psi", 10 * len(payload_prior))
    rotor, drive = ca.SX.sym("rotor", n), ca.SX.sym("drive", len(names))
    rows = []
    for i in range(n):
        k = links.index(i) if i in links else None
        link = None if k is None else link_from_log_cholesky(phi[k * 10 : k * 10 + 10], margin=options.margin)
        rows.append(ca.vertcat(link if link is not None else ca.DM(prior[i, :10]), rotor[i]))
    standard = ca.vertcat(*rows)
    bodies = [
        link_from_log_cholesky(psi[k * 10 : k * 10 + 10], margin=options.margin) for k in range(len(payload_prior))
    ]
    payloads = ca.vertcat(*bodies) if bodies else ca.DM.zeros(0, 1)
    x = ca.vertcat(ca.mtimes(ca.DM(model.parameter_map), standard), drive, payloads)
    count = float(equations.count.sum())
    scale = prior_scale(prior)
    pull = ca.sumsqr((standard - ca.DM(prior.reshape(-1))) / ca.DM(scale.reshape(-1)))
    if bodies:
        scale = prior_scale(np.column_stack([payload_prior, np.zeros(len(payload_prior))]))[:, :10]
        pull += ca.sumsqr((payloads - ca.DM(payload_prior.reshape(-1))) / ca.DM(scale.reshape(-1)))
    variables = ca.vertcat(phi, rotor, drive, psi)
    start = np.concatenate([*(chart_start(prior[i, :10], options.margin) for i in links),
                            np.maximum(prior[:, ROTOR], 0.0), np.zeros(len(names)),
                            *(chart_start(body, options.margin) for body in payload_prior)])  # fmt: skip
    lower = np.concatenate([np.full(phi.numel(), -np.inf), np.zeros(n), drive_lower, np.full(psi.numel(), -np.inf)])
    evaluate = ca.Function("standard", [variables], [standard, x, payloads])
    x_opt, w = start, 1.0 / sigma**2
    for _ in range(2):  # then once more weighted by the consistent fit's own residuals (module docstring)
        gram, moment, energy = equations.weighted(w)
        residual = (ca.bilin(ca.DM(gram), x, x) - 2 * ca.dot(ca.DM(moment), x) + energy) / count
        x_opt, status = _solve(variables, residual + options.prior_weight * pull, x_opt, lower, evaluate)
        w = 1.0 / residual_sigma(equations, np.asarray(evaluate(x_opt)[1]).reshape(-1)) ** 2
    values, _, bodies_opt = (np.asarray(v) for v in evaluate(x_opt))
    drive_opt = x_opt[phi.numel() + n : phi.numel() + n + len(names)]
    return values.reshape(n, -1), drive_opt, bodies_opt.reshape(-1, 10), status


def chart_start(link, margin):
    """Chart coordinates of a link with the margin taken off (projected if inconsistent)."""
    shifted = link_from_pseudo_inertia(pseudo_inertia(link) - margin * np.eye(4))
    return log_cholesky_from_link(shifted, floor=max(margin, 1e-9))


def prior_scale(prior):
    """Per standard parameter, the size the pull towards the prior is measured in (never below a floor)."""
    mass = np.maximum(np.abs(prior[:, :1]), 0.1)
    moment = np.maximum(np.abs(prior[:, 1:4]), 0.01 * mass)
    inertia = np.maximum(np.abs(prior[:, 4:10]), 1e-3 * mass)
    rotor = np.maximum(np.abs(prior[:, ROTOR:]), 1e-3)
    return np.concatenate([mass, moment, inertia, rotor], axis=1)


def drive_lower_bounds(names):
    """0 for friction and drive inertias, none for torque offsets."""
    return np.array([-np.inf if name.startswith("offset") else 0.0 for name in names])
