"""DiagnosisContext: one preprocessed recording with the nominal model's signals the candidate terms are built from.

``build_context`` evaluates, once per recording, everything candidate columns need: the measured
torque and its time derivatives (full rate), the nominal rigid-body torque of the robot file
(the prior), its Jacobians with respect to q and qd and the mass matrix (Pinocchio
``computeRNEADerivatives``), the PSDM regressor and the gravity torque under a tilted gravity.
The expensive matrices are evaluated on a decimated grid (``rate_hz``, default 200 Hz); signals
that are differentiated (torque derivatives for delay, elasticity, backlash) are differentiated at
full rate first and then decimated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.oracle import build_pinocchio_model

from ..preprocessing import central_difference, zero_phase_filter
from ..recording import Recording


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

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_dof(self) -> int:
        return int(self.q.shape[1])

    def friction_shift(self, joint: int, shift_rate: np.ndarray) -> np.ndarray | None:
        """Change of the robot file's LuGre friction of ``joint`` when the true velocity is the recorded one
        minus ``shift_rate`` (full rate, (n_full,)): ``F(qd_rec) - F(qd_rec - shift_rate)``, decimated (n_samples,);
        None without drives."""
        from ..friction import LuGreParameters, simulate_lugre

        if self.drives is None:
            return None
        d = self.drives[joint]
        p = LuGreParameters(fc=d.fc, fs=max(d.fs, 1e-9), vs=d.vs, fv=d.fv, dv=d.dv, sigma0=d.sigma0, sigma1=d.sigma1)
        qd = self.full_qd[:, joint]
        recorded, _ = simulate_lugre(p, self.full_t, qd, z0=0.0)
        true, _ = simulate_lugre(p, self.full_t, qd - shift_rate, z0=0.0)
        return (recorded - true)[self.keep]

    def smooth_transform(self, joint: int, function) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``s = function(tau_joint)`` at full rate, low-pass filtered like the recording, with its
        first and second time derivatives, all decimated: three arrays (n_samples,)."""
        s, sd, sdd = self.smooth_transform_full(joint, function)
        return s[self.keep], sd[self.keep], sdd[self.keep]

    def smooth_transform_full(self, joint: int, function) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As ``smooth_transform`` at full rate (not decimated)."""
        s = function(self.full_tau[:, joint])
        if self.cutoff_hz is not None:
            rate = 1.0 / float(np.median(np.diff(self.full_t)))
            if self.cutoff_hz < 0.5 * rate:
                s = zero_phase_filter(s, rate, self.cutoff_hz, 4)
        sd, sdd = central_difference(self.full_t, s)
        return s, sd, sdd


def _tilt_axes(gravity: np.ndarray) -> np.ndarray:
    g = gravity / np.linalg.norm(gravity)
    helper = np.eye(3)[int(np.argmin(np.abs(g)))]
    a1 = np.cross(g, helper)
    a1 /= np.linalg.norm(a1)
    a2 = np.cross(g, a1)
    return np.vstack([a1, a2])


def build_context(robot, model, recording: Recording, rate_hz: float = 200.0,
                  cutoff_hz: float | None = 15.0, torque_constants=None, with_regressor: bool = False) -> DiagnosisContext:
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

    Raises
    ------
    RecordingError
        When the recording has no qd/qdd (not preprocessed) or the wrong number of joints.
    """
    recording.check_robot(robot.n_dof, robot.name)
    if recording.qd is None or recording.qdd is None:
        raise RecordingError(f"Recording.qd and qdd are missing ({recording.name}); run preprocess(recording) first.")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ParameterError(f"DiagnosisOptions.rate_hz must be positive [Hz]; got {rate_hz!r}.")
    tau_full = recording.joint_torque(torque_constants)
    step = max(1, int(round(1.0 / (rate_hz * recording.dt))))
    keep = np.arange(0, recording.n_samples, step)
    # drop the ends where the zero-phase filter and differences are least reliable
    margin = min(keep.size // 20, int(round(0.2 / (recording.dt * step))))
    keep = keep[margin:keep.size - margin] if margin > 0 else keep
    tau_rate_full, tau_accel_full = central_difference(recording.t, tau_full)
    q, qd, qdd = recording.q[keep], recording.qd[keep], recording.qdd[keep]
    pmodel = build_pinocchio_model(robot)
    data = pmodel.createData()
    n, m = robot.n_dof, keep.size
    tau_rigid = np.empty((m, n))
    dq, dv, mass = (np.empty((m, n, n)) for _ in range(3))
    for k in range(m):
        pin.computeRNEADerivatives(pmodel, data, q[k], qd[k], qdd[k])
        dq[k], dv[k] = data.dtau_dq, data.dtau_dv
        mm = np.triu(data.M)
        mass[k] = mm + np.triu(mm, 1).T
        tau_rigid[k] = pin.rnea(pmodel, data, q[k], qd[k], qdd[k])
    gravity = np.asarray(robot.gravity, dtype=float)
    axes = _tilt_axes(gravity)
    tilt = np.empty((m, n, 2))
    for a, axis in enumerate(axes):
        tilted = pmodel.copy()
        tilted.gravity.linear = np.cross(axis, gravity)
        tdata = tilted.createData()
        tilt[:, :, a] = [pin.computeGeneralizedGravity(tilted, tdata, x) for x in q]
    regressor = model.regressor(q, qd, qdd) if with_regressor else None
    standard = np.array(robot.nominal_dynamic_parameters(), dtype=float)
    reference = standard.copy()
    reference[-1, 0] += 1.0  # a unit mass keeps every perturbed inertia valid
    payload = np.empty((m, n, 4))

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
    return DiagnosisContext(
        t=recording.t[keep], q=q, qd=qd, qdd=qdd, tau=tau_full[keep], tau_rate=tau_rate_full[keep],
        tau_accel=tau_accel_full[keep], tau_rigid=tau_rigid, dtau_dq=dq, dtau_dqd=dv, mass=mass,
        regressor=regressor, payload=payload, tilt=tilt, tilt_axes=axes, full_t=recording.t.copy(), full_tau=tau_full, full_qd=recording.qd.copy(), keep=keep,
        cutoff_hz=cutoff_hz, parameter_map=np.asarray(model.parameter_map),
        drives=robot.drives, name=recording.name)

