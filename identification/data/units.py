"""Units of a controller's log: the factors that turn its stated units into the recording's SI units.

A log states positions in degrees, torques in mN m or time in milliseconds as often as in SI. The user says
so once, beside the column group (``--columns t=Time:ms,q=AxisPos_A:deg,tau=MotorTorque_A:mNm``), and every
command reads the file in SI; a unit that does not belong to the signal is refused with the ones that do. A CSV
header that states its units (``t [s]``, ``q1 [deg]``, ``tau1 (mNm)``) is read the same way (:func:`header_unit`).
"""

from __future__ import annotations

import math
import re

import numpy as np

from psdm_casadi.errors import ParameterError, RecordingError

__all__ = ["PERCENT", "UNITS", "header_unit", "si_factor", "to_si"]

#: A motor current in per cent of its motor's rated current (``--columns i=CurrAct_A:%``): kept as logged here (factor
#: 1) and turned into amperes by the robot's reader (``robot_recordings``) with the robot file's ``[transmission]
#: rated_current``, which only it knows. Never a header's unit: a header ``i1 [%]`` is refused, naming --columns.
PERCENT = "%"

_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3, "m": 1.0, "mm": 1e-3}
_TORQUE = {"Nm": 1.0, "mNm": 1e-3, "kNm": 1e3, "N": 1.0}
#: signal -> {unit: factor to SI}; positions in rad (m for prismatic joints), torques in N m, currents in A.
UNITS = {
    "t": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9},
    "q": _ANGLE,
    "qd": {f"{u}/s": f for u, f in _ANGLE.items()},
    "qdd": {f"{u}/s2": f for u, f in _ANGLE.items()},
    "tau": _TORQUE,
    "i": {"A": 1.0, "mA": 1e-3},
}


_HEADER_UNIT = re.compile(r"^(.*?\S)\s*[\[(]\s*([^\])]*?)\s*[\])]$")
#: Every unit a header may state, by its factor to SI (a unit names its dimension, whatever the column).
_ANY_UNIT = {
    **{u: f for table in UNITS.values() for u, f in table.items()},
    "°": math.pi / 180.0, "degree": math.pi / 180.0, "degrees": math.pi / 180.0, "radian": 1.0, "radians": 1.0,
    "sec": 1.0, "msec": 1e-3, "rad/s^2": 1.0, "deg/s^2": math.pi / 180.0, "Nm": 1.0,
}  # fmt: skip


def header_unit(source: str, name: str) -> tuple:
    """``(name, factor to SI)`` of a header field that may state its unit: ``q1 [deg]`` -> ``("q1", pi/180)``,
    ``t (ms)`` -> ``("t", 1e-3)``, ``q1`` -> ``("q1", 1.0)``.

    Raises
    ------
    RecordingError
        For a bracketed suffix that is not a unit (naming the column and the units there are).
    """
    match = _HEADER_UNIT.match(name)
    if match is None:
        return name, 1.0
    unit = match.group(2).replace(" ", "").replace("·", "").replace("*", "")
    if unit not in _ANY_UNIT:
        raise RecordingError(
            f"{source}: column {name!r} states {match.group(2)!r}, which is not a unit psdm reads (s, ms, rad, deg, "
            f"m, mm, N m, mN m, kN m, A, mA, rad/s, ...). Write the unit in SI or one of those, or rename the column"
            + (
                " (currents in % of the rated current: --columns i=PREFIX:% with rated_current in the robot file's "
                "[transmission])."
                if unit == PERCENT
                else "."
            )
        )
    return match.group(1), _ANY_UNIT[unit]


def si_factor(signal: str, unit: str) -> float:
    """The factor that turns ``signal`` in ``unit`` into SI (``deg`` -> pi/180); refused with the units there are.
    A current in per cent of the rated current (:data:`PERCENT`) is 1: the robot's reader scales it."""
    known = UNITS.get(signal, {})
    compact = unit.replace(" ", "").replace("·", "").replace("*", "")
    if signal == "i" and compact == PERCENT:
        return 1.0
    if compact not in known:
        rated = ", % (of each motor's rated current: rated_current in the robot file's [transmission])"
        raise ParameterError(
            f"--columns {signal}=...:{unit}: {unit!r} is not a unit of {signal}; use one of {', '.join(known)}"
            f"{rated if signal == 'i' else ''} (e.g. --columns q=Position:deg,tau=Torque:mNm,t=Time:ms)."
        )
    return known[compact]


def to_si(names: tuple, data: np.ndarray, units: tuple) -> np.ndarray:
    """``data`` (columns ``names`` in standard names: t, q1.., tau1..) with each ``(signal, unit)`` of ``units``
    scaled to SI; a new read-only array (the same array when every unit is SI)."""
    scale = np.ones(len(names))
    for signal, unit in units:
        factor = si_factor(signal, unit)
        for k, name in enumerate(names):
            if name == signal or (name.startswith(signal) and name[len(signal) :].isdigit()):
                scale[k] = factor
    if np.all(scale == 1.0):
        return data
    out = np.asarray(data) * scale
    out.setflags(write=False)
    return out
