"""DiagnosisContext: one preprocessed recording with the nominal model's signals the candidate terms are built from.

``build_context`` evaluates, once per recording, everything candidate columns need: the measured
torque and its time derivatives (full rate), the nominal rigid-body torque of the robot file
(the prior), its Jacobians with respect to q and qd and the mass matrix (Pinocchio
``computeRNEADerivatives``), the PSDM regressor and the gravity torque under a tilted gravity.
The expensive matrices are evaluated on a decimated grid (``rate_hz``: identify's samples, ``filter_choice``); signals
that are differentiated (torque derivatives for delay, elasticity, backlash) are differentiated at
full rate first and then decimated.

Long recordings: the grid holds at most ``max_samples`` samples (``DiagnosisOptions.max_samples``; a
longer recording gets a coarser grid, logged, with a warning below ``MIN_GRID_PER_CUTOFF`` samples per
period of the cut-off), so the grid's matrices (about 1.8 kB per sample for 6 joints) do not grow with
the recording. The full-rate signals (time, filtered torque and velocity, raw torque) are the
recordings' own read-only arrays, not copies; the torque derivatives are taken one joint at a time;
the robot file's LuGre friction is simulated in pieces (``simulate_friction``, ``simulation.LUGRE_CHUNK``).

With a LuGre friction prior (the robot file's drives, ``filtered_friction``), columns with the sign of
the velocity are built at full rate with the exact sign and low-pass filtered like the recording
(``DiagnosisContext.lowpass``) before decimation: the measured torque is the filtered true torque,
whose friction steps are smeared over the filter's impulse response, and a sharp column evaluated on
the filtered velocity leaves that smear as a residual far above the sensor noise. With the robot file's LuGre
friction as the nominal model, the sparse terms' sign and low-speed features (``DiagnosisContext.sign_qd``) take
the velocity of the raw angle filtered at ``SIGN_CUTOFF_FACTOR`` times the
cutoff (``sign_velocity``): at identify's 10 Hz a velocity filtered like the torque misplaces the reversals where a
joint sticks by tens of milliseconds, and the sign columns then miss friction that depends on the angle (a 0.8 N m
position-dependent friction of the virtual Denso left 0.5 N m of its 0.7 N m, found with the sharper sign down to
0.07 N m) or a low-speed hump. A model file's Coulomb-viscous or Stribeck friction keeps the filtered velocity.
Without a prior the smooth sign ``tanh(qd / SMOOTH_VELOCITY)`` of the filtered velocity is kept: its
width stands in for the unknown pre-sliding, and filtered low-speed columns of a guessed shape turn
into pulses at every reversal that trade against inertia (unphysical friction amplitudes that do not
carry over to the validation recording).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import pinocchio as pin

from identification.calibration.payload_fit import FlangeRegressor
from identification.data.filter_choice import EDGE_PERIODS, grid_step, kept_samples
from identification.data.preprocessing import PreprocessOptions, central_difference, zero_phase_filter
from identification.data.recording import Recording
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from identification.diagnosis.candidates.friction import recording_cache
from identification.diagnosis.columns import row_chunks
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.oracle import build_pinocchio_model

logger = logging.getLogger(__name__)

FILTER_ORDER = PreprocessOptions().order  # the order ``diagnose`` preprocesses the recordings with
SIGN_CUTOFF_FACTOR = 2.0  # the velocity of the friction columns' sign: filtered at this times the cutoff
MIN_GRID_PER_CUTOFF = 4.0  # a grid coarser than this many samples per cut-off period is reported (``build_context``)


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
    payload : array (n_samples, n_dof, 10)
        Torque per unit mass, first moment and inertia about the link frame origin of a body fixed to the flange (m,
        mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz, Pinocchio's order): ``payload_fit.FlangeRegressor``, the columns
        ``psdm validate``'s payload check and identify's unknown payloads use too.
    tilt : array (n_samples, n_dof, 2)
        Gravity torque of a gravity tilted by 1 rad about two axes normal to gravity (linearised).
    tilt_axes : array (2, 3)
    full_t, full_tau : arrays
        Full-rate time and filtered torque (for smoothed nonlinear transforms of the torque).
    full_qd : array (n_full, n_dof)
        Full-rate velocity of the preprocessed recording.
    sign_qd : array (n_full, n_dof) or None
        Full-rate velocity the sparse terms' sign and low-speed features take their sign from (``sign_velocity``);
        None: ``full_qd``.
    keep : array of int
        Indices of the decimated samples in the full-rate arrays.
    cutoff_hz : float or None
        Cut-off of the preprocessing filter (re-applied to transformed torque signals).
    drives : tuple of DriveParameters or None
        The robot file's drives (LuGre friction of ``friction_shift``).
    name : str
    gravity : array (n_samples, n_dof) or None
        Gravity torque of the robot file's nominal model on the grid [N m] (the scale the plausibility of a
        candidate's torque is judged against, ``candidates.base.torque_bound``).
    filtered_friction : bool
        Whether friction-like columns use the exact sign filtered like the recording (with a LuGre prior)
        or the smooth sign of the filtered velocity (``friction_sign``).
    full_tau_raw : array (n_full, n_dof) or None
        The measured torque before filtering (on ``full_t``): nonlinear functions of the torque (the
        backlash flank) are taken of it and then filtered, as the sensor saw them; None falls back to
        ``full_tau``.
    torque_constants : array (n_dof,) or None
        Kt [N m/A] the torque was computed with from motor currents; None for a torque signal. On currents the
        robot file's rigid body is taken in identify's map (``merged_rotors``: the rotors the base parameters hold).
    tau_held : array (n_samples, n_dof) or None
        The torque of the friction a model file holds (``held_friction.HeldFriction``; None: none), which no fit
        estimates: every fit explains ``tau_fit``.
    held_offsets : tuple of float
        The torque offset [N m] per joint ``tau_held`` holds (a model file's; empty: none): a fitted offset on such a
        joint is the part the data add to it, and its plausibility is judged on the joint's whole offset
        (``candidates.base.held_offset``).
    coulomb_velocity : float or tuple of float
        The smoothing velocity [rad/s] of the nominal friction's sign (one, or one per joint) without a LuGre prior
        (``nominal.friction_blocks``; ``DiagnosisOptions.coulomb_velocity``).
    segments : tuple of int
        Where each recording after the first starts in the full-rate arrays of a context pooling several
        (``pooled_context``; empty: one recording): each is filtered on its own (``lowpass_full``).
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
    gravity: np.ndarray | None = None
    missing: tuple = ()
    sign_qd: np.ndarray | None = None
    torque_constants: np.ndarray | None = None
    tau_held: np.ndarray | None = None
    held_offsets: tuple = ()
    coulomb_velocity: float | tuple = SMOOTH_VELOCITY
    segments: tuple = ()

    @property
    def tau_fit(self) -> np.ndarray:
        """The measured torque the fits explain (n_samples, n_dof): ``tau`` less the held friction's (``tau_held``)."""
        return self.tau if self.tau_held is None else self.tau - self.tau_held

    def without_torque(self, joints) -> DiagnosisContext:
        """This context with the joints ``joints`` left out (no torque measurement in one of the diagnosis's
        recordings, ``missing_torque``): their torque is the nominal rigid body's, so there is nothing to explain on
        them, and ``missing`` names them, so every fit weighs their rows by nothing (``design.joint_weights``) and no
        term is fitted on them."""
        joints = sorted({int(j) for j in joints})
        if not joints:
            return self
        tau, rate, accel = self.tau.copy(), self.tau_rate.copy(), self.tau_accel.copy()
        tau[:, joints], rate[:, joints], accel[:, joints] = self.tau_rigid[:, joints], 0.0, 0.0
        full = self.full_tau.copy()
        full[:, joints] = 0.0
        raw, held = (None if x is None else x.copy() for x in (self.full_tau_raw, self.tau_held))
        for values in (x for x in (raw, held) if x is not None):
            values[:, joints] = 0.0
        return replace(self, tau=tau, tau_rate=rate, tau_accel=accel, full_tau=full, full_tau_raw=raw, tau_held=held,
                       missing=tuple(joints))  # fmt: skip

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

    @cached_property
    def full_rate_hz(self) -> float:
        """Sample rate of the full-rate signals [Hz] (computed once: every filtered column asks for it)."""
        return 1.0 / float(np.median(np.diff(self.full_t)))

    def lowpass(self, values: np.ndarray) -> np.ndarray:
        """Full-rate ``values`` (n_full, ...) filtered like the recording (zero phase, cut-off ``cutoff_hz``),
        decimated to the grid: (n_samples, ...)."""
        return self.lowpass_full(values)[self.keep]

    def lowpass_full(self, values: np.ndarray) -> np.ndarray:
        """As ``lowpass`` without decimation (n_full, ...); each recording of a pooled context on its own."""
        values = np.asarray(values, dtype=float)
        rate = self.full_rate_hz
        if self.cutoff_hz is None or self.cutoff_hz >= 0.5 * rate:
            return values
        parts = np.split(values, list(self.segments))
        return np.concatenate([zero_phase_filter(part, rate, self.cutoff_hz, FILTER_ORDER) for part in parts])

    def friction_sign(self, joint: int, factor: np.ndarray | None = None, sharp: bool = False) -> np.ndarray:
        """``factor * sign(qd)`` of ``joint`` on the grid (n_samples,), ``factor`` (n_full,) at full rate (default 1).

        With ``filtered_friction`` the exact sign at full rate, multiplied and filtered like the recording;
        otherwise ``factor * tanh(qd / SMOOTH_VELOCITY)`` on the grid (see the module docstring). ``sharp``: the sign
        of ``sign_qd`` where there is one (the sparse terms)."""
        if self.filtered_friction:
            sign = np.sign((self.sign_qd if sharp and self.sign_qd is not None else self.full_qd)[:, joint])
            return self.lowpass(sign if factor is None else sign * factor)
        sign = np.tanh(self.qd[:, joint] / SMOOTH_VELOCITY)
        return sign if factor is None else sign * np.asarray(factor)[self.keep]

    def friction_shift(self, joint: int, shift_rate: np.ndarray) -> np.ndarray | None:
        """Change of the robot file's LuGre friction of ``joint`` when the true velocity is the recorded one
        minus ``shift_rate`` (full rate, (n_full,)): ``F(qd_rec) - F(qd_rec - shift_rate)``, decimated (n_samples,);
        None without drives."""
        if self.drives is None:
            return None
        p = lugre_parameters(self.drives[joint])
        qd = self.full_qd[:, joint]
        cache = recording_cache(self, _RECORDED_FRICTION)  # the recorded velocity's friction: once per recording
        if (joint, p) not in cache:
            cache[joint, p] = simulate_friction(p, self.full_t, qd)
        recorded = cache[joint, p]
        true = simulate_friction(p, self.full_t, qd - shift_rate)
        return self.lowpass(recorded - true)


_RECORDED_FRICTION = {}  # each recording's LuGre friction of each joint (``friction_shift``, ``recording_cache``)


def lugre_parameters(drive):
    """The LuGre friction (``LuGreParameters``) of a robot file's drive (a Stribeck torque of at least 1e-9 N m)."""
    from identification.friction.models import LuGreParameters

    d = drive
    return LuGreParameters(fc=d.fc, fs=max(d.fs, 1e-9), vs=d.vs, fv=d.fv, dv=d.dv, sigma0=d.sigma0, sigma1=d.sigma1)


def simulate_friction(parameters, t: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """LuGre friction torque (n_full,) [N m] along ``qd`` from a relaxed bristle (``simulate_lugre``, z0 = 0).

    A recording longer than ``simulation.LUGRE_CHUNK`` samples is simulated in pieces by ``simulate_lugre`` itself
    (the bristle state carried across them), which keeps the simulator's temporaries in the processor's cache."""
    from identification.friction.simulation import simulate_lugre

    return simulate_lugre(parameters, t, qd, z0=0.0)[0]


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


def _decimated_indices(
    recording: Recording,
    rate_hz: float,
    max_samples: int | None = None,
    cutoff_hz: float | None = None,
    identify: bool = False,
    edge_periods: float = EDGE_PERIODS,
) -> np.ndarray:
    """Indices of the samples of a ``rate_hz`` grid (coarser when it would hold more than ``max_samples``
    samples), without the ends where the zero-phase filter and the differences are least reliable: 5 % of the
    grid (at most 0.2 s) at each end, or with ``identify`` (filtered at ``cutoff_hz``) identify's samples
    (``filter_choice.kept_samples``: every ``grid_step``-th, ``edge_periods`` filter periods trimmed), so a model
    file is judged on the samples ``psdm validate`` judges it on."""
    rate = 1.0 / recording.dt
    step = grid_step(rate, rate_hz) if identify else max(1, int(round(1.0 / (rate_hz * recording.dt))))
    if max_samples is not None:
        step = max(step, -(-recording.n_samples // int(max_samples)))
    if identify and cutoff_hz is not None:
        return np.arange(recording.n_samples)[kept_samples(recording.n_samples, rate, cutoff_hz, step, edge_periods)]
    keep = np.arange(0, recording.n_samples, step)
    margin = min(keep.size // 20, int(round(0.2 / (recording.dt * step))))
    return keep[margin : keep.size - margin] if margin > 0 else keep


def _grid(recording: Recording, rate_hz: float, max_samples, cutoff_hz, identify=False, edge=EDGE_PERIODS):
    """``_decimated_indices``, logging a grid that ``max_samples`` made coarser than ``rate_hz``."""
    keep = _decimated_indices(recording, rate_hz, max_samples, cutoff_hz, identify, edge)
    if max_samples is None or keep.size >= _decimated_indices(recording, rate_hz, None, cutoff_hz, identify, edge).size:
        return keep
    grid_hz = 1.0 / (recording.dt * float(keep[1] - keep[0]))
    source = recording.name or "the recording"
    logger.info(
        f"diagnose: {source} ({recording.duration:.0f} s) on a {grid_hz:.3g} Hz grid of {keep.size} samples "
        f"(DiagnosisOptions.max_samples={max_samples})"
    )
    if cutoff_hz is not None and grid_hz < MIN_GRID_PER_CUTOFF * cutoff_hz:
        logger.warning(
            f"diagnose: the {grid_hz:.3g} Hz grid of {source} has fewer than {MIN_GRID_PER_CUTOFF:g} samples per "
            f"period of the {cutoff_hz:g} Hz cut-off: raise DiagnosisOptions.max_samples or lower the cut-off"
        )
    return keep


def _rigid_body_signals(pmodel, q, qd, qdd) -> tuple:
    """Nominal rigid-body torque (n_samples, n_dof), its Jacobians with respect to q and qd and the mass
    matrix (each (n_samples, n_dof, n_dof)), from Pinocchio's ``computeRNEADerivatives``."""
    data = pmodel.createData()
    m, n = q.shape
    tau_rigid = np.empty((m, n))
    dq, dv, upper = (np.empty((m, n, n)) for _ in range(3))
    for k in range(m):
        pin.computeRNEADerivatives(pmodel, data, q[k], qd[k], qdd[k])
        dq[k], dv[k], upper[k] = data.dtau_dq, data.dtau_dv, data.M
        tau_rigid[k] = pin.rnea(pmodel, data, q[k], qd[k], qdd[k])
    upper = np.triu(upper)  # Pinocchio fills the upper triangle of M
    return tau_rigid, dq, dv, upper + np.triu(upper, 1).transpose(0, 2, 1)


def _gravity_torque(pmodel, q) -> np.ndarray:
    """The nominal model's gravity torque (n_samples, n_dof) at the angles ``q``."""
    data = pmodel.createData()
    return np.array([pin.computeGeneralizedGravity(pmodel, data, x) for x in q]).reshape(q.shape)


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


def _joint_torque(recording: Recording, torque_constants) -> np.ndarray:
    """``recording.joint_torque(torque_constants)``, the recorded torque itself when that is what it copies (a
    Recording's arrays are read-only: an hour at 1 kHz is then held once)."""
    if recording.tau is not None and (torque_constants is None or recording.current is None):
        return recording.tau
    return recording.joint_torque(torque_constants)


def _raw_torque(raw: Recording, recording: Recording, tau_full, torque_constants) -> np.ndarray:
    """The torque of ``raw`` (before preprocessing) on the time grid of ``recording`` (n_full, n_dof)."""
    source = _joint_torque(raw, torque_constants)
    if source.shape == tau_full.shape and np.allclose(raw.t, recording.t):
        return source
    return np.column_stack([np.interp(recording.t, raw.t, source[:, j]) for j in range(tau_full.shape[1])])


def sign_velocity(raw: Recording | None, recording: Recording, cutoff_hz: float | None) -> np.ndarray:
    """The full-rate velocity (n_full, n_dof) on ``recording``'s time grid that the friction columns take their sign
    and low-speed shape from: the angle of ``raw`` (before preprocessing) filtered at ``SIGN_CUTOFF_FACTOR`` times
    ``cutoff_hz`` (at most a quarter of the rate) and differentiated, one joint at a time; the preprocessed
    ``recording.qd`` when there is no raw recording or no cutoff (module docstring)."""
    if raw is None or cutoff_hz is None:
        return recording.qd
    rate = 1.0 / float(recording.dt)
    cutoff = min(SIGN_CUTOFF_FACTOR * float(cutoff_hz), 0.25 * rate)
    if cutoff <= float(cutoff_hz):
        return recording.qd
    same = raw.q.shape == recording.q.shape and np.allclose(raw.t, recording.t)
    out = np.empty(recording.q.shape)
    for j in range(recording.q.shape[1]):
        q = raw.q[:, j] if same else np.interp(recording.t, raw.t, raw.q[:, j])
        out[:, j] = central_difference(recording.t, zero_phase_filter(q, rate, cutoff, FILTER_ORDER))[0]
    out.flags.writeable = False
    return out


def _torque_derivatives(t, tau_full, keep) -> tuple:
    """First and second time derivatives of the torque at full rate (central differences), on the grid ``keep``;
    one joint at a time, so the full-rate temporaries stay one column long."""
    rate, accel = (np.empty((keep.size, tau_full.shape[1])) for _ in range(2))
    for j in range(tau_full.shape[1]):
        first, second = central_difference(t, tau_full[:, j])
        rate[:, j], accel[:, j] = first[keep], second[keep]
    return rate, accel


def _regressor(model, q, qd, qdd) -> np.ndarray:
    """The PSDM regressor (n_samples, n_dof, n_base), evaluated in chunks of rows (``CHUNK_ROWS``)."""
    return np.concatenate([model.regressor(q[rows], qd[rows], qdd[rows]) for rows in row_chunks(q.shape[0])])


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
    max_samples: int | None = None,
    identify_samples: bool = False,
    edge_periods: float = EDGE_PERIODS,
    sign_from_raw: bool = True,
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
    max_samples : int, optional
        Most samples of the grid: a longer recording gets a coarser grid (``DiagnosisOptions.max_samples``);
        default no bound.
    identify_samples : bool
        Keep identify's samples (``DiagnosisOptions.samples``), ``edge_periods`` filter periods trimmed at each end
        (``DiagnosisOptions.edge_periods``).
    sign_from_raw : bool
        With ``raw`` and ``filtered_friction``: the friction columns' velocity is ``sign_velocity``'s (the robot file's
        LuGre friction, whose bristles the nominal model simulates through each reversal); False keeps the
        preprocessed velocity (a model file's Coulomb-viscous or Stribeck friction, whose lacking shapes,
        ``lacking_friction_shapes``, are judged on it).

    Raises
    ------
    RecordingError
        When the recording has no qd/qdd (not preprocessed) or the wrong number of joints.
    """
    recording.check_robot(robot.n_dof, robot.name)
    check_preprocessed(recording)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ParameterError(f"DiagnosisOptions.rate_hz must be positive [Hz]; got {rate_hz!r}.")
    if max_samples is not None and not (isinstance(max_samples, (int, np.integer)) and max_samples >= 3):
        raise ParameterError(
            f"build_context.max_samples must be an integer >= 3 or None; got {max_samples!r}. "
            "Use DiagnosisOptions().max_samples."
        )
    tau_full = _joint_torque(recording, torque_constants)
    keep = _grid(recording, rate_hz, max_samples, cutoff_hz, identify_samples, edge_periods)
    tau_rate, tau_accel = _torque_derivatives(recording.t, tau_full, keep)
    q, qd, qdd = recording.q[keep], recording.qd[keep], recording.qdd[keep]
    pmodel = build_pinocchio_model(robot)
    tau_rigid, dq, dv, mass = _rigid_body_signals(pmodel, q, qd, qdd)
    axes, tilt = _tilted_gravity_torque(pmodel, np.asarray(robot.gravity, dtype=float), q)
    regressor = _regressor(model, q, qd, qdd) if with_regressor else None
    payload = FlangeRegressor(robot)(q, qd, qdd)  # the flange body's columns, as payload_check and identify
    tau_raw = None if raw is None else _raw_torque(raw, recording, tau_full, torque_constants)
    filtered_friction = (robot.drives is not None) if filtered_friction is None else bool(filtered_friction)
    sign_qd = sign_velocity(raw, recording, cutoff_hz) if filtered_friction and sign_from_raw else None
    return DiagnosisContext(
        t=recording.t[keep], q=q, qd=qd, qdd=qdd, tau=tau_full[keep], tau_rate=tau_rate, tau_accel=tau_accel,
        tau_rigid=tau_rigid, dtau_dq=dq, dtau_dqd=dv, mass=mass, regressor=regressor, payload=payload, tilt=tilt,
        tilt_axes=axes, full_t=recording.t, full_tau=tau_full, full_qd=recording.qd, sign_qd=sign_qd, keep=keep,
        cutoff_hz=cutoff_hz, parameter_map=np.asarray(model.parameter_map), drives=robot.drives, name=recording.name,
        full_tau_raw=tau_raw, filtered_friction=filtered_friction, gravity=_gravity_torque(pmodel, q),
        torque_constants=None if tau_full is recording.tau else np.asarray(torque_constants, dtype=float),
    )  # fmt: skip
