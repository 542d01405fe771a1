"""Offset or balancer, from the data: a constant torque against one that follows the joint's angle as gravity does.

``offset_reading`` reads a data-chosen torque offset by its size: one reaching a tenth of the joint's recorded peak
torque and a fifth of its gravity torque is no sensor's zero error. Size alone does not tell a sensor from a balancer,
though: a joint-torque sensor re-zeroed between recordings can hold 3 N m on a light arm's elbow, a fifth of its
gravity torque. How the torque moves with the joint does. A balancer (a spring, a gas spring, a cam) holds up a share
of the joint's gravity torque, a torque of the joint's own angle of one period per revolution to first order,
``a sin q + b cos q``; a sensor's offset is the same at every angle.

:func:`offset_or_balancer` fits both to the torque the offset takes (the offset plus what the fit leaves on its joint):
the constant, and the sinusoid of the angle with its phase free. Where a balancer's torque is flattest (at its peak,
near horizontal) the sinusoid still curves by ``1 - cos`` of the distance from the peak, a share of its size no
amplitude or phase removes, so a constant is told from it only over a swing wide enough for that curvature to show
beyond the noise; a torque with a slope over the swing is told from a constant over any swing. They are compared
where they differ:

- on the training recordings, cut into ``FOLDS`` contiguous blocks (as ``counterbalance_folds``), each block predicted
  by the columns fitted on the others, the blocks together (the paired RMSE difference's margin, ``never_worse``,
  its standard error at least the spread of the blocks' changes, as ``counterbalance_folds.with_fold_spread``);
- on the held-out part when there is one, by the columns fitted on all the training data.

A judge's vote is the column whose RMSE on its joint is lower beyond that judge's noise margin, none within it.
``BALANCER`` or ``OFFSET`` where a judge votes for it and none against; ``UNDECIDED`` otherwise, when the judges
disagree, and where they say offset over a swing on which a balancer of the offset's size at its flattest departs from
a constant by less than the scatter the constant leaves (``_flattest``): there a constant's win says the sinusoid
fitted something else the residual holds (an unmodelled tool's torque, the links' errors), not that no balancer
could explain it (the heavy virtual arm's shoulder, half a radian near horizontal). Undecided, the reading by size
stands (the offset named a counterbalance, its spring judged as ``counterbalance_column`` judges one in the offset's
place): the data give no reason to overrule it, and the simpler reading, a sensor offset, is the one the offset's size
argues against. The report says which it was and why, with the numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.paired_margin import MARGIN_FLOOR, MARGIN_SIGMAS, paired_rmse_margin

__all__ = [
    "BALANCER",
    "OFFSET",
    "UNDECIDED",
    "OffsetVerdict",
    "offset_or_balancer",
]

BALANCER, OFFSET, UNDECIDED = "balancer", "offset", "undecided"
#: Contiguous blocks per training recording, each held out once (as ``counterbalance_folds.FOLDS``).
FOLDS = 4
#: Where in the recorded swing the flattest balancer's peak is looked for (``_flattest``).
PEAKS = 21


@dataclass(frozen=True)
class OffsetVerdict:
    """What the data say about a large torque offset on ``joint`` (0-based): ``verdict`` (``BALANCER``, ``OFFSET``
    or ``UNDECIDED``), the recorded ``swing`` of the joint [rad], per judge ``(route, rmse with the constant, rmse
    with the sinusoid of the angle, margin)`` [N m], and how far a balancer of the offset's size at its flattest
    departs from a constant over the swing (``flattest``, RMS) against the ``scatter`` the constant leaves [N m]."""

    joint: int
    verdict: str
    swing: float
    judges: tuple = ()
    flattest: float = 0.0
    scatter: float = 0.0
    note: str = ""  # why the data cannot tell, where it is not the swing (``undecided``)

    @property
    def named(self) -> bool:
        """Whether the offset's reading by size stands (a counterbalance named): the data did not say offset."""
        return self.verdict != OFFSET

    def numbers(self) -> str:
        return "; ".join(f"{route}: {a:.4g} N m with the constant, {b:.4g} with a sinusoid of the angle "
                         f"(margin {m:.2g})" for route, a, b, m in self.judges)  # fmt: skip

    def sentence(self) -> str:
        """The data's verdict in the report's words."""
        j, swing = self.joint + 1, f"{self.swing:.3g} rad"
        if self.verdict == BALANCER:
            return (
                f"the torque follows joint {j}'s angle as a balancer's does: over its recorded swing of {swing} "
                f"a sinusoid of the angle (a sin q + b cos q) predicts it better than a constant ({self.numbers()})"
            )
        if self.verdict == OFFSET:
            return (
                f"but the torque is constant over joint {j}'s recorded swing of {swing}, where a balancer's would "
                f"follow the angle (one of this size at its flattest by {self.flattest:.3g} N m RMS, the constant "
                f"leaves {self.scatter:.3g}): the constant predicts it better ({self.numbers()}); a sensor offset (a "
                "re-zeroed sensor's, say), kept as the offset"
            )
        if self.note:
            return f"the data cannot tell a balancer from a constant on joint {j}: {self.note} ({self.numbers()})"
        return (
            f"over joint {j}'s recorded swing of {swing} the data cannot tell a balancer from a constant (a balancer "
            f"of this size at its flattest departs from one by {self.flattest:.3g} N m RMS, the constant leaves "
            f"{self.scatter:.3g}; {self.numbers() or 'no judge'}): the reading by size stands"
        )


def offset_or_balancer(joint: int, training, held_out=(), folds: int = FOLDS) -> OffsetVerdict:
    """The ``OffsetVerdict`` of ``joint`` (module docstring). ``training`` and ``held_out``: per recording, ``(q, tau)``
    of the joint's angle [rad] and the torque the offset takes [N m] (the offset plus the fit's residual there)."""
    training = [(np.asarray(q, dtype=float), np.asarray(t, dtype=float)) for q, t in training]
    held_out = [(np.asarray(q, dtype=float), np.asarray(t, dtype=float)) for q, t in held_out]
    angles = np.concatenate([q for q, _ in training])
    judges, votes = [], []
    blocks = _blocks(training, folds)
    if blocks:
        pooled, changes = ([], []), []
        for k in range(folds):
            fitted = [piece for i, piece in enumerate(blocks) if i != k]
            residuals = _residuals(np.concatenate([p[0] for p in fitted]),
                                   np.concatenate([p[1] for p in fitted]), *blocks[k])  # fmt: skip
            changes.append(_rmse(residuals[1]) - _rmse(residuals[0]))
            for side, residual in zip(pooled, residuals):
                side.append(residual)
        spread = float(np.std(changes, ddof=1) / np.sqrt(folds))
        judges.append(_judge(f"{folds} training blocks", *map(np.concatenate, pooled), votes, spread))
    if held_out:
        q_all, t_all = angles, np.concatenate([t for _, t in training])
        residuals = _residuals(q_all, t_all, np.concatenate([q for q, _ in held_out]),
                               np.concatenate([t for _, t in held_out]))  # fmt: skip
        judges.append(_judge("the held-out part", *residuals, votes))
    decided = set(votes) - {UNDECIDED}
    verdict = decided.pop() if len(decided) == 1 else UNDECIDED
    torque = np.concatenate([t for _, t in training])
    flattest = _flattest(angles, float(np.mean(torque))) if angles.size else 0.0
    scatter = judges[0][1] if judges else float(np.std(torque))
    if verdict == OFFSET and flattest < scatter:  # a balancer this flat is lost in what the constant leaves
        verdict = UNDECIDED
    swing = float(np.ptp(angles)) if angles.size else 0.0
    return OffsetVerdict(int(joint), verdict, swing, tuple(judges), flattest, scatter)


def _flattest(q, level: float) -> float:
    """RMS [N m] by which the flattest torque of the angle a balancer has, a sinusoid peaking inside the recorded
    angles ``q`` and scaled to best match a constant ``level``, departs from that constant: its curvature, which no
    amplitude removes (``1 - cos`` of the distance from its peak)."""
    least = np.inf
    for peak in np.linspace(np.min(q), np.max(q), PEAKS):
        shape = np.cos(q - peak)
        scale = float(np.sum(shape)) / float(shape @ shape)
        least = min(least, _rmse(1.0 - scale * shape))
    return abs(level) * least


def _blocks(training, folds: int) -> list:
    """Per fold, ``(q, tau)`` of the ``k``-th contiguous block of every training recording; empty when a recording
    has fewer samples than blocks."""
    if not training or min(q.size for q, _ in training) < 2 * folds:
        return []
    cut = [np.array_split(np.arange(q.size), folds) for q, _ in training]
    return [(np.concatenate([q[c[k]] for (q, _), c in zip(training, cut)]),
             np.concatenate([t[c[k]] for (_, t), c in zip(training, cut)])) for k in range(folds)]  # fmt: skip


def _residuals(q_fit, t_fit, q, t) -> tuple:
    """(constant's, sinusoid's) residuals (n, 1) on ``(q, t)`` of the two fitted to ``(q_fit, t_fit)``."""
    coefficients, *_ = np.linalg.lstsq(np.column_stack([np.sin(q_fit), np.cos(q_fit)]), t_fit, rcond=None)
    return (t - np.mean(t_fit))[:, None], (t - np.column_stack([np.sin(q), np.cos(q)]) @ coefficients)[:, None]


def _rmse(residual) -> float:
    return float(np.sqrt(np.mean(np.square(residual))))


def _judge(route: str, constant, balancer, votes: list, spread: float = 0.0) -> tuple:
    """``(route, rmse constant, rmse balancer, margin)`` of one judge on the two columns' residuals (n, 1), its vote
    appended to ``votes``: the never-worse margin of the paired difference (``paired_margin``), its standard error at
    least ``spread``."""
    before, after, error = (float(v[0]) for v in paired_rmse_margin(constant, balancer))
    margin = max(MARGIN_SIGMAS * max(error, spread), MARGIN_FLOOR * before)
    votes.append(BALANCER if after < before - margin else OFFSET if before < after - margin else UNDECIDED)
    return route, before, after, margin
