"""A torque offset read with the robot file's rigid body held: the balancer identify's links absorbed.

``offset_reading`` reads a data-chosen torque offset by its size in identify's own fit, and ``offset_or_balancer``
judges it on that fit's residual. Both come too late where the links absorbed the balancer first: a link's gravity
torque is a sinusoid of the joint angles, so a balancer's torque of the angle (a spring's, a gas spring's, a cam's:
most of it a sinusoid of the joint's angle) goes into the links' first moments, and the offset keeps only what no
sinusoid holds, a small constant. On a 210 kg-class arm with a gas spring taking half of joint 2's gravity torque
and a robot file whose masses are 10-20 % off, identify moved two links to their bounds and left an offset of 8 % of
the joint's recorded peak torque, under the size a sensor's zero error may reach; its residual was flat.

With the robot file's rigid body held (``robot_file_check.file_friction``: the file's links, each joint's drive
columns of the fit, offsets included, fitted by least squares on the training recordings, a known payload's torque
taken off) nothing absorbs it: the torque the offset stands for is the file-held offset plus the file-held residual
of its joint, on the training recordings and the held-out ones. The file's own errors give a torque of the angle
there too: links lighter or heavier than the file states take the file's gravity torque times some share ``e`` away,
up to the share their masses are uncertain by (``prior_pull.mass_uncertainty``: the envelope's mass bounds; every
mass off by that much in one direction). So the torque is read by what the recording shows, not by a fixed share
of the offset's size:

- ``share``: the ``e`` of the least squares of the torque in the file's gravity torque over the training poses (a
  constant free), reported;
- the file's gravity torque times ``e``, held to the masses' uncertainty, is given back, and ``offset_or_balancer``
  judges what is left: whether a sinusoid of the joint's angle predicts it better than a constant beyond the noise
  margin, on the training blocks and on the held-out part. Both say so: a torque of the angle no error of the
  file's masses holds (the file's inertia errors leave some torque of the motion that one judge alone may take for
  one).

Balancer (``FileHeldReading.balancer``): identify names a counterbalance on the joint (``counterbalance_
sources``, by ``BY_OFFSET``) and tries a spring there in the offset's place. In identify's fit the links already hold
the balancer's curve, so the spring cannot lower its joint there; it spans what the links and the offset hold, and is
kept where no joint is worse without them holding it (``counterbalance_column.Judges.replacing``), as one named by
the gravity departure.
Without links in the robot file, with an unknown payload on a training recording (the file cannot hold its torque),
on a joint gravity does not load, or without held-out recordings, there is no reading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.offset_or_balancer import BALANCER, OffsetVerdict, offset_or_balancer
from identification.calibration.offset_reading import LOADED_SHARE, OffsetReading
from identification.calibration.trajectory_data import drive_offset

__all__ = ["FileHeldReading", "file_held_offsets"]


@dataclass(frozen=True)
class FileHeldReading:
    """A data-chosen torque offset on ``joint`` (0-based) read with the robot file's rigid body held.

    ``offset`` identify's offset and ``held`` the file-held fit's [N m]; ``share`` of the file's gravity torque the
    torque the offset stands for takes away, beside ``uncertainty``, the share the file's masses are uncertain by;
    ``verdict`` the ``OffsetVerdict`` on that torque once the file's masses hold what they can of it;
    ``gravity`` the file's gravity torque amplitude and ``peak`` the recorded peak torque on the joint [N m]."""

    joint: int
    offset: float
    held: float
    share: float
    uncertainty: float
    verdict: OffsetVerdict
    gravity: float
    peak: float

    @property
    def balancer(self) -> bool:
        """Whether a torque of the angle is left beyond the noise once the file's masses hold what they can: every
        judge (the training blocks, the held-out part) says so, not only one with the other undecided."""
        judges = self.verdict.judges
        return self.verdict.verdict == BALANCER and bool(judges) and all(b < a - m for _, a, b, m in judges)

    def reading(self) -> OffsetReading:
        """As ``offset_reading`` states an offset no sensor has (the spring takes its place)."""
        return OffsetReading(self.joint, self.offset, self.gravity, self.peak)

    def sentence(self) -> str:
        j = self.joint + 1
        said = (f"with the robot file's rigid body held, the torque offset on joint {j} ({self.offset:+.4g} N m in "
                f"identify's fit, {self.held:+.4g} with the file's links) stands for a torque that "
                f"takes {self.share:.0%} of the file's gravity torque away over the recorded poses (its masses "
                f"uncertain by {self.uncertainty:.0%}, which hold that much of it)")  # fmt: skip
        if self.balancer:
            return (f"{said} and {self.verdict.sentence()}: the links absorbed a counterbalance or spring the offset "
                    "alone does not show")  # fmt: skip
        return f"{said}: no torque of the angle the file's masses cannot hold ({self.verdict.numbers() or 'no judge'})"


def file_held_offsets(problem, fit, calibrated, validation, joints, kt=None) -> dict:
    """``{0-based joint: FileHeldReading}`` of ``fit``'s data-chosen offsets on ``joints`` (module docstring).
    ``problem``: ``(robot, model, recordings, options, configurations)`` of the fit (raw training recordings,
    ``configurations`` their payloads); ``calibrated`` its model file (prepares the raw held-out ``validation``
    recordings as the file says; ``kt`` for recordings of currents)."""
    from identification.calibration.column_candidates import prepare_training
    from identification.calibration.payload_fit import subtract_known_payloads
    from identification.calibration.prior_pull import mass_uncertainty
    from identification.calibration.robot_file_check import file_friction
    from psdm_casadi.oracle import PinocchioOracle

    robot, model, recordings, options, configurations = problem
    names = list(fit.drive_names)
    joints = [j for j in joints if f"offset{j + 1}" in names]
    uncertainty = mass_uncertainty(options)
    uncertainty = float(options.prior_uncertainty) if uncertainty is None else uncertainty
    unknown = configurations is not None and any(c.unknown for c in configurations)
    if not joints or not validation or robot.links is None or unknown:
        return {}
    prepared = subtract_known_payloads(robot, prepare_training(robot, recordings, options).prepared, configurations)
    oracle = PinocchioOracle(robot)
    held = file_friction(oracle, fit, prepared)

    def residual(ready):  # (angles, file-held residual, the file's gravity torque) of a prepared recording
        zero = np.zeros_like(ready.q)
        return ready.q, ready.tau - held.predict(oracle, ready.q, ready.qd, ready.qdd), oracle.rnea(ready.q, zero, zero)

    training = [residual(r) for r in prepared]
    out_of_sample = [residual(calibrated.predict_recording(model, r, kt)[0]) for r in validation]
    peak = np.nanmax(np.abs(np.concatenate([r.tau for r in prepared])), axis=0)
    out = {}
    for j in joints:
        gravity = np.concatenate([g[:, j] for _, _, g in training])
        if not float(np.max(np.abs(gravity))) >= LOADED_SHARE * peak[j]:
            continue
        keep, values = held.coefficients[j]
        level = sum(float(v) for k, v in zip(keep, values) if names[k] == f"offset{j + 1}")
        torque = np.concatenate([t[:, j] for _, t, _ in training]) + level
        share = _file_share(torque, gravity)
        scale = float(np.clip(share, -uncertainty, uncertainty))  # the most of it the file's masses may hold
        pairs = [[(qk[:, j], tk[:, j] + level + scale * gk[:, j]) for qk, tk, gk in side]
                 for side in (training, out_of_sample)]  # fmt: skip
        offset = drive_offset(fit.drive, names, j, required=True)
        out[j] = FileHeldReading(j, offset, level, share, uncertainty, offset_or_balancer(j, *pairs),
                                 float(np.max(np.abs(gravity))), float(peak[j]))  # fmt: skip
    return out


def _file_share(torque, gravity) -> float:
    """The share ``e`` of the file's gravity torque ``g`` that the torque ``t = c - e g`` takes away (least squares
    over the finite samples, ``c`` free): what the file's links would hold if their masses were ``1 - e`` times
    their stated ones."""
    ok = np.isfinite(torque) & np.isfinite(gravity)
    swing = gravity[ok] - np.mean(gravity[ok])
    return -float((torque[ok] - np.mean(torque[ok])) @ swing) / max(float(swing @ swing), 1e-300)
