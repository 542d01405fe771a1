"""Block cross-validation of identify's counterbalance spring over the training recordings (no held-out recording).

``psdm identify robot.toml rec.csv`` without ``--validate`` has no recording to judge the spring its envelope report
names on (``counterbalance_column``). It takes the second opinion the diagnosis takes with one validation recording
(``diagnosis.second_opinion``, block cross-validation): each training recording is cut into ``FOLDS`` contiguous
blocks; each block is held out once, and the models without and with the springs, both identified on the rest (the
pieces before and after the block, each a recording of its own), predict it. The blocks' predictions are judged taken
together (``residual_comparison`` of every held-out residual: the RMSE per joint and the never-worse margin of its
paired difference, the standard error at least the spread of the folds' changes: ``with_fold_spread``), and each
block's comparison is kept (``BlockFolds.compare``): the spring must lower its own joint's error in every block
(``counterbalance_column.Opinion.lowers``), as on each held-out recording. A block where it is worse, even within
that block's noise, is a stretch of the motion it does not fit: the TX40's spurious cubic spring on joint 2 (named
while its links absorbed its rotors) raised the first block (the start from the home pose) by 6 % while lowering the
others by 24-34 %, and raised the held-out end (the return to the home pose) from 3.80 to 4.22 N m. The heavy arm's
cam counterbalance lowers joint 2 in every block (seed 2: 217 -> 143, 434 -> 162, 149 -> 102, 286 -> 138 N m).

Blocks are only cut where every piece stays long enough to be prepared (``MIN_BLOCK_S``, and ``MIN_BLOCK_PERIODS``
periods of the filter), and not for recordings that carry payloads (a held-out block would be judged without its
load): then nothing is tried and the report says why, as when a fold cannot be identified (a piece that does not
excite what the fit identifies: ``FoldFailure``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from identification.calibration.finding_value import validation_rmse
from identification.calibration.never_worse import JointComparison, TrainingRefits, paired_rmse_margin
from identification.calibration.shared_barrier import shared_solvers
from psdm_casadi.errors import PSDMError

__all__ = [
    "FOLDS",
    "MIN_BLOCK_PERIODS",
    "MIN_BLOCK_S",
    "FoldFailure",
    "BlockFolds",
    "block_folds",
    "fold_comparison",
    "residual_comparison",
    "with_fold_spread",
]

#: Contiguous blocks per training recording, each held out once (the diagnosis's second opinion uses as many).
FOLDS = 4
#: Shortest block [s], and in filter periods (the preparation trims periods at each end of every piece).
MIN_BLOCK_S = 1.5
MIN_BLOCK_PERIODS = 15

ROUTE = "block cross-validation over the training recordings"


class FoldFailure(Exception):
    """A fold could not be identified or judged (``BlockFolds.compare``); its message says why, for the report."""


@dataclass(frozen=True, eq=False)
class BlockFolds:
    """The training recordings cut for the cross-validation.

    Attributes
    ----------
    training : tuple of tuple of Recording
        Per fold, the pieces the models are identified on.
    held_out : tuple of tuple of Recording
        Per fold, the blocks they predict.
    baselines : dict
        Per fold, the model without springs once identified (shared by every spring shape tried).
    solvers : dict
        The barrier-path solvers the folds' fits share (``shared_barrier``: one per structure, over every spring shape
        tried and the never-worse refits, ``refits``).
    """

    training: tuple
    held_out: tuple
    baselines: dict = field(default_factory=dict)
    solvers: dict = field(default_factory=dict, repr=False)

    @property
    def route(self) -> str:
        return f"{ROUTE} ({len(self.training)} blocks)"

    def baseline(self, k: int, identify):
        """Fold ``k``'s model without springs: ``identify(pieces)``, once."""
        if k not in self.baselines:
            self.baselines[k] = identify(self.training[k])
        return self.baselines[k]

    def refits(self, identify_without, identify_with) -> TrainingRefits:
        """The never-worse second opinion of these blocks (``never_worse.TrainingRefits``): block ``k``'s models
        without the springs (``baseline``, the labels ``("springs",)``) and with them (``identify_with(pieces)``), for
        a joint a held-out recording finds over its margin."""
        return TrainingRefits(lambda labels, k: self.baseline(k, identify_without) if labels
                              else identify_with(self.training[k]), len(self.training), ("springs",),
                              solvers=self.solvers)  # fmt: skip

    def compare(self, identify_without, identify_with, model, kt=None) -> tuple:
        """(comparison over every held-out block taken together, per-fold comparisons) of the models
        ``identify_without(pieces)`` and ``identify_with(pieces)`` of each fold on its held-out blocks
        (``residual_comparison`` of :meth:`residuals`)."""
        return fold_comparison(self.residuals(identify_without, identify_with, model, kt))

    def residuals(self, identify_without, identify_with, model, kt=None) -> tuple:
        """Per fold, ``(without, with)``: the residuals (n_samples, n_dof) of its models ``identify_without(pieces)``
        (``baseline``) and ``identify_with(pieces)`` on its held-out blocks, in turn; ``FoldFailure`` naming the fold
        that could not be identified or judged."""
        out = []
        for k, (pieces, held) in enumerate(zip(self.training, self.held_out)):
            try:
                with shared_solvers(self.solvers):  # judges: one barrier-path solver per structure
                    without, with_it = self.baseline(k, identify_without), identify_with(pieces)
                residuals = [[_residual(m, model, block, kt) for block in held] for m in (without, with_it)]
            except PSDMError as error:  # a piece that excites too little, too short to prepare, a fit that fails
                raise FoldFailure(f"block {k + 1} of {len(self.training)}: {str(error).splitlines()[0]}") from error
            out.append(tuple(np.concatenate(r, axis=0) for r in residuals))
        return tuple(out)


def _residual(calibrated, model, recording, kt) -> np.ndarray:
    """Measured less predicted torque (n_samples, n_dof) of a model on a raw recording, prepared as its file says."""
    _, _, prepared, predicted = validation_rmse(calibrated, model, recording, kt)
    return np.asarray(prepared.tau) - np.asarray(predicted)


def residual_comparison(before: np.ndarray, after: np.ndarray) -> JointComparison:
    """``JointComparison`` of two models' residuals on the same samples, with the never-worse margin
    (``never_worse.paired_rmse_margin``: circular block bootstrap of the paired difference, never below the floor)."""
    return JointComparison.from_noise(*paired_rmse_margin(before, after))


def block_folds(recordings, configurations=None, cutoff_hz=None, folds: int = FOLDS) -> BlockFolds | str:
    """The ``BlockFolds`` of ``recordings`` (filtered at ``cutoff_hz``, None: unfiltered), or why they cannot be cut
    (a sentence for the report)."""
    if configurations is not None and any(c.kind != "none" for c in configurations):
        return "the training recordings carry payloads (a held-out block would be judged without its load)"
    durations = [float(r.t[-1] - r.t[0]) for r in recordings]
    shortest = min(durations)
    block = max(MIN_BLOCK_S, MIN_BLOCK_PERIODS / cutoff_hz if cutoff_hz else 0.0)
    if shortest / folds < block:
        short = [f"{os.path.basename(str(r.name)) or 'a training recording'} ({d:.3g} s)"
                 for r, d in zip(recordings, durations) if d / folds < block]  # fmt: skip
        every = "" if len(recordings) == 1 else " (every training recording is cut alike)"
        return (f"{' and '.join(short)} {'are' if len(short) > 1 else 'is'} too short to cut into {folds} blocks of "
                f"at least {block:.3g} s{every}")  # fmt: skip
    training, held_out = [[] for _ in range(folds)], [[] for _ in range(folds)]
    for recording in recordings:
        edges = np.linspace(0, recording.n_samples, folds + 1).astype(int)
        for k in range(folds):
            held_out[k].append(recording.slice(edges[k], edges[k + 1]))
            if edges[k] > 0:
                training[k].append(recording.slice(0, edges[k]))
            if edges[k + 1] < recording.n_samples:
                training[k].append(recording.slice(edges[k + 1], None))
    return BlockFolds(tuple(map(tuple, training)), tuple(map(tuple, held_out)))


def fold_comparison(residuals) -> tuple:
    """(comparison over every held-out block taken together, with the folds' spread: ``with_fold_spread``; per-fold
    comparisons) of ``BlockFolds.residuals``."""
    folds = [residual_comparison(*fold) for fold in residuals]
    together = residual_comparison(*(np.concatenate([fold[i] for fold in residuals]) for i in (0, 1)))
    return with_fold_spread(together, folds), tuple(folds)


def with_fold_spread(together: JointComparison, folds) -> JointComparison:
    """``together`` with its standard error at least the spread of the folds' RMSE changes (their standard deviation
    over sqrt(folds)): each fold's models are identified on less data than the final one, and how much a change
    varies from fold to fold is the noise of the cross-validation itself, which a bootstrap of the residuals does
    not see (the tutorial's spring on joint 4 changes joint 3 by +0.02, 0, +0.28 and -0.02 N m in its 4 folds)."""
    changes = np.array([f.after - f.before for f in folds])
    spread = np.std(changes, axis=0, ddof=1) / np.sqrt(len(folds)) if len(folds) > 1 else np.zeros_like(together.after)
    return JointComparison.from_noise(together.before, together.after, np.maximum(together.standard_error, spread))
