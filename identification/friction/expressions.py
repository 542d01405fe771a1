"""The LuGre model of one joint as CasADi expressions and Functions (paper eqs. 12, 14 and the step).

The symbolic twin of :mod:`identification.friction.simulation`, for NLPs and MPC: eq. 12 (``zdot``),
eq. 14 (torque) and the exponential-integrator step of :mod:`identification.friction.lugre_step`,
with the seven parameters symbolic in :data:`identification.friction.models.LUGRE_PARAMETER_NAMES`
order. :func:`build_lugre_expressions` returns them as named Functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from identification.friction.lugre_step import phi_function_expressions
from psdm_casadi.errors import ParameterError

__all__ = [
    "LuGreExpressions",
    "build_lugre_expressions",
    "lugre_zdot_expression",
    "lugre_torque_expression",
    "lugre_step_expression",
]


@dataclass(frozen=True)
class LuGreExpressions:
    """CasADi Functions of the LuGre model of one joint, for NLPs and MPC.

    Attributes
    ----------
    zdot : casadi.Function
        ``(z, qd, p) -> zdot`` [rad/s], eq. 12; ``p`` is the (7,) parameter vector.
    torque : casadi.Function
        ``(z, qd, p) -> tau`` [N m], eq. 14.
    step : casadi.Function
        ``(s, qd_start, qd_end, h, p) -> s_next``: one exponential-integrator step of the bristle
        force ``s = sigma0 z`` [N m] (:mod:`identification.friction.lugre_step`); ``qd_start``
        and ``qd_end`` of one sign.
    """

    zdot: ca.Function
    torque: ca.Function
    step: ca.Function


def build_lugre_expressions(symbol=ca.SX):
    """Build the CasADi LuGre Functions (eq. 12, eq. 14 and the discrete step), parameters symbolic.

    Parameters
    ----------
    symbol : {casadi.SX, casadi.MX}
        Symbol class of the Functions' bodies.

    Returns
    -------
    LuGreExpressions

    Examples
    --------
    >>> f = build_lugre_expressions()
    >>> p = [1.0, 1.5, 0.01, 0.5, 1.0, 1e5, 10.0]
    >>> round(float(f.torque(1e-5, 0.2, p)), 6)   # steady sliding: z = g/sigma0
    1.1
    """
    if symbol not in (ca.SX, ca.MX):
        raise ParameterError(
            f"build_lugre_expressions.symbol must be casadi.SX or casadi.MX; got {symbol!r}. Pass casadi.SX."
        )
    z = symbol.sym("z")
    s = symbol.sym("s")
    qd = symbol.sym("qd")
    qd0 = symbol.sym("qd_start")
    qd1 = symbol.sym("qd_end")
    h = symbol.sym("h")
    p = symbol.sym("p", 7)
    zdot_expr = lugre_zdot_expression(z, qd, p)
    tau_expr = lugre_torque_expression(z, qd, p)
    s_next = lugre_step_expression(s, qd0, qd1, h, p)
    return LuGreExpressions(
        zdot=ca.Function("zdot", [z, qd, p], [zdot_expr], ["z", "qd", "p"], ["zdot"]),
        torque=ca.Function("torque", [z, qd, p], [tau_expr], ["z", "qd", "p"], ["tau"]),
        step=ca.Function("step", [s, qd0, qd1, h, p], [s_next], ["s", "qd_start", "qd_end", "h", "p"], ["s_next"]),
    )


def _unpack(p):
    return [p[i] for i in range(7)]


def _stribeck_g(qd, fc, fs, vs):
    return fc + (fs - fc) * ca.exp(-((qd / vs) ** 2))


def lugre_zdot_expression(z, qd, p):
    """Symbolic eq. 12: ``zdot = qd - sigma0 |qd| z / g(qd)``; ``p`` in ``LUGRE_PARAMETER_NAMES`` order."""
    fc, fs, vs, _, _, sigma0, _ = _unpack(p)
    return qd - sigma0 * ca.fabs(qd) * z / _stribeck_g(qd, fc, fs, vs)


def lugre_torque_expression(z, qd, p):
    """Symbolic eq. 14: ``sigma0 z + sigma1 zdot + fv |qd|**dv sign(qd)``."""
    _, _, _, fv, dv, sigma0, sigma1 = _unpack(p)
    viscous = ca.if_else(qd == 0, 0.0, fv * ca.exp(dv * ca.log(ca.fabs(qd) + (qd == 0))) * ca.sign(qd))
    return sigma0 * z + sigma1 * lugre_zdot_expression(z, qd, p) + viscous


def lugre_step_expression(s, qd_start, qd_end, h, p, sign=None):
    """Symbolic exponential-integrator step of the bristle force ``s = sigma0 z`` (see ``lugre_step``).

    ``qd_start`` and ``qd_end`` must not differ in sign (split the step at the zero crossing);
    ``sign`` defaults to ``sign(qd_start + qd_end)``.
    """
    fc, fs, vs, _, _, sigma0, _ = _unpack(p)
    if sign is None:
        sign = ca.sign(qd_start + qd_end)
    g_a = _stribeck_g(qd_start, fc, fs, vs)
    g_b = _stribeck_g(qd_end, fc, fs, vs)
    x = 0.5 * h * sigma0 * (ca.fabs(qd_start) / g_a + ca.fabs(qd_end) / g_b)
    phi1, phi2 = phi_function_expressions(x)
    y_a = sign * g_a
    y_b = sign * g_b
    return ca.exp(-x) * s + x * (phi1 * y_a + phi2 * (y_b - y_a))
