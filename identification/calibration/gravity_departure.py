"""A joint whose fitted gravity torque alone leaves the robot file's: a counterbalance the links' first moments took.

A balancer's torque on a shoulder (a spring, a gas spring, a cam) opposes the joint's gravity torque over its range
and takes a large share of it. Its first harmonic has the shape of gravity torques, and inside the links' envelopes
the consistent fit can take it into the links' first moments beside the tool it also absorbs (the heavy virtual arm
at seed 1: no offset chosen, joint 2's fitted gravity torque thousands of N m off the truth's, every link inside its
envelope, nothing named).

What tells it from a wrong robot file or a tool is where the departure sits and which way it points. The fitted minus
the file's gravity torque is computed on the training poses; for each joint, a body at the flange (its mass and first
moment) is fitted to the departures of the other joints by least squares (a tool moves every joint that carries it, in
ratios the kinematics fix). A joint is named where what is then left sits on it (at least ``LOCAL`` of the squared
departure left, ``absorbed_effect.LOCAL``) and opposes the file's gravity torque there by a share between
``FILE_GRAVITY_ERROR`` and the whole of it: a robot file's masses and centres of mass are off by tens of percent (CAD),
spread over the several links a joint carries and of either sign, and a balancer never takes more than the gravity it
balances. On the heavy arm at seed 1 joint 2 is left with 2769 N m RMS opposing 60 % of its gravity, the others within
135 N m; joint 3 alone would need a torque beyond its whole gravity torque, joint 5 a tool of negative mass.

A tool has mass. Where the least squares want a negative one, the physical body nearest them (mass at least 0; a body
without mass has no first moment) is none, and the joint is read both ways, with no body and with the least squares'
body, and named only where both name it. A balancer on an arm without a tool leaves the other joints' departures at
the fit's error, which a trace of mass either side of zero fits; its joint is named either way (it was dropped
unread when that trace came out negative). A departure only one of the two readings names is not one joint's torque
alone: the others' departures hold something no tool gives, and what is left on the joint depends on how it is read.

A joint's own torque offset (a drive column the data chose) is counted in its departure: over the half radian or so
an arm sweeps near horizontal a balancer's torque is mostly a constant, which the offset takes, and the links' first
moments take only its swing (links 2 and 3 together: a mass moved between them through joint 2's grouped first
moment, link 3's own first moment, which joint 3 also feels, left as it was). Their sum is the torque of that joint
alone the fit puts beside the file's gravity; either part alone is a fraction of it. A sensor's zero error is a few
percent of the joint's torque (``offset_reading.SENSOR_SHARE``), of either sign, and does not reach the share alone.

Only a joint gravity gives a torque can depart (``gravity_load.joints_carrying_gravity`` at the recorded poses): an
upright arm's base axis carries none, and no fitted parameter moves its gravity torque.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.absorbed_effect import LOCAL
from identification.calibration.gravity_load import joints_carrying_gravity, recorded_poses
from identification.calibration.trajectory_data import drive_offset

__all__ = ["FILE_GRAVITY_ERROR", "GravityDeparture", "gravity_departures", "theta_departures"]

#: The share of a joint's gravity torque a robot file's CAD errors (masses and centres of mass 10-20 % off, spread
#: over the links the joint carries) may move: a fitted gravity torque departing from the file's by more is no CAD
#: error. The one threshold of that idea: identify's departure here, the diagnosis's free recalibration
#: (``diagnosis.angle_law_choice``, ``diagnosis.hidden_balancer``).
FILE_GRAVITY_ERROR = 0.25


@dataclass(frozen=True)
class GravityDeparture:
    """On ``joint`` (0-based) the fitted gravity torque leaves the robot file's by ``departure`` [N m RMS, a body at
    the flange fitted to the other joints' departures taken out, its torque ``offset`` [N m] counted], ``local`` of
    the squared departure left on every joint, opposing the file's gravity torque (``gravity`` [N m RMS] there) by
    ``share`` of it."""

    joint: int
    departure: float
    gravity: float
    local: float
    share: float
    offset: float = 0.0

    @property
    def _with(self) -> str:
        return f" with its torque offset ({self.offset:+.4g} N m)" if self.offset else ""

    def sentence(self) -> str:
        """Why it is named, in the report's words."""
        return (
            f"the fitted gravity torque of joint {self.joint + 1}{self._with} leaves the robot file's by "
            f"{self.departure:.4g} N m RMS, opposing its gravity torque ({self.gravity:.4g} N m RMS) by "
            f"{self.share:.0%} of it and {self.local:.0%} of every joint's departure once a body at the flange "
            "explains the others: a torque of "
            "that joint alone, more than a robot file's errors give, most likely a counterbalance or spring the "
            f"links' first moments{' and the offset' if self.offset else ''} absorb"
        )

    @property
    def evidence(self) -> str:
        """The same, as the envelope report states a finding's evidence (``envelope_report.named_by_departure``)."""
        return (
            f"the fitted gravity torque of joint {self.joint + 1}{self._with} leaves the robot file's by "
            f"{self.departure:.4g} N m RMS, {self.local:.0%} of every joint's departure once a body at the flange "
            f"explains the others, opposing {self.share:.0%} of its gravity torque; no body at the flange gives it"
        )


def gravity_departures(robot, model, recordings, fit) -> dict:
    """``{0-based joint: GravityDeparture}`` of ``fit`` on the raw training ``recordings`` (module docstring), each
    joint's own torque offset (a drive column of the fit, ``offset<j>``; none in a fit without drive columns) counted
    in its departure; empty without the robot file's links."""
    drive, names = getattr(fit, "drive", ()), getattr(fit, "drive_names", ())
    offsets = np.array([drive_offset(drive, names, j) for j in range(robot.n_dof)])
    return theta_departures(robot, model, recordings, fit.theta, offsets)


def theta_departures(robot, model, recordings, theta, offsets=None) -> dict:
    """``gravity_departures`` of the base parameters ``theta`` (inside the fit, before its ``TrajectoryFit``) and the
    fit's torque ``offsets`` per joint [N m] (None: none), each counted on its own joint only (the constant column
    takes what the links leave of a balancer over the recorded range). The envelope report's naming of a pressed
    link (``held_back.causes``) passes none: it asks what the link holds, and an offset is not in it."""
    if robot.links is None or not recordings:
        return {}
    q = recorded_poses(recordings)
    zero = np.zeros_like(q)
    g_file = model.inverse_dynamics(q, zero, zero, model.base_parameters(robot.nominal_dynamic_parameters()))
    difference = model.inverse_dynamics(q, zero, zero, np.asarray(theta, dtype=float)) - g_file
    offsets = np.zeros(robot.n_dof) if offsets is None else np.asarray(offsets, dtype=float)
    carries = joints_carrying_gravity(robot, q)
    bodies = np.abs(model.parameter_map).reshape(model.n_base, robot.n_dof, 11)[:, :, :4].max(axis=(0, 2))
    last = int(np.flatnonzero(bodies > 0)[-1])  # the last link with mass carries a body at the flange
    flange = np.stack(
        [model.inverse_dynamics(q, zero, zero, model.parameter_map[:, 11 * last + k]) for k in range(4)], axis=-1
    )  # fmt: skip  (samples, joints, mass and first moment)
    out = {}
    for j in np.flatnonzero(carries).tolist():  # no balancer, nor a departure, where gravity gives no torque
        others = [k for k in range(robot.n_dof) if k != j]
        body, *_ = np.linalg.lstsq(flange[:, others].reshape(-1, 4), difference[:, others].ravel(), rcond=None)
        bodies = (body,) if body[0] >= 0.0 else (np.zeros(4), body)  # a negative mass: no tool, and the fitted one
        read = [_departure(j, difference - flange @ b, g_file, offsets[j]) for b in bodies]
        if all(read):  # named either way the others are read: the negative mass does not decide it
            out[j] = read[0]
    return out


def _departure(j: int, left, g_file, offset: float) -> GravityDeparture | None:
    """The ``GravityDeparture`` of joint ``j`` where ``left`` (samples, joints) [N m] is the fitted minus the file's
    gravity torque (``g_file``) once a body at the flange is taken out, ``offset`` the joint's own torque offset
    counted in it; None where it does not sit on the joint or opposes no share of its gravity a balancer takes."""
    left = left.copy()
    left[:, j] += offset  # what the joint's own constant column holds of it
    power = np.mean(left**2, axis=0)
    gravity = float(np.dot(g_file[:, j], g_file[:, j]))
    if not (gravity > 0.0 and power.sum() > 0.0):
        return None
    share = float(-np.dot(left[:, j], g_file[:, j]) / gravity)  # the share of gravity it takes, opposing it
    local = float(power[j] / power.sum())
    if not (local >= LOCAL and FILE_GRAVITY_ERROR <= share <= 1.0):
        return None
    rms = float(np.sqrt(gravity / g_file.shape[0]))
    return GravityDeparture(j, float(np.sqrt(power[j])), rms, local, share, float(offset))
