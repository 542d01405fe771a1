"""Pinocchio's aba as a CasADi Function through a Python callback, with its analytical first derivatives.

This is what a CasADi user without ``pinocchio.casadi`` (the pip ``pin`` wheel is built without
it) can put into an optimal-control problem: ``pinocchio.aba`` for the value and
``pinocchio.computeABADerivatives`` for the Jacobian, so a gradient-based solver can use it. It
has no second derivatives (CasADi would have to differentiate the Jacobian callback), so it fits a
Gauss-Newton or limited-memory Hessian only, and it cannot be compiled or expanded to SX.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin

_NAMES_IN = ("q", "qd", "tau")


class _DenseCallback(ca.Callback):
    """Shared plumbing: dense (n_dof, 1) inputs and (n_dof, n_dof or 1) outputs on one Pinocchio model."""

    def __init__(self, model, n_in, names_out, out_columns):
        ca.Callback.__init__(self)
        self.model = model
        self.data = model.createData()
        self.n = model.nv
        self.n_inputs = n_in
        self.names_out = names_out
        self.out_columns = out_columns

    def get_n_in(self):
        return self.n_inputs

    def get_n_out(self):
        return len(self.names_out)

    def get_name_out(self, i):
        return self.names_out[i]

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(self.n, self.out_columns)


class PinocchioAbaJacobian(_DenseCallback):
    """``(q, qd, tau, qdd) -> (d qdd/d q, d qdd/d qd, d qdd/d tau)`` by ``pinocchio.computeABADerivatives``."""

    def __init__(self, model, name, opts=None):
        super().__init__(model, 4, ["jac_qdd_q", "jac_qdd_qd", "jac_qdd_tau"], model.nv)
        self.construct(name, dict(opts or {}))

    def get_name_in(self, i):
        return (*_NAMES_IN, "out_qdd")[i]

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.n, 1)

    def eval(self, args):
        q, qd, tau = (np.asarray(a, dtype=float).ravel() for a in args[:3])
        dq, dqd, dtau = pin.computeABADerivatives(self.model, self.data, q, qd, tau)
        return [np.array(dq), np.array(dqd), np.array(dtau)]


class PinocchioAba(_DenseCallback):
    """``(q, qd, tau) -> qdd`` by ``pinocchio.aba``, differentiable once through ``PinocchioAbaJacobian``.

    Keep the object alive while the Functions built on it are in use (CasADi holds no Python reference).

    Examples
    --------
    >>> aba = PinocchioAba(oracle.model)                # doctest: +SKIP
    >>> qdd = aba(q, qd, tau)                           # doctest: +SKIP
    """

    def __init__(self, model, name="pinocchio_aba"):
        super().__init__(model, 3, ["qdd"], 1)
        self._jacobian = None
        self.construct(name, {})

    def get_name_in(self, i):
        return _NAMES_IN[i]

    def eval(self, args):
        q, qd, tau = (np.asarray(a, dtype=float).ravel() for a in args)
        return [pin.aba(self.model, self.data, q, qd, tau)]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        self._jacobian = PinocchioAbaJacobian(self.model, name, opts)
        return self._jacobian
