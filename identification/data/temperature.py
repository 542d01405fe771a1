"""The joints' temperature a recording file logs beside its signals: what tells a warming gearbox's friction apart.

Controllers log each actuator's temperature (the Kinova Gen3's ``Temp1..Temp7``, a KUKA's ``temperature_1..``, a UR's
``joint_temperatures_0..``). The identification does not fit them; ``calibration.drift_choice`` compares the
recordings' mean temperatures per joint with their friction, so a drift between recordings that the temperature
explains is read along it. Only CSV text is searched (other formats give none); a file whose temperature columns
cannot be read gives none, as the recording itself is read and checked by ``io``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

__all__ = ["TEMPERATURE_COLUMN", "logged_temperatures"]

#: A per-joint temperature column: ``Temp3``, ``temperature_3``, ``joint_temperatures_2``, ``T_motor3`` is not one.
TEMPERATURE_COLUMN = re.compile(r"^(?:joint_?)?temp(?:erature)?s?[ _]?(\d+)$", re.IGNORECASE)


def _header(path: Path) -> tuple:
    """(header line number, its column names, the delimiter) of a CSV file's first non-comment line."""
    with open(path, encoding="utf-8-sig", errors="replace") as handle:
        for number, line in enumerate(handle):
            text = line.split("#", 1)[0].strip()
            if text:
                delimiter = next((d for d in (",", ";", "\t") if d in text), None)
                return number, tuple(name.strip() for name in text.split(delimiter)), delimiter
    return 0, (), None


def logged_temperatures(path, n_dof: int) -> np.ndarray | None:
    """Each joint's mean temperature over a CSV recording that logs one temperature column per joint (numbered from 0
    or 1, in the joints' order), shape (n_dof,); None for another format or without such columns."""
    path = Path(path)
    if path.suffix.lower() != ".csv" or not path.is_file():
        return None
    try:
        number, names, delimiter = _header(path)
    except OSError:
        return None
    found = {int(m.group(1)): k for k, name in enumerate(names) if (m := TEMPERATURE_COLUMN.match(name))}
    first = 0 if 0 in found else 1
    columns = [found.get(first + j) for j in range(n_dof)]
    if any(c is None for c in columns):
        return None
    try:
        values = np.loadtxt(path, delimiter=delimiter, skiprows=number + 1, usecols=columns, comments="#", ndmin=2)
    except (ValueError, OSError):
        return None
    with np.errstate(invalid="ignore"):
        mean = np.nanmean(values, axis=0) if values.size else np.full(n_dof, np.nan)
    return mean if np.all(np.isfinite(mean)) else None
