"""The joints' temperature a recording logs beside its signals: what tells a warming gearbox's friction apart.

Controllers log each actuator's temperature (the Kinova Gen3's ``Temp1..Temp7``, a KUKA's ``temperature_1..``, a UR's
``joint_temperatures_0..``). The readers keep such columns with the recording (``Recording.temperature``, NaN where a
slow logger wrote no reading; ``io`` names them ``temp1..tempn``); the identification does not fit them.
``calibration.drift_choice`` compares the recordings' mean temperatures per joint with their friction, so a drift
between recordings that the temperature explains is read along it.
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["TEMPERATURE_COLUMN", "TEMPERATURE_PREFIX", "is_temperature_column", "logged_temperatures",
           "temperature_joints", "temperatures_at"]  # fmt: skip

#: A per-joint temperature column: ``Temp3``, ``temperature_3``, ``joint_temperatures_2``, ``T_motor3`` is not one.
TEMPERATURE_COLUMN = re.compile(r"^(?:joint_?)?temp(?:erature)?s?[ _]?(\d+)$", re.IGNORECASE)
#: The standard name of joint j's temperature column: ``temp1..tempn`` (what ``save_recording`` writes).
TEMPERATURE_PREFIX = "temp"


def is_temperature_column(name: str) -> bool:
    """Whether a column holds a joint's temperature (``TEMPERATURE_COLUMN``): its NaN are readings not taken."""
    return TEMPERATURE_COLUMN.match(name) is not None


def temperature_joints(names) -> dict:
    """``{column name: joint number (1-based)}`` of the temperature columns among ``names``; a group numbered from 0
    (``joint_temperatures_0..5``) is joints 1..n in that order."""
    found = {name: int(m.group(1)) for name in names if (m := TEMPERATURE_COLUMN.match(name))}
    shift = 1 if 0 in found.values() else 0
    return {name: number + shift for name, number in found.items()}


def logged_temperatures(recording) -> np.ndarray | None:
    """Each joint's mean logged temperature [°C] over a recording, shape (n_dof,) (its readings' mean, NaN between
    them left out); None when it logs none, or not for every joint."""
    temperature = getattr(recording, "temperature", None)
    if temperature is None or temperature.shape[0] == 0:
        return None
    logged = ~np.isnan(temperature)
    if not np.all(logged.any(axis=0)):
        return None
    return np.nansum(temperature, axis=0) / logged.sum(axis=0)


def temperatures_at(recording, t) -> np.ndarray | None:
    """Each joint's logged temperature [°C] at the times ``t`` [s], shape (len(t), n_dof): its readings interpolated
    linearly in time (held beyond the first and last), NaN for a joint without one; None when the recording logs
    none. A prepared recording (filtered, resampled, trimmed) is so given the temperatures of its raw one."""
    temperature = getattr(recording, "temperature", None)
    if temperature is None:
        return None
    t = np.asarray(t, dtype=float)
    out = np.full((t.size, temperature.shape[1]), np.nan)
    for j in range(temperature.shape[1]):
        read = ~np.isnan(temperature[:, j])
        if read.any():
            out[:, j] = np.interp(t, recording.t[read], temperature[read, j])
    return out
