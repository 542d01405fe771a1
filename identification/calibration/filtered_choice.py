"""Per joint, which Coulomb column the data want: ``tanh`` of the filtered velocity, or the raw sign filtered like the
torque (``filtered_sign``).

The column choice (``column_choice``) holds both columns of every joint among its candidates (``column_candidates``:
``fc<j>`` and ``fcf<j>``), so the choice costs no fit of its own: each joint's two forms are two sub-models of the same
summed normal equations. The two have as many parameters, so the training BIC's change is the log-likelihood's; the
verdict is the one every candidate gets (``column_verdict``: the training BIC and the joint's held-out error agree, a
clear held-out gain where the BIC does not decide, and no rise on any validation recording).

The joints are judged one at a time, the largest training gain first, each beside the forms the joints before it took:
a joint's filtered form moves the shared rigid-body parameters, and another joint whose own step is still smeared by
``tanh`` reads that as a rise it does not show once its own column is filtered too (on a virtual arm with a sharp
Coulomb step on four joints, judged each against ``tanh`` on every other joint, two of them were refused for a rise of
2-4 % on another that both then remove). A joint's filtered form must not raise another joint's held-out error by more
than ``OTHER_JOINTS`` beside the forms taken so far; one refused so is judged once more after the others. The model
with every joint's chosen form must then be never worse than the one with ``tanh`` on every joint: where a joint's
held-out error rises by more than ``OTHER_JOINTS``, the kept joint of the smallest training gain goes back to ``tanh``,
until none does. The choice is not judged again on the model identify writes (``column_check``, eight refits per
column by block folds without validation recordings): its own never-worse rule stands for that check (on the TX40 the
check doubled identify's CPU time, the filtered forms' departures from the plain rule judged by fold refits).

A joint the shape choice gave the Stribeck shape is a candidate too, against that shape: a Stribeck fit with a hump at
low speed also follows the filter's smearing of a sharp Coulomb step (which it passes for a Stribeck effect when the
hump is above the Coulomb level), so the filtered Coulomb-viscous form, two parameters fewer, replaces it where the
data want it so (the BIC counts the two) and it lowers the joint's held-out RMS error clearly, by ``HELD_OUT_GAIN``
(a shape the data chose is not traded for a form the free least squares prefer by a little: a heavy virtual arm's
Stribeck joint 1, replaced on such a gain, validated 20 % worse in the model identify writes). A Stribeck joint keeps
``tanh``: its Coulomb and static columns share the smooth sign with the hump of the filtered velocity.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.column_candidates import solve_columns
from identification.calibration.column_verdict import HELD_OUT_GAIN, Evidence, verdict

__all__ = ["OTHER_JOINTS", "filtered_evidence"]

#: The rise of a joint's held-out RMS error (a ratio) over the model with ``tanh`` on every joint that no choice of
#: filtered forms may cause.
OTHER_JOINTS = 1.01
#: The parameters the Stribeck shape adds to a joint (``column_choice.STRIBECK_PARAMETERS``: fs and vs).
SHAPE_PARAMETERS = 2


def filtered_evidence(found, stribeck) -> tuple:
    """(one ``Evidence`` per joint, term ``"filtered"``; the Stribeck joints left) of ``found``
    (``column_candidates.Candidates`` with the ``fcf<j>`` columns): each joint's filtered Coulomb-viscous form against
    its form with ``tanh`` (the Stribeck shape on the joints of ``stribeck``, 0-based), module docstring."""
    gains = _training_gains(found, tuple(stribeck))
    start = found.evaluate(tuple(stribeck))  # ``tanh`` on every joint: what no joint may be worse than
    out, plain, kept, waiting = {}, start, [], [int(k) for k in np.argsort(-gains, kind="stable")]
    for _ in range(2):  # a joint refused for another joint's rise is judged again beside the forms kept after it
        again = []
        for j in waiting:
            shape = tuple(k for k in stribeck if k not in kept)
            out[j], evaluated, others = _judged(found.with_filtered(kept), shape, j, plain)
            if out[j].kept:  # the model with it is the one the next joints are judged beside
                kept, plain = [*kept, j], evaluated
            again += [j] if others else []
        waiting = again
    while kept:
        held = found.with_filtered(kept).evaluate(tuple(k for k in stribeck if k not in kept))[1]
        worse = [k for k in range(held.size) if held[k] > start[1][k] * OTHER_JOINTS**2]
        if not worse:
            break
        j = min(kept, key=lambda k: gains[k])
        rises = "; ".join(f"joint {k + 1} by {np.sqrt(held[k] / start[1][k]) - 1:.1%}" for k in worse)
        note = f", but the forms kept raise the held-out error over tanh on every joint ({rises}): the least gain goes"
        out[j] = replace(out[j], kept=False, departs=False, reason=out[j].reason + note)
        kept.remove(j)
    return [out[j] for j in range(found.effective.size)], tuple(k for k in stribeck if k not in kept)


def _training_gains(found, shape) -> np.ndarray:
    """Per joint the training log-likelihood its filtered form gains, alone (the order of :func:`filtered_evidence`):
    one weighted least squares each, without held-out predictions."""
    (total, weighted) = found.summed(None)
    plain = total.residual_sum(solve_columns(weighted, found.transform(shape))[0])
    gains = np.zeros(found.effective.size)
    for j in range(gains.size):
        other = (tuple(k for k in shape if k != j), (f"fc{j + 1}",))
        gains[j] = np.log(plain[j] / total.residual_sum(solve_columns(weighted, found.transform(*other))[0])[j])
    return gains * found.effective


def _judged(found, shape, j, plain) -> tuple:
    """(Evidence, ``Candidates.evaluate`` of the model with it, whether another joint's rise refused it) of joint
    ``j``'s filtered form beside ``found``'s forms and the Stribeck joints ``shape``; ``plain``:
    ``found.evaluate(shape)``, the model as it stands. Kept only where no other joint's held-out error rises by more
    than ``OTHER_JOINTS`` over ``plain``'s."""
    smooth, filtered = (shape, ()), (tuple(k for k in shape if k != j), (f"fc{j + 1}",))
    train_s, held_s, _, _ = plain
    evaluated = train_f, held_f, x, _ = found.evaluate(*filtered)
    n = found.effective[j]
    # the training BIC's change: the log-likelihood's, and the two parameters of a Stribeck shape it replaces
    delta = float(n * np.log(train_s[j] / train_f[j]) + (SHAPE_PARAMETERS * np.log(n) if j in shape else 0.0))
    ratio = float(held_f[j] / held_s[j])
    kept, reason = verdict(found, filtered, smooth, j, delta, ratio)
    if kept and j in shape and 1.0 - np.sqrt(ratio) < HELD_OUT_GAIN:
        kept, reason = False, (f"{reason}, by {1.0 - np.sqrt(ratio):.0%}: less than the {HELD_OUT_GAIN:.0%} asked to "
                               "replace the Stribeck shape the data chose")  # fmt: skip
    others = [k for k in range(held_s.size) if k != j and held_f[k] > held_s[k] * OTHER_JOINTS**2] if kept else []
    if others:
        rises = "; ".join(f"joint {k + 1} by {np.sqrt(held_f[k] / held_s[k]) - 1:.1%}" for k in others)
        kept, reason = False, f"{reason}, but it raises the held-out error of another joint ({rises})"
    estimate = float(x[found.n_base + found.names.index(f"fcf{j + 1}")])
    # decided here, beside every joint's form and never worse than tanh on every joint: not judged again on the model
    # identify writes (``column_check``), whose block folds would refit the arm eight times per joint
    return Evidence("filtered", j, delta, ratio, kept, reason, estimate, None, False), evaluated, bool(others)
