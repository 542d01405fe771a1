"""Derivatives of the dynamics for export (DynamicsFunctions -> derivative Functions -> C, beside export_c).

Gradient-based MPC and trajectory optimisation need d(tau)/d(q, qd, qdd) and d(qdd)/d(q, qd, tau) at
every step; identification with noisy states needs the regressor's. The derivative Functions built here
take the same inputs as the dynamics they differentiate (a ``theta`` input stays, so ``export_c`` bakes
it in like the rest) and return the value first, then one Jacobian per input:

- ``inverse_dynamics_derivatives(q, qd, qdd) -> tau, dtau_dq, dtau_dqd, dtau_dqdd`` (the last is the
  mass matrix),
- ``forward_dynamics_derivatives(q, qd, tau) -> qdd, dqdd_dq, dqdd_dqd, dqdd_dtau``,
- ``regressor_derivatives(q, qd, qdd) -> dY_dq, dY_dqd, dY_dqdd`` (Jacobians of ``vec(Y)``, column-major).

Forward dynamics can be differentiated two ways. ``"direct"`` lets CasADi differentiate through the
LDL^T solve. ``"structured"`` uses qdd = D^-1 (tau - h): d(qdd)/d(tau) = D^-1 and
d(qdd)/d(q, qd) = -D^-1 d(ID)/d(q, qd) evaluated at qdd = FD(q, qd, tau), i.e. the inverse dynamics'
partial derivatives (cheap on the recursive form) followed by solves with one LDL^T factorisation of
D = d(ID)/d(qdd), which also gives qdd. ``"auto"`` builds both and keeps the one with fewer arithmetic
operations (the structured one only if it reproduces the given forward dynamics at a random state). Every
Jacobian is taken in CasADi's forward and in its reverse mode, and the smaller graph is kept.

Each of the first two also has a *sweep* Function with one more input, ``seed`` (n_dof), returning the value
and seed^T times each Jacobian: the reverse sweep of one row when the seed is a unit vector. For the forward
dynamics, seed^T d(qdd)/d(q, qd) = -(D^-1 seed)^T d(ID)/d(q, qd), one sweep of the inverse dynamics with the
seed D^-1 seed. ``export_derivatives`` writes the sweeps as vector code with the rows in SIMD lanes
(``codegen.lane_derivatives``): the values they read are computed once, and one vector instruction does the
work of several rows' sweeps. CasADi's scalar code stays in the file as the fallback (``-DPSDM_NO_LANES``).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from codegen.export import CExport, export_c
from codegen.lane_derivatives import lane_jacobian
from codegen.operation_count import count_operations
from psdm_casadi.errors import ParameterError
from psdm_casadi.forward import ldl_solve

FORMS = ("auto", "structured", "direct")
AD_WEIGHTS = (0.0, 1.0)  # CasADi's forward and reverse mode
THETA = "theta"
SWEEP_SUFFIX = "_sweep"


@dataclass(frozen=True)
class DerivativeFunctions:
    """The derivative Functions of one DynamicsFunctions (None where the source function is absent).

    Attributes
    ----------
    inverse_dynamics_derivatives, forward_dynamics_derivatives, regressor_derivatives : casadi.Function or None
    forward_form : str or None
        The form of the forward-dynamics derivatives that was kept (``"structured"`` or ``"direct"``).
    sweeps : tuple of casadi.Function
        ``<name>_sweep(..., seed) -> value, seed^T J...`` of the inverse and forward dynamics derivatives
        (the forward one only when it reproduces the given forward dynamics), for the vectorised export.
    """

    inverse_dynamics_derivatives: ca.Function | None
    forward_dynamics_derivatives: ca.Function | None
    regressor_derivatives: ca.Function | None
    forward_form: str | None = None
    sweeps: tuple = ()

    def all(self) -> list:
        """The Functions that were built, in export order."""
        found = (self.inverse_dynamics_derivatives, self.forward_dynamics_derivatives, self.regressor_derivatives)
        return [f for f in found if f is not None]


def _source(functions, name):
    function = getattr(functions, name, None)
    if function is None:
        return None
    if not isinstance(function, ca.Function):
        raise ParameterError(
            f"build_derivative_functions functions.{name} must be a casadi.Function; got {type(function).__name__}. "
            "Pass the DynamicsFunctions of build_recursive_functions or build_functions."
        )
    return function if function.is_a("SXFunction") else function.expand()


def _extra_inputs(function, first: int):
    """Symbols and names of the inputs after the first ``first`` (theta, when present)."""
    inputs = function.sx_in()
    return list(inputs[first:]), list(function.name_in()[first:])


def _function(name, inputs, input_names, outputs, output_names):
    """A Function with dense outputs (fixed column-major layouts, like the peers' matrices)."""
    dense = [ca.densify(o) for o in outputs]
    return ca.Function(name, inputs, dense, input_names, output_names, {"cse": True})


def _jacobian_blocks(inputs, output, weight):
    """d(output)/d(input) for every input, by CasADi's forward (weight 0) or reverse (weight 1) mode."""
    function = ca.Function("blocks", inputs, [output], {"ad_weight": weight, "ad_weight_sp": weight})
    return function.jacobian().call([*inputs, output])


def _fewest_operations(build):
    """The Function ``build(weight)`` with fewer operations of forward and reverse mode (reverse reuses the
    values of the forward pass, which the outputs hold anyway, and is usually smaller)."""
    return min((build(weight) for weight in AD_WEIGHTS), key=lambda f: count_operations(f).n_operations)


def _inverse_derivatives(inverse):
    """tau and its Jacobians in q, qd, qdd (the last is the mass matrix)."""
    q, qd, qdd = inverse.sx_in()[:3]
    extra, extra_names = _extra_inputs(inverse, 3)
    tau = inverse.call([q, qd, qdd, *extra])[0]

    def build(weight):
        blocks = _jacobian_blocks([q, qd, qdd, *extra], tau, weight)
        return _function(
            "inverse_dynamics_derivatives",
            [q, qd, qdd, *extra],
            ["q", "qd", "qdd", *extra_names],
            [tau, *blocks[:3]],
            ["tau", "dtau_dq", "dtau_dqd", "dtau_dqdd"],
        )

    return _fewest_operations(build)


def _inverse_sweep(inverse):
    """(q, qd, qdd[, theta], seed) -> tau, seed^T d(tau)/d(q, qd, qdd): one reverse sweep."""
    q, qd, qdd = inverse.sx_in()[:3]
    extra, extra_names = _extra_inputs(inverse, 3)
    seed = ca.SX.sym("seed", q.numel())
    tau = inverse.call([q, qd, qdd, *extra])[0]
    row = ca.vertsplit(ca.jtimes(tau, ca.vertcat(q, qd, qdd), seed, True), q.numel())
    return _function(
        "inverse_dynamics_derivatives" + SWEEP_SUFFIX,
        [q, qd, qdd, *extra, seed],
        ["q", "qd", "qdd", *extra_names, "seed"],
        [tau, *row],
        ["tau", "dtau_dq", "dtau_dqd", "dtau_dqdd"],
    )


def _forward_sweep(forward, inverse):
    """(q, qd, tau[, theta], seed) -> qdd, seed^T d(qdd)/d(q, qd, tau), from one LDL^T of D = d(ID)/d(qdd):
    with u = D^-1 seed, seed^T d(qdd)/d(q, qd) = -u^T d(ID)/d(q, qd) at qdd and seed^T d(qdd)/d(tau) = u^T."""
    q, qd, tau = forward.sx_in()[:3]
    extra, extra_names = _extra_inputs(forward, 3)
    n = q.numel()
    seed, acceleration = ca.SX.sym("seed", n), ca.SX.sym("acceleration", n)
    tau_of_acceleration = inverse.call([q, qd, acceleration, *extra])[0]
    mass = ca.jacobian(tau_of_acceleration, acceleration)  # the inverse dynamics are linear in the acceleration
    qdd = ldl_solve(mass, tau - inverse.call([q, qd, ca.SX.zeros(n), *extra])[0])
    solved = ldl_solve(mass, seed)
    row = ca.jtimes(tau_of_acceleration, ca.vertcat(q, qd), solved, True)
    row = ca.vertsplit(-ca.substitute(row, acceleration, qdd), n)
    return _function(
        "forward_dynamics_derivatives" + SWEEP_SUFFIX,
        [q, qd, tau, *extra, seed],
        ["q", "qd", "tau", *extra_names, "seed"],
        [qdd, *row, solved],
        ["qdd", "dqdd_dq", "dqdd_dqd", "dqdd_dtau"],
    )


def _solve_columns(matrix, rhs):
    """matrix^-1 rhs column by column with the LDL^T of psdm_casadi.forward (CSE shares the factorisation)."""
    return ca.horzcat(*[ldl_solve(matrix, rhs[:, k]) for k in range(rhs.size2())])


def _forward_structured(forward, inverse):
    """One LDL^T of D = d(ID)/d(qdd) gives qdd = D^-1 (tau - ID(q, qd, 0)), D^-1 and -D^-1 d(ID)/d(q, qd) at qdd."""
    q, qd, tau = forward.sx_in()[:3]
    extra, extra_names = _extra_inputs(forward, 3)
    n = q.numel()
    acceleration = ca.SX.sym("acceleration", n)
    tau_of_acceleration = inverse.call([q, qd, acceleration, *extra])[0]
    bias = inverse.call([q, qd, ca.SX.zeros(n), *extra])[0]

    def build(weight):
        d_q, d_qd, mass = _jacobian_blocks([q, qd, acceleration, *extra], tau_of_acceleration, weight)[:3]
        qdd = ldl_solve(mass, tau - bias)  # the mass matrix does not depend on the acceleration
        d_state = ca.substitute(ca.horzcat(d_q, d_qd), acceleration, qdd)
        solved = _solve_columns(mass, ca.horzcat(-d_state, ca.SX.eye(n)))
        return _function(
            "forward_dynamics_derivatives",
            [q, qd, tau, *extra],
            ["q", "qd", "tau", *extra_names],
            [qdd, solved[:, :n], solved[:, n : 2 * n], solved[:, 2 * n :]],
            ["qdd", "dqdd_dq", "dqdd_dqd", "dqdd_dtau"],
        )

    return _fewest_operations(build)


def _forward_direct(forward):
    """qdd and its Jacobians by CasADi's differentiation through the solve."""
    q, qd, tau = forward.sx_in()[:3]
    extra, extra_names = _extra_inputs(forward, 3)
    qdd = forward.call([q, qd, tau, *extra])[0]

    def build(weight):
        blocks = _jacobian_blocks([q, qd, tau, *extra], qdd, weight)
        return _function(
            "forward_dynamics_derivatives",
            [q, qd, tau, *extra],
            ["q", "qd", "tau", *extra_names],
            [qdd, *blocks[:3]],
            ["qdd", "dqdd_dq", "dqdd_dqd", "dqdd_dtau"],
        )

    return _fewest_operations(build)


def _inverts(forward, structured, rng_seed=0) -> bool:
    """Whether the qdd of a form built from the inverse dynamics (structured, or the sweep: its seed is set to
    zero) equals the given forward dynamics at a random state (they need not invert each other: a model may add
    terms to one only)."""
    rng = np.random.default_rng(rng_seed)
    args = [rng.uniform(-1.0, 1.0, forward.size_in(i)) for i in range(forward.n_in())]
    want = np.array(forward.call(args)[0]).ravel()
    seeds = [np.zeros(structured.size_in(i)) for i in range(len(args), structured.n_in())]
    got = np.array(structured.call(args + seeds)[0]).ravel()
    return bool(np.allclose(got, want, rtol=1e-8, atol=1e-8 * max(1.0, np.abs(want).max())))


def _regressor_derivatives(regressor):
    """Jacobians of vec(Y) (column-major) in q, qd, qdd."""
    q, qd, qdd = regressor.sx_in()[:3]
    y = ca.vec(ca.densify(regressor.call([q, qd, qdd])[0]))  # column-major, like the exported Y
    outputs = [ca.jacobian(y, q), ca.jacobian(y, qd), ca.jacobian(y, qdd)]
    return _function("regressor_derivatives", [q, qd, qdd], ["q", "qd", "qdd"], outputs, ["dY_dq", "dY_dqd", "dY_dqdd"])


def build_derivative_functions(functions, *, form: str = "auto", regressor: bool = True) -> DerivativeFunctions:
    """Build the derivative Functions of a DynamicsFunctions(-like) object.

    Parameters
    ----------
    functions : DynamicsFunctions-like
        Needs ``inverse_dynamics`` (inputs q, qd, qdd[, theta]); ``forward_dynamics`` (q, qd, tau[, theta])
        and ``regressor`` (q, qd, qdd) are differentiated when present. The recursive form
        (``build_recursive_functions``) gives the smallest graphs.
    form : {"auto", "structured", "direct"}
        How the forward dynamics are differentiated (see the module docstring); ``"auto"`` keeps the form with
        fewer arithmetic operations.
    regressor : bool
        Also differentiate the regressor.

    Returns
    -------
    DerivativeFunctions

    Raises
    ------
    ParameterError
        For an unknown ``form`` or when ``functions`` has no inverse dynamics.
    """
    if form not in FORMS:
        raise ParameterError(f"build_derivative_functions form must be one of {FORMS}; got {form!r}.")
    inverse = _source(functions, "inverse_dynamics")
    if inverse is None:
        raise ParameterError(
            "build_derivative_functions functions must have an inverse_dynamics Function; got "
            f"{type(functions).__name__} without one. Pass build_recursive_functions(model, robot)."
        )
    forward = _source(functions, "forward_dynamics")
    forward_derivatives, forward_form, sweeps = None, None, [_inverse_sweep(inverse)]
    if forward is not None:
        sweep = _forward_sweep(forward, inverse)
        if _inverts(forward, sweep):
            sweeps.append(sweep)
        candidates = {}
        if form in ("auto", "structured"):
            candidates["structured"] = _forward_structured(forward, inverse)
            if form == "auto" and not _inverts(forward, candidates["structured"]):
                del candidates["structured"]
        if form in ("auto", "direct"):
            candidates["direct"] = _forward_direct(forward)
        forward_form = min(candidates, key=lambda k: count_operations(candidates[k]).n_operations)
        forward_derivatives = candidates[forward_form]
    source_regressor = _source(functions, "regressor") if regressor else None
    return DerivativeFunctions(
        inverse_dynamics_derivatives=_inverse_derivatives(inverse),
        forward_dynamics_derivatives=forward_derivatives,
        regressor_derivatives=None if source_regressor is None else _regressor_derivatives(source_regressor),
        forward_form=forward_form,
        sweeps=tuple(sweeps),
    )


def lane_kernels(derivatives: DerivativeFunctions, theta=None, *, prefix: str = "psdm_", fast_trig: bool = True):
    """The vector code of every sweep of ``derivatives``, for ``export_c(kernels=...)``.

    Parameters
    ----------
    derivatives : DerivativeFunctions
    theta : array, optional
        Base parameters baked into the exported functions; sweeps with a theta input get no vector code
        without it (their runtime-theta flavour keeps CasADi's scalar code).
    prefix : str
        Prefix of the exported C symbols (``export_c``'s).
    fast_trig : bool
        As for ``export_c``.

    Returns
    -------
    list of LaneJacobian
        One per sweep the lane writer translates, named ``<prefix><derivative function>``.
    """
    kernels = []
    for sweep in derivatives.sweeps:
        inputs, names = sweep.sx_in(), sweep.name_in()
        if THETA in names:
            index = names.index(THETA)
            if theta is None or np.size(theta) != sweep.numel_in(index):
                continue  # no baked flavour, or a theta export_c refuses with its own message
            args = [ca.DM(np.asarray(theta, dtype=float).reshape(sweep.size_in(index), order="F")) if i == index else x
                    for i, x in enumerate(inputs)]  # fmt: skip
            sweep = ca.Function(sweep.name(), inputs[:index] + inputs[index + 1 :], sweep.call(args), {"cse": True})
        name = prefix + sweep.name().removesuffix(SWEEP_SUFFIX)
        kernel = lane_jacobian(sweep, name, sweep.n_in() - 1, sweep.size_in(0)[0], fast_trig=fast_trig)
        if kernel is not None:
            kernels.append(kernel)
    return kernels


def export_derivatives(functions, folder, *, form: str = "auto", regressor: bool = True, **options) -> CExport:
    """Export the dynamics and their derivatives into one C folder (``export_c`` plus the derivative Functions).

    With theta baked in, the inverse and forward dynamics derivatives run their rows' reverse sweeps in vector
    lanes (``lane_kernels``); ``-DPSDM_NO_LANES`` compiles CasADi's scalar code instead.

    Parameters
    ----------
    functions : DynamicsFunctions-like
        As for ``export_c``; its ``inverse_dynamics, forward_dynamics, regressor, mass_matrix`` are exported
        too, followed by ``<prefix>inverse_dynamics_derivatives``, ``<prefix>forward_dynamics_derivatives`` and
        ``<prefix>regressor_derivatives`` (with ``_theta`` runtime flavours as ``export_c`` writes them).
    folder : str or Path
    form, regressor
        As for ``build_derivative_functions``.
    **options
        Passed to ``export_c`` (``theta``, ``runtime_theta``, ``library``, ``prefix``, ``overwrite``, ...).

    Returns
    -------
    CExport
    """
    from codegen.export import EXPORTED_ATTRIBUTES

    derivatives = build_derivative_functions(functions, form=form, regressor=regressor)
    dynamics = [getattr(functions, a) for a in EXPORTED_ATTRIBUTES if getattr(functions, a, None) is not None]
    options.setdefault("regressor_structure", getattr(functions, "regressor_structure", None))
    kernels = lane_kernels(
        derivatives,
        options.get("theta"),
        prefix=options.get("prefix", "psdm_"),
        fast_trig=options.get("fast_trig", True),
    )
    return export_c([*dynamics, *derivatives.all()], folder, kernels=kernels, **options)
