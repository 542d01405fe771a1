"""A column the held-out data alone decided is checked on the model identify writes: no joint made worse.

The column choice (``column_choice``) judges its candidates on the free least squares of every candidate column. Where
the training BIC decides and the held-out error agrees, that is the verdict. Where the held-out data alone decide
(``Evidence.departs``: a BIC inside the indifferent band, kept for a clear held-out gain or refused for too small a
one; or a column one validation recording contradicts), the verdict rests on two free least-squares fits of the
training data, and those can be far from the model identify writes: the consistent fit, pulled towards the robot
file. On the Kinova Gen3's CLI defaults (one 4.7-s recording, opti_traj_testing1 -> 2) the free fit predicts the
held-out recording at 5.6/11.6/3.2/1.5/2.5/1.4/0.27 N m, the written model at 1.2/2.8/0.64/0.95/0.30/0.51/0.17. Its
joint-7 drive inertia (BIC -1.1) lowers the free fit's joint 7 by 56 % (0.60 -> 0.27 N m) and raises the written model's
(0.170 -> 0.268): the free fit's joint 7 wants what the pull holds back in link 7 (a tool). Kept, it also says the
torque signal holds rotors (``merged_rotors``: any kept ``Ia<j>``), so the rotors the base parameters hold on joints
1-2 are taken from the training data and held only >= 0, the pull no longer holds the inertia about joint 2 (0.93 ->
3.38, data 4.67, file 0.82), and joint 2 goes from 2.77 to 6.85 N m.

So each such column is decided on the written model, one at a time (in the choice's order): the model is fitted with
the choice as it stands and with that column as the plain rule would have it (its BIC's sign and the pooled held-out
error), and the choice stands unless it is worse than the plain one beyond the never-worse margin
(``never_worse.compare_models``) on some joint of the held-out recordings. A refusal is a model change as much as a
keep: it is judged the same way. Each departure costs one consistent fit; without held-out recordings (the choice then
cross-validates over the training blocks) there is nothing to check on, and the choice stands as made.
"""

from __future__ import annotations

import logging

__all__ = ["check_departures"]

logger = logging.getLogger(__name__)


def check_departures(choice, fit_of, compare) -> tuple:
    """(choice, its fit) after each of ``choice.departures`` was checked on the written model (module docstring).

    ``fit_of(choice)``: the fit of a ``ColumnChoice``; ``compare(before, after)``: the ``never_worse.JointComparison``
    of two fits on the held-out recordings (``before``: the plain rule's, ``after``: the choice's).
    """
    fit = fit_of(choice)
    for evidence in choice.departures:
        current = next(e for e in choice.evidence if (e.term, e.joint) == (evidence.term, evidence.joint))
        plain_fit = fit_of(choice.decided(current, not current.kept, current.reason))
        comparison = compare(plain_fit, fit)
        what = "keeping" if current.kept else "refusing"
        if comparison.worse:
            reason = (f"{current.reason}; but {what} it makes the model identify writes worse on the held-out "
                      f"recordings: {comparison.text()} (as the training BIC decides -> as the held-out data decide), "
                      "so the training BIC decides")  # fmt: skip
            choice, fit = choice.decided(current, not current.kept, reason), plain_fit
        else:
            reason = f"{current.reason}; the model identify writes is no worse on any held-out joint for {what} it"
            choice = choice.decided(current, current.kept, reason)
        logger.info("identify: %s on joint %d: %s", current.term, current.joint + 1, reason)
    return choice, fit
