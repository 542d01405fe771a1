"""The preparation identify chooses for a recording: one definition of the filter, grid and trims for every command.

``psdm identify`` filters a recording by a zero-phase Butterworth low-pass at ``min(MAX_CUTOFF_HZ, rate / 10)``
(``choose_filter``), keeps samples at about ``SAMPLES_PER_CUTOFF`` times the cutoff and drops ``EDGE_PERIODS`` filter
periods at each end, where the filter's start-up transient corrupts the differentiated acceleration (``kept_samples``;
the four-step route's ``preparation.trim_filter_edges`` trims the same). The
identification (``calibration.trajectory_data.prepare_recording``), a calibrated model's stored preparation
(``calibration.model_preparation``) and the diagnosis (``DiagnosisOptions`` by default, and the samples its
contexts keep) all take it from here, so a diagnosis of a model file is judged on the very samples ``psdm validate``
judges it on.
"""

from __future__ import annotations

import numpy as np

from psdm_casadi.errors import ParameterError, RecordingError

__all__ = ["AUTO", "EDGE_PERIODS", "MAX_CUTOFF_HZ", "SAMPLES_PER_CUTOFF", "choose_filter", "edge_samples", "grid_step",
           "kept_samples", "resolve_auto"]  # fmt: skip

#: Highest default low-pass cutoff [Hz]: the joint motion of excitation trajectories is a few Hz at most.
MAX_CUTOFF_HZ = 10.0
#: Samples are kept at about this many times the cutoff.
SAMPLES_PER_CUTOFF = 10.0
#: Filter periods (``1 / cutoff``) trimmed at each end of a filtered recording. The zero-phase filter's padding at the
#: ends (27 samples) is far shorter than its settling, so where a recording starts or ends in motion (a real log, a
#: recording split for validation) the differentiated acceleration carries a start-up transient about three periods in:
#: the true model's torque error on a virtual Denso recording cut out of a motion falls 0.52, 0.15, 0.046, 0.016 N m
#: (joint 2) with 1, 2, 3, 4 periods trimmed; the Panda's robot-file model validates joint 1 of Gaz et al.'s recording
#: at 1.91, 0.85, 0.71, 0.69 N m. Model files written before the trim was stored (``model_preparation``, preparation
#: version 1) are judged with one period, as they were.
#: The transient is the filter's response to the cut: it pads each end with only 27 samples and starts from a still
#: signal before them, so its size in the acceleration is about 2 cutoff x the speed at the cut (21 rad/s^2 for 1 rad/s
#: at 10 Hz), and it decays as the Butterworth's least damped pole pair, by ``exp(-2 pi sin(pi / (2 order)))`` = 0.29
#: per period for order 8 (test_edge_trim checks both): three periods leave 2-3 % of it. Measured on a recording cut
#: in motion (the Panda's at 70 %, its model's residual on the same samples of the whole recording as reference), the
#: first 0.1 s kept carries 0.46 / 0.30 / 0.49 N m on joints 1-3, 2.5 times the middle's residual; six periods
#: (settling to 1e-3) would leave 0.013. Not taken: the fits hardly change (Panda <= 2 % better per joint on the same
#: held-out samples), and trimming ends at rest as well (which have no transient) costs the TX40's wrist 3-38 %
#: (joint 6 takes a torque offset that does not hold out of sample) and the slow samples a Stribeck hump is fitted on.
#: A trim scaled per end by its speed at the cut is the fix that would keep those.
EDGE_PERIODS = 3
#: A cutoff or grid rate left to identify's choice (``DiagnosisOptions`` defaults).
AUTO = "auto"


def grid_step(rate_hz: float, grid_rate_hz: float) -> int:
    """Keep every this-many samples of a ``rate_hz`` recording for a grid of about ``grid_rate_hz`` [Hz] (>= 1)."""
    return max(1, int(rate_hz // grid_rate_hz))


def choose_filter(rate_hz: float, cutoff_hz: float | None = None) -> tuple[float, int]:
    """(cutoff [Hz], decimation step) for a sampling rate: ``min(10 Hz, rate/10)``, samples at ~10x cutoff."""
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise RecordingError(f"the sampling rate must be positive [Hz]; got {rate_hz!r}. Check the time column.")
    cutoff = min(MAX_CUTOFF_HZ, rate_hz / 10.0) if cutoff_hz is None else float(cutoff_hz)
    if not (0 < cutoff < rate_hz / 2):
        raise ParameterError(
            f"cutoff_hz must be in (0, {rate_hz / 2:g}) Hz (below Nyquist for {rate_hz:g} Hz); got {cutoff!r}."
        )
    return cutoff, grid_step(rate_hz, SAMPLES_PER_CUTOFF * cutoff)


def edge_samples(rate_hz: float, cutoff_hz: float, edge_periods: float = EDGE_PERIODS) -> int:
    """Samples trimmed at each end of a ``rate_hz`` recording filtered at ``cutoff_hz``: ``ceil(edge_periods rate /
    cutoff)``."""
    return int(np.ceil(float(edge_periods) * rate_hz / cutoff_hz))


def kept_samples(
    n_samples: int, rate_hz: float, cutoff_hz: float, step: int, edge_periods: float = EDGE_PERIODS
) -> slice:
    """The samples kept of a recording filtered at ``cutoff_hz``: every ``step``-th, without ``edge_periods`` filter
    periods (``edge_samples``) at each end."""
    edge = edge_samples(rate_hz, cutoff_hz, edge_periods)
    return slice(edge, n_samples - edge, int(step))


def resolve_auto(cutoff_hz, grid_rate_hz, rate_hz: float) -> tuple:
    """``(cutoff [Hz] or None, grid rate [Hz])`` with ``AUTO`` ones as identify chooses them for a recording sampled at
    ``rate_hz``: the cutoff of ``choose_filter``, the grid ``SAMPLES_PER_CUTOFF`` times the cutoff (identify's cutoff
    for an unfiltered one)."""
    default = choose_filter(rate_hz)[0]
    cutoff = default if cutoff_hz == AUTO else cutoff_hz
    if grid_rate_hz == AUTO:
        grid_rate_hz = SAMPLES_PER_CUTOFF * (default if cutoff is None else cutoff)
    return cutoff, float(grid_rate_hz)
