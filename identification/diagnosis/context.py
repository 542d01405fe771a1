"""DiagnosisContext: one preprocessed recording with the nominal model's signals the candidate terms are built from.

``build_context`` evaluates, once per recording, everything candidate columns need: the measured
torque and its time derivatives (full rate), the nominal rigid-body torque of the robot file
(the prior), its Jacobians with respect to q and qd and the mass matrix (Pinocchio
``computeRNEADerivatives``), the PSDM regressor and the gravity torque under a tilted gravity.
The expensive matrices are evaluated on a decimated grid (``rate_hz``, default 200 Hz); signals
that are differentiated (torque derivatives for delay, elasticity, backlash) are differentiated at
full rate first and then decimated.

With a LuGre friction prior (the robot file's drives, ``filtered_friction``), columns with the sign of
the velocity are built at full rate with the exact sign and low-pass filtered like the recording
(``DiagnosisContext.lowpass``) before decimation: the measured torque is the filtered true torque,
whose friction steps are smeared over the filter's impulse response, and a sharp column evaluated on
the filtered velocity leaves that smear as a residual far above the sensor noise.
Without a prior the smooth sign ``tanh(qd / SMOOTH_VELOCITY)`` of the filtered velocity is kept: its
width stands in for the unknown pre-sliding, and filtered low-speed columns of a guessed shape turn
into pulses at every reversal that trade against inertia (unphysical friction amplitudes that do not
carry over to the validation recording).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from identification.data.preprocessing import PreprocessOptions, central_difference, zero_phase_filter
from identification.data.recording import Recording
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.oracle import build_pinocchio_model

FILTER_ORDER = PreprocessOptions().order  # the order ``diagnose`` preprocesses the recordings with


@dataclass(frozen=True, eq=False)
class DiagnosisContext:
    """Signals of one recording on the decimated grid (``n_samples``) plus full-rate torque helpers.

    Attributes
    ----------
    t, q, qd, qdd, tau : arrays (n_samples,) / (n_samples, n_dof)
        Decimated preprocessed signals [s, rad, rad/s, rad/s^2, N m].
    tau_rate, tau_accel : arrays (n_samples, n_dof)
        First and second time derivatives of the (filtered) measured torque [N m/s, N m/s^2].
    tau_rigid : array (n_samples, n_dof)
        Rigid-body torque of the robot file's nominal parameters [N m].
    dtau_dq, dtau_dqd, mass : arrays (n_samples, n_dof, n_dof)
        Jacobians of the nominal rigid-body torque and the mass matrix.
    regressor : array (n_samples, n_dof, n_base) or None
        PSDM regressor Y(q, qd, qdd) (only when requested: it is slow for 7 joints).
    payload : array (n_samples, n_dof, 4)
        Torque per unit mass and first moments (m, mx, my, mz) added to the last link (RNEA is linear in them).
    tilt : array (n_samples, n_dof, 2)
        Gravity torque of a gravity tilted by 1 rad about two axes normal to gravity (linearised).
    tilt_axes : array (2, 3)
    full_t, full_tau : arrays
        Full-rate time and filtered torque (for smoothed nonlinear transforms of the torque).
    keep : array of int
        Indices of the decimated samples in the full-rate arrays.
    cutoff_hz : float or None
        Cut-off of the preprocessing filter (re-applied to transformed torque signals).
    drives : tuple of DriveParameters or None
        The robot file's drives (LuGre friction of ``friction_shift``).
    name : str
    filtered_friction : bool
        Whether friction-like columns use the exact sign filtered like the recording (with a LuGre prior)
        or the smooth sign of the filtered velocity (``friction_sign``).
    full_tau_raw : array (n_full, n_dof) or None
        The measured torque before filtering (on ``full_t``): nonlinear functions of the torque (the
        backlash flank) are taken of it and then filtered, as the sensor saw them; None falls back to
        ``full_tau``.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    tau_rate: np.ndarray
    tau_accel: np.ndarray
    tau_rigid: np.ndarray
    dtau_dq: np.ndarray
    dtau_dqd: np.ndarray
    mass: np.ndarray
    regressor: np.ndarray | None
    payload: np.ndarray
    tilt: np.ndarray
    tilt_axes: np.ndarray
    full_t: np.ndarray
    full_tau: np.ndarray
    full_qd: np.ndarray
    keep: np.ndarray
    cutoff_hz: float | None
    parameter_map: np.ndarray
    drives: tuple | None = None
    name: str = ""
    full_tau_raw: np.ndarray | None = None
    filtered_friction: bool = True

    @property
    def raw_torque(self) -> np.ndarray:
        """Measured torque before filtering (n_full, n_dof), or the filtered one when it is not known."""
        return self.full_tau if self.full_tau_raw is None else self.full_tau_raw

    def delayed_torque_difference(self, delay: float) -> np.ndarray:
        """``tau(t) - tau(t + delay)`` of the filtered measured torque on the grid (n_samples, n_dof): the torque
        a delay of the torque signal by ``delay`` [s] adds to the model (linear interpolation at full rate)."""
        t = self.t + float(delay)
        shifted = np.column_stack([np.interp(t, self.full_t, self.full_tau[:, j]) for j in range(self.n_dof)])
        return self.tau - shifted

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_dof(self) -> int:
        return int(self.q.shape[1])

    @property
    def full_rate_hz(self) -> float:
        """Sample rate of the full-rate signals [Hz]."""
        return 1.0 / float(np.median(np.diff(self.full_t)))

    def lowpass(self, values: np.ndarray) -> np.ndarray:
        """Full-rate ``values`` (n_full, ...) filtered like the recording (zero phase, cut-off ``cutoff_hz``),
        decimated to the grid: (n_samples, ...)."""
        return self.lowpass_full(values)[self.keep]

    def lowpass_full(self, values: np.ndarray) -> np.ndarray:
        """As ``lowpass`` without decimation (n_full, ...)."""
        values = np.asarray(values, dtype=float)
        rate = self.full_rate_hz
        if self.cutoff_hz is not None and self.cutoff_hz < 0.5 * rate:
            values = zero_phase_filter(values, rate, self.cutoff_hz, FILTER_ORDER)
        return values

    def friction_sign(self, joint: int, factor: np.ndarray | None = None) -> np.ndarray:
        """``factor * sign(qd)`` of ``joint`` on the grid (n_samples,), ``factor`` (n_full,) at full rate (default 1).

        With ``filtered_friction`` the exact sign at full rate, multiplied and filtered like the recording;
        otherwise ``factor * tanh(qd / SMOOTH_VELOCITY)`` on the grid (see the module docstring)."""
        if self.filtered_friction:
            sign = np.sign(self.full_qd[:, joint])
            return self.lowpass(sign if factor is None else sign * factor)
        sign = np.tanh(self.qd[:, joint] / SMOOTH_VELOCITY)
        return sign if factor is None else sign * np.asarray(factor)[self.keep]

    def friction_shift(self, joint: int, shift_rate: np.ndarray) -> np.ndarray | None:
        """Change of the robot file's LuGre friction of ``joint`` when the true velocity is the recorded one
        minus ``shift_rate`` (full rate, (n_full,)): ``F(qd_rec) - F(qd_rec - shift_rate)``, decimated (n_samples,);
        None without drives."""
        from identification.friction.models import LuGreParameters
        from identification.friction.simulation import simulate_lugre

        if self.drives is None:
            return None
        d = self.drives[joint]
        p = LuGreParameters(fc=d.fc, fs=max(d.fs, 1e-9), vs=d.vs, fv=d.fv, dv=d.dv, sigma0=d.sigma0, sigma1=d.sigma1)
        qd = self.full_qd[:, joint]
        recorded, _ = simulate_lugre(p, self.full_t, qd, z0=0.0)
        true, _ = simulate_lugre(p, self.full_t, qd - shift_rate, z0=0.0)
        return self.lowpass(recorded - true)


def check_preprocessed(recording: Recording) -> Recording:
    """Raise :class:`RecordingError` unless ``recording`` holds qd and qdd (is preprocessed); return it."""
    if recording.qd is None or recording.qdd is None:
        raise RecordingError(f"Recording.qd and qdd are missing ({recording.name}); run preprocess(recording) first.")
    return recording


def _tilt_axes(gravity: np.ndarray) -> np.ndarray:
    g = gravity / np.linalg.norm(gravity)
    helper = np.eye(3)[int(np.argmin(np.abs(g)))]
    a1 = np.cross(g, helper)
    a1 /= np.linalg.norm(a1)
    a2 = np.cross(g, a1)
    return np.vstack([a1, a2])


def _decimated_indices(recording: Recording, rate_hz: float) -> np.ndarray:
    """Indices of the samples of a ``rate_hz`` grid, without the ends where the zero-phase filter and the
    differences are least reliable (5 % of the grid, at most 0.2 s each)."""
    step = max(1, int(round(1.0 / (rate_hz * recording.dt))))
    keep = np.arange(0, recording.n_samples, step)
    margin = min(keep.size // 20, int(round(0.2 / (recording.dt * step))))
    return keep[margin : keep.size - margin] if margin > 0 else keep


def _rigid_body_signals(pmodel, q, qd, qdd) -> tuple:
    """Nominal rigid-body torque (n_samples, n_dof), its Jacobians with respect to q and qd and the mass
    matrix (each (n_samples, n_dof, n_dof)), from Pinocchio's ``computeRNEADerivatives``."""
    data = pmodel.createData()
    m, n = q.shape
    tau_rigid = np.empty((m, n))
    dq, dv, mass = (np.empty((m, n, n)) for _ in range(3))
    for k in range(m):
        pin.computeRNEADerivatives(pmodel, data, q[k], qd[k], qdd[k])
        dq[k], dv[k] = data.dtau_dq, data.dtau_dv
        mm = np.triu(data.M)
        mass[k] = mm + np.triu(mm, 1).T
        tau_rigid[k] = pin.rnea(pmodel, data, q[k], qd[k], qdd[k])
    return tau_rigid, dq, dv, mass


def _tilted_gravity_torque(pmodel, gravity: np.ndarray, q) -> tuple:
    """The two tilt axes normal to gravity (2, 3) and the gravity torque of a gravity tilted by 1 rad about each
    (linearised), (n_samples, n_dof, 2)."""
    axes = _tilt_axes(gravity)
    tilt = np.empty((q.shape[0], q.shape[1], 2))
    for a, axis in enumerate(axes):
        tilted = pmodel.copy()
        tilted.gravity.linear = np.cross(axis, gravity)
        tdata = tilted.createData()
        tilt[:, :, a] = [pin.computeGeneralizedGravity(tilted, tdata, x) for x in q]
    return axes, tilt


def _payload_torque(robot, q, qd, qdd, tau_rigid) -> np.ndarray:
    """Torque per unit mass and first moments (m, mx, my, mz) added to the last link, (n_samples, n_dof, 4).

    RNEA is linear in them: differences of RNEA with the nominal parameters, with a unit mass added to the
    last link (which keeps every perturbed inertia valid) and with a unit first moment added to that."""
    standard = np.array(robot.nominal_dynamic_parameters(), dtype=float)
    reference = standard.copy()
    reference[-1, 0] += 1.0
    payload = np.empty((q.shape[0], q.shape[1], 4))

    def rnea_all(params):
        pm = build_pinocchio_model(robot, params)
        pd_ = pm.createData()
        return np.array([pin.rnea(pm, pd_, a, b, c) for a, b, c in zip(q, qd, qdd)])

    tau_ref = rnea_all(reference)
    payload[:, :, 0] = tau_ref - tau_rigid
    for c in (1, 2, 3):
        shifted = reference.copy()
        shifted[-1, c] += 1.0
        payload[:, :, c] = rnea_all(shifted) - tau_ref
    return payload


def _raw_torque(raw: Recording, recording: Recording, tau_full, torque_constants) -> np.ndarray:
    """The torque of ``raw`` (before preprocessing) on the time grid of ``recording`` (n_full, n_dof)."""
    source = raw.joint_torque(torque_constants)
    if source.shape == tau_full.shape and np.allclose(raw.t, recording.t):
        return source.copy()
    return np.column_stack([np.interp(recording.t, raw.t, source[:, j]) for j in range(tau_full.shape[1])])


def build_context(
    robot,
    model,
    recording: Recording,
    rate_hz: float = 200.0,
    cutoff_hz: float | None = 15.0,
    torque_constants=None,
    with_regressor: bool = False,
    raw: Recording | None = None,
    filtered_friction: bool | None = None,
) -> DiagnosisContext:
    """Evaluate the nominal model's signals on a preprocessed recording.

    Parameters
    ----------
    robot : RobotDescription
        The robot file: its nominal inertia is the rigid-body prior.
    model : PSDMModel
        ``derive_psdm(robot)``.
    recording : Recording
        Preprocessed (filtered, with qd and qdd).
    rate_hz : float
        Rate of the decimated grid [Hz].
    cutoff_hz : float or None
        Cut-off the recording was filtered with.
    torque_constants : array (n_dof,), optional
        Kt [N m/A] when the recording holds currents only.
    raw : Recording, optional
        The same recording before preprocessing (its torque, interpolated onto the preprocessed
        time grid, is ``DiagnosisContext.full_tau_raw``).
    filtered_friction : bool, optional
        ``DiagnosisContext.filtered_friction``; default: whether the robot file has drives (a LuGre prior).

    Raises
    ------
    RecordingError
        When the recording has no qd/qdd (not preprocessed) or the wrong number of joints.
    """
    recording.check_robot(robot.n_dof, robot.name)
    check_preprocessed(recording)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ParameterError(f"DiagnosisOptions.rate_hz must be positive [Hz]; got {rate_hz!r}.")
    tau_full = recording.joint_torque(torque_constants)
    keep = _decimated_indices(recording, rate_hz)
    tau_rate_full, tau_accel_full = central_difference(recording.t, tau_full)
    q, qd, qdd = recording.q[keep], recording.qd[keep], recording.qdd[keep]
    pmodel = build_pinocchio_model(robot)
    tau_rigid, dq, dv, mass = _rigid_body_signals(pmodel, q, qd, qdd)
    axes, tilt = _tilted_gravity_torque(pmodel, np.asarray(robot.gravity, dtype=float), q)
    regressor = model.regressor(q, qd, qdd) if with_regressor else None
    payload = _payload_torque(robot, q, qd, qdd, tau_rigid)
    tau_raw = None if raw is None else _raw_torque(raw, recording, tau_full, torque_constants)
    return DiagnosisContext(
        t=recording.t[keep],
        q=q,
        qd=qd,
        qdd=qdd,
        tau=tau_full[keep],
        tau_rate=tau_rate_full[keep],
        tau_accel=tau_accel_full[keep],
        tau_rigid=tau_rigid,
        dtau_dq=dq,
        dtau_dqd=dv,
        mass=mass,
        regressor=regressor,
        payload=payload,
        tilt=tilt,
        tilt_axes=axes,
        full_t=recording.t.copy(),
        full_tau=tau_full,
        full_qd=recording.qd.copy(),
        keep=keep,
        cutoff_hz=cutoff_hz,
        parameter_map=np.asarray(model.parameter_map),
        drives=robot.drives,
        name=recording.name,
        full_tau_raw=tau_raw,
        filtered_friction=(robot.drives is not None) if filtered_friction is None else bool(filtered_friction),
    )
