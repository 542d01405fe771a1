"""The multiple-shooting NLP of a LuGre fit, assembled from one small CasADi Function per interval.

Shared by both measurement models of :func:`identification.friction.shooting.fit_lugre_multiple_shooting`
(the friction at the samples, :mod:`identification.friction.shooting`, and the central-difference
measurement, :mod:`identification.friction.measurement`). Each model builds the SX Function of one
shooting interval with :func:`build_shooting_interval`; :func:`assemble_shooting_nlp` maps it over
the intervals and returns the NLP with its exact Lagrangian Hessian, assembled from per-interval
8 x 8 blocks (CasADi's generic Hessian of the whole graph scales quadratically here, because the
seven parameters couple every sample).

Decision variables: ``log_p`` (7, the parameters as logarithms of their ratio to the initial guess)
then the scaled bristle force ``w`` at the shooting nodes.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.sparse as sps

__all__ = ["build_shooting_interval", "assemble_shooting_nlp"]


def build_shooting_interval(name, log_p, w, w_next, steps, data, continuity, cost):
    """The Function pair of one multiple-shooting interval of a LuGre fit, from its SX expressions.

    Parameters
    ----------
    name : str
        Name of the interval Function; its Hessian is ``name + "_hessian"``.
    log_p : casadi.SX, shape (7, 1)
        Parameters as logarithms of their ratio to the initial guess.
    w, w_next : casadi.SX, scalar
        Scaled bristle force at this interval's node and at the next one.
    steps, data : casadi.SX
        Per-sample-interval and per-sample numeric inputs of the interval (model specific).
    continuity : casadi.SX, scalar
        Continuity defect, linear in ``w_next``.
    cost : casadi.SX, scalar
        The interval's share of the objective.

    Returns
    -------
    interval : casadi.Function
        ``(log_p, w, w_next, steps, data) -> (continuity, cost)``.
    hessian : casadi.Function
        ``(log_p, w, steps, data, lam_f, lam) -> (36,)``: the upper triangle of the 8 x 8 Hessian
        of ``lam_f * cost + lam * continuity`` over ``(log_p, w)`` (continuity is linear in
        ``w_next``, which therefore has no second derivatives).
    """
    lam_f = ca.SX.sym("lam_f")
    lam = ca.SX.sym("lam")
    z = ca.vertcat(log_p, w)
    hess = ca.hessian(lam_f * cost + lam * continuity, z)[0]
    triu = ca.vertcat(*[hess[i, j] for i, j in zip(*np.triu_indices(8))])
    return (
        ca.Function(name, [log_p, w, w_next, steps, data], [continuity, cost]),
        ca.Function(f"{name}_hessian", [log_p, w, steps, data, lam_f, lam], [triu]),
    )


def _scatter(n_nodes, block_node):
    """Sparse map from stacked upper-triangular 8x8 blocks to the upper triangle of the NLP Hessian.

    Block b covers variables ``(0..6, 7 + block_node[b])``. Returns the target sparsity and the
    (nnz x 36 n_blocks) 0/1 matrix that sums block entries into its nonzeros (column-major order).
    """
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


def assemble_shooting_nlp(n_nodes, groups):
    """f, g and the exact Lagrangian Hessian of the shooting NLP from mapped interval Functions.

    Parameters
    ----------
    n_nodes : int
        Number of shooting nodes; the last interval has no successor and no continuity constraint.
    groups : list of tuple
        ``(nodes, interval, hessian, steps, data)``: the intervals starting at ``nodes`` (int array)
        share one Function pair of :func:`build_shooting_interval` and take their ``steps``/``data``
        columns side by side, interval-major.

    Returns
    -------
    nlp : dict
        ``{"x", "f", "g"}`` for ``casadi.nlpsol`` (the form its interface takes).
    hess_lag : casadi.Function
        ``nlp_hess_l(x, p, lam_f, lam_g) -> triu_hess_gamma_x_x`` for Ipopt's ``hess_lag`` option.
    """
    x = ca.MX.sym("x", 7 + n_nodes)
    log_p = x[:7]
    w = x[7:].T
    w_next = ca.horzcat(w[:, 1:], ca.MX.zeros(1, 1))  # the last interval has no successor
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", n_nodes - 1)
    lam = ca.horzcat(lam_g.T, ca.MX.zeros(1, 1))
    cons, costs, hessians, order = [], [], [], []
    for nodes, fun, hess, steps, data in groups:
        cols = nodes.tolist()
        step_in, data_in = ca.DM(steps), ca.DM(data)
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
    return {"x": x, "f": f, "g": g}, hess_lag
