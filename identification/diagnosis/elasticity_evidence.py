"""What a kept joint elasticity rests on, in the report: the frequencies its torque acts at and the mode it implies.

A compliance of ``c`` between the recorded angle and the link changes the model's torque by its friction part (the
velocity shifted by ``c dtau/dt``, which matters at velocity reversals) and its rigid part, chiefly ``-c M[:, j]
d^2 tau_j/dt^2`` (``candidates.deflection``). The rigid part grows with the square of the frequency: it is the torque a
link mass behind a spring of stiffness ``k = 1/c`` adds near its mode ``sqrt(k / M_jj) / (2 pi)``, where the link
swings more than the recorded angle shows. So a true elasticity leaves its mark in a band of frequencies where the
measured torque exceeds the nominal model's, in phase with it, by more than an inertia off by tens of per cent can give
(a wrong inertia scales the rigid body's torque alike at every frequency, friction acts at the reversals).

``elasticity_evidence`` states that on the training recording for each ``joint_elasticity`` finding: the band around
the peak of its torque's spectrum and the share of its power there, the share of its friction part, the ratio of the
measured torque to the nominal model's in that band, the mode, and the torsion at the peak torque. On the Kinova Gen3's
joint-torque sensors the compliances of joints 1 and 2 act in a band the commanded trajectory does not hold, the motor
currents carry that band alike (``benchmarks/kinova_gen3.py``, ``elasticity_check``), and the same column fitted to
the currents' residual gives about the same stiffness: a deflection between the recorded angle and the link, not a
stand-in for the file's inertia, its tool or a one-way joint's friction (the file states no friction to shift).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.signal import butter, sosfiltfilt

from identification.metrics import rms

BAND = np.sqrt(2.0)  # the band reported is the spectrum's peak frequency divided and multiplied by this
ORDER = 2  # Butterworth band-pass order (zero-phase) of the band's torques


def elasticity_evidence(finding, term, coefficients, context, nominal) -> str:
    """The sentence on ``finding`` (a kept ``joint_elasticity``, its ``term`` and fitted ``coefficients``) on the
    training ``context`` with the nominal model's torque ``nominal`` (n_samples, n_dof); "" for any other finding,
    a compliance that is not positive, or a recording too short for a band."""
    c = float(np.ravel(coefficients)[0]) if len(np.ravel(coefficients)) else 0.0
    if finding.effect != "joint_elasticity" or len(finding.joints) != 1 or not c > 0:
        return ""
    j, t = finding.joints[0], np.asarray(context.t, dtype=float)
    rigid = -c * (
        context.tau[:, j] * context.dtau_dq[:, j, j]
        + context.tau_rate[:, j] * context.dtau_dqd[:, j, j]
        + context.tau_accel[:, j] * context.mass[:, j, j]
    )
    whole = c * np.asarray(term.columns(context))[:, j, 0]
    rate = 1.0 / float(np.median(np.diff(t))) if t.size > 1 else 0.0
    frequency = np.fft.rfftfreq(t.size, 1.0 / rate) if rate > 0 else np.zeros(0)
    power = np.abs(np.fft.rfft(rigid - rigid.mean())) ** 2
    if frequency.size < 4 or not np.sum(power[1:]) > 0:
        return ""
    peak = float(frequency[1:][np.argmax(power[1:])])
    low, high = peak / BAND, min(peak * BAND, 0.45 * rate)
    if not 0 < low < high:
        return ""
    inside = (frequency >= low) & (frequency <= high)
    sos = butter(ORDER, [low, high], btype="band", fs=rate, output="sos")
    measured, model = (sosfiltfilt(sos, x) for x in (context.tau[:, j], np.asarray(nominal)[:, j]))
    ratio = rms(measured) / max(rms(model), 1e-12)
    inertia = float(np.mean(context.mass[:, j, j]))
    mode = np.sqrt(1.0 / (c * inertia)) / (2.0 * np.pi)
    friction = rms(whole - rigid) / max(rms(whole), 1e-12)
    peak_torque = float(np.max(np.abs(context.tau[:, j])))
    n = j + 1
    share = float(np.sum(power[inside]) / np.sum(power))
    return (
        f"joint {n}'s compliance acts at {low:.2g}-{high:.2g} Hz on the training recording ({share:.0%} of its "
        f"torque's power; its friction part, at velocity reversals, {friction:.0%} of it): there the measured torque "
        f"of joint {n} is {ratio:.2g} x the nominal model's for the recorded angle, as a link (inertia "
        f"{inertia:.3g} kg m^2 about joint {n}) swinging behind a spring of {1.0 / c:.4g} N m/rad (its mode "
        f"{mode:.2g} Hz) gives; "
        f"torsion {np.degrees(c * peak_torque):.2g} deg at the peak torque {peak_torque:.3g} N m. An inertia off by "
        "tens of per cent scales the torque alike at every frequency, and friction acts at the reversals"
    )


def with_elasticity_evidence(findings, final, context, nominal) -> tuple:
    """``findings`` with each kept joint elasticity's ``elasticity_evidence`` among its notes (the final fit's terms
    and coefficients by label; ``context`` and ``nominal`` the training recording's)."""
    fitted = {term.label: (term, coefficients) for term, coefficients in zip(final.terms, final.coefficients)}
    out = []
    for finding in findings:
        term, coefficients = fitted.get(finding.label, (None, ()))
        note = "" if term is None else elasticity_evidence(finding, term, coefficients, context, nominal)
        out.append(replace(finding, notes=finding.notes + (note,)) if note else finding)
    return tuple(out)
