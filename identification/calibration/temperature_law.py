"""A joint's friction along its temperature: the law that explains a drift between recordings logged warmer or colder.

``friction_drift`` gives each training recording's friction of a joint with its standard deviations;
``data.temperature`` each recording's mean temperature of that joint. Where the recordings' temperatures are spread by
at least ``TEMPERATURE_SPREAD``, each coefficient is fitted as a straight line in temperature (weighted least squares
with the coefficients' variances; with two recordings the line through both). With three or more recordings the line
must explain the recordings (its chi-square at ``friction_drift.ALPHA``), else the temperature does not explain the
drift (wear, another lubricant state) and ``None`` is returned. The friction the model keeps is the line's at the
target temperature (the held-out recordings', else the latest recording's), at most half the training range beyond
it (a line is not extrapolated far) and never below 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.calibration.friction_drift import ALPHA

__all__ = ["TEMPERATURE_SPREAD", "TemperatureLaw", "temperature_law"]

#: [°C] Recordings whose temperatures of a joint lie closer than this cannot tell its friction's law in temperature.
TEMPERATURE_SPREAD = 1.0


@dataclass(frozen=True)
class TemperatureLaw:
    """One joint's friction coefficients ``values`` at ``target`` [°C] from lines of ``slopes`` [per °C] fitted over
    the recordings' ``temperatures``; ``clamped`` when the target was moved into reach of the training range."""

    temperatures: tuple
    slopes: tuple
    target: float
    values: np.ndarray
    clamped: bool

    def to_dict(self, names) -> dict:
        return {
            "temperatures_c": list(self.temperatures),
            "slopes_per_c": dict(zip(names, self.slopes)),
            "at_c": self.target,
            "values": dict(zip(names, self.values.tolist())),
            "clamped": self.clamped,
        }


def temperature_law(values, stds, temperatures, target) -> TemperatureLaw | None:
    """The law of one joint's friction ``values`` (recordings, coefficients) with ``stds`` over the recordings'
    ``temperatures`` [°C], read at ``target`` (module docstring); None where the temperatures are too close or, with
    three or more recordings, the lines do not explain the recordings."""
    t = np.asarray(temperatures, dtype=float)
    if t.size < 2 or not np.all(np.isfinite(t)) or np.ptp(t) < TEMPERATURE_SPREAD:
        return None
    design = np.column_stack([np.ones_like(t), t - t.mean()])
    lines, chi2 = [], 0.0
    for k in range(values.shape[1]):
        w = 1.0 / np.maximum(stds[:, k], 1e-12 * max(float(np.max(np.abs(values[:, k]))), 1e-300)) ** 2
        line = np.linalg.lstsq(design * np.sqrt(w)[:, None], values[:, k] * np.sqrt(w), rcond=None)[0]
        chi2 += float(np.sum(w * (values[:, k] - design @ line) ** 2))
        lines.append(line)
    dof = values.shape[1] * (t.size - 2)
    if dof > 0 and stats.chi2.sf(chi2, dof) < ALPHA:
        return None
    half = 0.5 * float(np.ptp(t))
    reach = float(np.clip(target, t.min() - half, t.max() + half))
    at = np.array([line[0] + line[1] * (reach - t.mean()) for line in lines])
    return TemperatureLaw(tuple(float(x) for x in t), tuple(float(line[1]) for line in lines), reach,
                          np.maximum(at, 0.0), reach != float(target))  # fmt: skip
