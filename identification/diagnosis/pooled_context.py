"""One ``DiagnosisContext`` of several training recordings: the diagnosis fits and selects on all of them at once.

``psdm diagnose MODEL --train A B`` refits the model with its findings (``--apply``) on every ``--train`` recording;
a diagnosis that selected on ``A`` alone chose a law over ``A``'s travel that the refit then fitted over both (a
quartic spring chosen over a third of a joint's range is no spring over all of it). So the diagnosis's training
context pools them: each recording is prepared on its own (its filter, its grid, its edges trimmed), and the pool
holds their grid samples one after the other, so every column, fit and selection sees all of them, as identify's fit
stacks its recordings' rows. The full-rate signals follow one another too, each recording's time continuing one
sample after the previous one's end (a drift is judged along the recordings in the order given), and every full-rate
filter of a column runs over each recording on its own (``DiagnosisContext.segments``), so no column's filter rings
across the seam; the few samples a column takes across it (a difference, an interpolation) lie in the ends the grid
trims.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from psdm_casadi.errors import RecordingError

__all__ = ["pooled_context"]

#: Fields stacked along the samples: the grid's, then the full-rate ones (``None`` in any recording: ``None``).
GRID_FIELDS = ("q", "qd", "qdd", "tau", "tau_rate", "tau_accel", "tau_rigid", "dtau_dq", "dtau_dqd", "mass",
               "regressor", "payload", "tilt", "gravity", "tau_held")  # fmt: skip
FULL_FIELDS = ("full_tau", "full_qd", "sign_qd", "full_tau_raw")

#: Relative difference of two recordings' sample periods up to which they are pooled as one rate.
RATE_TOLERANCE = 1e-3


def pooled_context(contexts):
    """The ``DiagnosisContext`` of the recordings of ``contexts`` one after the other (module docstring); one context
    as it is.

    Raises
    ------
    RecordingError
        When the recordings were sampled at different rates (their full-rate signals are filtered at one rate).
    """
    contexts = list(contexts)
    first = contexts[0]
    if len(contexts) == 1:
        return first
    steps = [float(np.median(np.diff(c.full_t))) for c in contexts]
    if max(steps) - min(steps) > RATE_TOLERANCE * min(steps):
        rates = ", ".join(f"{c.name or 'recording'} {1.0 / s:.6g} Hz" for c, s in zip(contexts, steps))
        raise RecordingError(
            f"the training recordings are sampled at different rates ({rates}); the diagnosis fits them together "
            "at one rate. Resample them to one rate, or pass them to --train one at a time."
        )
    shifts, end = [], None
    for c, step in zip(contexts, steps):  # each recording's time continues one sample after the previous one's end
        shift = 0.0 if end is None else end + step - float(c.full_t[0])
        shifts.append(shift)
        end = float(c.full_t[-1]) + shift
    starts = np.cumsum([0] + [c.full_t.shape[0] for c in contexts])
    fields = {name: _stacked([getattr(c, name) for c in contexts]) for name in GRID_FIELDS + FULL_FIELDS}
    return replace(
        first, **fields,
        t=np.concatenate([c.t + s for c, s in zip(contexts, shifts)]),
        full_t=np.concatenate([c.full_t + s for c, s in zip(contexts, shifts)]),
        keep=np.concatenate([c.keep + int(n) for c, n in zip(contexts, starts)]),
        segments=tuple(int(n) for n in starts[1:-1]),
        name=" + ".join(c.name or "recording" for c in contexts),
    )  # fmt: skip


def _stacked(values):
    """The arrays ``values`` one after the other along the samples; None when any is None."""
    if any(v is None for v in values):
        return None
    return np.concatenate(values)
