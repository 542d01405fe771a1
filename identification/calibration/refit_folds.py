"""The never-worse gate's second opinion for a refit: the training recordings cut into blocks, each left out once.

training recordings + ``refit_on(labels, pieces)`` -> ``never_worse.TrainingRefits`` (or None, with the reason).

``recalibrate`` judges the model it refits with findings against the model before on the validation recordings
(``never_worse``). Both are estimates from the same training recordings; whether a joint's rise is the findings' doing
or the training fit's estimation noise is asked of the refits of both models without each of ``FOLDS`` contiguous
blocks of the training recordings (cut as identify's counterbalance cross-validation cuts them:
``counterbalance_folds.block_folds``, the pieces before and after a block each a recording of its own). The
recordings' payloads are already taken off their torque there, so a block is left out with its load; recordings too
short to cut give no second opinion, and the validation recordings alone decide.
"""

from __future__ import annotations

import logging
import os

from identification.calibration.counterbalance_folds import FOLDS, block_folds
from identification.calibration.never_worse import TrainingRefits

__all__ = ["FOLDS", "training_refits"]

logger = logging.getLogger(__name__)


def training_refits(train, refit_on, baseline, cutoff_hz=None, validation=()) -> TrainingRefits | None:
    """The ``TrainingRefits`` of the raw ``train`` recordings (filtered at ``cutoff_hz`` [Hz], None: unfiltered):
    ``refit_on(pieces)(labels)`` -> (CalibratedModel, fit) identified on ``pieces`` without the findings ``labels``
    (``keep_not_worse``'s ``refit`` on those recordings); ``baseline`` the labels whose drop gives the model before's
    structure. None when the recordings are too short to cut: the log line names them and the ``validation``
    recordings that then decide alone."""
    folds = block_folds(list(train), None, cutoff_hz)
    if isinstance(folds, str):
        names = [os.path.basename(str(r.name)) for r in validation if r.name]
        judged = (f"; the validation recording{'s' if len(names) > 1 else ''} {', '.join(names)} "
                  f"{'decide' if len(names) > 1 else 'decides'} alone") if names else ""  # fmt: skip
        logger.info("never worse: no second opinion from the training blocks: %s%s", folds, judged)
        return None
    return TrainingRefits(lambda labels, k: refit_on(list(folds.training[k]))(labels)[0], len(folds.training),
                          tuple(baseline))  # fmt: skip
