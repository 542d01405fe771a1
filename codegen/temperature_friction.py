"""The exported torque at the joints' temperature, for a model file whose friction has a law in temperature.

A model file's ``drive.temperature`` block (``identification.calibration.temperature_friction``) gives per joint the
reference temperature, the reach of the line and the slopes [per °C] of its friction coefficients. The exported
``inverse_dynamics`` stays the torque at the reference temperatures (its signature unchanged); this adds
``inverse_dynamics_at_temperature(q, qd, qdd, temperature)``: the same torque plus, per joint with a law,

    sum_k slope_k column_k(qd_j) (clip(temperature_j, low_j, high_j) - reference_j)

(``column_k`` the friction term's column, ``trajectory_data.friction_term``), exactly as
``CalibratedModel.predict(..., temperature=...)`` computes it. A NaN temperature (not measured) gives the reference's
friction, as the Python model reads it. CasADi folds ``x == x`` to true, so NaN is told apart by the two clips: C's
``fmin``/``fmax`` return the number beside a NaN, so ``fmax(fmin(x, high), low)`` is ``high`` and
``fmin(fmax(x, low), high)`` is ``low`` for a NaN, and both are ``clip(x)`` for a number. A model without the block gets
no such function.
"""

from __future__ import annotations

import dataclasses

import casadi as ca

from identification.calibration.trajectory_data import friction_term

__all__ = ["add_temperature_friction", "temperature_note"]

#: The exported function's name (``<prefix>inverse_dynamics_at_temperature`` in C).
FUNCTION = "inverse_dynamics_at_temperature"


def _torque(calibrated, laws, qd, temperature, stribeck, exponent):
    """The change of the friction torque (n_dof, 1) at ``temperature`` (module docstring)."""
    widths = calibrated.coulomb_widths
    out = ca.SX.zeros(calibrated.n_dof, 1)
    for law in laws.joints:
        j = law.joint
        low, high = law.reach
        clipped = ca.fmin(ca.fmax(temperature[j], low), high)
        measured = clipped - ca.fmax(ca.fmin(temperature[j], high), low)  # 0 for a number, low - high for NaN
        change = ca.if_else(measured == 0, clipped - law.reference, 0.0)
        vs, dv = None if stribeck is None else float(stribeck[j]), None if exponent is None else float(exponent[j])
        for name, slope in law.slopes.items():
            out[j] += slope * friction_term(name.rstrip("0123456789"), qd[j], widths[j], vs, dv) * change
    return out


def add_temperature_friction(functions, calibrated, stribeck=None, exponent=None):
    """The Functions with ``inverse_dynamics_at_temperature`` (module docstring); unchanged without a law.

    ``stribeck`` and ``exponent`` are the file's Stribeck velocities and viscous exponents per joint
    (``codegen.calibrated.stribeck_velocity`` and ``viscous_exponent``; None where the file has none).
    """
    laws = calibrated.temperature_friction
    if laws is None:
        return functions
    n = functions.n_dof
    q, qd, qdd, temperature = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "temperature"))
    tau = functions.inverse_dynamics(q, qd, qdd) + _torque(calibrated, laws, qd, temperature, stribeck, exponent)
    function = ca.Function(FUNCTION, [q, qd, qdd, temperature], [tau], ["q", "qd", "qdd", "temperature"], ["tau"],
                           {"cse": True})  # fmt: skip
    return dataclasses.replace(functions, inverse_dynamics_at_temperature=function)


def temperature_note(calibrated, prefix: str = "psdm_") -> list:
    """The header lines that document ``<prefix>inverse_dynamics_at_temperature`` and the laws (empty without)."""
    laws = calibrated.temperature_friction
    if laws is None:
        return []
    lines = [f"{prefix}inverse_dynamics_at_temperature(q, qd, qdd, temperature [degC, one per joint]) is "
             f"{prefix}inverse_dynamics with the friction moved along the model file's law in temperature: each "
             "coefficient + slope * (clip(temperature_j, low_j, high_j) - reference_j); a NaN temperature "
             "(not measured) gives the reference's friction. "
             f"{prefix}inverse_dynamics is the torque at the reference temperatures. Laws:"]  # fmt: skip
    for law in laws.joints:
        slopes = ", ".join(f"d{name}/dT = {slope:.17g}" for name, slope in law.slopes.items())
        lines.append(f"  joint {law.joint + 1}: reference {law.reference:.17g} degC, reach "
                     f"[{law.reach[0]:.17g}, {law.reach[1]:.17g}] degC, {slopes}")  # fmt: skip
    return lines
