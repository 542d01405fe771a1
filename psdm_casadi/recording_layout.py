"""RecordingLayout: how a robot's controller writes its recordings (which side each signal is on, the rate, the files).

Stated in the robot file's ``[recording]`` table and read with every recording of that robot
(``identification.data.robot_recordings``): motor-side signals are mapped to the joint side through
the robot's ``Transmission``, files without a time column get ``t = k / sample_rate``, and a recording
the controller wrote as one file per signal (positions in one file, torques in another, the columns in
joint order under any header) is read as one recording.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from psdm_casadi.errors import RobotFileError
from psdm_casadi.values import format_value, is_real_number

__all__ = ["RecordingLayout", "SIDES", "SIGNALS"]

#: The signals of a recording: positions, velocities, accelerations, torques, currents.
SIGNALS = ("q", "qd", "qdd", "tau", "current")
SIDES = ("joint", "motor")


@dataclass(frozen=True)
class RecordingLayout:
    """The side of each signal, the sample rate of files without time, and the files of a split recording.

    Parameters
    ----------
    sides : mapping signal -> {"joint", "motor"}
        Signals recorded on the motor side (after the encoder, before the gear); the others are joint side.
    sample_rate : float, optional
        Samples per second [Hz] of files that have no ``t`` column (``t = k / sample_rate``).
    files : tuple of (signal, file name)
        A recording written as one file per signal: the file holding each signal (its columns in joint
        order, any header), all in one folder.

    Raises
    ------
    RobotFileError
        Naming the field and the fix, for an unknown signal or side, a rate that is not > 0, a file
        named twice, or split files without positions or without torques or currents.
    """

    sides: dict = field(default_factory=dict)
    sample_rate: float | None = None
    files: tuple = ()

    def __post_init__(self):
        sides = dict(self.sides)
        for signal, side in sides.items():
            if signal not in SIGNALS or side not in SIDES:
                raise RobotFileError(
                    f"RecordingLayout.sides must map signals {list(SIGNALS)} to 'joint' or 'motor'; got "
                    f"{signal!r} = {format_value(side)}. Fix the [recording].side entry."
                )
        object.__setattr__(self, "sides", sides)
        rate = self.sample_rate
        if rate is not None and not (is_real_number(rate) and math.isfinite(rate) and rate > 0):
            raise RobotFileError(
                f"RecordingLayout.sample_rate must be a positive number [Hz]; got {format_value(rate)}. "
                "Give the samples per second, e.g. sample_rate = 5000.0."
            )
        files = tuple((str(signal), str(name)) for signal, name in self.files)
        signals = [signal for signal, _ in files]
        names = [name for _, name in files]
        if any(signal not in SIGNALS for signal in signals) or len(set(names)) != len(names):
            raise RobotFileError(
                f"RecordingLayout.files must name one file per signal of {list(SIGNALS)}, each file once; got "
                f"{dict(files)}. Fix the [recording].files table."
            )
        if files and ("q" not in signals or not {"tau", "current"} & set(signals)):
            raise RobotFileError(
                f"RecordingLayout.files must name the positions' file (q) and the torques' (tau) or currents' "
                f"(current); got {dict(files)}. Add the missing one."
            )
        object.__setattr__(self, "files", files)

    def side(self, signal: str) -> str:
        """``"motor"`` or ``"joint"`` (the default) for one of :data:`SIGNALS`. The currents, unless stated, are on
        the torques' side: a log's effort channel is one signal (``side = { q = "joint", tau = "motor" }`` of a cobot
        logging motor currents put them on the joint side before, and identify asked for [[drive]] kt while the
        file's ``motor_kt`` went unused)."""
        if signal == "current" and signal not in self.sides:
            return self.sides.get("tau", "joint")
        return self.sides.get(signal, "joint")

    @property
    def motor_signals(self) -> tuple:
        """The signals recorded on the motor side, in the order of :data:`SIGNALS`."""
        return tuple(signal for signal in SIGNALS if self.side(signal) == "motor")
