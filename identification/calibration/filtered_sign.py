"""The Coulomb column filtered like the torque: the preparation's zero-phase filter applied to the raw velocity's sign.

The preparation low-pass filters the torque (``trajectory_data.prepare_recording``), so the friction step a joint's
torque shows at each velocity reversal is the filter's response to a sign, smeared over its impulse response. The
Coulomb column ``tanh(qd / v)`` of the filtered velocity is another curve there: ``filter(sign(qd)) !=
tanh(filter(qd) / v)``, and at every reversal the regressor and the torque disagree (the parallel filtering of
Gautier: each regressor column filtered as the torque is). The filtered form is the same filter applied to
``tanh(qd_raw / SIGN_WIDTH)``, ``qd_raw`` the central differences of the raw angles: a sharp sign, smeared the way
the torque's friction step is.

The column choice (``column_choice``) decides it per joint from the data, beside the joint's ``tanh`` column in the
same candidate fit (its training BIC and held-out error, never worse on another joint): a joint whose friction steps
sharply at its reversals wants it, one whose sensor or drive smooths the step itself may not. The chosen joints are
part of the model file's preparation (``model_preparation``): every command that prepares a recording for the model
computes the same column. A prediction at a single state (``CalibratedModel.predict`` without the prepared
recording's ``sign``, the exported C) has no series to filter and keeps ``tanh(qd / v)``: an approximation at the
reversals, exact away from them.
"""

from __future__ import annotations

import numpy as np

from identification.data.preprocessing import central_difference, zero_phase_filter

__all__ = ["SIGN_WIDTH", "coulomb_sign", "filtered_sign", "filtered_text"]

#: [rad/s] the raw velocity's sign is ``tanh(qd_raw / SIGN_WIDTH)`` before the filter: sharp beside the filter's
#: smearing, soft enough that an encoder's velocity noise at rest averages out.
SIGN_WIDTH = 0.005


def filtered_sign(t, q, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """The filtered smooth sign of one joint's raw angles ``q`` (n_samples,) at times ``t``: the preparation's
    zero-phase filter (``rate_hz``, ``cutoff_hz``) of ``tanh(qd_raw / SIGN_WIDTH)``, every sample (the caller keeps
    the ones the preparation keeps)."""
    qd, _ = central_difference(np.asarray(t, dtype=float), np.asarray(q, dtype=float))
    return zero_phase_filter(np.tanh(qd / SIGN_WIDTH), rate_hz, cutoff_hz)


def coulomb_sign(qd, coulomb_velocity, sign=None) -> np.ndarray:
    """The Coulomb column's sign at velocities ``qd`` (numpy): ``tanh(qd / v)``, or ``sign`` (same shape; NaN on the
    joints of the ``tanh`` form) where it is a number: the filtered form of those joints."""
    smooth = np.tanh(qd / coulomb_velocity)
    return smooth if sign is None else np.where(np.isnan(sign), smooth, sign)


def filtered_text(joints) -> str:
    """``"the filtered sign on joints 1, 3"`` (0-based ``joints``), for the report's drive-column lines."""
    if not joints:
        return "Coulomb column: tanh(qd / v) of the filtered velocity on every joint (chosen from the data)"
    named = ", ".join(str(j + 1) for j in joints)
    return (
        f"Coulomb column: the preparation's filter applied to the raw velocity's sign on joint"
        f"{'s' if len(joints) > 1 else ''} {named}, tanh(qd / v) on the others (chosen from the data: filtered "
        "like the torque, the friction step at each reversal)"
    )
