"""Final fit of the kept terms: the nonlinear parameters by Ipopt (CasADi ``nlpsol``) after the linearised screening.

The selection ranks candidates with columns that are linear in their coefficients (a delay, backlash and
a warming-up friction enter through first-order or fixed-shape expansions). Once the terms are chosen,
``refine_fit`` fits the nominal friction, every kept term and the nonlinear parameters of the terms that
have them jointly, by weighted nonlinear least squares on the training recording (the same joint
weights as the selection), starting from the linear solution:

- ``delay``, ``backlash`` and ``joint_elasticity``: fitted exactly first (``signal_fit.fit_signal_terms``, variable
  projection: an interpolated delayed torque, a filtered flank of play or a torsion with its exact friction change)
  and held at those values here, as fixed torques. A kept backlash or joint elasticity is also refitted as the
  other one on the same joint, and the better exact fit is kept (``signal_fit.resolve_deflection``:
  their screening columns are alike);
- ``friction_drift``: a warm-up time constant T, ``rate T (1 - exp(-t / T)) sign(qd)`` (linear drift as T -> inf).

Terms without nonlinear parameters keep their linear columns. The refined fit replaces the linear one
only when Ipopt converges and the training error does not grow.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from identification.diagnosis.columns import as_dense
from identification.diagnosis.design import joint_weights, left_out
from identification.diagnosis.signal_fit import SIGNAL_KEYS, exact_contribution, fit_signal_terms, resolve_deflection


@dataclass(frozen=True)
class RefinedFit:
    """Outcome of ``refine_fit``: terms with their nonlinear parameters set, coefficients, predictions, Ipopt status."""

    terms: tuple
    coefficients: tuple
    friction_coefficients: np.ndarray
    prediction_train: np.ndarray
    prediction_validation: np.ndarray
    nonlinear: dict
    status: str
    iterations: int
    improved: bool


def _contribution(term, context, beta, p, fixed):
    """Extra torque (list of n_dof MX column vectors or None) of ``term`` with coefficients ``beta`` and
    nonlinear parameters ``p`` on ``context``; None for terms that keep linear columns. ``fixed`` maps the
    labels of the exactly fitted signal-level terms to their parameters (their torque is a constant here)."""
    key = term.key
    n = context.n_dof
    if term.label in fixed:
        extra = exact_contribution(term, context, fixed[term.label])
        return [ca.DM(extra[:, j]) for j in range(n)]
    if key == "friction_drift":
        j, rate, big_t = term.joint, beta[0], ca.exp(p[0])
        sign = ca.DM(context.friction_sign(j))  # as the measured torque sees it (the time shape varies slowly)
        t = ca.DM(context.t)
        out = [ca.DM.zeros(context.n_samples) for _ in range(n)]
        out[j] = rate * big_t * (1 - ca.exp(-t / big_t)) * sign
        return out
    return None


def _start(term, context, coefficients):
    """Initial nonlinear parameters (log scale) of a refinable term."""
    if term.key == "friction_drift":
        return [np.log(20.0 * float(context.t[-1] - context.t[0]) + 1.0)]
    return []


def _prediction(terms, fixed, ctx, base, beta0, betas, ps):
    n = ctx.n_dof
    out = [ca.mtimes(ca.DM(base[:, j, :]), beta0) for j in range(n)]
    for term, b, p in zip(terms, betas, ps):
        extra = _contribution(term, ctx, b, p, fixed)
        if extra is None:
            cols = term.columns(ctx)
            extra = [ca.mtimes(ca.DM(cols[:, j, :]), b) for j in range(n)]
        out = [o + e for o, e in zip(out, extra)]
    return out


def _unknowns(p0, terms, coefficients, friction_coefficients, fixed, context) -> tuple:
    """Symbols of the unknowns (``p0`` nominal friction coefficients ``beta0``, per-term coefficients ``betas``
    and nonlinear parameters ``ps``) with their start ``x0`` and bounds ``lbx``, ``ubx`` (exactly fitted terms
    held fixed)."""
    beta0 = ca.MX.sym("friction", p0)
    betas, ps, x0 = [], [], [np.asarray(friction_coefficients, dtype=float)]
    lbx, ubx = [np.full(p0, -np.inf)], [np.full(p0, np.inf)]
    for k, (term, c) in enumerate(zip(terms, coefficients)):
        betas.append(ca.MX.sym(f"beta{k}", len(c)))
        c = np.asarray(c, dtype=float)
        if term.label in fixed:  # held at the exact fit (its torque is a constant in this problem)
            c = np.array(fixed[term.label][: len(c)], dtype=float)
            lbx.append(c.copy())
            ubx.append(c.copy())
        else:
            lbx.append(np.full(len(c), -np.inf))
            ubx.append(np.full(len(c), np.inf))
        x0.append(c)
    for k, (term, c) in enumerate(zip(terms, coefficients)):
        start = _start(term, context, c)
        ps.append(ca.MX.sym(f"p{k}", len(start)))
        x0.append(np.asarray(start, dtype=float))
        lbx.append(np.full(len(start), -np.inf))
        ubx.append(np.full(len(start), np.inf))
    return beta0, betas, ps, np.concatenate(x0), np.concatenate(lbx), np.concatenate(ubx)


def _solve(x, objective, x0, lbx, ubx, max_iter) -> tuple:
    """Minimise ``objective`` over ``x`` with Ipopt from ``x0``: (solution, Ipopt stats, improved); the solution
    is ``x0`` unless Ipopt converged to finite values without raising the objective."""
    f_obj = ca.Function("objective", [x], [objective])
    solver = ca.nlpsol(
        "refine",
        "ipopt",
        {"x": x, "f": objective},
        {
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "print_time": False,
            "ipopt.max_iter": max_iter,
            "ipopt.tol": 1e-10,
        },
    )
    solution = solver(x0=x0, lbx=lbx, ubx=ubx)
    stats = solver.stats()
    xs = np.asarray(solution["x"]).ravel()
    before, after = float(f_obj(x0)), float(solution["f"])
    ok = bool(stats.get("success", False)) and np.all(np.isfinite(xs)) and after <= before
    if not ok:
        xs = x0
    return xs, stats, ok


def _unpack(xs, p0, terms, coefficients, fixed, context) -> tuple:
    """Split the solution ``xs`` into (terms with their nonlinear parameters set, coefficients per term,
    nonlinear parameters by label in physical units); the first ``p0`` entries are the nominal friction."""
    offset = p0
    new_coefficients = []
    for c in coefficients:
        new_coefficients.append(xs[offset : offset + len(c)].copy())
        offset += len(c)
    nonlinear, new_terms = {}, []
    for term, c in zip(terms, coefficients):
        m = len(_start(term, context, c))
        values = xs[offset : offset + m]
        offset += m
        if term.key == "backlash" and term.label in fixed:
            scale = float(fixed[term.label][1])
            term = term.on_training(context)  # the flank smoothing relative to the training recording's torque
            term = replace(term, torque_scale=scale / term.training_torque(context))
            nonlinear[term.label] = {"torque_scale_Nm": scale}
        elif term.key == "friction_drift":
            nonlinear[term.label] = {"time_constant_s": float(np.exp(values[0]))}
            term = replace(term, time_constant=float(np.exp(values[0])))
        elif term.key == "delay":
            nonlinear[term.label] = {"delay_s": float(new_coefficients[len(new_terms)][0])}
        new_terms.append(term)
    return tuple(new_terms), tuple(new_coefficients), nonlinear


def refine_fit(
    terms,
    coefficients,
    friction_coefficients,
    train_ctx,
    val_ctx,
    base_train,
    base_val,
    y_train,
    y_val,
    max_iter: int = 200,
) -> RefinedFit | None:
    """Refine the kept terms with Ipopt (see the module docstring); None when no term has nonlinear parameters."""
    refinable = [t.key in SIGNAL_KEYS + ("friction_drift",) for t in terms]
    if not any(refinable):
        return None
    base_train, base_val = as_dense(base_train), as_dense(base_val)
    sigma = joint_weights(train_ctx.tau, left_out(train_ctx))
    signal = fit_signal_terms(terms, coefficients, train_ctx, base_train, y_train, sigma)
    terms, coefficients, signal = resolve_deflection(terms, coefficients, signal, train_ctx, base_train, y_train, sigma)
    fixed = {} if signal is None else signal.parameters
    p0 = base_train.shape[2]
    beta0, betas, ps, x0, lbx, ubx = _unknowns(p0, terms, coefficients, friction_coefficients, fixed, train_ctx)
    pred_t = _prediction(terms, fixed, train_ctx, base_train, beta0, betas, ps)
    residual = ca.vertcat(*[(ca.DM(y_train[:, j]) - pred_t[j]) / sigma[j] for j in range(train_ctx.n_dof)])
    x = ca.vertcat(beta0, *betas, *ps)
    xs, stats, ok = _solve(x, ca.sumsqr(residual), x0, lbx, ubx, max_iter)
    pred_fn_t = ca.Function("pred_t", [x], [ca.horzcat(*pred_t)])
    pred_v = _prediction(terms, fixed, val_ctx, base_val, beta0, betas, ps)
    pred_fn_v = ca.Function("pred_v", [x], [ca.horzcat(*pred_v)])
    new_terms, new_coefficients, nonlinear = _unpack(xs, p0, terms, coefficients, fixed, train_ctx)
    return RefinedFit(
        terms=new_terms,
        coefficients=new_coefficients,
        friction_coefficients=xs[:p0].copy(),
        prediction_train=np.asarray(pred_fn_t(xs)),
        prediction_validation=np.asarray(pred_fn_v(xs)),
        nonlinear=nonlinear,
        status=str(stats.get("return_status", "")),
        iterations=int(stats.get("iter_count", 0)),
        improved=ok,
    )
