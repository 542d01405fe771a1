"""Joint friction models (Coulomb-viscous, Stribeck, LuGre), numeric and symbolic (paper eqs. 12-14, 20).

Sits between a friction experiment (plain ``t, qd, tau_friction`` arrays, paper eq. 19) and
:mod:`identification.friction.shooting`, which fits :class:`LuGreParameters` to such data.

The LuGre model of one joint (Canudas de Wit et al. 1995; paper eqs. 12-14)::

    g(qd)   = fc + (fs - fc) * exp(-(qd / vs)**2)                 Stribeck curve      (13, times sigma0)
    zdot    = qd - sigma0 * |qd| / g(qd) * z                      bristle deflection  (12)
    tau     = sigma0 * z + sigma1 * zdot + fv * |qd|**dv * sign(qd)                   (14)

is stiff: the relaxation rate ``a = sigma0 |qd| / g`` reaches 1e5 1/s on the Denso, so an explicit
step at 1 kHz diverges. The numeric simulation and the shooting NLP share one discretisation.
With the bristle force ``s = sigma0 z`` [N m] (of the order of the Coulomb torque, so well
scaled) eq. 12 reads ``sdot = -a(t) (s - y(t))`` with the quasi-steady force
``y = sign(qd) g(qd)``. Over a step of length h with ``qd`` linear and of one sign (steps are
split at zero crossings of the data), ``a`` is frozen at its trapezoidal mean and ``y`` is taken
linear, and this linear ODE is integrated exactly (an exponential integrator)::

    x      = h (a[k] + a[k+1]) / 2
    s[k+1] = exp(-x) s[k] + x (phi1(x) y[k] + phi2(x) (y[k+1] - y[k]))

with ``phi1(x) = (1 - exp(-x)) / x`` and ``phi2(x) = (x - 1 + exp(-x)) / x**2``. The scheme is
unconditionally stable, second order, reproduces steady sliding exactly (so the Stribeck curve is
the steady state of the discrete model) and is the trapezoidal rule in pre-sliding. At 1 kHz on
the Denso its torque error is about 1e-3 of the signal (tests/identification/test_friction.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.robot import DriveParameters

__all__ = [
    "LUGRE_PARAMETER_NAMES",
    "LuGreParameters",
    "CoulombViscous",
    "Stribeck",
    "lugre_step_coefficients",
    "simulate_lugre",
    "lugre_torque",
    "check_friction_data",
    "LuGreExpressions",
    "build_lugre_expressions",
    "lugre_zdot_expression",
    "lugre_torque_expression",
    "lugre_step_expression",
]

LUGRE_PARAMETER_NAMES = ("fc", "fs", "vs", "fv", "dv", "sigma0", "sigma1")
"""Order of the seven LuGre parameters in every array form (paper Table 2 column order)."""

_SERIES_LIMIT = 1e-3  # below this x = h * rate, phi1 and phi2 use their Taylor series


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


# ------------------------------------------------------------------------------------------------
# numeric simulation
# ------------------------------------------------------------------------------------------------
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


def _phi12_with(x, where, expm1):
    """phi1(x) = (1 - e^-x)/x and phi2(x) = (x - 1 + e^-x)/x^2, accurate for all x >= 0.

    ``where`` and ``expm1`` are numpy's or CasADi's, so both evaluations share one formula.
    """
    small = x < _SERIES_LIMIT
    xs = where(small, 1.0, x)
    em1 = expm1(-xs)
    phi1 = where(small, 1 - x / 2 + x * x / 6 - x**3 / 24, -em1 / xs)
    phi2 = where(small, 0.5 - x / 6 + x * x / 24 - x**3 / 120, (xs + em1) / (xs * xs))
    return phi1, phi2


def _phi12(x):
    """phi1, phi2 on numpy arrays."""
    return _phi12_with(x, np.where, np.expm1)


@dataclass(frozen=True)
class _SubstepLayout:
    """Data-only description of the integration sub-steps of a sampled velocity signal.

    Each sample interval k is split into ``substeps`` equal steps, and an interval in which the
    velocity changes sign is first split at its (linearly interpolated) zero crossing, so that the
    sign of ``qd`` is constant on every sub-step. ``first`` holds the sub-steps before the crossing
    (the whole interval when there is none), ``second`` those after it, for crossing intervals only.
    """

    h: np.ndarray  # (2, substeps, n_intervals) step lengths; second part zero where no crossing
    qd_a: np.ndarray  # velocity at the start of each sub-step
    qd_b: np.ndarray  # velocity at its end
    sign: np.ndarray  # sign of qd on the sub-step (-1, 0, 1)
    crossing: np.ndarray  # (n_intervals,) bool


def _substep_layout(t, qd, substeps):
    h = np.diff(t)
    q0 = qd[:-1]
    q1 = qd[1:]
    crossing = q0 * q1 < 0
    frac = np.ones_like(h)
    frac[crossing] = q0[crossing] / (q0[crossing] - q1[crossing])
    shape = (2, substeps, h.size)
    f0 = np.empty(shape)
    f1 = np.empty(shape)
    j = np.arange(substeps)[:, None]
    f0[0] = frac * j / substeps
    f1[0] = frac * (j + 1) / substeps
    f0[1] = frac + (1 - frac) * j / substeps
    f1[1] = frac + (1 - frac) * (j + 1) / substeps
    qd_a = q0 + (q1 - q0) * f0
    qd_b = q0 + (q1 - q0) * f1
    # exact zeros at the crossing (no round-off sign flips)
    qd_b[0, -1, crossing] = 0.0
    qd_a[1, 0, crossing] = 0.0
    step = h * (f1 - f0)
    step[1, :, ~crossing] = 0.0
    sign = np.sign(qd_a + qd_b)
    return _SubstepLayout(step, qd_a, qd_b, sign, crossing)


def _step_maps(p, h, qd_a, qd_b, sign):
    """Linear map ``s_end = decay s_start + gain`` of one sub-step (numpy; see module docstring)."""
    g_a = p.fc + (p.fs - p.fc) * np.exp(-((qd_a / p.vs) ** 2))
    g_b = p.fc + (p.fs - p.fc) * np.exp(-((qd_b / p.vs) ** 2))
    x = 0.5 * h * p.sigma0 * (np.abs(qd_a) / g_a + np.abs(qd_b) / g_b)
    phi1, phi2 = _phi12(x)
    y_a = sign * g_a
    y_b = sign * g_b
    return np.exp(-x), x * (phi1 * y_a + phi2 * (y_b - y_a))


def lugre_step_coefficients(parameters, h, qd_start, qd_end):
    """Coefficients of one exponential-integrator step of the bristle force ``s = sigma0 z``.

    ``s_end = decay * s_start + gain``, for ``qd`` linear over the step and of one sign (see the
    module docstring; :func:`simulate_lugre` splits steps at zero crossings before calling this).

    Parameters
    ----------
    parameters : LuGreParameters
    h : float or array
        Step length [s], >= 0.
    qd_start, qd_end : array
        Velocity at the start and end of each step [rad/s], of equal sign or zero.

    Returns
    -------
    decay, gain : ndarray
        ``decay`` in (0, 1], ``gain`` [N m].
    """
    qd_start = np.asarray(qd_start, dtype=float)
    qd_end = np.asarray(qd_end, dtype=float)
    return _step_maps(parameters, h, qd_start, qd_end, np.sign(qd_start + qd_end))


def lugre_torque(parameters, qd, s):
    """LuGre friction torque (eq. 14) [N m] from velocity ``qd`` and bristle force ``s = sigma0 z`` [N m]."""
    p = parameters
    qd = np.asarray(qd, dtype=float)
    g = p.fc + (p.fs - p.fc) * np.exp(-((qd / p.vs) ** 2))
    zdot = qd - np.abs(qd) * s / g
    return s + p.sigma1 * zdot + p.fv * np.abs(qd) ** p.dv * np.sign(qd)


def simulate_lugre(parameters, t, qd, z0=0.0, substeps=1):
    """Simulate the LuGre model along a sampled velocity signal (stiff-safe, any sigma0).

    The velocity is taken as linear between samples. Each sample interval is split at a zero
    crossing of ``qd`` and into ``substeps`` exponential-integrator steps (module docstring);
    their linear maps are composed, so the sequential loop costs one multiply-add per sample
    whatever ``substeps``.

    Parameters
    ----------
    parameters : LuGreParameters
    t : array, shape (n_samples,)
        Strictly increasing times [s].
    qd : array, shape (n_samples,)
        Joint velocity [rad/s].
    z0 : float
        Bristle deflection at ``t[0]`` [rad].
    substeps : int
        Integration steps per sample interval, >= 1. The scheme is second order; one step is
        accurate to about 1e-3 of the torque at 1 kHz on the Denso (see the tests), 32 or more give
        a reference solution.

    Returns
    -------
    tau : ndarray, shape (n_samples,)
        Friction torque [N m] (eq. 14).
    z : ndarray, shape (n_samples,)
        Bristle deflection [rad].

    Raises
    ------
    ParameterError, ShapeError
        Bad parameters or arrays; the message names the field.

    Examples
    --------
    >>> p = LuGreParameters(fc=1.0, fs=1.5, vs=0.01, fv=0.5, dv=1.0, sigma0=1e5, sigma1=10.0)
    >>> t = np.arange(0.0, 1.0, 1e-3)
    >>> tau, z = simulate_lugre(p, t, np.full_like(t, 0.2))
    >>> round(float(tau[-1]), 6)  # steady sliding: fc + fv * 0.2
    1.1
    """
    if not isinstance(parameters, LuGreParameters):
        raise ParameterError(
            f"simulate_lugre.parameters must be a LuGreParameters; got {type(parameters).__name__}. "
            "Build one with LuGreParameters(...)."
        )
    t, qd = check_friction_data(t, qd, owner="simulate_lugre")
    if not (isinstance(substeps, (int, np.integer)) and not isinstance(substeps, bool) and substeps >= 1):
        raise ParameterError(f"simulate_lugre.substeps must be an integer >= 1; got {substeps!r}. Pass e.g. 1 or 8.")
    if not np.isfinite(z0):
        raise ParameterError(f"simulate_lugre.z0 must be finite; got {z0}. Pass 0.0 for a relaxed bristle.")
    decay, gain = _interval_maps(parameters, _substep_layout(t, qd, int(substeps)))
    s = _run_recursion(decay, gain, parameters.sigma0 * float(z0))
    return lugre_torque(parameters, qd, s), s / parameters.sigma0


def _interval_maps(parameters, layout):
    """Per-sample-interval linear maps ``s[k+1] = decay[k] s[k] + gain[k]`` (sub-steps composed)."""
    decay = np.ones(layout.h.shape[-1])
    gain = np.zeros_like(decay)
    for part in range(2):
        for j in range(layout.h.shape[1]):
            d_j, g_j = _step_maps(
                parameters, layout.h[part, j], layout.qd_a[part, j], layout.qd_b[part, j], layout.sign[part, j]
            )
            decay, gain = d_j * decay, d_j * gain + g_j
    return decay, gain


def _run_recursion(decay, gain, s0):
    """Evaluate the first-order linear recursion sequentially (plain floats are fastest here)."""
    s = [s0]
    value = s0
    for d, g in zip(decay.tolist(), gain.tolist()):
        value = d * value + g
        s.append(value)
    return np.asarray(s)


# ------------------------------------------------------------------------------------------------
# symbolic pieces (CasADi)
# ------------------------------------------------------------------------------------------------
def _phi12_casadi(x):
    """phi1, phi2 as CasADi expressions."""
    return _phi12_with(x, ca.if_else, ca.expm1)


def _shooting_interval_functions(name, log_p, w, w_next, steps, data, continuity, cost):
    """The Function pair of one multiple-shooting interval of a LuGre fit (shared by both measurement models).

    ``name(log_p, w, w_next, steps, data) -> (continuity, cost)`` and
    ``name_hessian(log_p, w, steps, data, lam_f, lam) -> (36,)``: the upper triangle of the 8 x 8 Hessian
    of ``lam_f * cost + lam * continuity`` over ``(log_p, w)`` (continuity is linear in ``w_next``).
    """
    lam_f = ca.SX.sym("lam_f")
    lam = ca.SX.sym("lam")
    z = ca.vertcat(log_p, w)
    hess = ca.hessian(lam_f * cost + lam * continuity, z)[0]
    triu = ca.vertcat(*[hess[i, j] for i, j in zip(*np.triu_indices(8))])
    return (
        ca.Function(name, [log_p, w, w_next, steps, data], [continuity, cost]),
        ca.Function(f"{name}_hessian", [log_p, w, steps, data, lam_f, lam], [triu]),
    )


@dataclass(frozen=True)
class LuGreExpressions:
    """CasADi Functions of the LuGre model of one joint, for NLPs and MPC.

    Attributes
    ----------
    zdot : casadi.Function
        ``(z, qd, p) -> zdot`` [rad/s], eq. 12; ``p`` is the (7,) parameter vector.
    torque : casadi.Function
        ``(z, qd, p) -> tau`` [N m], eq. 14.
    step : casadi.Function
        ``(s, qd_start, qd_end, h, p) -> s_next``: one exponential-integrator step of the bristle
        force ``s = sigma0 z`` [N m] (module docstring); ``qd_start`` and ``qd_end`` of one sign.
    """

    zdot: ca.Function
    torque: ca.Function
    step: ca.Function


def build_lugre_expressions(symbol=ca.SX):
    """Build the CasADi LuGre Functions (eq. 12, eq. 14 and the discrete step), parameters symbolic.

    Parameters
    ----------
    symbol : {casadi.SX, casadi.MX}
        Symbol class of the Functions' bodies.

    Returns
    -------
    LuGreExpressions

    Examples
    --------
    >>> f = build_lugre_expressions()
    >>> p = [1.0, 1.5, 0.01, 0.5, 1.0, 1e5, 10.0]
    >>> round(float(f.torque(1e-5, 0.2, p)), 6)   # steady sliding: z = g/sigma0
    1.1
    """
    if symbol not in (ca.SX, ca.MX):
        raise ParameterError(
            f"build_lugre_expressions.symbol must be casadi.SX or casadi.MX; got {symbol!r}. Pass casadi.SX."
        )
    z = symbol.sym("z")
    s = symbol.sym("s")
    qd = symbol.sym("qd")
    qd0 = symbol.sym("qd_start")
    qd1 = symbol.sym("qd_end")
    h = symbol.sym("h")
    p = symbol.sym("p", 7)
    zdot_expr = lugre_zdot_expression(z, qd, p)
    tau_expr = lugre_torque_expression(z, qd, p)
    s_next = lugre_step_expression(s, qd0, qd1, h, p)
    return LuGreExpressions(
        zdot=ca.Function("zdot", [z, qd, p], [zdot_expr], ["z", "qd", "p"], ["zdot"]),
        torque=ca.Function("torque", [z, qd, p], [tau_expr], ["z", "qd", "p"], ["tau"]),
        step=ca.Function("step", [s, qd0, qd1, h, p], [s_next], ["s", "qd_start", "qd_end", "h", "p"], ["s_next"]),
    )


def _unpack(p):
    return [p[i] for i in range(7)]


def _stribeck_g(qd, fc, fs, vs):
    return fc + (fs - fc) * ca.exp(-((qd / vs) ** 2))


def lugre_zdot_expression(z, qd, p):
    """Symbolic eq. 12: ``zdot = qd - sigma0 |qd| z / g(qd)``; ``p`` in :data:`LUGRE_PARAMETER_NAMES` order."""
    fc, fs, vs, _, _, sigma0, _ = _unpack(p)
    return qd - sigma0 * ca.fabs(qd) * z / _stribeck_g(qd, fc, fs, vs)


def lugre_torque_expression(z, qd, p):
    """Symbolic eq. 14: ``sigma0 z + sigma1 zdot + fv |qd|**dv sign(qd)``."""
    _, _, _, fv, dv, sigma0, sigma1 = _unpack(p)
    viscous = ca.if_else(qd == 0, 0.0, fv * ca.exp(dv * ca.log(ca.fabs(qd) + (qd == 0))) * ca.sign(qd))
    return sigma0 * z + sigma1 * lugre_zdot_expression(z, qd, p) + viscous


def lugre_step_expression(s, qd_start, qd_end, h, p, sign=None):
    """Symbolic exponential-integrator step of the bristle force ``s = sigma0 z`` (module docstring).

    ``qd_start`` and ``qd_end`` must not differ in sign (split the step at the zero crossing);
    ``sign`` defaults to ``sign(qd_start + qd_end)``.
    """
    fc, fs, vs, _, _, sigma0, _ = _unpack(p)
    if sign is None:
        sign = ca.sign(qd_start + qd_end)
    g_a = _stribeck_g(qd_start, fc, fs, vs)
    g_b = _stribeck_g(qd_end, fc, fs, vs)
    x = 0.5 * h * sigma0 * (ca.fabs(qd_start) / g_a + ca.fabs(qd_end) / g_b)
    phi1, phi2 = _phi12_casadi(x)
    y_a = sign * g_a
    y_b = sign * g_b
    return ca.exp(-x) * s + x * (phi1 * y_a + phi2 * (y_b - y_a))


