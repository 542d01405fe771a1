"""The velocity the diagnosis's friction columns take their sign from (``context.sign_velocity``, issue 25).

At identify's 10 Hz cutoff a velocity filtered like the torque misplaces the reversals where a joint sticks; the sign
columns, filtered like the recording afterwards, then differ from the filtered true sign by far more than the sensor
noise. The reference here is the exact velocity of a synthetic motion that sticks for about 60 ms at each reversal.
"""

from __future__ import annotations

import numpy as np

from identification.data.preprocessing import PreprocessOptions, preprocess, zero_phase_filter
from identification.data.recording import Recording
from identification.diagnosis.context import SIGN_CUTOFF_FACTOR, sign_velocity

RATE, CUTOFF = 1000.0, 10.0


def _sticking_motion():
    """``(recording, exact velocity)``: 1 rad/s cosines whose speed stays 0 while |cos| < 0.1 (a stick at each
    reversal), the angle integrated exactly (trapezoid at 1 kHz)."""
    t = np.arange(0.0, 8.0, 1.0 / RATE)
    c = np.column_stack([np.cos(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.3 * t + 0.4)])
    qd = np.sign(c) * np.maximum(np.abs(c) - 0.1, 0.0)
    q = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (qd[1:] + qd[:-1]) / RATE, axis=0)])
    return Recording(t=t, q=q, tau=np.zeros_like(q)), qd


def test_the_sign_velocity_places_the_reversals_where_the_joint_sticks():
    raw, exact = _sticking_motion()
    prepared = preprocess(raw, PreprocessOptions(cutoff_hz=CUTOFF))
    sharp = sign_velocity(raw, prepared, CUTOFF)
    assert sharp.shape == prepared.qd.shape and not sharp.flags.writeable
    inner = slice(int(0.5 * RATE), -int(0.5 * RATE))

    def column_error(velocity):  # the filtered sign column against the filtered exact sign, as the torque sees it
        error = zero_phase_filter(np.sign(velocity) - np.sign(exact), RATE, CUTOFF)[inner]
        return float(np.sqrt(np.mean(error**2)))

    filtered, sharper = column_error(prepared.qd), column_error(sharp)
    assert sharper < 0.5 * filtered, (filtered, sharper)
    # the velocity itself: the sharper filter follows the exact one closer where the joint moves
    moving = (np.abs(exact) > 0.2)[inner]
    assert np.max(np.abs(sharp - exact)[inner][moving]) < np.max(np.abs(prepared.qd - exact)[inner][moving])


def test_without_a_raw_recording_or_a_filter_the_preprocessed_velocity_is_kept():
    raw, _ = _sticking_motion()
    prepared = preprocess(raw, PreprocessOptions(cutoff_hz=CUTOFF))
    assert sign_velocity(None, prepared, CUTOFF) is prepared.qd
    assert sign_velocity(raw, prepared, None) is prepared.qd
    # a cutoff so close to the rate that twice it would pass a quarter of it: the preprocessed velocity
    slow = preprocess(raw, PreprocessOptions(cutoff_hz=0.3 * RATE))
    assert SIGN_CUTOFF_FACTOR * 0.3 * RATE > 0.25 * RATE
    assert sign_velocity(raw, slow, 0.3 * RATE) is slow.qd
