"""Joint friction models: LuGre, Coulomb-viscous and Stribeck parameters (paper eqs. 12-14, 20).

The values a friction experiment (plain ``t, qd, tau_friction`` arrays, paper eq. 19) is fitted
to, and the check of those arrays. The LuGre model of one joint (Canudas de Wit et al. 1995;
paper eqs. 12-14)::

    g(qd)   = fc + (fs - fc) * exp(-(qd / vs)**2)                 Stribeck curve      (13, times sigma0)
    zdot    = qd - sigma0 * |qd| / g(qd) * z                      bristle deflection  (12)
    tau     = sigma0 * z + sigma1 * zdot + fv * |qd|**dv * sign(qd)                   (14)

Its discretisation is :mod:`identification.friction.lugre_step`, its numeric simulation
:mod:`identification.friction.simulation` and its CasADi form
:mod:`identification.friction.expressions`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import InsufficientExcitationError, ParameterError, ShapeError
from psdm_casadi.robot import DriveParameters

__all__ = [
    "LUGRE_PARAMETER_NAMES",
    "LuGreParameters",
    "CoulombViscous",
    "Stribeck",
    "check_friction_data",
    "check_slides_both_ways",
]

LUGRE_PARAMETER_NAMES = ("fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1")
"""Order of the seven LuGre parameters in every array form (paper Table 2 column order)."""


def _check_positive(owner, name, value, allow_zero=False):
    value = float(value)
    ok = np.isfinite(value) and (value >= 0.0 if allow_zero else value > 0.0)
    if not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise ParameterError(f"{owner}.{name} must be finite and {bound}; got {value}. Pass a physical value.")
    return value


@dataclass(frozen=True)
class LuGreParameters:
    """The seven LuGre friction parameters of one joint (paper eqs. 12-14, Table 2).

    Parameters
    ----------
    fc : float
        Coulomb friction torque [N m], > 0.
    fs : float
        Static (break-away) friction torque [N m], > 0.
    vs : float
        Stribeck velocity [rad/s], > 0.
    fv : float
        Viscous coefficient [N m (s/rad)**dv], >= 0.
    dv : float
        Viscous exponent [-], > 0 (1 is linear viscous friction).
    sigma0 : float
        Bristle stiffness [N m/rad], > 0.
    sigma1 : float
        Bristle damping [N m s/rad], >= 0.

    Raises
    ------
    ParameterError
        A value is not finite or out of its range; the message names the field.

    Examples
    --------
    >>> p = LuGreParameters(fc=9.6, fs=12.5, vs=0.0144, fv=23.7, dv=0.61, sigma0=2.9e5, sigma1=22.8)
    >>> round(float(p.steady_state(1.0)), 2)
    33.3
    """

    fc: float
    fs: float
    vs: float
    fv: float
    dv: float
    sigma0: float
    sigma1: float

    def __post_init__(self):
        for name in LUGRE_PARAMETER_NAMES:
            value = _check_positive("LuGreParameters", name, getattr(self, name), allow_zero=name in ("fv", "sigma1"))
            object.__setattr__(self, name, value)

    # -- conversions -------------------------------------------------------------------------
    @classmethod
    def from_drive(cls, drive):
        """Take the friction part of a :class:`psdm_casadi.robot.DriveParameters`."""
        if not isinstance(drive, DriveParameters):
            raise ParameterError(
                f"LuGreParameters.from_drive drive must be a DriveParameters; got {type(drive).__name__}. "
                "Pass robot.drives[i]."
            )
        return cls(**{name: getattr(drive, name) for name in LUGRE_PARAMETER_NAMES})

    def to_drive(self, kt):
        """Return a :class:`DriveParameters` with these friction values and torque constant ``kt`` [N m/A]."""
        return DriveParameters(kt=float(kt), **self.as_dict())

    @classmethod
    def from_array(cls, values):
        """Build from a length-7 array in :data:`LUGRE_PARAMETER_NAMES` order."""
        values = np.asarray(values, dtype=float).ravel()
        if values.shape != (7,):
            raise ShapeError(
                f"LuGreParameters.from_array values must have 7 entries {LUGRE_PARAMETER_NAMES}; "
                f"got shape {values.shape}. Pass one value per parameter."
            )
        return cls(*values.tolist())

    def as_array(self):
        """Return the parameters as a (7,) array in :data:`LUGRE_PARAMETER_NAMES` order."""
        return np.array([getattr(self, name) for name in LUGRE_PARAMETER_NAMES])

    def as_dict(self):
        """Return ``{name: value}`` in :data:`LUGRE_PARAMETER_NAMES` order."""
        return {name: getattr(self, name) for name in LUGRE_PARAMETER_NAMES}

    def relative_error(self, reference):
        """Return ``{name: |self - reference| / |reference|}`` against true ``reference`` parameters."""
        return {
            name: abs(getattr(self, name) - getattr(reference, name)) / abs(getattr(reference, name))
            for name in LUGRE_PARAMETER_NAMES
        }

    # -- steady state ---------------------------------------------------------------------------
    def stribeck(self):
        """The steady-state (constant velocity) curve of this LuGre model as a :class:`Stribeck`."""
        return Stribeck(fc=self.fc, fs=self.fs, vs=self.vs, fv=self.fv, dv=self.dv)

    def steady_state(self, qd):
        """Steady-state friction torque [N m] at constant velocity ``qd`` [rad/s] (the Stribeck curve)."""
        return self.stribeck().torque(qd)


@dataclass(frozen=True)
class CoulombViscous:
    """High-speed friction model of paper eq. 20: ``(fc + fv |qd|**dv) sign(qd)``.

    Parameters
    ----------
    fc : float
        Coulomb torque [N m], >= 0.
    fv : float
        Viscous coefficient [N m (s/rad)**dv], >= 0.
    dv : float
        Viscous exponent, > 0.

    Examples
    --------
    >>> CoulombViscous(fc=1.0, fv=2.0, dv=1.0).torque([-1.0, 0.0, 0.5]).tolist()
    [-3.0, 0.0, 2.0]
    """

    fc: float
    fv: float
    dv: float = 1.0

    def __post_init__(self):
        for name in ("fc", "fv", "dv"):
            value = _check_positive("CoulombViscous", name, getattr(self, name), allow_zero=name != "dv")
            object.__setattr__(self, name, value)

    def torque(self, qd):
        """Friction torque [N m] at velocities ``qd`` [rad/s] (any shape)."""
        qd = np.asarray(qd, dtype=float)
        return (self.fc + self.fv * np.abs(qd) ** self.dv) * np.sign(qd)


@dataclass(frozen=True)
class Stribeck:
    """Steady-state Stribeck curve ``(g(qd) + fv |qd|**dv) sign(qd)``, g of paper eq. 13 times sigma0.

    Parameters
    ----------
    fc, fs : float
        Coulomb and static torque [N m], > 0.
    vs : float
        Stribeck velocity [rad/s], > 0.
    fv : float
        Viscous coefficient, >= 0.
    dv : float
        Viscous exponent, > 0.

    Examples
    --------
    >>> s = Stribeck(fc=1.0, fs=2.0, vs=0.01, fv=0.0, dv=1.0)
    >>> round(float(s.torque(1e-9)), 9), float(s.torque(1.0))
    (2.0, 1.0)
    """

    fc: float
    fs: float
    vs: float
    fv: float
    dv: float = 1.0

    def __post_init__(self):
        for name in ("fc", "fs", "vs", "fv", "dv"):
            value = _check_positive("Stribeck", name, getattr(self, name), allow_zero=name == "fv")
            object.__setattr__(self, name, value)

    def breakaway(self, qd):
        """``g(qd) * sigma0``: the Coulomb-to-static torque envelope [N m] at speed ``qd``."""
        qd = np.asarray(qd, dtype=float)
        return self.fc + (self.fs - self.fc) * np.exp(-((qd / self.vs) ** 2))

    def torque(self, qd):
        """Friction torque [N m] at constant velocities ``qd`` [rad/s] (any shape)."""
        qd = np.asarray(qd, dtype=float)
        return (self.breakaway(qd) + self.fv * np.abs(qd) ** self.dv) * np.sign(qd)


def check_friction_data(t, qd, tau=None, owner="friction data", signal="qd"):
    """Validate friction-experiment arrays and return them as float 1-D arrays.

    Parameters
    ----------
    t : array, shape (n_samples,)
        Strictly increasing sample times [s].
    qd : array, shape (n_samples,)
        Joint velocity [rad/s], finite.
    tau : array, shape (n_samples,), optional
        Friction torque [N m], finite.
    owner : str
        Name used in error messages.
    signal : str
        Name of the second array in error messages (``"q"`` when positions are passed).

    Returns
    -------
    tuple of ndarray
        ``(t, qd)`` or ``(t, qd, tau)``.

    Raises
    ------
    ShapeError
        An array is not 1-D, lengths differ, or fewer than 3 samples.
    ParameterError
        NaN/inf values or time not strictly increasing.
    """
    arrays = {"t": t, signal: qd} if tau is None else {"t": t, signal: qd, "tau": tau}
    out = {}
    for name, value in arrays.items():
        value = np.asarray(value, dtype=float)
        if value.ndim == 2 and 1 in value.shape:
            value = value.ravel()
        if value.ndim != 1:
            raise ShapeError(f"{owner}.{name} must be 1-D (n_samples,); got shape {value.shape}. Pass one joint.")
        if not np.all(np.isfinite(value)):
            bad = int(np.flatnonzero(~np.isfinite(value))[0])
            raise ParameterError(
                f"{owner}.{name} must be finite; got {value[bad]} at sample {bad}. Remove or interpolate it."
            )
        out[name] = value
    n = out["t"].size
    for name, value in out.items():
        if value.size != n:
            raise ShapeError(f"{owner}.{name} must have the length of t ({n}); got {value.size}. Pass matching arrays.")
    if n < 3:
        raise ShapeError(f"{owner}.t must hold at least 3 samples; got {n}. Pass a longer record.")
    if not np.all(np.diff(out["t"]) > 0):
        raise ParameterError(
            f"{owner}.t must be strictly increasing; got a non-increasing step. Sort or deduplicate it."
        )
    return tuple(out.values())


def _longest_run(flags: np.ndarray) -> int:
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return int(np.max(edges[1::2] - edges[::2])) if edges.size else 0


def check_slides_both_ways(qd, owner="friction data", fraction=0.25, min_samples=10):
    """Raise unless the joint slides in both directions: ``min_samples`` consecutive samples faster than
    ``fraction * max|qd|``, once with ``qd > 0`` and once with ``qd < 0``.

    A LuGre fit needs sliding strokes of both signs (Coulomb friction is odd in qd; one sign alone does not
    separate it from a torque offset), and strokes are runs of samples: the velocity of a joint that stands
    still (encoder noise, quantisation) changes sign from sample to sample and never forms a run of ten.

    Parameters
    ----------
    qd : array, shape (n_samples,)
        Joint velocity [rad/s], sampled in time order.
    owner : str
        Name used in error messages.
    fraction : float
        Share of the peak speed a sliding sample exceeds (0.25: the high-speed samples of eq. 20).
    min_samples : int
        Least run length [samples].

    Raises
    ------
    InsufficientExcitationError
        Naming the missing direction(s) and the fix.
    """
    qd = np.asarray(qd, dtype=float).reshape(-1)
    peak = float(np.max(np.abs(qd))) if qd.size else 0.0
    threshold = fraction * peak
    runs = {"positive": _longest_run(qd > threshold), "negative": _longest_run(qd < -threshold)}
    if peak > 0 and all(run >= min_samples for run in runs.values()):
        return
    raise InsufficientExcitationError(
        f"{owner}.qd must slide in both directions ({min_samples} consecutive samples faster than {fraction:g} of "
        f"the peak speed {peak:.3g} rad/s each way); got runs of {runs['positive']} positive and "
        f"{runs['negative']} negative samples. Record the joint oscillating in both directions up to sliding speeds "
        "well above its Stribeck velocity (a still or dithering joint gives noise)."
    )
