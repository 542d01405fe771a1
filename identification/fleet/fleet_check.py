"""Fleet-relative check: a robot whose recent parameters leave the spread of its fleet of one model.

Per parameter name (robots whose baseline shares a PSDM model share names), each robot's recent level is the
mean of its last ``recent_days`` values; the fleet's centre and spread are the median and the scaled median
absolute deviation of those levels (robust: the robots that drift do not widen it), and a robot's standardised
distance is ``(level - median) / sqrt(spread^2 + sigma_level^2)``. The threshold is family-wise over every robot
and parameter tested (Bonferroni at ``alpha``), and a fleet needs ``min_robots`` robots to have a spread at all.

The spread is itself estimated from a handful of robots, so the threshold is Student's t, not the normal
quantile: the MAD of n values is as precise as a standard deviation of about 0.37 n of them (its efficiency
for normal data), which gives ``0.37 n - 1`` degrees of freedom (at least 1). With the normal quantile a cell
of 8 healthy robots whose friction spreads by tens of percent, as manufacturing gives, had 3 false alarms in
12 days (``benchmarks/fleet.py --robots 8 --days 12``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.fleet.drift import DriftFinding, series_of
from identification.fleet.phrases import describe

__all__ = ["FleetCheckOptions", "fleet_outliers"]

MAD_TO_SIGMA = 1.4826
MAD_EFFICIENCY = 0.37  # asymptotic efficiency of the MAD against the standard deviation, normal data


@dataclass(frozen=True)
class FleetCheckOptions:
    """Family-wise false-alarm rate, the days that make a robot's recent level, and the smallest fleet."""

    alpha: float = 0.01
    recent_days: int = 3
    min_robots: int = 5


def fleet_outliers(rows, options: FleetCheckOptions | None = None) -> list:
    """Findings (``test = "fleet"``) of robots whose recent level of a parameter leaves the fleet's spread."""
    options = options or FleetCheckOptions()
    by_name: dict = {}
    for s in series_of(rows):
        by_name.setdefault(s.parameter, []).append(s)
    tested = {name: group for name, group in by_name.items() if len(group) >= options.min_robots}
    n_tests = sum(len(group) for group in tested.values())
    if not n_tests:
        return []
    findings = []
    for name, group in sorted(tested.items()):
        dof = max(1.0, MAD_EFFICIENCY * len(group) - 1.0)
        threshold = float(stats.t.isf(options.alpha / (2 * n_tests), dof))
        levels = np.array([np.mean(s.values[-options.recent_days :]) for s in group])
        sigmas = np.array(
            [np.sqrt(np.mean(s.sigmas[-options.recent_days :] ** 2) / options.recent_days) for s in group]
        )
        centre = float(np.median(levels))
        spread = MAD_TO_SIGMA * float(np.median(np.abs(levels - centre)))
        z = (levels - centre) / np.sqrt(spread**2 + sigmas**2)
        for s, level, zk in zip(group, levels, z):
            if abs(zk) > threshold:
                size, sigma = float(level - centre), float(np.sqrt(spread**2))
                relative = 100.0 * size / abs(centre) if abs(centre) > 0 and name != "payload_mass" else None
                text = describe(name, s.joint, size, sigma, relative, str(s.days[-1]), "fleet")
                findings.append(DriftFinding(s.robot_id, s.joint, name, "fleet", s.days[-1], size, sigma, relative,
                                             float(zk), text))  # fmt: skip
    return findings
