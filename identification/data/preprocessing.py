"""Preprocessing of recordings as in the paper: zero-phase Butterworth filtering, central differences, splitting.

``preprocess`` turns a raw ``Recording`` into one with filtered positions and torques/currents and
with velocities and accelerations; ``Recording.split`` then cuts it 85/15 into training and validation.

Uneven time steps: a Butterworth filter is defined for a uniform sample rate, so a recording with
uneven steps is first resampled (cubic spline, not-a-knot) onto a uniform grid with the median step
over the same time span; the result lives on that grid. Across a gap (a step longer than ``GAP_STEPS``
median steps: messages a logger dropped) the torques and currents are interpolated linearly: a cubic spline
through noisy torques swings far outside them over a gap (its end slopes come from single noisy samples: over
a 60 ms gap of a 1 kHz log by tens of N m), a torque the fit then takes as measured; the line stays between
the samples measured on either side. Without filtering (``cutoff_hz=None``) no
resampling happens and the differences use the exact three-point formulas for uneven steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfilt, sosfilt_zi

from identification.data.recording import Recording
from identification.data.temperature import temperatures_at
from psdm_casadi.errors import ParameterError, RecordingError

DIFFERENTIATIONS = ("central", "none")
#: A time step longer than this many median steps is a gap (``resample_uniform``).
GAP_STEPS = 2.5


@dataclass(frozen=True)
class PreprocessOptions:
    """Options of ``preprocess`` (paper section 3: 8th-order zero-phase Butterworth, central differences, 85/15).

    Parameters
    ----------
    cutoff_hz : float or None
        Butterworth cutoff [Hz]; the paper uses 4 Hz (motor, gravity), 40 Hz (friction), 15 Hz
        (inertial). ``None`` disables filtering.
    order : int
        Order of the Butterworth design; ``filtfilt`` applies it forward and backward, so the
        magnitude response is squared and the phase is zero.
    differentiation : {"central", "none"}
        ``"central"`` computes qd and qdd from the filtered q by central differences
        (``qd[k] = (q[k+1] - q[k-1]) / 2T``, ``qdd[k] = (q[k+1] - 2 q[k] + q[k-1]) / T^2``; second-order
        one-sided at the ends; exact three-point weights on uneven grids). ``"none"`` keeps recorded
        qd/qdd (filtered).
    split_fraction : float
        Training share for ``Recording.split`` (paper: 0.85).
    uniform_rtol : float
        Relative tolerance on the time steps below which a recording counts as uniform.

    Raises
    ------
    ParameterError
        Naming the field and the fix.
    """

    cutoff_hz: float | None = 15.0
    order: int = 8
    differentiation: str = "central"
    split_fraction: float = 0.85
    uniform_rtol: float = 1e-6

    def __post_init__(self):
        if self.cutoff_hz is not None and not (np.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise ParameterError(
                f"PreprocessOptions.cutoff_hz must be a positive frequency [Hz] or None; got {self.cutoff_hz!r}."
            )
        if not (isinstance(self.order, (int, np.integer)) and 1 <= self.order <= 20):
            raise ParameterError(
                f"PreprocessOptions.order must be an integer in 1..20; got {self.order!r}. Use 8 as in the paper."
            )
        if self.differentiation not in DIFFERENTIATIONS:
            raise ParameterError(
                f"PreprocessOptions.differentiation must be one of {DIFFERENTIATIONS}; got {self.differentiation!r}."
            )
        if not 0.0 < self.split_fraction < 1.0:
            raise ParameterError(
                f"PreprocessOptions.split_fraction must be in (0, 1); got {self.split_fraction!r}. "
                "Use 0.85 as in the paper."
            )
        if not self.uniform_rtol >= 0:
            raise ParameterError(f"PreprocessOptions.uniform_rtol must be >= 0; got {self.uniform_rtol!r}.")


def central_difference(t, x) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives of samples ``x`` on a (possibly uneven) grid ``t``.

    Interior points use the three-point formulas (for uniform steps ``(x[k+1]-x[k-1])/2T`` and
    ``(x[k+1]-2x[k]+x[k-1])/T^2``, the paper's central difference); the end points use
    second-order one-sided formulas for the first derivative and copy the neighbouring second derivative.

    Parameters
    ----------
    t : array, shape (n_samples,)
    x : array, shape (n_samples,) or (n_samples, n_columns)

    Returns
    -------
    (array, array)
        First and second derivatives, shaped like ``x``.
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.shape[0] < 3:
        raise RecordingError(f"central_difference needs at least 3 samples; got {t.shape[0]}.")
    if x.ndim == 1:
        return _central_difference_1d(t, x)
    # one column at a time: the temporaries stay one column long (the values are those of the whole array)
    first, second = np.empty(x.shape), np.empty(x.shape)
    flat_first, flat_second = first.reshape(x.shape[0], -1), second.reshape(x.shape[0], -1)
    for c, column in enumerate(x.reshape(x.shape[0], -1).T):
        flat_first[:, c], flat_second[:, c] = _central_difference_1d(t, column)
    return first, second


def _central_difference_1d(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    first = np.gradient(x, t, edge_order=2)
    h1, h2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    second = np.empty_like(x)
    second[1:-1] = 2.0 * (h1 * x[2:] - (h1 + h2) * x[1:-1] + h2 * x[:-2]) / (h1 * h2 * (h1 + h2))
    second[0], second[-1] = second[1], second[-2]
    return first, second


@lru_cache(maxsize=64)
def lowpass_sections(order: int, cutoff_hz: float, sample_rate_hz: float) -> np.ndarray:
    """The Butterworth low-pass's second-order sections (read-only), designed once per (order, cut-off, rate): the
    design costs more than filtering a few seconds of one signal, and a diagnosis filters thousands of columns."""
    sos = butter(order, cutoff_hz, btype="low", fs=sample_rate_hz, output="sos")
    sos.flags.writeable = False
    return sos


def zero_phase_filter(x, sample_rate_hz: float, cutoff_hz: float, order: int = 8) -> np.ndarray:
    """Butterworth low-pass applied forward and backward (``filtfilt``): zero phase, magnitude squared.

    Parameters
    ----------
    x : array, shape (n_samples,) or (n_samples, n_columns)
        Uniformly sampled signal(s), time on axis 0.
    sample_rate_hz : float
    cutoff_hz : float
        Must be below the Nyquist frequency ``sample_rate_hz / 2``.
    order : int

    Returns
    -------
    array, shaped like ``x``
        A new array; the columns of a multi-column ``x`` are filtered one at a time (same values, a
        one-column temporary memory).

    Raises
    ------
    ParameterError
        When the cutoff is not below Nyquist.
    RecordingError
        When there are too few samples for the filter's edge padding.
    """
    nyquist = 0.5 * sample_rate_hz
    if not cutoff_hz < nyquist:
        raise ParameterError(
            f"PreprocessOptions.cutoff_hz must be below the Nyquist frequency {nyquist:g} Hz of this recording; "
            f"got {cutoff_hz!r}. Lower the cutoff or record faster."
        )
    sos = lowpass_sections(int(order), float(cutoff_hz), float(sample_rate_hz)).copy()  # scipy wants it writable
    x = np.asarray(x, dtype=float)
    padlen = 3 * (2 * len(sos) + 1)
    if x.shape[0] <= padlen:
        raise RecordingError(
            f"Recording.t holds {x.shape[0]} samples; a zero-phase filter of order {order} needs more than {padlen}. "
            "Record longer or lower PreprocessOptions.order."
        )
    zi = lowpass_initial_state(int(order), float(cutoff_hz), float(sample_rate_hz))
    # scipy's edge padding: three times the taps, a first-order section (odd order) counted as one
    padlen = 3 * (2 * len(sos) + 1 - min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0))))
    if x.ndim == 1:
        return _filtfilt(sos, zi, x, padlen)
    # one column at a time into one array: the filter's padded temporaries stay one column long (the values are
    # those of filtering the whole array)
    out = np.empty(x.shape)
    flat = out.reshape(x.shape[0], -1)
    for c, column in enumerate(x.reshape(x.shape[0], -1).T):
        flat[:, c] = _filtfilt(sos, zi, column, padlen)
    return out


@lru_cache(maxsize=64)
def lowpass_initial_state(order: int, cutoff_hz: float, sample_rate_hz: float) -> np.ndarray:
    """``sosfilt_zi`` of ``lowpass_sections`` (read-only): the filter's steady state for a unit step, once per design
    (scipy's ``sosfiltfilt`` solves for it on every call, which cost more than the filtering of a short signal)."""
    zi = sosfilt_zi(lowpass_sections(order, cutoff_hz, sample_rate_hz).copy())
    zi.flags.writeable = False
    return zi


def _filtfilt(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """scipy's ``sosfiltfilt(sos, x)`` of a 1-D ``x`` (odd extension by ``padlen``, the steady-state initial
    conditions ``zi``), step for step, with ``zi`` given (tests/identification/test_diagnosis_shape_grid.py checks the
    values are scipy's, bit for bit)."""
    ext = np.concatenate((2 * x[:1] - x[padlen:0:-1], x, 2 * x[-1:] - x[-2 : -(padlen + 2) : -1]))
    y, _ = sosfilt(sos, ext, zi=zi * ext[:1])
    y, _ = sosfilt(sos, y[::-1], zi=zi * y[-1:])
    return y[::-1][padlen:-padlen]


def resample_uniform(recording: Recording) -> Recording:
    """The recording on a uniform grid with its median step over the same span (cubic spline per signal; torques
    and currents linear across gaps, module docstring)."""
    dt = recording.dt
    n = int(np.floor(recording.duration / dt + 1e-9)) + 1
    t = recording.t[0] + dt * np.arange(n)
    gaps = np.flatnonzero(np.diff(recording.t) > GAP_STEPS * dt)  # step k: from t[k] to t[k + 1]
    inside = np.zeros(n, dtype=bool)
    for k in gaps:
        inside |= (t > recording.t[k]) & (t < recording.t[k + 1])
    changes = {}
    for key in ("q", "tau", "current", "qd", "qdd"):
        value = getattr(recording, key)
        if value is not None:
            changes[key] = CubicSpline(recording.t, value, axis=0)(t)
            if key in ("tau", "current") and inside.any():
                line = [
                    np.interp(t[inside], recording.t, column) for column in np.reshape(value, (value.shape[0], -1)).T
                ]
                changes[key][inside] = np.reshape(np.column_stack(line), changes[key][inside].shape)
    if recording.temperature is not None:  # a slow logger's readings, linear between them
        changes["temperature"] = temperatures_at(recording, t)
    return recording.with_signals(t=t, **changes)


def preprocess(recording: Recording, options: PreprocessOptions | None = None) -> Recording:
    """Filter a recording (zero phase) and add velocities and accelerations by central differences.

    Parameters
    ----------
    recording : Recording
    options : PreprocessOptions, optional
        Defaults to ``PreprocessOptions()``.

    Returns
    -------
    Recording
        Filtered q, tau and current, with qd and qdd; on a uniform grid when the input was uneven
        and filtering was requested (see the module docstring). The input is not modified.

    Raises
    ------
    ParameterError
        When the cutoff is not below the Nyquist frequency.
    RecordingError
        When the recording is too short for the filter.

    Examples
    --------
    >>> clean = preprocess(rec, PreprocessOptions(cutoff_hz=40.0))      # doctest: +SKIP
    >>> train, validation = clean.split(0.85)                           # doctest: +SKIP
    """
    options = PreprocessOptions() if options is None else options
    if not isinstance(options, PreprocessOptions):
        raise ParameterError(f"preprocess options must be a PreprocessOptions; got {type(options).__name__}.")
    rec = recording
    changes = {}
    # overflow (huge values, tiny time steps) is reported by _check_overflow, naming the signal, not as warnings
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        if options.cutoff_hz is not None:
            if not rec.is_uniform(options.uniform_rtol):
                rec = resample_uniform(rec)
            rate = 1.0 / rec.dt
            for key in ("q", "tau", "current", "qd", "qdd"):
                value = getattr(rec, key)
                if value is not None:
                    changes[key] = _filter(rec.name, value, rate, options)
        if options.differentiation == "central":
            q = changes.get("q", rec.q)
            changes["qd"], changes["qdd"] = central_difference(rec.t, q)
    _check_overflow(rec, changes)
    if not changes:
        return rec
    for value in changes.values():  # fresh arrays: read-only, the Recording keeps them without a copy
        value.setflags(write=False)
    return rec.with_signals(**changes)


def _filter(source: str, value: np.ndarray, rate: float, options: PreprocessOptions) -> np.ndarray:
    """``zero_phase_filter`` whose refusals (too short, cutoff above Nyquist) name the recording."""
    try:
        return zero_phase_filter(value, rate, options.cutoff_hz, options.order)
    except (RecordingError, ParameterError) as exc:
        if not source:
            raise
        raise type(exc)(f"{source}: {exc}") from None


def _check_overflow(recording: Recording, changes: dict) -> None:
    """Refuse a filtered or differentiated signal that overflowed, naming the recording, the column and the cause."""
    for key, value in changes.items():
        columns = np.reshape(value, (len(value), -1))
        bad = ~np.isfinite(columns)
        if not np.any(bad):
            continue
        row, column = (int(i) for i in np.argwhere(bad)[0])
        source = recording.name or "the recording"
        raise RecordingError(
            f"preprocess of {source}: Recording.{key} must be finite; got {float(columns[row, column])!r} "
            f"in column {key}{column + 1} at sample {row} (smallest time step {np.diff(recording.t).min():.3g} s, "
            f"largest |q| {np.abs(recording.q).max():.3g}). Check the units of t [s] and of the signals (SI)."
        )
