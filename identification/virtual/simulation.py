"""The virtual robot: simulate_recording() turns a reference trajectory into a Recording with known truth.

The simulator is independent of the PSDM model: rigid-body dynamics come from Pinocchio's ``aba``
on the robot's nominal (true) inertia, friction from the LuGre model (paper eqs. 12-14) with the
robot's drive parameters, motor currents from ``tau = Kt i`` (eq. 11). A joint controller
(feed-forward with the true rigid-body model plus steady-state friction, and PD feedback) tracks
the reference at the sample rate; its torque command is held over each sample period (zero-order
hold), which is what a robot that reports current set-points records.

Integration: each sample period is cut into ``substeps`` steps of semi-implicit (symplectic) Euler
for the rigid body; the stiff LuGre state z is advanced by the exact solution of eq. 12 over the
step with the velocity held at its new value, which is stable for any bristle stiffness and keeps
``z`` tracking ``q`` in the pre-sliding regime. The joint torque recorded at sample k is the command
applied from t_k, so it balances the acceleration at t_k exactly.

``SimulationOptions.integrator="leapfrog"`` uses the second-order Stormer-Verlet splitting instead
(half drift of q and z, kick, half drift). Symplectic Euler kicks at the start of each sub-step, so
the second difference of the recorded q weights the held commands of samples k-1 and k by
``(S - 1) / 2S`` and ``(S + 1) / 2S`` (S sub-steps; 0.375/0.625 for S = 4) instead of the 1/2 and
1/2 of continuous time: a timing error of half a sub-step that the friction identification sees
as a phase error of the bristle ringing of heavy joints (it biases sigma1). Leapfrog kicks at the
sub-step centres, which restores 1/2 and 1/2.

The truth of a run and its files are in :mod:`identification.virtual.truth`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline

from identification.data.recording import Recording
from identification.virtual.effects import ExtraPhysics, Payload
from identification.virtual.joint_loop import joint_loop_gains, tracks
from identification.virtual.lugre_exact import LuGreArrays, steady_state_friction
from identification.virtual.truth import SimulationTruth
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.oracle import build_pinocchio_model
from psdm_casadi.robot import RobotDescription

__all__ = ["SimulationOptions", "simulate_recording"]

logger = logging.getLogger(__name__)

FEEDFORWARDS = ("model", "gravity", "none")
INTEGRATORS = ("symplectic-euler", "leapfrog")


@dataclass(frozen=True)
class SimulationOptions:
    """Options of the virtual robot.

    Parameters
    ----------
    rate : float
        Sample and control rate [Hz] (default 1 kHz).
    duration : float or None
        Simulated time [s]; defaults to the span of an array reference (required for a callable one).
    substeps : int
        Integration steps per sample period (rigid body and LuGre state).
    integrator : {"symplectic-euler", "leapfrog"}
        Scheme of each sub-step (module docstring): first-order symplectic Euler (default) or
        second-order leapfrog, whose recorded torques and positions obey the continuous-time relation
        ``J (q[k+1] - 2 q[k] + q[k-1]) / T^2 = (tau[k-1] + tau[k]) / 2 - <friction>`` of a held command
        (use it for friction experiments; ``qdd``/``tau_friction`` of the truth are then taken at the
        middle of the first sub-step).
    bandwidth_hz : float
        Bandwidth of the PD loop [Hz]: ``Kp = M_ii w^2``, ``Kd = 2 zeta M_ii w`` with the mass-matrix
        diagonal at the first reference pose.
    integral_gain : float
        Integral action of the joint controller as a fraction of the Routh bound's scale:
        ``Ki = integral_gain * M_ii w^3`` (stable for ``integral_gain < 2 zeta``); it removes the
        steady tracking error an unmodelled load (a spring, a payload) would leave. 0 gives a PD loop.
    settled_start : bool
        The controller has been holding the start state before the recording, as a robot in position
        control does before a run: its integral term starts at the torque the feed-forward misses there
        (hidden extras, the plant's own inertia or friction where the controller's model differs), so
        the recording starts without a sag (without hidden extras the controller's model is the plant and
        there is nothing to hold). False starts the integral term at zero, a controller
        switched on at the first sample (a hidden torque then shows a start-up transient).
    damping_ratio : float
        ``zeta`` of the PD loop.
    feedforward : {"model", "gravity", "none"}
        ``"model"``: rigid-body inverse dynamics of the reference (true model, known payload);
        ``"gravity"``: gravity only; ``"none"``: PD only.
    friction_feedforward : bool
        Add the steady-state friction of the reference velocity to the command.
    friction : bool
        Simulate LuGre friction (off: a frictionless robot).
    payload : Payload or None
        Known end-effector load (the calibration weight of the motor step); the feed-forward knows it.
    encoder_resolution : float or None
        Quantisation step of the recorded q [rad or m]; default ``2 pi / 2^20 / 100`` = 6e-8 rad: a
        20-bit motor-side encoder behind a 1:100 gearbox, as on industrial arms. The joint-side
        resolution matters for friction identification: pre-sliding motion spans micro-radians at
        velocities of about 1e-3 rad/s (see ``trajopt.friction_design.FrictionDesign``).
    current_resolution : float or None
        Quantisation step of the recorded current [A].
    q_noise_std, current_noise_std, tau_noise_std : float
        Standard deviation of white noise on the recorded q [rad], current [A], tau [N m].
    record_current, record_tau, record_velocity : bool
        Which signals the recording carries (velocity: the true qd, as from a tachometer).

    Raises
    ------
    ParameterError
        Naming the field and the fix.
    """

    rate: float = 1000.0
    duration: float | None = None
    substeps: int = 2
    integrator: str = "symplectic-euler"
    bandwidth_hz: float = 10.0
    damping_ratio: float = 1.0
    integral_gain: float = 0.25
    settled_start: bool = True
    feedforward: str = "model"
    friction_feedforward: bool = True
    friction: bool = True
    payload: Payload | None = None
    encoder_resolution: float | None = 2.0 * np.pi / 2**20 / 100
    current_resolution: float | None = 1e-3
    q_noise_std: float = 0.0
    current_noise_std: float = 0.005
    tau_noise_std: float = 0.0
    record_current: bool = True
    record_tau: bool = False
    record_velocity: bool = False

    def __post_init__(self):
        if not (np.isfinite(self.integral_gain) and 0.0 <= self.integral_gain < 2.0 * self.damping_ratio):
            raise ParameterError(
                f"SimulationOptions.integral_gain must be in [0, 2 damping_ratio) for a stable loop; "
                f"got {self.integral_gain!r}. Use 0.25 (or 0 for a PD loop)."
            )
        for key in ("rate", "bandwidth_hz", "damping_ratio"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"SimulationOptions.{key} must be positive; got {value!r}.")
        if self.duration is not None and not (np.isfinite(self.duration) and self.duration > 0):
            raise ParameterError(f"SimulationOptions.duration must be positive [s] or None; got {self.duration!r}.")
        if not (isinstance(self.substeps, (int, np.integer)) and self.substeps >= 1):
            raise ParameterError(f"SimulationOptions.substeps must be an integer >= 1; got {self.substeps!r}.")
        if self.integrator not in INTEGRATORS:
            raise ParameterError(
                f"SimulationOptions.integrator must be one of {INTEGRATORS}; got {self.integrator!r}. "
                "Pass 'leapfrog' for friction experiments."
            )
        if self.feedforward not in FEEDFORWARDS:
            raise ParameterError(
                f"SimulationOptions.feedforward must be one of {FEEDFORWARDS}; got {self.feedforward!r}."
            )
        for key in ("encoder_resolution", "current_resolution"):
            value = getattr(self, key)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ParameterError(
                    f"SimulationOptions.{key} must be positive or None (no quantisation); got {value!r}."
                )
        for key in ("q_noise_std", "current_noise_std", "tau_noise_std"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value >= 0):
                raise ParameterError(f"SimulationOptions.{key} must be >= 0; got {value!r}.")
        if not (self.record_current or self.record_tau):
            raise ParameterError("SimulationOptions.record_current and record_tau are both False; record at least one.")
        if self.payload is not None and not isinstance(self.payload, Payload):
            raise ParameterError(
                f"SimulationOptions.payload must be a Payload or None; got {type(self.payload).__name__}."
            )


def _drives(robot: RobotDescription) -> tuple:
    if robot.drives is None:
        raise ParameterError(
            f"RobotDescription.drives is empty for {robot.name!r}; the virtual robot needs Kt and LuGre values. "
            "Add one [[drive]] table per joint."
        )
    return robot.drives


def _sample_reference(reference, t: np.ndarray, n_dof: int):
    """Reference (q, qd, qdd) at times t, each (n_samples, n_dof)."""
    if isinstance(reference, Recording):
        reference = (
            (reference.t, reference.q)
            + (() if reference.qd is None else (reference.qd,))
            + (() if reference.qdd is None else (reference.qdd,))
        )
    if callable(reference):
        out = reference(t)
        if not (isinstance(out, tuple) and len(out) == 3):
            raise ParameterError(
                "simulate_recording reference(t) must return a tuple (q, qd, qdd); got "
                f"{type(out).__name__}. Return three (n_samples, n_dof) arrays."
            )
        arrays = [np.asarray(a, dtype=float) for a in out]
    else:
        if not (isinstance(reference, (tuple, list)) and 2 <= len(reference) <= 4):
            raise ParameterError(
                "simulate_recording reference must be a callable t -> (q, qd, qdd), a Recording, or a tuple "
                f"(t, q[, qd[, qdd]]) of arrays; got {type(reference).__name__}."
            )
        t_ref = np.asarray(reference[0], dtype=float)
        parts = [np.asarray(a, dtype=float) for a in reference[1:]]
        spline = CubicSpline(t_ref, parts[0], axis=0)
        arrays = [spline(t)]
        arrays.append(CubicSpline(t_ref, parts[1], axis=0)(t) if len(parts) > 1 else spline(t, 1))
        if len(parts) > 2:
            arrays.append(CubicSpline(t_ref, parts[2], axis=0)(t))
        elif len(parts) > 1:
            arrays.append(CubicSpline(t_ref, parts[1], axis=0)(t, 1))
        else:
            arrays.append(spline(t, 2))
    for name, arr in zip(("q", "qd", "qdd"), arrays):
        if arr.shape != (t.shape[0], n_dof):
            hint = f" Pass {name}.T." if arr.shape == (n_dof, t.shape[0]) else ""
            raise ShapeError(
                f"simulate_recording reference {name} must have shape (n_samples, {n_dof}) to match "
                f"RobotDescription.n_dof={n_dof}; got {arr.shape}.{hint}"
            )
        if not np.all(np.isfinite(arr)):
            raise ParameterError(
                f"simulate_recording reference {name} must be finite; got NaN/inf. Fix the trajectory."
            )
    return arrays


def _reference_span(reference):
    if isinstance(reference, Recording):
        return float(reference.t[0]), reference.duration
    if isinstance(reference, (tuple, list)) and len(reference) >= 2:
        t_ref = np.asarray(reference[0], dtype=float)
        if t_ref.ndim != 1 or t_ref.shape[0] < 2 or np.any(np.diff(t_ref) <= 0):
            raise ParameterError(
                "simulate_recording reference t must be a strictly increasing 1-D array of >= 2 times."
            )
        return float(t_ref[0]), float(t_ref[-1] - t_ref[0])
    return 0.0, None


def _quantise(x, step):
    return x if step is None else np.round(x / step) * step


def _checked_drives_and_extras(robot: RobotDescription, options: SimulationOptions, extras: tuple) -> tuple:
    """The robot's drives, once the extra physics and the payload are checked against its joints."""
    n = robot.n_dof
    drives = _drives(robot)
    for term in extras:
        if not isinstance(term, ExtraPhysics):
            raise ParameterError(f"simulate_recording extras must be ExtraPhysics terms; got {type(term).__name__}.")
        term.validate(n)
    if options.payload is not None:
        options.payload.validate(n)
    return drives


def _controller_and_plant(robot: RobotDescription, standard, options: SimulationOptions, extras: tuple) -> tuple:
    """(robot, parameters) of the controller's model, the truth plus the known payload, and of the plant, which
    adds the hidden extras: ``(ctrl_robot, ctrl_params, plant_robot, plant_params)``."""
    ctrl_robot, ctrl_params = robot, standard
    if options.payload is not None:
        ctrl_robot, ctrl_params = options.payload.modify_model(robot, standard)
    plant_robot, plant_params = ctrl_robot, ctrl_params
    for term in extras:
        plant_robot, plant_params = term.modify_model(plant_robot, plant_params)
    return ctrl_robot, ctrl_params, plant_robot, plant_params


def _sample_times(reference, options: SimulationOptions) -> np.ndarray:
    """Sample times at ``options.rate`` over ``options.duration`` (default: the reference's span) from its start."""
    t0, span = _reference_span(reference)
    duration = options.duration if options.duration is not None else span
    if duration is None:
        raise ParameterError("SimulationOptions.duration is None and the reference is a callable; set duration [s].")
    n_samples = int(np.floor(duration * options.rate + 1e-9)) + 1
    return t0 + np.arange(n_samples) / options.rate


def _feedforward(model, data, q_ref, qd_ref, qdd_ref, lugre, options: SimulationOptions) -> np.ndarray:
    """Feed-forward torque of the reference (n_samples, n_dof): ``options.feedforward`` plus steady friction."""
    if options.feedforward == "model":
        tau_ff = np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q_ref, qd_ref, qdd_ref)])
    elif options.feedforward == "gravity":
        tau_ff = np.array([pin.computeGeneralizedGravity(model, data, a) for a in q_ref])
    else:
        tau_ff = np.zeros_like(q_ref)
    if options.friction and options.friction_feedforward:
        tau_ff = tau_ff + steady_state_friction(qd_ref, lugre)
    return tau_ff


def _sensor_recording(robot_name, t, q, qd, tau_motor, kt, options: SimulationOptions, extras: tuple, rng) -> Recording:
    """What the sensors record: signal-level physics of the extras, then noise and quantisation."""
    q_meas, tau_meas = q, tau_motor
    for term in extras:
        q_meas, tau_meas = term.measure(t, q_meas, tau_meas)
    q_rec = _quantise(q_meas + options.q_noise_std * rng.standard_normal(q.shape), options.encoder_resolution)
    current = tau_rec = None
    if options.record_current:
        current = _quantise(
            tau_meas / kt + options.current_noise_std * rng.standard_normal(q.shape), options.current_resolution
        )
    if options.record_tau:
        tau_rec = tau_meas + options.tau_noise_std * rng.standard_normal(q.shape)
    return Recording(
        t=t,
        q=q_rec,
        tau=tau_rec,
        current=current,
        qd=qd.copy() if options.record_velocity else None,
        name=f"virtual {robot_name}",
    )


def simulate_recording(
    robot: RobotDescription,
    reference,
    options: SimulationOptions | None = None,
    rng: np.random.Generator | None = None,
    extras=(),
) -> tuple[Recording, SimulationTruth]:
    """Simulate the virtual robot tracking a reference and return what its sensors record, with the truth.

    Parameters
    ----------
    robot : RobotDescription
        The true robot: its nominal links, rotor inertia and drives are the simulation truth
        (use ``robot.with_links`` or ``dataclasses.replace(robot, drives=...)`` for another truth).
    reference : callable or tuple or Recording
        ``reference(t) -> (q, qd, qdd)`` evaluated on the array of sample times (each (n_samples, n_dof)),
        or a tuple ``(t, q[, qd[, qdd]])`` of arrays (missing derivatives from a cubic spline), or a Recording.
    options : SimulationOptions, optional
    rng : numpy.random.Generator, optional
        Source of sensor noise; ``np.random.default_rng(0)`` when omitted.
    extras : sequence of ExtraPhysics
        Hidden extra physics (see ``extra_physics``).

    Returns
    -------
    (Recording, SimulationTruth)

    Raises
    ------
    ParameterError
        For a robot without drives or inertia, a bad reference or a bad option.
    ShapeError
        When the reference arrays do not have one column per joint.

    Examples
    --------
    >>> rec, truth = simulate_recording(robot, (t, q), SimulationOptions(), np.random.default_rng(0))  # doctest: +SKIP
    """
    options = SimulationOptions() if options is None else options
    rng = np.random.default_rng(0) if rng is None else rng
    extras = tuple(extras)
    drives = _checked_drives_and_extras(robot, options, extras)
    standard = robot.nominal_dynamic_parameters()
    ctrl_robot, ctrl_params, plant_robot, plant_params = _controller_and_plant(robot, standard, options, extras)
    t = _sample_times(reference, options)
    q_ref, qd_ref, qdd_ref = _sample_reference(reference, t, robot.n_dof)

    lugre = LuGreArrays.from_drives(drives)
    kt = np.array([d.kt for d in drives])
    ctrl_model = build_pinocchio_model(ctrl_robot, ctrl_params)
    ctrl_data = ctrl_model.createData()
    tau_ff = _feedforward(ctrl_model, ctrl_data, q_ref, qd_ref, qdd_ref, lugre, options)
    loop = (ctrl_model, ctrl_data, q_ref, options.rate, options.bandwidth_hz, options.damping_ratio,
            options.integral_gain)  # fmt: skip
    plant = build_pinocchio_model(plant_robot, plant_params)
    reference_start = (q_ref, qd_ref, qdd_ref[0])
    with np.errstate(all="ignore"):  # a diverging run is detected below, not warned about sample by sample
        states = _integrate(plant, lugre, t, reference_start, tau_ff, joint_loop_gains(*loop),
                            options, extras)  # fmt: skip
    if not tracks(states[0], q_ref):
        logger.info("virtual %s: the joint loop diverged with gains from the mass-matrix diagonal; retuned", robot.name)
        gains = joint_loop_gains(*loop, retuned=True)
        states = _integrate(plant, lugre, t, reference_start, tau_ff, gains, options, extras)
    q, qd, qdd, z, tau_motor, tau_f, tau_x = states
    recording = _sensor_recording(robot.name, t, q, qd, tau_motor, kt, options, extras, rng)
    truth = SimulationTruth(
        robot_name=robot.name,
        standard_parameters=standard,
        kt=kt,
        friction=lugre.as_table(),
        gravity=np.asarray(plant_robot.gravity, dtype=float).copy(),
        payload=options.payload,
        extras=extras,
        options=options,
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        z=z,
        tau_motor=tau_motor,
        tau_friction=tau_f,
        tau_extra=tau_x,
    )
    return recording, truth


def _integrate(model, lugre, t, reference, tau_ff, gains, options, extras):
    """The time loop: PID + feed-forward at each sample, ``substeps`` symplectic-Euler or leapfrog steps, exact z
    steps. ``reference`` is ``(q_ref, qd_ref, qdd_ref[0])``."""
    q_ref, qd_ref, qdd_start = reference
    kp, kd, ki = gains
    n_samples, n = q_ref.shape
    data = model.createData()
    aba = pin.aba
    substeps = int(options.substeps)
    h = 1.0 / (options.rate * substeps)
    friction = bool(options.friction)
    torque_terms = [e for e in extras if e.has_torque]
    # this loop runs per sub-step: numpy is slower with a Python scalar operand than with an array of the
    # same length, so every constant below is a length-n array
    fc, dfs = lugre.fc.copy(), lugre.fs - lugre.fc
    inv_vs, inv_s0 = 1.0 / lugre.vs, 1.0 / lugre.sigma0
    s0, s1, fv, dv = lugre.sigma0, lugre.sigma1, lugre.fv, lugre.dv
    h_vec, minus_h = np.full(n, h), np.full(n, -h)
    leapfrog = options.integrator == "leapfrog"
    half_h, minus_half_h = 0.5 * h_vec, 0.5 * minus_h

    q = q_ref[0].copy()
    qd = qd_ref[0].copy()
    # friction quantities at the current velocity: rate = |qd| / g(qd), visc = Fv |qd|^dv sign(qd)
    a, sg = np.abs(qd), np.sign(qd)
    x = qd * inv_vs
    g = (fc + dfs * np.exp(-(x * x))) * inv_s0
    rate = a / g
    visc = fv * a**dv * sg
    z = g * sg if friction else np.zeros(n)
    zero = np.zeros(n)
    tau_x = zero

    out_q, out_qd, out_qdd = (np.empty((n_samples, n)) for _ in range(3))
    out_z, out_tau, out_tf, out_tx = (np.empty((n_samples, n)) for _ in range(4))
    error_integral = np.zeros(n)
    if options.settled_start and extras and np.all(ki > 0):  # the integral term holds what the feed-forward misses
        tau_f = (s0 * z + s1 * (qd - rate * z) + visc) if friction else zero
        tau_x = sum(e.torque(t[0], q, qd, tau_ff[0]) for e in torque_terms) if torque_terms else zero
        needed = pin.rnea(model, data, q, qd, qdd_start) + tau_f + tau_x
        error_integral = (needed - tau_ff[0]) / ki
        tau_x = zero
    dt = 1.0 / options.rate
    for k in range(n_samples):
        error = q_ref[k] - q
        tau_cmd = tau_ff[k] + kp * error + kd * (qd_ref[k] - qd) + ki * error_integral
        error_integral = error_integral + dt * error
        out_q[k], out_qd[k], out_z[k], out_tau[k] = q, qd, z, tau_cmd
        tk = t[k]
        for s in range(substeps):
            if leapfrog:
                # half drift of q and z at the current velocity; the kick below acts at the sub-step centre
                q = q + half_h * qd
                if friction:
                    rest = g * sg
                    z = rest + (z - rest) * np.exp(minus_half_h * rate)
            if friction:
                tau_f = s0 * z + s1 * (qd - rate * z) + visc  # eq. 14 with zdot of eq. 12
                net = tau_cmd - tau_f
            else:
                tau_f, net = zero, tau_cmd
            if torque_terms:
                tau_x = sum(e.torque(tk + (s + 0.5 * leapfrog) * h, q, qd, tau_cmd) for e in torque_terms)
                net = net - tau_x
            qdd = aba(model, data, q, qd, net)
            if s == 0:
                out_qdd[k], out_tf[k], out_tx[k] = qdd, tau_f, tau_x
            qd = qd + h_vec * qdd
            if friction:
                a, sg = np.abs(qd), np.sign(qd)
                x = qd * inv_vs
                g = (fc + dfs * np.exp(-(x * x))) * inv_s0
                rate = a / g
                visc = fv * a**dv * sg
                rest = g * sg
                z = rest + (z - rest) * np.exp((minus_half_h if leapfrog else minus_h) * rate)  # exact z step
            q = q + (half_h if leapfrog else h_vec) * qd
    return out_q, out_qd, out_qdd, out_z, out_tau, out_tf, out_tx
