"""How a raw recording is prepared before a model is judged on it: the identification's own preparation, one for all.

``psdm identify`` filters each recording (zero-phase Butterworth at ``min(10 Hz, rate / 10)``), differentiates it,
trims one filter period at each end and keeps samples at about ten times the cutoff
(``trajectory_data.prepare_recording``). Every command that judges a model prepares its recordings the same way:
``psdm validate``, ``identify --validate`` and ``diagnose --apply`` through ``CalibratedModel.predict_recording``,
and ``psdm diagnose`` of a model file, whose preprocessing takes the file's cutoff and grid rate. ``diagnose`` of a
robot file takes the preparation ``identify`` would choose for the training recording (``default_preparation``).

The calibrated-model file stores it in ``identification.preparation`` (``PREPARATION_VERSION``): the filter, its
order, the cutoff, the grid rate and the edge trim. A file written before the block holds only
``identification.cutoff_hz``: it is judged with that cutoff and today's filter, as before, and ``Preparation.note``
says so.
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.data.filter_choice import SAMPLES_PER_CUTOFF, choose_filter
from identification.data.preprocessing import PreprocessOptions

__all__ = ["PREPARATION_VERSION", "SAMPLES_PER_CUTOFF", "Preparation", "default_preparation", "model_preparation",
           "preparation_block"]  # fmt: skip

PREPARATION_VERSION = 1
FILTER = "zero-phase Butterworth low-pass (filtfilt)"
ORDER = PreprocessOptions().order
EDGE = "ceil(rate / cutoff) samples (one filter period) trimmed at each end"


@dataclass(frozen=True)
class Preparation:
    """The preparation a model is judged with.

    Attributes
    ----------
    cutoff_hz : float
        Low-pass cutoff [Hz].
    grid_rate_hz : float
        Rate [Hz] of the samples kept after the filter.
    source : str
        Where it comes from: ``"model file"``, ``"older model file"`` or ``"identify's default"``.
    note : str
        What a reader should know (an older file's preparation was not stored), or empty.
    """

    cutoff_hz: float
    grid_rate_hz: float
    source: str
    note: str = ""

    def text(self) -> str:
        """``zero-phase Butterworth ... order 8 at 10 Hz, samples at 100 Hz, ... (the model file's own)``."""
        return (f"{FILTER} of order {ORDER} at {self.cutoff_hz:g} Hz, samples kept at {self.grid_rate_hz:g} Hz, "
                f"{EDGE} ({self.source})")  # fmt: skip

    def to_dict(self) -> dict:
        return {"cutoff_hz": self.cutoff_hz, "grid_rate_hz": self.grid_rate_hz, "source": self.source,
                "note": self.note, "text": self.text()}  # fmt: skip


def preparation_block(cutoff_hz, decimation) -> dict:
    """The ``identification.preparation`` block of a fit prepared at ``cutoff_hz`` (one per training recording)."""
    cutoff = float(cutoff_hz[0])
    return {"version": PREPARATION_VERSION, "filter": FILTER, "order": ORDER, "cutoff_hz": cutoff,
            "grid_rate_hz": SAMPLES_PER_CUTOFF * cutoff, "edge": EDGE,
            "decimation": [int(step) for step in decimation]}  # fmt: skip


def model_preparation(document: dict) -> Preparation:
    """The preparation of a calibrated-model document (its stored block, or an older file's cutoff)."""
    identification = document["identification"]
    block = identification.get("preparation")
    if block is not None:
        return Preparation(float(block["cutoff_hz"]), float(block["grid_rate_hz"]), "model file")
    cutoff = float(identification["cutoff_hz"][0])
    note = (
        "this model file was written before its preparation was stored (identification.preparation); it is judged "
        f"with its cutoff {cutoff:g} Hz and today's filter, as before. Re-run 'psdm identify' to store it."
    )
    return Preparation(cutoff, SAMPLES_PER_CUTOFF * cutoff, "older model file", note=note)


def default_preparation(recording) -> Preparation:
    """The preparation ``psdm identify`` chooses for ``recording`` (``filter_choice.choose_filter``)."""
    cutoff, _ = choose_filter(1.0 / recording.dt)
    return Preparation(cutoff, SAMPLES_PER_CUTOFF * cutoff, "identify's default for the training recording")
