"""Engineering words for a drift finding: what the parameter is, its unit, and the likely cause of a change.

``describe("fc3", +3.6, ...)`` gives "joint 3 Coulomb friction +38 % since 2026-10-12 (+3.6 +- 0.4 N m,
9 sigma): gearbox wear or lubrication". The names are those of the daily update
(:mod:`identification.fleet.update`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Meaning", "describe", "meaning"]


@dataclass(frozen=True)
class Meaning:
    """What a parameter is (``label``), its unit and the likely cause of a rise and of a fall."""

    label: str
    unit: str
    rise: str
    fall: str


MEANINGS = {
    "fc": Meaning("Coulomb friction", "N m", "gearbox wear or lubrication", "lubricant change or a warmer joint"),
    "fv": Meaning("viscous friction", "N m s/rad", "lubricant ageing or seal wear", "a warmer, thinner lubricant"),
    "kt": Meaning("torque constant", "N m/A", "a current sensor or drive parameter change",
                  "drive degrading (magnet demagnetisation or winding fault)"),
    "spring_k": Meaning("spring (counterbalance) stiffness", "N m/rad", "a counterbalance recharged or stiffer spring",
                        "counterbalance losing pressure or a weakened spring"),
    "spring_c": Meaning("spring preload", "N m", "a counterbalance preload change", "a counterbalance preload change"),
    "bias": Meaning("torque offset", "N m", "a torque sensor offset or a cable pulling", "a torque sensor offset"),
    "ripple_amp": Meaning("torque ripple", "N m", "a developing gear tooth or bearing defect", "ripple decreasing"),
    "payload_mass": Meaning("payload", "kg", "a tool changed or a load added", "a tool changed or a load removed"),
    "rmse": Meaning("baseline model's torque error", "N m",
                    "the model no longer explains the robot: the fleet diagnoses the days its refit does not explain",
                    "the model explains the robot better than in its baseline window"),
}  # fmt: skip
PATTERN = re.compile(
    r"^(fc|fv|kt)(\d+)$|^(spring_k|spring_c|bias|rmse)_(\d+)$|^(ripple_amp)\d+_(\d+)$|^(payload_mass)$"
)


def meaning(name: str) -> Meaning | None:
    """The meaning of a parameter name (None for the raw ripple sine and cosine and unknown names)."""
    match = PATTERN.match(name)
    if match is None:
        return None
    key = next(group for group in match.groups()[0::2] if group)
    return MEANINGS[key]


def describe(parameter: str, joint: int, size: float, sigma: float, relative: float | None, since: str,
             test: str) -> str:  # fmt: skip
    """One sentence: where, what, how much (relative, absolute with sigma, in sigma) since when, likely cause."""
    m = meaning(parameter) or Meaning(parameter, "", "a change", "a change")
    where = f"joint {joint} " if joint else ""
    how = f"{relative:+.0f} % " if relative is not None else ""
    z = abs(size) / sigma if sigma > 0 else float("inf")
    cause = m.rise if size > 0 else m.fall
    scope = "outside its fleet's spread" if test == "fleet" else f"since {since}"
    return f"{where}{m.label} {how}{scope} ({size:+.3g} +- {sigma:.2g} {m.unit}, {z:.0f} sigma): {cause}"
