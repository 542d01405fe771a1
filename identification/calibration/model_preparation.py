"""How a raw recording is prepared before a model is judged on it: the identification's own preparation, one for all.

``psdm identify`` filters each recording (zero-phase Butterworth at ``min(10 Hz, rate / 10)``), differentiates it,
trims ``filter_choice.EDGE_PERIODS`` filter periods at each end and keeps samples at about ten times the cutoff
(``trajectory_data.prepare_recording``). Every command that judges a model prepares its recordings the same way:
``psdm validate``, ``identify --validate`` and ``diagnose --apply`` through ``CalibratedModel.predict_recording``,
and ``psdm diagnose`` of a model file, whose preprocessing takes the file's cutoff and grid rate. ``diagnose`` of a
robot file takes the preparation ``identify`` would choose for the training recording (``default_preparation``).

The calibrated-model file stores it in ``identification.preparation`` (``PREPARATION_VERSION``): the filter, its
order, the cutoff, the grid rate and the edge trim (``edge_periods``, since version 2). A file is judged as it was
written: a version-1 block (written when identify trimmed one filter period) and a file written before the block
(only ``identification.cutoff_hz``: that cutoff and today's filter) are judged with one period trimmed
(``LEGACY_EDGE_PERIODS``), so ``psdm validate`` of an old file gives the numbers it gave; ``Preparation.note`` says so.
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.data.filter_choice import EDGE_PERIODS, SAMPLES_PER_CUTOFF, choose_filter
from identification.data.preprocessing import PreprocessOptions

__all__ = ["EDGE_PERIODS", "LEGACY_EDGE_PERIODS", "PREPARATION_VERSION", "SAMPLES_PER_CUTOFF", "Preparation",
           "default_preparation", "edge_text", "model_preparation", "preparation_block"]  # fmt: skip

PREPARATION_VERSION = 2
FILTER = "zero-phase Butterworth low-pass (filtfilt)"
ORDER = PreprocessOptions().order
#: Filter periods trimmed at each end by the files of preparation version 1 and older (``kept_samples`` then).
LEGACY_EDGE_PERIODS = 1


def edge_text(edge_periods: float) -> str:
    """``ceil(3 rate / cutoff) samples (3 filter periods) trimmed at each end``; one period: ``ceil(rate / cutoff)``."""
    if float(edge_periods) == 1.0:
        return "ceil(rate / cutoff) samples (one filter period) trimmed at each end"
    return f"ceil({edge_periods:g} rate / cutoff) samples ({edge_periods:g} filter periods) trimmed at each end"


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
        What a reader should know (an older file's preparation was not stored, or trimmed one period), or empty.
    edge_periods : float
        Filter periods trimmed at each end (``filter_choice.kept_samples``).
    """

    cutoff_hz: float
    grid_rate_hz: float
    source: str
    note: str = ""
    edge_periods: float = EDGE_PERIODS

    def text(self) -> str:
        """``zero-phase Butterworth ... order 8 at 10 Hz, samples at 100 Hz, ... (the model file's own)``."""
        return (f"{FILTER} of order {ORDER} at {self.cutoff_hz:g} Hz, samples kept at {self.grid_rate_hz:g} Hz, "
                f"{edge_text(self.edge_periods)} ({self.source})")  # fmt: skip

    def to_dict(self) -> dict:
        return {"cutoff_hz": self.cutoff_hz, "grid_rate_hz": self.grid_rate_hz, "edge_periods": self.edge_periods,
                "source": self.source, "note": self.note, "text": self.text()}  # fmt: skip


def preparation_block(cutoff_hz, decimation, edge_periods: float = EDGE_PERIODS) -> dict:
    """The ``identification.preparation`` block of a fit prepared at ``cutoff_hz`` (one per training recording)."""
    cutoff = float(cutoff_hz[0])
    return {"version": PREPARATION_VERSION, "filter": FILTER, "order": ORDER, "cutoff_hz": cutoff,
            "grid_rate_hz": SAMPLES_PER_CUTOFF * cutoff, "edge_periods": edge_periods,
            "edge": edge_text(edge_periods), "decimation": [int(step) for step in decimation]}  # fmt: skip


def model_preparation(document: dict) -> Preparation:
    """The preparation of a calibrated-model document: its stored block (a version-1 block: one filter period
    trimmed), or an older file's cutoff (one period too)."""
    identification = document["identification"]
    block = identification.get("preparation")
    fix = f"Re-run 'psdm identify' to store today's preparation ({EDGE_PERIODS:g} filter periods trimmed)."
    if block is not None:
        cutoff, grid = float(block["cutoff_hz"]), float(block["grid_rate_hz"])
        if int(block.get("version", 1)) >= 2:
            return Preparation(cutoff, grid, "model file", edge_periods=float(block["edge_periods"]))
        note = (f"this model file's preparation is version 1 (identification.preparation), written when identify "
                f"trimmed one filter period at each end; it is judged with one period, as before. {fix}")  # fmt: skip
        return Preparation(cutoff, grid, "model file", note=note, edge_periods=LEGACY_EDGE_PERIODS)
    cutoff = float(identification["cutoff_hz"][0])
    note = (
        "this model file was written before its preparation was stored (identification.preparation); it is judged "
        f"with its cutoff {cutoff:g} Hz, today's filter and one filter period trimmed at each end, as before. {fix}"
    )
    return Preparation(cutoff, SAMPLES_PER_CUTOFF * cutoff, "older model file", note, LEGACY_EDGE_PERIODS)


def default_preparation(recording) -> Preparation:
    """The preparation ``psdm identify`` chooses for ``recording`` (``filter_choice.choose_filter``)."""
    cutoff, _ = choose_filter(1.0 / recording.dt)
    return Preparation(cutoff, SAMPLES_PER_CUTOFF * cutoff, "identify's default for the training recording")
