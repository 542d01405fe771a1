"""A gravity departure the bounds make: the inertia about a joint held back, not a counterbalance on it.

Where the data want more inertia about a joint than the robot file's links and drive bounds can give (a rotor, a
coupled load the file does not state: ``held_back``, kind ``"axis"``, held by the envelope), the consistent fit
takes what it can of that inertia's torque into the links' first moments: on a periodic motion a torque of the
joint's angle follows its acceleration. The fitted gravity torque of that joint then leaves the robot file's alone
(``gravity_departure``), and the links it moved are pushed against their envelopes, which reads as a counterbalance
on the joint; the spring tried there is refused, at the cost of a refit per block and shape.

The data tell the two apart through their own unconstrained least squares (``TrajectoryFit.theta_ols``), which
holds no bound: a counterbalance is in what the data want, so their gravity torque departs on the joint as well
(the heavy virtual arm's cam on joint 2), while a held-back inertia is taken by the inertia about the joint and their
gravity torque stays the robot file's (the virtual Denso with a hidden rotor inertia on joint 1). Correlating the
fit's departure with the joint's acceleration does not tell them: a departure is a gravity torque, a function of the
configuration, by construction. A departure yields where all hold:

- the fit names it (``gravity_departure.theta_departures`` of the fit's base parameters);
- the data's least squares name none on that joint (the same reading of ``theta_ols``);
- the fit holds back the inertia about that joint, the data wanting more than the envelope and bounds allow.

Then the report says once that the held-back inertia is the effect, with the data's value, names no counterbalance
there (the links pushed on its behalf are named after it) and identify's counterbalance route tries no spring there.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from identification.calibration.gravity_departure import theta_departures

__all__ = [
    "InertiaDeparture",
    "inertia_departures",
    "inertia_note",
    "stored_inertia_departures",
    "yielded_findings",
]


@dataclass(frozen=True)
class InertiaDeparture:
    """On ``joint`` (0-based) the fit's gravity torque departs by ``departure`` [N m RMS] where the data's least
    squares depart by none: the inertia about the joint (``parameter``, ``words``) the fit holds back at ``fitted``
    where the data want ``data`` +/- ``data_std`` (robot file ``file``) moved it."""

    joint: int
    departure: float
    parameter: str
    words: str
    data: float
    data_std: float
    fitted: float
    file: float

    def to_dict(self) -> dict:
        return asdict(self)

    def sentence(self) -> str:
        """What the report says once, in its words."""
        return (
            f"the fitted gravity torque of joint {self.joint + 1} leaves the robot file's by {self.departure:.4g} N m "
            "RMS where the data's own least squares leave it as the file has it: it is not a counterbalance but "
            f"{self.words} ({self.parameter}) the envelope and bounds hold back (the data want {self.data:.4g} +/- "
            f"{self.data_std:.2g}, the model keeps {self.fitted:.4g}, robot file {self.file:.4g}), whose torque "
            "the links' first moments take in part; no spring is tried there"
        )


def inertia_departures(robot, model, recordings, theta, theta_ols, held) -> dict:
    """``{0-based joint: InertiaDeparture}`` (module docstring) of a fit's base parameters ``theta`` and the data's
    least squares ``theta_ols`` on its prepared training ``recordings``, ``held`` its ``held_back.HeldBack``; the
    departures are read only where such an inertia is held back."""
    inertias = {h.joint: h for h in held if h.kind == "axis" and h.holder == "envelope" and h.data > h.fitted}
    if not inertias or theta_ols is None or not np.all(np.isfinite(theta_ols)):
        return {}
    fitted = {j: d for j, d in theta_departures(robot, model, recordings, theta).items() if j in inertias}
    if not fitted:
        return {}
    data = theta_departures(robot, model, recordings, theta_ols)
    return {j: InertiaDeparture(j, d.departure, inertias[j].parameter, inertias[j].words, inertias[j].data,
                                inertias[j].data_std, inertias[j].fitted, inertias[j].file)
            for j, d in fitted.items() if j not in data}  # fmt: skip


def yielded_findings(findings, departures) -> tuple:
    """``findings`` (``envelope_report.EnvelopeFinding``) with each link named a counterbalance on a joint of
    ``departures`` (``{joint: InertiaDeparture}``) named after the held-back inertia instead: the link was pushed on
    its behalf. Its message keeps what is pushed and by how much."""
    out = []
    for finding in findings:
        at = finding.effect_joint if finding.effect_joint >= 0 else finding.joint
        drive = any(b.startswith("drive") for b in finding.bounds)
        if drive or finding.absorbs != "counterbalance" or at not in departures:
            out.append(finding)
            continue
        item = departures[at]
        message = (f"{finding.pushed}. This is {item.words} ({item.parameter}) the fit holds back (see HELD BACK), "
                   "which the link's first moment takes in part on a periodic motion; not a counterbalance: the "
                   f"data's own least squares leave joint {at + 1}'s gravity torque as the robot file has "
                   "it.")  # fmt: skip
        out.append(replace(finding, absorbs="drive_inertia", alternatives=(), effect_joint=at, message=message,
                           evidence=item.sentence()))  # fmt: skip
    return tuple(out)


def inertia_note(departures) -> tuple:
    """The ``(name, value)`` pair stored with the fit's bounds (``TrajectoryFit.envelope_bounds``; none without)."""
    return (("inertia_departures", [d.to_dict() for d in departures.values()]),) if departures else ()


def stored_inertia_departures(envelope_bounds) -> dict:
    """``{joint: InertiaDeparture}`` of a fit's ``envelope_bounds`` pairs or a model file's ``standard.envelope``
    dict (none in a file written before they were stored)."""
    entries = dict(envelope_bounds or {}).get("inertia_departures", ())
    return {int(e["joint"]): InertiaDeparture(**e) for e in entries}
