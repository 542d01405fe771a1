"""The inputs of the motor and gravity steps built from recordings: the motor step's pair of sweeps, and folding.

The motor and gravity experiments run out along a path and retrace it (paper 3.1-3.2);
:func:`fold_out_and_back` averages such a recording with its time mirror, which cancels friction
(odd in qd), and :class:`MotorExperiment` pairs one joint's folded sweeps without and with the
calibration mass. Used by :mod:`identification.calibration.steps` (which re-exports both) and
:mod:`identification.calibration.preparation`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError, ShapeError

__all__ = ["MotorExperiment", "fold_out_and_back"]


@dataclass(frozen=True, eq=False)
class MotorExperiment:
    """One joint's motor calibration (paper 3.1): the same sweep without and with the known mass.

    Parameters
    ----------
    joint : int
        Swept joint, 0-based.
    nominal : Recording
        Folded, preprocessed sweep without the calibration mass (currents required).
    loaded : Recording
        Folded, preprocessed sweep with the mass, same sample count as ``nominal``.
    """

    joint: int
    nominal: Recording
    loaded: Recording

    def __post_init__(self):
        for name in ("nominal", "loaded"):
            if not isinstance(getattr(self, name), Recording):
                raise ParameterError(
                    f"MotorExperiment.{name} must be a Recording; got {type(getattr(self, name)).__name__}."
                )
        if self.nominal.n_samples != self.loaded.n_samples:
            raise ShapeError(
                f"MotorExperiment.loaded must have the sample count of nominal ({self.nominal.n_samples}); got "
                f"{self.loaded.n_samples}. Record both sweeps along the same reference at the same rate."
            )
        for name in ("nominal", "loaded"):
            if getattr(self, name).current is None:
                raise RecordingError(
                    f"MotorExperiment.{name}.current is missing; Kt needs motor currents. Record currents i1..in."
                )


def fold_out_and_back(recording: Recording, tolerance: float = 0.02) -> Recording:
    """Average an out-and-back experiment with its time mirror: sample k with sample n-1-k.

    The motor and gravity experiments retrace their path, so ``q[k] == q[n-1-k]`` while the velocity
    changes sign; averaging the torques (or currents) of the pair cancels friction (odd in qd).
    The result keeps the first half: averaged q, tau and current, and the forward velocity and
    acceleration (for speed thresholds).

    Parameters
    ----------
    recording : Recording
        Preprocessed (qd present).
    tolerance : float
        Largest allowed ``|q[k] - q[n-1-k]|`` [rad or m].

    Returns
    -------
    Recording
        ``n_samples // 2`` samples.

    Raises
    ------
    RecordingError
        When the recording does not retrace its path or has no velocities.
    """
    if recording.qd is None:
        raise RecordingError(
            f"Recording.qd is missing ({recording.name}); fold_out_and_back needs velocities. "
            "Run preprocess(recording) first."
        )
    n = recording.n_samples
    half = n // 2
    first, mirror = np.arange(half), n - 1 - np.arange(half)
    gap = np.abs(recording.q[first] - recording.q[mirror]).max()
    if not gap <= tolerance:
        raise RecordingError(
            f"Recording.q must retrace its path (q[k] == q[n-1-k]) to fold it; got a gap of {gap:.3g} "
            f"({recording.name}), above tolerance {tolerance}. Record the experiment forward and back along "
            "the same path with symmetric timing."
        )

    def avg(x):
        return None if x is None else 0.5 * (x[first] + x[mirror])

    return Recording(
        t=recording.t[first],
        q=avg(recording.q),
        tau=avg(recording.tau),
        current=avg(recording.current),
        qd=recording.qd[first],
        qdd=None if recording.qdd is None else recording.qdd[first],
        name=f"{recording.name} (folded)",
    )
