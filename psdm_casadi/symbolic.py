"""build_functions(): CasADi expression graphs of a PSDMModel (regressor, inverse/forward dynamics, mass matrix).

The graphs exploit the PSDM structure: the per-joint trig basis {1, s, c, sc, c^2} is computed once,
products of basis functions share their common factors, and each torque is a sum over
acceleration functions of trig polynomials factored recursively over joints (Horner-like), so that
zero entries of P never appear. With numeric base parameters (``theta=``) CasADi folds the
constants and the graph is smallest.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.forward import ldl_solve, symmetric_from_columns
from psdm_casadi.model import PSDMModel


@dataclass(frozen=True)
class DynamicsFunctions:
    """CasADi functions of one PSDM model.

    Every function has named inputs and outputs. When built with numeric ``theta`` the
    ``theta`` input is absent (the parameters are compiled in).

    Attributes
    ----------
    regressor : casadi.Function
        (q, qd, qdd) -> Y, shape (n_dof, n_base).
    gravity_regressor : casadi.Function
        (q) -> Y_grav, shape (n_dof, n_base).
    inverse_dynamics : casadi.Function
        (q, qd, qdd[, theta]) -> tau.
    mass_matrix : casadi.Function
        (q[, theta]) -> D, symmetric (n_dof, n_dof).
    bias : casadi.Function
        (q, qd[, theta]) -> h = C(q, qd) qd + G(q), so that tau = D qdd + h.
    gravity : casadi.Function
        (q[, theta]) -> G.
    forward_dynamics : casadi.Function
        (q, qd, tau[, theta]) -> qdd, by LDL^T of D.
    n_dof, n_base : int
    theta : numpy.ndarray or None
        The compiled-in base parameters, if any.
    regressor_structure : psdm_casadi.recursive.RegressorStructure or None
        The regressor's pieces (joint chain, unit-parameter wrenches, preimage) when built by the
        recursive form; ``codegen.export_c`` writes a vectorised regressor from them.
    motor_torque : casadi.Function or None
        (q, qd, qdd[, theta]) -> tau_m = N_q^-T tau, the motor torques of a robot with a transmission
        (``codegen.motor_torque.add_motor_torque``); None otherwise.
    inverse_dynamics_at_temperature : casadi.Function or None
        (q, qd, qdd, temperature) -> tau of a calibrated model whose friction has a law in the joints' temperature
        (``codegen.temperature_friction``); None otherwise.
    """

    regressor: ca.Function
    gravity_regressor: ca.Function
    inverse_dynamics: ca.Function
    mass_matrix: ca.Function
    bias: ca.Function
    gravity: ca.Function
    forward_dynamics: ca.Function
    n_dof: int
    n_base: int
    theta: np.ndarray | None = None
    regressor_structure: object | None = None
    motor_torque: ca.Function | None = None
    inverse_dynamics_at_temperature: ca.Function | None = None

    def all(self) -> list:
        """All functions, regressor first."""
        return [
            self.regressor,
            self.gravity_regressor,
            self.inverse_dynamics,
            self.mass_matrix,
            self.bias,
            self.gravity,
            self.forward_dynamics,
        ]


def baked_theta(theta, n_base: int) -> np.ndarray:
    """Numeric base parameters to compile in, as a flat float array of length ``n_base``."""
    baked = np.asarray(theta, dtype=float).reshape(-1)
    if baked.size != n_base:
        raise ShapeError(f"theta must have {n_base} base parameters; got {baked.size}.")
    return baked


def assemble_functions(
    symbols,
    theta_inputs: list,
    theta_names: list,
    *,
    regressor,
    gravity_regressor,
    tau,
    bias,
    gravity,
    mass_columns,
    theta,
) -> DynamicsFunctions:
    """The named CasADi Functions of one model's expressions (shared by both forms of the model).

    ``symbols`` is ``(q, qd, qdd, tau_in)``; ``mass_columns[k]`` is column k of the mass matrix, whose
    entries from k down fill the lower triangle, mirrored; forward dynamics solve it by LDL^T.
    """
    q, qd, qdd, tau_in = symbols
    mass = symmetric_from_columns(mass_columns)
    qdd_forward = ldl_solve(mass, tau_in - bias)

    def function(name, inputs, input_names, output, output_name):
        return ca.Function(
            name, inputs + theta_inputs, [output], input_names + theta_names, [output_name], {"cse": True}
        )

    return DynamicsFunctions(
        regressor=ca.Function("regressor", [q, qd, qdd], [regressor], ["q", "qd", "qdd"], ["Y"], {"cse": True}),
        gravity_regressor=ca.Function("gravity_regressor", [q], [gravity_regressor], ["q"], ["Y_grav"], {"cse": True}),
        inverse_dynamics=function("inverse_dynamics", [q, qd, qdd], ["q", "qd", "qdd"], tau, "tau"),
        mass_matrix=function("mass_matrix", [q], ["q"], mass, "D"),
        bias=function("bias", [q, qd], ["q", "qd"], bias, "h"),
        gravity=function("gravity", [q], ["q"], gravity, "G"),
        forward_dynamics=function("forward_dynamics", [q, qd, tau_in], ["q", "qd", "tau"], qdd_forward, "qdd"),
        n_dof=q.numel(),
        n_base=regressor.size2(),
        theta=theta,
    )


class _Terms:
    """Shared SX building blocks: per-joint basis values and factored trig polynomials."""

    def __init__(self, model: PSDMModel, q: ca.SX):
        n = model.n_dof
        self.n = n
        self.basis = []
        for j in range(n):
            if model.revolute[j]:
                s, c = ca.sin(q[j]), ca.cos(q[j])
                self.basis.append([None, s, c, s * c, c * c])
            else:
                self.basis.append([None, q[j], q[j] * q[j]])
        exps = model.exponents
        self.digits = np.zeros((model.n_functions, n), dtype=int)
        for j in range(n):
            if model.revolute[j]:
                s_pow, c_pow = exps[n + j], exps[2 * n + j]
                self.digits[:, j] = np.select(
                    [
                        (s_pow == 1) & (c_pow == 0),
                        (s_pow == 0) & (c_pow == 1),
                        (s_pow == 1) & (c_pow == 1),
                        (c_pow == 2),
                    ],
                    [1, 2, 3, 4],
                    0,
                )
            else:
                self.digits[:, j] = exps[j]
        self._products = {(): None}

    def product(self, digits: tuple):
        """Product of basis functions for a multi-index, sharing prefixes (None means 1)."""
        if digits in self._products:
            return self._products[digits]
        head = self.product(digits[:-1])
        j = len(digits) - 1
        factor = self.basis[j][digits[-1]]
        if factor is None:
            value = head
        else:
            value = factor if head is None else head * factor
        self._products[digits] = value
        return value

    def polynomial(self, coefficients: dict):
        """sum_v coef_v prod_j basis_j[v_j], factored recursively from the last joint."""
        return self._factor(coefficients, self.n)

    def _factor(self, coefficients: dict, n_joints: int):
        if not coefficients:
            return 0
        if n_joints == 0:
            return coefficients[()]
        j = n_joints - 1
        groups = defaultdict(dict)
        for digits, coef in coefficients.items():
            groups[digits[j]][digits[:j]] = coef
        total = 0
        for digit in sorted(groups):
            inner = self._factor(groups[digit], j)
            factor = self.basis[j][digit]
            total = total + (inner if factor is None else factor * inner)
        return total


def _acceleration_factor(model: PSDMModel, qd, qdd, gravity_on: bool = True):
    """The acceleration function of each model function (g, qdd_k, qd_k^2 or qd_j qd_k) as SX."""
    n = model.n_dof
    vel, acc = model.exponents[3 * n : 4 * n], model.exponents[4 * n :]
    factors, keys = [], []
    for f in range(model.n_functions):
        kk = np.nonzero(acc[:, f])[0]
        vv = np.nonzero(vel[:, f])[0]
        if kk.size:
            keys.append(("qdd", int(kk[0])))
            factors.append(qdd[int(kk[0])])
        elif vv.size == 1:
            keys.append(("qd2", int(vv[0])))
            factors.append(qd[int(vv[0])] ** 2)
        elif vv.size == 2:
            keys.append(("qdqd", int(vv[0]), int(vv[1])))
            factors.append(qd[int(vv[0])] * qd[int(vv[1])])
        else:
            keys.append(("g",))
            factors.append(model.gravity_magnitude if gravity_on else 0.0)
    return keys, factors


def _weights(model: PSDMModel, theta):
    """w[i][f] = (P_i theta)_f for the nonzero entries: per joint a dict function -> coefficient."""
    weights = []
    for i in range(model.n_dof):
        p_i = model.reduction[:, :, i]
        rows, cols = np.nonzero(p_i)
        per_function = defaultdict(lambda: 0)
        for f, l in zip(rows, cols):
            per_function[int(f)] = per_function[int(f)] + float(p_i[f, l]) * theta[int(l)]
        weights.append(dict(per_function))
    return weights


def _torques(model, terms, weights, qd, qdd, include=None):
    """tau_i = sum_a a * poly_{i,a}(q), with optional filtering of acceleration-function kinds."""
    keys, factors = _acceleration_factor(model, qd, qdd)
    grouped = [defaultdict(dict) for _ in range(model.n_dof)]
    for i in range(model.n_dof):
        for f, w in weights[i].items():
            if include is not None and keys[f][0] not in include:
                continue
            grouped[i][(keys[f], f)] = w
    taus = []
    for i in range(model.n_dof):
        by_acceleration = defaultdict(dict)
        factor_of = {}
        for (key, f), w in grouped[i].items():
            by_acceleration[key][tuple(terms.digits[f])] = w
            factor_of[key] = factors[f]
        total = 0
        for key in sorted(by_acceleration, key=str):
            total = total + factor_of[key] * terms.polynomial(by_acceleration[key])
        taus.append(total)
    return ca.vertcat(*taus)


def _regressor_sum(model: PSDMModel, y: list, rows: np.ndarray) -> ca.SX:
    """Y[i, k] = sum_f y_f P[f, k, i] over the selected functions, skipping zero entries of P."""
    out = ca.SX.zeros(model.n_dof, model.n_base)
    for i in range(model.n_dof):
        functions, columns = np.nonzero(model.reduction[:, :, i] * rows[:, None])
        entries = defaultdict(lambda: 0)
        for f, k in zip(functions, columns):
            entries[int(k)] = entries[int(k)] + float(model.reduction[f, k, i]) * y[int(f)]
        for k, value in entries.items():
            out[i, k] = value
    return out


def build_functions(model: PSDMModel, theta=None) -> DynamicsFunctions:
    """Build the CasADi functions of a PSDM model.

    Parameters
    ----------
    model : PSDMModel
    theta : array, shape (n_base,), optional
        Numeric base parameters to compile in; the functions then have no ``theta`` input.

    Returns
    -------
    DynamicsFunctions

    Raises
    ------
    ParameterError
        When the model has no monomial table (derived in the recursive form, e.g. beyond 8 joints).

    Examples
    --------
    >>> fns = build_functions(model)                          # doctest: +SKIP
    >>> tau = fns.inverse_dynamics(q, qd, qdd, theta)         # DM, or SX/MX for derivatives
    """
    if not model.has_monomials:
        raise ParameterError(
            f"build_functions needs the model's monomial table (the sum form); model {model.robot_name!r} has "
            f"{model.n_dof} joints and was derived without one (the recursive form). Use "
            "build_recursive_functions(model, robot) (or --form recursive)."
        )
    n, l = model.n_dof, model.n_base
    q, qd, qdd, tau_in = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    if theta is None:
        theta_sym = ca.SX.sym("theta", l)
        theta_values, theta_inputs, theta_names = [theta_sym[k] for k in range(l)], [theta_sym], ["theta"]
        baked = None
    else:
        baked = baked_theta(theta, l)
        theta_values, theta_inputs, theta_names = list(baked), [], []

    terms = _Terms(model, q)
    keys, factors = _acceleration_factor(model, qd, qdd)

    # Regressor: every function once (shared prefix products), then sparse sums over P.
    y = []
    for f in range(model.n_functions):
        trig = terms.product(tuple(terms.digits[f]))
        y.append(factors[f] if trig is None else factors[f] * trig)
    regressor = _regressor_sum(model, y, np.ones(model.n_functions, dtype=bool))
    gravity_regressor = _regressor_sum(model, y, model.gravity_functions)

    weights = _weights(model, theta_values)
    tau = _torques(model, terms, weights, qd, qdd)
    gravity = _torques(model, terms, weights, qd, qdd, include={"g"})
    bias = _torques(model, terms, weights, qd, qdd, include={"g", "qd2", "qdqd"})
    # Mass matrix column k: the qdd_k terms with qdd = e_k; fill the lower triangle, mirror it.
    columns = [
        ca.substitute(_torques(model, terms, weights, qd, qdd, include={"qdd"}), qdd, ca.DM(np.eye(n)[k]))
        for k in range(n)
    ]
    return assemble_functions(
        (q, qd, qdd, tau_in),
        theta_inputs,
        theta_names,
        regressor=regressor,
        gravity_regressor=gravity_regressor,
        tau=tau,
        bias=bias,
        gravity=gravity,
        mass_columns=columns,
        theta=baked,
    )
