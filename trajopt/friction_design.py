"""The content of a friction experiment (paper 3.3): which amplitudes, speeds and frequencies a joint runs.

``FrictionDesign`` is the blind design of the calibration (it needs only the joint limits);
``friction_experiment`` in :mod:`trajopt.experiments` turns it into a trajectory.
``tuned_friction_signal`` places the same kinds of segments with the LuGre parameters known, for
testing and benchmarking a friction fit on data that resolves every parameter.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from psdm_casadi.errors import ParameterError

__all__ = ["FrictionDesign", "tuned_friction_signal"]


def _positive_tuple(owner, name, values):
    values = tuple(float(v) for v in np.atleast_1d(values))
    if not values or not all(np.isfinite(v) and v > 0 for v in values):
        raise ParameterError(f"{owner}.{name} must be a non-empty tuple of positive numbers; got {values!r}.")
    return values


@dataclass(frozen=True)
class FrictionDesign:
    """Content of one joint's friction experiment (paper 3.3), designed without knowing the friction.

    Four groups of ``q = A (1 - cos 2 pi f t)`` segments of the moving joint, each starting and
    ending at rest and followed by ``pause`` seconds at rest (the bristles relax to a new rest state):

    1. pre-sliding (``sigma0``, ``sigma1``): amplitudes ``presliding_amplitudes`` [rad] at
       ``presliding_hz``. Hysteresis loops need amplitudes of 0.3 to 3 break-away displacements
       ``fc / sigma0``, which differ by orders of magnitude between base and wrist joints; a
       logarithmic sweep from 5 urad to 5 mrad covers every joint without knowing ``sigma0``.
    2. break-away (``sigma1``): amplitudes ``breakaway_amplitudes`` [rad] well beyond the break-away
       displacement at ``breakaway_hz``, ``breakaway_periods`` times. Every reversal stops the joint
       at a high deceleration and it sticks: the joint then rings on the bristle stiffness, damped by
       sigma1, so these segments carry far more sigma1 information per second than the others. The
       amplitude stays small (2 mrad): larger ones stop the joint so hard that, at 1 kHz, the model
       of the measured friction errs at the stick and biases sigma1.
    3. Stribeck region (``fs``, ``vs``): peak speeds ``stribeck_speeds`` [rad/s] at ``stribeck_hz``,
       log-spaced from below the smallest to above the largest plausible ``vs``.
    4. sliding (``fc``, ``fv``, ``dv``): peak speeds ``sliding_fractions`` of the joint speed limit at
       ``sliding_hz`` (raised where the joint range or acceleration limit requires).

    The pre-sliding velocities are about 1e-3 rad/s, so the position must be recorded far below
    1 urad (a motor-side encoder behind the gearbox) and the data used at the full rate.

    Parameters
    ----------
    presliding_amplitudes : tuple of float
        [rad] (or [m]).
    presliding_hz : float
        [Hz]
    presliding_periods : int
    breakaway_amplitudes : tuple of float
        [rad] (or [m]); may be empty.
    breakaway_hz : float
        [Hz]
    breakaway_periods : int
    stribeck_speeds : tuple of float
        Peak speeds [rad/s].
    stribeck_hz : float
        [Hz]
    stribeck_periods : int
    sliding_fractions : tuple of float
        Peak speeds as fractions of ``qd_max``, in (0, 1].
    sliding_hz : float
        [Hz]
    sliding_periods : int
    pause : float
        Rest after each segment [s], >= 0.
    frequency_scale : float
        Multiplies every frequency at the same amplitudes (pre-sliding) and peak speeds (others):
        ``validation()`` uses 1.3 for a second, different experiment.

    Raises
    ------
    ParameterError
        Naming the field.

    Examples
    --------
    >>> round(FrictionDesign().duration, 1)
    27.6
    """

    presliding_amplitudes: tuple = tuple(np.round(np.logspace(np.log10(5e-6), np.log10(5e-3), 8), 9))
    presliding_hz: float = 10.0
    presliding_periods: int = 4
    breakaway_amplitudes: tuple = (2e-3,)
    breakaway_hz: float = 10.0
    breakaway_periods: int = 6
    stribeck_speeds: tuple = tuple(np.round(np.logspace(np.log10(3e-3), np.log10(0.5), 6), 5))
    stribeck_hz: float = 1.0
    stribeck_periods: int = 2
    sliding_fractions: tuple = (0.1, 0.3, 0.6, 0.9)
    sliding_hz: float = 0.5
    sliding_periods: int = 1
    pause: float = 0.2
    frequency_scale: float = 1.0

    def __post_init__(self):
        for name in ("presliding_amplitudes", "stribeck_speeds", "sliding_fractions"):
            object.__setattr__(self, name, _positive_tuple("FrictionDesign", name, getattr(self, name)))
        breakaway = tuple(float(v) for v in np.atleast_1d(self.breakaway_amplitudes))
        if breakaway:
            breakaway = _positive_tuple("FrictionDesign", "breakaway_amplitudes", breakaway)
        object.__setattr__(self, "breakaway_amplitudes", breakaway)
        if max(self.sliding_fractions) > 1.0:
            raise ParameterError(f"FrictionDesign.sliding_fractions must be in (0, 1]; got {self.sliding_fractions!r}.")
        for name in ("presliding_hz", "breakaway_hz", "stribeck_hz", "sliding_hz", "frequency_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"FrictionDesign.{name} must be positive; got {value!r}.")
        for name in ("presliding_periods", "breakaway_periods", "stribeck_periods", "sliding_periods"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value >= 1):
                raise ParameterError(f"FrictionDesign.{name} must be an integer >= 1; got {value!r}.")
        if not (np.isfinite(self.pause) and self.pause >= 0):
            raise ParameterError(f"FrictionDesign.pause must be >= 0 [s]; got {self.pause!r}.")

    @classmethod
    def quick(cls) -> FrictionDesign:
        """A shorter experiment (about half as long): fewer segments per group, for demos and tests."""
        return cls(
            presliding_amplitudes=(1e-5, 6e-5, 3e-4, 1.5e-3),
            presliding_periods=3,
            breakaway_amplitudes=(2e-3,),
            breakaway_periods=4,
            stribeck_speeds=(0.005, 0.03, 0.2),
            sliding_fractions=(0.2, 0.8),
        )

    def validation(self) -> FrictionDesign:
        """The same design at 1.3 times the frequencies: a second experiment for validation."""
        return replace(self, frequency_scale=1.3 * self.frequency_scale)

    @property
    def duration(self) -> float:
        """Length [s] before any frequency raise for range or acceleration limits."""
        s = self.frequency_scale
        return (
            len(self.presliding_amplitudes) * (self.presliding_periods / (s * self.presliding_hz) + self.pause)
            + len(self.breakaway_amplitudes) * (self.breakaway_periods / (s * self.breakaway_hz) + self.pause)
            + len(self.stribeck_speeds) * (self.stribeck_periods / (s * self.stribeck_hz) + self.pause)
            + len(self.sliding_fractions) * (self.sliding_periods / (s * self.sliding_hz) + self.pause)
        )

    def segments(self, qd_max: float, qdd_max: float, room: float) -> list:
        """``(amplitude, frequency, periods)`` of every segment for a joint with these limits.

        A segment whose travel ``2 A`` exceeds ``room`` or whose peak acceleration ``A (2 pi f)^2``
        exceeds ``0.8 qdd_max`` runs at a higher frequency (same peak speed) or, when both bind, at a
        lower peak speed. The 20 % left is for the path the robot is given: a segment starts from rest
        with a step in acceleration, which the cubic spline through the knots overshoots (by about
        13 % on the built-in Denso), and the spline must stay within the limit.

        Parameters
        ----------
        qd_max, qdd_max : float
            The joint's speed [rad/s] and acceleration [rad/s^2] limits.
        room : float
            Travel available on one side of the pose [rad].

        Returns
        -------
        list of (float, float, int)
            Amplitude [rad], frequency [Hz] and number of periods of each segment, in order.
        """
        s = self.frequency_scale
        wanted = [(a, s * self.presliding_hz, self.presliding_periods, None) for a in self.presliding_amplitudes]
        wanted += [(a, s * self.breakaway_hz, self.breakaway_periods, None) for a in self.breakaway_amplitudes]
        wanted += [(None, s * self.stribeck_hz, self.stribeck_periods, v) for v in self.stribeck_speeds]
        wanted += [(None, s * self.sliding_hz, self.sliding_periods, f * qd_max) for f in self.sliding_fractions]
        out = []
        for amplitude, frequency, periods, speed in wanted:
            omega = 2.0 * np.pi * frequency
            if speed is None:
                speed = amplitude * omega
            speed = min(speed, 0.95 * qd_max)
            omega = max(omega, 2.0 * speed / room)  # travel 2 A = 2 v / w within room
            accel = 0.8 * qdd_max
            if speed * omega > accel:  # peak acceleration v w
                omega = accel / speed
                if 2.0 * speed / omega > room:
                    speed = np.sqrt(accel * room / 2.0)
                    omega = accel / speed
            out.append((speed / omega, omega / (2.0 * np.pi), periods))
        return out


def tuned_friction_signal(parameters, qd_max, rate=1000.0, frequency_scale=1.0, pause=0.2):
    """A friction experiment tuned with the LuGre parameters known (for testing and benchmarking the fit).

    The blind design the calibration uses is ``FrictionDesign``; this one places its segments at
    multiples of the true ``fc / sigma0``, ``vs`` and ``qd_max``: a series of ``q = A (1 - cos(2 pi f t))``,
    each starting and ending at rest (``qd`` continuous), separated by ``pause`` seconds of rest.

    * pre-sliding: amplitudes 0.3, 0.7, 1.5, 3 times the break-away displacement ``fc / sigma0``
      at 10 Hz, 4 periods each (hysteresis loops; ``sigma0`` and ``sigma1``);
    * Stribeck region: peak speeds 0.5, 1, 2, 4 times ``vs`` at 1 Hz, 2 periods (``fs``, ``vs``);
    * sliding: peak speeds 0.1, 0.3, 0.6, 0.9 of ``qd_max`` at 0.5 Hz, 1 period (``fc, fv, dv``).

    Parameters
    ----------
    parameters : object with attributes fc, sigma0, vs
        The true LuGre parameters (e.g. ``identification.friction.models.LuGreParameters``).
    qd_max : float
        Speed limit of the joint [rad/s].
    rate : float
        Sample rate [Hz].
    frequency_scale : float
        Multiplies every frequency at the same amplitudes and peak speeds (1.3: a validation run).
    pause : float
        Rest after each segment [s].

    Returns
    -------
    (t, q, qd) : arrays, shape (n_samples,)
        [s], [rad] relative to the start pose, [rad/s].
    """
    xb = parameters.fc / parameters.sigma0
    segments = [(k * xb, 10.0 * frequency_scale, 4) for k in (0.3, 0.7, 1.5, 3.0)]
    segments += [(v * parameters.vs / (2 * np.pi * frequency_scale), frequency_scale, 2) for v in (0.5, 1, 2, 4)]
    f_slide = 0.5 * frequency_scale
    segments += [(v * qd_max / (2 * np.pi * f_slide), f_slide, 1) for v in (0.1, 0.3, 0.6, 0.9)]
    starts, total = [], 0.0
    for _, frequency, periods in segments:
        starts.append(total)
        total += periods / frequency + pause
    t = np.arange(0.0, total, 1.0 / rate)
    q = np.zeros_like(t)
    qd = np.zeros_like(t)
    for start, (amplitude, frequency, periods) in zip(starts, segments):
        omega = 2 * np.pi * frequency
        m = (t >= start) & (t <= start + periods / frequency)
        q[m] = amplitude * (1 - np.cos(omega * (t[m] - start)))
        qd[m] = amplitude * omega * np.sin(omega * (t[m] - start))
    return t, q, qd
