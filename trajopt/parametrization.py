"""Trajectory families for excitation: finite Fourier series and the paper's sum of sines (eq. 22).

Each family maps a decision vector ``x`` to joint trajectories ``q(t), qd(t), qdd(t)`` in two forms
that share one layout: ``evaluate`` (numpy, for sampling and verification) and ``symbolic`` (CasADi,
for the optimisation problem). The two are written independently and tested against each other and
against finite differences.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError


def _check_positive(owner: str, field: str, value, fix: str) -> None:
    if not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value) or value <= 0:
        raise ParameterError(f"{owner}.{field} must be a positive finite number; got {value!r}. {fix}")


def _check_count(owner: str, field: str, value, fix: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ParameterError(f"{owner}.{field} must be an integer >= 1; got {value!r}. {fix}")


def _times(t) -> np.ndarray:
    times = np.asarray(t, dtype=float).reshape(-1)
    if not np.all(np.isfinite(times)):
        raise ParameterError("t must hold finite times [s]; got NaN or inf. Pass a finite time grid.")
    return times


def smoothstep(u):
    """Quintic ramp 0->1 on [0, 1] with zero first and second derivatives at both ends, and its derivatives.

    ``s(u) = u^3 (10 - 15 u + 6 u^2)`` with ``u`` clipped to [0, 1]; it fades a trajectory in and
    out so that it starts and ends at rest.

    Parameters
    ----------
    u : array
        Normalised time [-].

    Returns
    -------
    s, ds, dds : arrays, shape of ``u``
        The ramp and its first and second derivatives with respect to ``u``.
    """
    u = np.clip(u, 0.0, 1.0)
    s = u**3 * (10 - 15 * u + 6 * u**2)
    ds = 30 * u**2 * (1 - u) ** 2
    dds = 60 * u * (1 - u) * (1 - 2 * u)
    return s, ds, dds


@dataclass(frozen=True)
class FourierTrajectory:
    """Finite Fourier series with a common base frequency (periodic excitation, Swevers et al.).

    For joint ``i`` and ``w = 2 pi / period``::

        q_i(t)   = q0_i + sum_k  a_ik/(k w) sin(k w t) - b_ik/(k w) cos(k w t)
        qd_i(t)  =        sum_k  a_ik cos(k w t) + b_ik sin(k w t)
        qdd_i(t) =        sum_k -a_ik k w sin(k w t) + b_ik k w cos(k w t)

    The trajectory is linear in its parameters, so joint limits on a grid are linear constraints.

    Parameters
    ----------
    n_dof : int
        Number of joints.
    n_harmonics : int
        Harmonics per joint (the highest frequency is ``n_harmonics / period`` Hz).
    period : float
        Period [s]; the excitation repeats, so recordings can be averaged over periods.
    rest_to_rest : bool
        When True, ``qd`` and ``qdd`` vanish at ``t = 0`` (and so at every multiple of the period):
        two linear equality constraints per joint (``equality``).

    Notes
    -----
    Decision vector layout, per joint ``i`` in order: ``a_i1..a_iH, b_i1..b_iH, q0_i``.

    Examples
    --------
    >>> traj = FourierTrajectory(n_dof=2, n_harmonics=3, period=10.0)
    >>> q, qd, qdd = traj.evaluate([0.0, 1.0], np.zeros(traj.n_parameters))
    >>> q.shape
    (2, 2)
    """

    n_dof: int
    n_harmonics: int = 5
    period: float = 10.0
    rest_to_rest: bool = False

    def __post_init__(self):
        _check_count("FourierTrajectory", "n_dof", self.n_dof, "Pass the robot's number of joints.")
        _check_count("FourierTrajectory", "n_harmonics", self.n_harmonics, "Use e.g. 5 harmonics.")
        _check_positive("FourierTrajectory", "period", self.period, "Give the period in seconds, e.g. 10.")

    # --- layout ------------------------------------------------------------------------------
    @property
    def duration(self) -> float:
        """Length of one period [s]."""
        return float(self.period)

    @property
    def periodic(self) -> bool:
        return True

    @property
    def base_frequency(self) -> float:
        """Base angular frequency ``2 pi / period`` [rad/s]."""
        return 2.0 * math.pi / self.period

    @property
    def max_frequency(self) -> float:
        """Highest angular frequency in the family [rad/s]."""
        return self.n_harmonics * self.base_frequency

    @property
    def n_per_joint(self) -> int:
        return 2 * self.n_harmonics + 1

    @property
    def n_parameters(self) -> int:
        return self.n_dof * self.n_per_joint

    def parameter_names(self) -> tuple:
        names = []
        for i in range(1, self.n_dof + 1):
            names += [f"a{i}_{k}" for k in range(1, self.n_harmonics + 1)]
            names += [f"b{i}_{k}" for k in range(1, self.n_harmonics + 1)]
            names.append(f"q0_{i}")
        return tuple(names)

    def _coefficients(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.shape != (self.n_parameters,):
            raise ShapeError(
                f"FourierTrajectory parameters must have length n_parameters={self.n_parameters}; "
                f"got {x.shape[0]}. Use FourierTrajectory.parameter_names() for the layout."
            )
        return x.reshape(self.n_dof, self.n_per_joint)

    def basis(self, t) -> tuple:
        """Basis rows shared by every joint: ``q_i(t) = Bq(t) @ c_i`` etc.

        Returns
        -------
        Bq, Bqd, Bqdd : arrays, shape (n_samples, 2 n_harmonics + 1)
        """
        t = _times(t)[:, None]
        k = np.arange(1, self.n_harmonics + 1)[None, :]
        w = self.base_frequency
        s, c = np.sin(k * w * t), np.cos(k * w * t)
        ones, zeros = np.ones_like(t), np.zeros_like(t)
        bq = np.hstack([s / (k * w), -c / (k * w), ones])
        bqd = np.hstack([c, s, zeros])
        bqdd = np.hstack([-s * k * w, c * k * w, zeros])
        return bq, bqd, bqdd

    # --- numeric and symbolic evaluation -------------------------------------------------------
    def evaluate(self, t, x) -> tuple:
        """Joint position, velocity and acceleration at times ``t``.

        Parameters
        ----------
        t : array, shape (n_samples,)
            Times [s].
        x : array, shape (n_parameters,)
            Decision vector.

        Returns
        -------
        q, qd, qdd : arrays, shape (n_samples, n_dof)
        """
        coefficients = self._coefficients(x)
        t = _times(t)
        k = np.arange(1, self.n_harmonics + 1)
        w = self.base_frequency
        a, b, q0 = coefficients[:, : self.n_harmonics], coefficients[:, self.n_harmonics : -1], coefficients[:, -1]
        phase = w * np.outer(t, k)  # (n_samples, H)
        s, c = np.sin(phase), np.cos(phase)
        q = q0[None, :] + s @ (a / (k * w)).T - c @ (b / (k * w)).T
        qd = c @ a.T + s @ b.T
        qdd = -s @ (a * k * w).T + c @ (b * k * w).T
        return q, qd, qdd

    def symbolic(self, x, t) -> tuple:
        """CasADi expressions of q, qd, qdd on the grid ``t`` (numbers) for a symbolic ``x``.

        Returns
        -------
        q, qd, qdd : casadi.MX or casadi.SX, shape (n_samples, n_dof)
        """
        c = ca.reshape(x, self.n_per_joint, self.n_dof)  # column i = coefficients of joint i
        bq, bqd, bqdd = self.basis(t)
        return ca.mtimes(ca.DM(bq), c), ca.mtimes(ca.DM(bqd), c), ca.mtimes(ca.DM(bqdd), c)

    def equality(self, x):
        """Linear equality constraints (== 0) of the family: rest-to-rest at t = 0, or empty."""
        if not self.rest_to_rest:
            return ca.MX(0, 1) if isinstance(x, ca.MX) else ca.DM(0, 1)
        _, bqd, bqdd = self.basis([0.0])
        c = ca.reshape(x, self.n_per_joint, self.n_dof)
        return ca.vertcat(ca.mtimes(ca.DM(bqd), c).T, ca.mtimes(ca.DM(bqdd), c).T)

    def offsets(self, x) -> np.ndarray:
        """Mean joint position of each joint (the constant term q0), shape (n_dof,)."""
        return self._coefficients(x)[:, -1].copy()

    def with_offsets(self, x, offsets) -> np.ndarray:
        """A copy of ``x`` whose constant terms are ``offsets`` (n_dof,)."""
        c = self._coefficients(x).copy()
        c[:, -1] = np.asarray(offsets, dtype=float).reshape(self.n_dof)
        return c.ravel()

    def scale_joints(self, x, scales) -> np.ndarray:
        """Scale the oscillation of each joint about its offset; q - q0, qd and qdd scale exactly."""
        c = self._coefficients(x).copy()
        c[:, :-1] *= np.asarray(scales, dtype=float).reshape(self.n_dof, 1)
        return c.ravel()

    def bounds(self, q_min, q_max) -> tuple:
        """Box bounds on ``x``: offsets inside the position range, coefficients free."""
        lb = np.full((self.n_dof, self.n_per_joint), -np.inf)
        ub = np.full((self.n_dof, self.n_per_joint), np.inf)
        lb[:, -1], ub[:, -1] = q_min, q_max
        return lb.ravel(), ub.ravel()

    def random_parameters(self, rng: np.random.Generator, center) -> np.ndarray:
        """Random coefficients (amplitudes decaying as 1/k) about ``center``; not yet scaled to limits."""
        k = np.arange(1, self.n_harmonics + 1)
        a = rng.standard_normal((self.n_dof, self.n_harmonics)) / k
        b = rng.standard_normal((self.n_dof, self.n_harmonics)) / k
        if self.rest_to_rest:  # qd(0) = sum a = 0, qdd(0) = sum k b = 0: solve for the first harmonic
            a[:, 0] = -a[:, 1:].sum(axis=1)
            b[:, 0] = -(k[1:] * b[:, 1:]).sum(axis=1)
        c = np.hstack([a, b, np.asarray(center, dtype=float).reshape(self.n_dof, 1)])
        return c.ravel()

    def default_grid(self, n_samples: int) -> np.ndarray:
        """``n_samples`` equally spaced times over one period, end excluded (periodic)."""
        return np.linspace(0.0, self.period, int(n_samples), endpoint=False)


@dataclass(frozen=True)
class SumOfSinesTrajectory:
    """The paper's eq. 22: a sum of sines per joint with free amplitude, frequency and phase.

    ``q_i(t) = c_i + h(t) sum_k A_ik sin(w_ik t + phi_ik)`` where ``c_i`` is an optional offset
    (the paper has none) and ``h`` is 1, or with ``rest_to_rest`` a quintic window rising over
    ``ramp`` seconds at the start and falling at the end, so that ``qd`` and ``qdd`` vanish at both
    ends and ``q`` starts and ends at ``c``.

    Parameters
    ----------
    n_dof : int
    n_terms : int
        Sines per joint (3 in the paper).
    duration : float
        Length [s].
    frequency_min, frequency_max : float
        Bounds of every ``w_ik`` [rad/s].
    offset : bool
        Whether each joint has a free constant offset ``c_i``.
    rest_to_rest : bool
        Window the sum so the trajectory starts and ends at rest.
    ramp : float
        Window ramp length [s] when ``rest_to_rest``; default ``duration / 10``.

    Notes
    -----
    Decision vector layout, per joint: ``A_i1..A_iK, w_i1..w_iK, phi_i1..phi_iK[, c_i]``.
    """

    n_dof: int
    n_terms: int = 3
    duration: float = 10.0
    frequency_min: float = 0.1
    frequency_max: float = 3.0
    offset: bool = True
    rest_to_rest: bool = False
    ramp: float | None = None

    def __post_init__(self):
        owner = "SumOfSinesTrajectory"
        _check_count(owner, "n_dof", self.n_dof, "Pass the robot's number of joints.")
        _check_count(owner, "n_terms", self.n_terms, "Use e.g. 3 sines per joint as in the paper.")
        _check_positive(owner, "duration", self.duration, "Give the duration in seconds.")
        _check_positive(owner, "frequency_min", self.frequency_min, "Use e.g. 0.1 rad/s.")
        _check_positive(owner, "frequency_max", self.frequency_max, "Use e.g. 3 rad/s.")
        if self.frequency_min >= self.frequency_max:
            raise ParameterError(
                f"{owner}.frequency_min must be below frequency_max; got {self.frequency_min} >= "
                f"{self.frequency_max}. Swap or widen them."
            )
        if self.ramp is not None:
            _check_positive(owner, "ramp", self.ramp, "Give the window ramp in seconds.")
            if 2 * self.ramp > self.duration:
                raise ParameterError(
                    f"{owner}.ramp must be at most duration/2={self.duration / 2}; got {self.ramp}. Shorten it."
                )

    @property
    def periodic(self) -> bool:
        return False

    @property
    def max_frequency(self) -> float:
        return float(self.frequency_max)

    @property
    def n_per_joint(self) -> int:
        return 3 * self.n_terms + int(self.offset)

    @property
    def n_parameters(self) -> int:
        return self.n_dof * self.n_per_joint

    def parameter_names(self) -> tuple:
        names = []
        for i in range(1, self.n_dof + 1):
            for sym in ("A", "w", "phi"):
                names += [f"{sym}{i}_{k}" for k in range(1, self.n_terms + 1)]
            if self.offset:
                names.append(f"c_{i}")
        return tuple(names)

    def _split(self, x) -> tuple:
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.shape != (self.n_parameters,):
            raise ShapeError(
                f"SumOfSinesTrajectory parameters must have length n_parameters={self.n_parameters}; "
                f"got {x.shape[0]}. Use SumOfSinesTrajectory.parameter_names() for the layout."
            )
        c = x.reshape(self.n_dof, self.n_per_joint)
        k = self.n_terms
        offset = c[:, 3 * k] if self.offset else np.zeros(self.n_dof)
        return c[:, :k], c[:, k : 2 * k], c[:, 2 * k : 3 * k], offset

    def window(self, t) -> tuple:
        """Window ``h`` and its first two time derivatives at ``t`` (ones and zeros without rest_to_rest)."""
        t = _times(t)
        if not self.rest_to_rest:
            return np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
        ramp = self.duration / 10 if self.ramp is None else self.ramp
        s1, ds1, dds1 = smoothstep(t / ramp)
        s2, ds2, dds2 = smoothstep((self.duration - t) / ramp)
        ds1, dds1 = ds1 / ramp, dds1 / ramp**2
        ds2, dds2 = -ds2 / ramp, dds2 / ramp**2
        return s1 * s2, ds1 * s2 + s1 * ds2, dds1 * s2 + 2 * ds1 * ds2 + s1 * dds2

    def evaluate(self, t, x) -> tuple:
        """Joint position, velocity and acceleration at times ``t``, arrays (n_samples, n_dof)."""
        amplitude, frequency, phase, offset = self._split(x)
        t = _times(t)
        arg = t[:, None, None] * frequency[None] + phase[None]  # (n_samples, n_dof, K)
        s = (amplitude[None] * np.sin(arg)).sum(axis=2)
        sd = (amplitude * frequency)[None] * np.cos(arg)
        sd = sd.sum(axis=2)
        sdd = -((amplitude * frequency**2)[None] * np.sin(arg)).sum(axis=2)
        h, dh, ddh = (w[:, None] for w in self.window(t))
        return offset[None, :] + h * s, dh * s + h * sd, ddh * s + 2 * dh * sd + h * sdd

    def symbolic(self, x, t) -> tuple:
        """CasADi expressions of q, qd, qdd (n_samples x n_dof) on the numeric grid ``t``."""
        t = _times(t)
        h, dh, ddh = (ca.DM(w) for w in self.window(t))
        tt = ca.DM(t)
        k, m = self.n_terms, self.n_per_joint
        cols_q, cols_qd, cols_qdd = [], [], []
        for i in range(self.n_dof):
            base = i * m
            s = sd = sdd = 0
            for j in range(k):
                amp, freq, ph = x[base + j], x[base + k + j], x[base + 2 * k + j]
                arg = freq * tt + ph
                sin_arg, cos_arg = ca.sin(arg), ca.cos(arg)
                s = s + amp * sin_arg
                sd = sd + amp * freq * cos_arg
                sdd = sdd - amp * freq**2 * sin_arg
            offset = x[base + 3 * k] if self.offset else 0
            cols_q.append(offset + h * s)
            cols_qd.append(dh * s + h * sd)
            cols_qdd.append(ddh * s + 2 * dh * sd + h * sdd)
        return ca.horzcat(*cols_q), ca.horzcat(*cols_qd), ca.horzcat(*cols_qdd)

    def equality(self, x):
        """No equality constraints: rest-to-rest is built into the window."""
        return ca.MX(0, 1) if isinstance(x, ca.MX) else ca.DM(0, 1)

    def offsets(self, x) -> np.ndarray:
        return self._split(x)[3].copy()

    def with_offsets(self, x, offsets) -> np.ndarray:
        if not self.offset:
            return np.asarray(x, dtype=float).copy()
        c = np.asarray(x, dtype=float).reshape(self.n_dof, self.n_per_joint).copy()
        c[:, 3 * self.n_terms] = np.asarray(offsets, dtype=float).reshape(self.n_dof)
        return c.ravel()

    def scale_joints(self, x, scales) -> np.ndarray:
        """Scale the amplitudes of each joint; q - c, qd and qdd scale exactly."""
        self._split(x)
        c = np.asarray(x, dtype=float).reshape(self.n_dof, self.n_per_joint).copy()
        c[:, : self.n_terms] *= np.asarray(scales, dtype=float).reshape(self.n_dof, 1)
        return c.ravel()

    def bounds(self, q_min, q_max) -> tuple:
        """Box bounds: frequencies in [frequency_min, frequency_max], phases in [-2 pi, 2 pi], offsets in range."""
        k = self.n_terms
        lb = np.full((self.n_dof, self.n_per_joint), -np.inf)
        ub = np.full((self.n_dof, self.n_per_joint), np.inf)
        lb[:, k : 2 * k], ub[:, k : 2 * k] = self.frequency_min, self.frequency_max
        lb[:, 2 * k : 3 * k], ub[:, 2 * k : 3 * k] = -2 * math.pi, 2 * math.pi
        if self.offset:
            lb[:, 3 * k], ub[:, 3 * k] = q_min, q_max
        return lb.ravel(), ub.ravel()

    def random_parameters(self, rng: np.random.Generator, center) -> np.ndarray:
        """Random frequencies (uniform), phases and amplitudes ~ N(0,1)/w; not yet scaled to limits."""
        k = self.n_terms
        freq = rng.uniform(self.frequency_min, self.frequency_max, (self.n_dof, k))
        amp = rng.standard_normal((self.n_dof, k)) / freq
        phase = rng.uniform(-math.pi, math.pi, (self.n_dof, k))
        blocks = [amp, freq, phase]
        if self.offset:
            blocks.append(np.asarray(center, dtype=float).reshape(self.n_dof, 1))
        return np.hstack(blocks).ravel()

    def default_grid(self, n_samples: int) -> np.ndarray:
        """``n_samples`` equally spaced times on [0, duration], both ends included."""
        return np.linspace(0.0, self.duration, int(n_samples))
