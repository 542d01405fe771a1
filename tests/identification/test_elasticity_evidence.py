"""The report's evidence for a kept joint elasticity (``diagnosis.elasticity_evidence``) against a closed-form truth.

One joint of constant inertia M behind a spring k: the link accelerates as ``A sin(w t)`` (w = 5 Hz) on top of a slow
swing, the torque is ``M qdd_link``, and the recorded angle is the link's plus ``tau / k`` (as the virtual robot's
``JointElasticity`` records it). The nominal model's torque for the recorded angle is ``M qdd_recorded``: in the band
the measured torque is ``1 / (1 - M w^2 / k)`` times it, and the mode is ``sqrt(k / M) / (2 pi)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis.elasticity_evidence import elasticity_evidence, with_elasticity_evidence


@dataclass(frozen=True)
class _Finding:  # the fields of ``report.Finding`` the evidence reads
    effect: str
    joints: tuple
    label: str
    notes: tuple = ()


M, K, W, A = 0.8, 0.8 * (2 * np.pi * 8.0) ** 2, 2 * np.pi * 5.0, 2.0  # mode 8 Hz, oscillation 5 Hz


def _case():
    t = np.arange(0.0, 6.0, 0.005)
    slow = 0.3 * 2 * np.pi
    qdd_link = A * np.sin(W * t) + 1.5 * np.sin(slow * t)
    tau = M * qdd_link
    tau_accel = M * (-A * W**2 * np.sin(W * t) - 1.5 * slow**2 * np.sin(slow * t))
    tau_rate = M * (A * W * np.cos(W * t) + 1.5 * slow * np.cos(slow * t))
    qdd_recorded = qdd_link + tau_accel / K
    zeros = np.zeros((t.size, 1, 1))
    context = SimpleNamespace(t=t, tau=tau[:, None], tau_rate=tau_rate[:, None], tau_accel=tau_accel[:, None],
                              dtau_dq=zeros, dtau_dqd=zeros, mass=np.full((t.size, 1, 1), M))  # fmt: skip
    nominal = (M * qdd_recorded)[:, None]

    class Term:  # the elasticity's column without a friction part (a file that states no friction)
        label = "joint_elasticity[j1]"

        @staticmethod
        def columns(ctx):
            return (-ctx.tau_accel[:, 0] * M)[:, None, None]

    finding = _Finding("joint_elasticity", (0,), Term.label)
    return context, nominal, Term(), finding


def test_the_band_the_ratio_the_mode_and_the_torsion_are_the_truths():
    context, nominal, term, finding = _case()
    text = elasticity_evidence(finding, term, (1.0 / K,), context, nominal)
    low, high = (float(x) for x in text.split("acts at ")[1].split(" Hz")[0].split("-"))
    assert low < 5.0 < high
    ratio = float(text.split("joint 1 is ")[1].split(" x")[0])
    assert ratio == pytest.approx(1.0 / (1.0 - M * W**2 / K), rel=0.05)  # 1.64
    assert "its mode 8 Hz" in text and f"{K:.4g} N m/rad" in text
    assert "its friction part, at velocity reversals, 0% of it" in text
    torsion = np.degrees(np.max(np.abs(context.tau)) / K)
    assert f"torsion {torsion:.2g} deg" in text


def test_only_a_positive_compliance_of_a_kept_elasticity_gets_it():
    context, nominal, term, finding = _case()
    assert elasticity_evidence(finding, term, (-1e-4,), context, nominal) == ""
    spring = _Finding("spring", (0,), "spring[j1]")
    assert elasticity_evidence(spring, term, (1.0 / K,), context, nominal) == ""
    final = SimpleNamespace(terms=(term,), coefficients=((1.0 / K,),))
    noted, other = with_elasticity_evidence((finding, spring), final, context, nominal)
    assert len(noted.notes) == 1 and "behind a spring" in noted.notes[0] and other is spring
