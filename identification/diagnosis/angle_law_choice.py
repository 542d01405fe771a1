"""An angle law the free recalibration matches only by moving a link's gravity far from the robot file stands.

``rigid_body="auto"`` (``rigid_body_choice.prior_wins``) lets the prior model with its findings lose to a full
rigid-body recalibration that predicts the validation recording about as well with fewer findings: wrong CAD inertia is
not missing physics. It counts findings, not parameters, so a counterbalance (a spring or a gas spring on a shoulder,
one or two coefficients) loses to a recalibration of dozens of base parameters that takes its torque into a link's
gravity moment: a balancer's torque, a smooth law of the joint's own angle, is close to the shape of that joint's
gravity torque over a recorded range, so the recording alone hardly separates a lighter link from the balancer.

The robot file does separate them: its masses and centres of mass are off by their CAD error (10-20 %), not by the
size of a counterbalance. :func:`gravity_backed_laws` therefore compares, on the validation recording, the
recalibrated rigid body's gravity torque on the finding's joint with the robot file's (both at rest: the regressor at
zero velocity and acceleration). The finding stands when that departure and the finding's own torque both exceed
``FILE_GRAVITY_ERROR`` of the file's gravity torque there (``gravity_departure``: no CAD error explains them), and
what is left of the departure once the finding's torque is taken off is within that share (the departure is the
balancer's torque: the recalibration only moved the link to carry it). Only a plausible angle law counts (a spring
of positive stiffness, a gas spring that pushes: ``implausibility``); payload and rotor-inertia findings still have to
beat the recalibration, as does any finding whose torque the departure does not equal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.gravity_departure import FILE_GRAVITY_ERROR
from identification.calibration.merged_rotors import robot_file_theta
from identification.diagnosis.backed_name import ANGLE_LAWS
from identification.metrics import rms

__all__ = ["GravityBacked", "gravity_backed_laws", "gravity_torque"]


@dataclass(frozen=True)
class GravityBacked:
    """An angle-law finding (``label``, ``effect``, 0-based ``joint``) whose torque the recalibration matched only by
    moving the joint's gravity torque: the RMS [N m] over the validation recording of the file's gravity torque
    (``file_gravity``), of the recalibration's departure from it (``departure``) and of that departure less the
    finding's torque (``remainder``), and of the finding's torque (``law``)."""

    label: str
    effect: str
    joint: int
    file_gravity: float
    departure: float
    remainder: float
    law: float

    def note(self) -> str:
        """The report's sentence."""
        j = self.joint + 1
        return (
            f"`{self.label}` kept although a full rigid-body recalibration predicts about as well without it: that "
            f"recalibration moves joint {j}'s gravity torque by {self.departure:.4g} N m RMS from the robot file's "
            f"({self.file_gravity:.4g} N m RMS), as the finding's torque ({self.law:.4g} N m RMS) does, more than the "
            f"{FILE_GRAVITY_ERROR:.0%} a CAD error explains; without the finding's torque it leaves "
            f"{self.remainder:.4g} N m RMS: the links were made to carry the balancer."
        )


def gravity_torque(model, q, theta) -> np.ndarray:
    """The rigid body's torque at rest, ``Y(q, 0, 0) theta`` (n_samples, n_dof), for base parameters ``theta``."""
    q = np.asarray(q, dtype=float)
    return np.asarray(model.regressor(q, np.zeros_like(q), np.zeros_like(q)), dtype=float) @ np.asarray(theta)


def gravity_backed_laws(robot, model, ctx_v, theta_identified, terms, coefficients, findings, ctx_t=None) -> tuple:
    """The ``GravityBacked`` angle-law findings of the prior fit (``terms`` with their final ``coefficients`` and the
    ``findings`` of ``report_assembly.findings_of``, in the same order), judged on the validation context ``ctx_v``
    against the recalibrated base parameters ``theta_identified`` (in the map of ``merged_rotors.robot_file_theta``);
    ``ctx_t`` judges a term's plausibility (its recorded range)."""
    laws = [(t, c, f) for t, c, f in zip(terms, coefficients, findings) if t.key in ANGLE_LAWS and len(f.joints) == 1]
    if not laws:
        return ()
    plausible = [(t, c, f) for t, c, f in laws if t.implausibility(np.asarray(c, dtype=float), ctx_t) is None]
    if not plausible:
        return ()
    theta_file = robot_file_theta(robot, model, ctx_v.torque_constants)
    file_gravity = gravity_torque(model, ctx_v.q, theta_file)
    departure = gravity_torque(model, ctx_v.q, theta_identified) - file_gravity
    backed = []
    for term, c, finding in plausible:
        j = finding.joints[0]
        law = np.asarray(term.columns(ctx_v), dtype=float)[:, j, :] @ np.asarray(c, dtype=float)
        scale = FILE_GRAVITY_ERROR * float(rms(file_gravity[:, j]))
        moved, left = float(rms(departure[:, j])), float(rms(departure[:, j] - law))
        size = float(rms(law))
        if min(moved, size) > scale and left <= scale:
            backed.append(GravityBacked(term.label, finding.effect, j, float(rms(file_gravity[:, j])), moved, left,
                                        size))  # fmt: skip
    return tuple(backed)
