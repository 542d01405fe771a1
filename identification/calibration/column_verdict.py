"""One verdict on every candidate column of the column choice (``column_choice``): kept or not, and why.

A candidate of one joint (an offset, the Stribeck shape, a drive inertia, a drive loss, the viscous power law) is kept
when the training BIC wants it and it lowers the joint's held-out error, clearly where the BIC does not decide, and on
each validation recording (:func:`verdict`); :class:`Evidence` records what the data said.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["HELD_OUT_GAIN", "INDIFFERENT_BIC", "STRONG_BIC", "Evidence", "plain_reason", "verdict"]

#: A column the training data are indifferent to (its BIC change within ``INDIFFERENT_BIC`` of 0: "not worth more
#: than a bare mention", Kass and Raftery 1995) is kept when it lowers the joint's held-out RMS error by
#: ``HELD_OUT_GAIN`` (the gain a diagnosis asks of a finding), whatever its kind. A joint-torque sensor's offset moves
#: between recordings (the Kinova Gen3's joint 7 shows only noise and offset); on one short recording the training BIC
#: cannot tell it from viscous friction, which then absorbs it and predicts a faster held-out motion badly (joint 7:
#: 0.40 N m against 0.21 for the robot file; with its offset 0.17).
INDIFFERENT_BIC, HELD_OUT_GAIN = 2.0, 0.2
#: A column the training data are against, but not strongly (its BIC change from ``-STRONG_BIC`` to
#: ``-INDIFFERENT_BIC``: "positive" evidence, short of "strong", Kass and Raftery 1995), is kept too when the held-out
#: data want it clearly (``HELD_OUT_GAIN``, on each validation recording), and identify checks that verdict on the model
#: it writes (``column_check``). The Kinova's joint-7 offset is at BIC -1.95 with the Coulomb smoothing at 0.05 rad/s
#: and -2.08 at the data's 0.0206 (held-out gain 35 %; the written model's joint 7 0.40 N m without it, 0.17 with): a
#: knife-edge at -2 that no training evidence short of strong should decide against a held-out gain that clear.
STRONG_BIC = 6.0


@dataclass(frozen=True)
class Evidence:
    """What the data said about one candidate of one joint: ``term`` ``"stribeck"`` (the shape), ``"offset"``,
    ``"Ia"`` or ``"loss"`` (a drive loss: ``estimate`` is its coefficient ``mu``).

    ``delta_bic``: the training BIC without the candidate minus with it (positive: the training data want it);
    ``held_out_ratio``: held-out sum of squared residuals with it over without it (below 1: it predicts
    better); ``estimate`` and ``std``: its least-squares value in the full model (per-joint columns); ``departs``: the
    verdict departs from the plain rule's (the training BIC's sign and the pooled held-out error), so the held-out
    data alone decided it (an indifferent BIC and the gain asked, or a rise on one validation recording): identify
    checks such a column on the model it writes (``column_check``); ``written``: an offset kept by the plain rule that
    identify checks on the model it writes all the same, with validation recordings (``column_choice``, step 3).
    """

    term: str
    joint: int | None
    delta_bic: float
    held_out_ratio: float
    kept: bool
    reason: str
    estimate: float | None = None
    std: float | None = None
    departs: bool = False
    written: bool = False

    def to_dict(self) -> dict:
        out = asdict(self)
        out["joint"] = None if self.joint is None else self.joint + 1
        return out


def verdict(found, full, sub, j, delta, ratio) -> tuple:
    """(kept, reason) of one candidate of joint ``j``, of any kind (offset, Stribeck shape, drive inertia, drive loss;
    ``full`` and ``sub``: the models with and without it, as ``(stribeck, dropped)``): the training BIC wants it and it
    lowers the joint's held-out error, clearly (by ``HELD_OUT_GAIN``) where the BIC is indifferent (within
    ``INDIFFERENT_BIC`` of 0, either way) or against it short of strongly (down to ``-STRONG_BIC``), and on each
    validation recording (``Candidates.part_sums``): a column one recording contradicts is that recording's (a sensor's
    offset, its friction), not the arm's, and a pooled gain on the others does not outvote it."""
    gain = 1.0 - np.sqrt(ratio)
    if -STRONG_BIC <= delta <= INDIFFERENT_BIC:
        kept = bool(gain >= HELD_OUT_GAIN)
        training = "are indifferent" if delta >= -INDIFFERENT_BIC else "are against it, not strongly,"
        reason = (f"the training data {training} (BIC {delta:+.2g}) and it lowers the held-out RMS error by "
                  f"{gain:.0%}" + ("" if kept else f", less than the {HELD_OUT_GAIN:.0%} asked of a column the "
                  "training data do not decide"))  # fmt: skip
    else:
        kept, reason = delta > 0 and ratio < 1, plain_reason(delta, ratio, delta > 0 and ratio < 1)
    if not kept or not found.parts:
        return kept, reason
    count = np.array([max(part.count[j], 1) for part in found.parts])
    with_it = np.sqrt(found.part_sums(*full)[:, j] / count)
    without = np.sqrt(found.part_sums(*sub)[:, j] / count)
    rises = [f"validation recording {k + 1} of {len(count)}: {b:.3g} -> {a:.3g} N m"
             for k, (b, a) in enumerate(zip(without, with_it)) if a >= b]  # fmt: skip
    if rises:
        training = (
            "want" if delta > INDIFFERENT_BIC else "are indifferent to" if delta >= -INDIFFERENT_BIC else "are against"
        )
        return False, (f"the training data {training} it (BIC {delta:+.2g}) and it lowers the held-out RMS error "
                       f"taken together by {gain:.0%}, but it raises it on {'; '.join(rises)}: that recording's, not "
                       "the arm's")  # fmt: skip
    return kept, reason


def plain_reason(delta, ratio, kept) -> str:
    if kept:
        return "the training data want it (BIC) and it predicts the held-out data better"
    if delta <= 0:
        return "the training data do not want it (BIC)"
    return "the training data want it (BIC) but it does not predict the held-out data better"
