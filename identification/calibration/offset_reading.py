"""An offset no sensor has: a constant torque the size of a joint's gravity load is a counterbalance the offset absorbs.

A torque offset is a sensor's or a current measurement's zero error: a strain-gauge joint-torque sensor's zero drifts
by a few tenths of a percent to a few percent of its rated range, a current sensor's by about as much of its peak
current, and the rated range is at least the torque the joint reaches on an exciting recording. An offset chosen from
the data (``column_choice``) on a joint gravity loads, reaching ``SENSOR_SHARE`` of the joint's recorded peak torque
(several times what any sensor's zero error gives) and ``GRAVITY_SHARE`` of the robot file's gravity torque on the
recorded poses, is no sensor's: it is a torque of the position the constant column takes over the recorded range. On an
industrial shoulder that is most likely a counterbalance (a spring, a gas spring, a cam): a balancer opposes the
joint's gravity torque over the range and takes a large share of it, and over the half radian or so an arm sweeps
near horizontal its torque is nearly constant (the heavy virtual arm: joint 2's offset took 51 % and 70 % of the
robot file's gravity torque there). A true sensor offset (the Panda's, the TX40's, a virtual SCARA's 0.3 N m) is a
small fraction of both.

:func:`oversized_offset` reads one joint; :func:`fit_offsets` reads every data-chosen offset of a fit against the
robot file's gravity torque on the training recordings, of joint torques or of motor currents (read as joint torques
through the torque constants the fit used: a balancer's offset on currents is no sensor's either). ``identify``
(``counterbalance_column``) names such a joint's counterbalance and tries a spring there in place of the offset, and
leaves it unjudged on the model it writes (``column_check``); the diagnosis names such a ``torque_offset`` finding a
counterbalance (``diagnosis.counterbalance_naming``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.gravity_load import recorded_poses
from identification.calibration.trajectory_data import drive_offset

__all__ = [
    "GRAVITY_SHARE",
    "LOADED_SHARE",
    "SENSOR_SHARE",
    "OffsetReading",
    "data_chosen_offsets",
    "fit_offsets",
    "oversized_offset",
]

#: The largest zero error of a torque or current measurement, as a share of the joint's recorded peak torque: a few
#: percent of the rated range at most, with a margin (the rated range is at least the recorded peak).
SENSOR_SHARE = 0.1
#: A constant torque read as a position-dependent load reaches this share of the joint's gravity torque amplitude
#: (as a low-harmonic ripple is named a counterbalance, ``diagnosis.counterbalance_naming``).
GRAVITY_SHARE = 0.2
#: A joint gravity loads: the robot file's gravity torque amplitude at least this share of its recorded peak torque.
LOADED_SHARE = 0.1


@dataclass(frozen=True)
class OffsetReading:
    """A torque offset [N m] on ``joint`` (0-based) too large for a sensor's, with the numbers that say so: the
    robot file's gravity torque amplitude on the recorded poses and the joint's recorded peak torque [N m]; ``held``:
    the part of the offset a model file holds (the diagnosis of a model file fits the rest), 0 when none."""

    joint: int
    offset: float
    gravity: float
    peak: float
    held: float = 0.0

    @property
    def gravity_share(self) -> float:
        return abs(self.offset) / self.gravity

    @property
    def peak_share(self) -> float:
        return abs(self.offset) / self.peak

    def sentence(self, verdict=None) -> str:
        """Why the offset is not a sensor's by its size, in the report's words, and what the data say of it
        (``verdict``: an ``offset_or_balancer.OffsetVerdict``; where it says offset, the size's reading is
        overruled)."""
        parts = (f" (the model file's part {self.held:+.4g} N m plus the data's part {self.offset - self.held:+.4g} "
                 "N m)" if self.held else "")  # fmt: skip
        size = (
            f"the torque offset {self.offset:+.4g} N m{parts} on joint {self.joint + 1} is {self.gravity_share:.0%} "
            f"of its gravity torque in the robot file ({self.gravity:.4g} N m) and {self.peak_share:.0%} of its "
            f"recorded peak torque ({self.peak:.4g} N m); a torque sensor's or current measurement's zero error is a "
            f"few percent of its range (at most {SENSOR_SHARE:.0%} of the recorded peak)"
        )
        if verdict is not None and not verdict.named:
            return f"{size}; {verdict.sentence()}"
        said = f"{size}: it is a position-dependent torque the offset absorbs, most likely a counterbalance or spring"
        return said if verdict is None else f"{said}; {verdict.sentence()}"


def oversized_offset(joint: int, offset: float, gravity: float, peak: float) -> OffsetReading | None:
    """The ``OffsetReading`` of ``offset`` [N m] on ``joint`` when it is no sensor's (module docstring): the joint
    gravity loaded (``gravity``, the robot file's gravity torque amplitude on the recorded poses, at least
    ``LOADED_SHARE`` of ``peak``, the recorded peak torque) and the offset at least ``SENSOR_SHARE`` of ``peak`` and
    ``GRAVITY_SHARE`` of ``gravity``; None otherwise."""
    offset, gravity, peak = float(offset), float(gravity), float(peak)
    if not (peak > 0.0 and gravity >= LOADED_SHARE * peak):
        return None
    if abs(offset) < SENSOR_SHARE * peak or abs(offset) < GRAVITY_SHARE * gravity:
        return None
    return OffsetReading(int(joint), offset, gravity, peak)


def fit_offsets(robot, model, recordings, fit, joints, kt=None) -> dict:
    """``{0-based joint: OffsetReading}`` of the offsets of ``fit`` (its drive columns ``offset<j>``) on ``joints``
    (the offsets the data chose) that no sensor has, against the robot file's gravity torque and the recorded joint
    torque of the raw training ``recordings``: a recording's torque, or its motor currents times ``kt`` (the torque
    constants [N m/A] the fit read them with; None: recordings of currents are not read). A current measurement's zero
    error is a share of its range as a torque sensor's is, and an offset fitted to currents through ``kt`` is in the
    same units as their peak, so the share of the peak does not depend on ``kt`` being right. None read: no reading.
    Empty without the file's links."""
    names = list(fit.drive_names)
    found = [j for j in joints if f"offset{j + 1}" in names]
    read = [r for r in recordings if getattr(r, "tau", None) is not None
            or (kt is not None and getattr(r, "current", None) is not None)]  # fmt: skip
    if not found or not read or robot.links is None:
        return {}
    tau = np.concatenate([np.asarray(r.tau if r.tau is not None else r.joint_torque(kt), dtype=float) for r in read])
    q = recorded_poses(read)  # every STRIDE-th: gravity is smooth in the pose
    zero = np.zeros_like(q)
    gravity = model.inverse_dynamics(q, zero, zero, model.base_parameters(robot.nominal_dynamic_parameters()))
    out = {}
    for j in found:
        reading = oversized_offset(j, drive_offset(fit.drive, names, j, required=True),
                                   np.max(np.abs(gravity[:, j])), np.max(np.abs(tau[:, j])))  # fmt: skip
        if reading is not None:
            out[j] = reading
    return out


def data_chosen_offsets(robot, model, recordings, options, fit, kt=None) -> dict:
    """``{0-based joint: offset_reading.OffsetReading}`` of the torque offsets the data chose (``options.
    offset_joints`` a tuple: not every joint's as asked) that no sensor has (``fit_offsets``; ``kt``: the torque
    constants of recordings of currents)."""
    if "offset" not in options.friction or options.offset_joints is None:
        return {}
    return fit_offsets(robot, model, recordings, fit, options.offset_joints, kt)
