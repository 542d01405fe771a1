"""Standstill samples of a joint: where friction holds whatever the controller asks, left out of a deflection's blocks.

While a joint stands still (at a slow reversal, at the start or the end of a motion) its friction is static: it holds
whatever torque the controller's integrator builds up, up to the breakaway level, and no friction law of the velocity
predicts it, nor a deflection's column (a joint elasticity's or a backlash's, ``candidates.deflection``), whose
friction part is the friction's change when the velocity is shifted by the deflection's rate. Such samples hold a
residual both rivals share, many times the sensor noise, and on a block of a few seconds a handful of them decide the
block: where pre-sliding and a true elasticity differ by a few hundredths of a N m while the joint moves, the bursts
of a stick make the block's paired difference noise (the short sine experiments of
``benchmarks/presliding_or_elasticity.py``: a true wrist elasticity lower on every block, yet on some in fewer of the
bootstrap resamples than ``presliding_or_elasticity.WIN_SHARE``). The block comparisons of a deflection
(``presliding_or_elasticity.compare``; ``second_opinion.SecondOpinion`` for the keys in ``DEFLECTIONS``) therefore
judge its joint's moving samples only (:func:`moving_samples`), rather than weighing whole blocks by how much they
move: the stick's residual is no evidence for either explanation, so it is left out, not diluted. The validation
recordings stay whole (a finding must improve each as it is).

Which samples stand still is the recording's own: a joint whose filtered velocity is below the velocity where the
diagnosis's friction sign is still in transition (``DiagnosisContext.coulomb_velocity``, the width of its smooth sign
``tanh(qd / v)``: a model file's, chosen by identify from the recording's reversals, ``coulomb_smoothing``; the
robot file's ``SMOOTH_VELOCITY`` otherwise), and the samples within the rise time of the preparation's low-pass
filter of one (``RISE_PERIODS`` periods of its cutoff, the 10-90 % rise of the zero-phase Butterworth,
``coulomb_smoothing``): the measured torque is filtered, so a stick's torque reaches the samples around it. No
threshold of its own: a fixed velocity would call a slow arm's whole motion a standstill, and taking the stick's
filtered neighbours as well (rather than a higher velocity) leaves the slow but sliding samples in.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.coulomb_width import joint_width

__all__ = ["DEFLECTIONS", "MIN_MOVING", "RISE_PERIODS", "block_mask", "moving_samples"]

#: Candidate keys whose block comparisons leave out their joint's standstill samples (module docstring).
DEFLECTIONS = ("joint_elasticity", "backlash")
#: The 10-90 % rise time of the preparation's zero-phase Butterworth [periods of its cutoff] (``coulomb_smoothing``).
RISE_PERIODS = 0.44
#: A block with fewer moving samples than this is judged on all its samples (nothing moving to compare).
MIN_MOVING = 20


def moving_samples(ctx, joint: int) -> np.ndarray:
    """Boolean mask (n_samples,) of the grid samples of ``ctx`` (a ``DiagnosisContext``) where ``joint`` is not at a
    standstill (module docstring): its filtered velocity at least ``ctx.coulomb_velocity``, and no such sample within
    ``RISE_PERIODS / ctx.cutoff_hz`` of it (none without a filter)."""
    still = np.abs(np.asarray(ctx.qd[:, int(joint)], dtype=float)) < joint_width(ctx.coulomb_velocity, int(joint))
    if ctx.cutoff_hz and still.any() and ctx.n_samples > 1:
        step = float(np.median(np.diff(ctx.t)))
        reach = int(round(RISE_PERIODS / float(ctx.cutoff_hz) / step))
        if reach > 0:
            still = np.convolve(still.astype(float), np.ones(2 * reach + 1), mode="same") > 0.5
    return ~still


def block_mask(moving: np.ndarray, block: np.ndarray) -> np.ndarray:
    """Boolean mask over ``block`` (indices of a held-out block) of its samples that move (``moving``, from
    ``moving_samples``); all of them when fewer than ``MIN_MOVING`` do (a block standing still throughout has nothing
    else to judge)."""
    kept = np.asarray(moving, dtype=bool)[block]
    return kept if int(kept.sum()) >= MIN_MOVING else np.ones(len(block), dtype=bool)
