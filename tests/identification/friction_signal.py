"""Friction-experiment signals, synthetic LuGre data and exact recordings for the friction tests (known truth)."""

import numpy as np

from identification.data.recording import Recording
from identification.friction.models import LuGreParameters
from identification.friction.simulation import simulate_lugre
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, load_robot
from trajopt.experiments import sine_experiment
from trajopt.friction_design import tuned_friction_signal

DENSO = BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"


def denso_truth(joint):
    """Paper Table 2 LuGre parameters of Denso joint ``joint`` (0-based) and its speed limit."""
    robot = load_robot(DENSO)
    return LuGreParameters.from_drive(robot.drives[joint]), float(robot.qd_max[joint])


def sine_series(parameters, qd_max, rate=1000.0, frequency_scale=1.0, pause=0.2):
    """``t, qd`` of the tuned friction experiment (pre-sliding, Stribeck and sliding segments)."""
    t, _, qd = tuned_friction_signal(parameters, qd_max, rate=rate, frequency_scale=frequency_scale, pause=pause)
    return t, qd


def synthetic_record(joint, rng=None, noise=0.0, frequency_scale=2.0, substeps=32):
    """``(truth, t, qd, tau)`` with tau from a fine-step LuGre simulation plus ``noise * fc`` white noise."""
    truth, qd_max = denso_truth(joint)
    t, qd = sine_series(truth, qd_max, frequency_scale=frequency_scale)
    tau, _ = simulate_lugre(truth, t, qd, substeps=substeps)
    if noise:
        tau = tau + noise * truth.fc * rng.standard_normal(t.size)
    return truth, t, qd, tau


def ringing_joint_record(
    parameters,
    inertia,
    rng=None,
    current_noise=0.0,
    rate=1000.0,
    substeps=16,
    amplitudes=(2e-3, 5e-3),
    hz=10.0,
    periods=6,
    sliding=(0.3, 1.5),
):
    """A single joint (``inertia`` [kg m^2], LuGre ``parameters``) under a held PD command: ``t, q, tau``.

    An independent fine-step plant (leapfrog, exact bristle steps, ``substeps`` per sample): the
    PD command (10 Hz, critically damped) is computed at each sample and held over the sample
    period, as a robot reporting its current set-points records it. The reference is
    ``A (1 - cos 2 pi f t)`` break-away segments (the joint sticks and rings on the bristles at
    every reversal) then two slow ``sliding`` strokes (peak speeds [rad/s]) for eq. 20.
    """
    pieces, start = [], 0.0
    for a in amplitudes:
        tb = np.arange(0.0, periods / hz, 1.0 / rate)
        pieces.append((start + tb, a * (1.0 - np.cos(2.0 * np.pi * hz * tb))))
        start += periods / hz
    for v in sliding:
        w = 2.0 * np.pi * 0.5
        tb = np.arange(0.0, 2.0, 1.0 / rate)
        pieces.append((start + tb, (v / w) * (1.0 - np.cos(w * tb))))
        start += 2.0
    t = np.concatenate([p[0] for p in pieces])
    ref = np.concatenate([p[1] for p in pieces])
    p = parameters
    kp, kd = inertia * (2 * np.pi * 10.0) ** 2, 2.0 * inertia * 2 * np.pi * 10.0
    h = 1.0 / (rate * substeps)

    def g(v):
        return p.fc + (p.fs - p.fc) * np.exp(-((v / p.vs) ** 2))

    def z_step(s, v, dt):  # s = sigma0 z, exact for constant v
        rest = g(v) * np.sign(v)
        return rest + (s - rest) * np.exp(-p.sigma0 * abs(v) * dt / g(v))

    q = qd = s = 0.0
    q_out, u_out = np.empty(t.size), np.empty(t.size)
    ref_d = np.gradient(ref, t)
    for k in range(t.size):
        u = kp * (ref[k] - q) + kd * (ref_d[k] - qd)
        q_out[k], u_out[k] = q, u
        for _ in range(substeps):
            q += 0.5 * h * qd
            s = z_step(s, qd, 0.5 * h)
            friction = s + p.sigma1 * (qd - abs(qd) * s / g(qd)) + p.fv * abs(qd) ** p.dv * np.sign(qd)
            qd += h * (u - friction) / inertia
            s = z_step(s, qd, 0.5 * h)
            q += 0.5 * h * qd
    if current_noise:
        u_out = u_out + current_noise * rng.standard_normal(t.size)
    return t, q_out, u_out


def measured_friction(t, q, tau, inertia):
    """Eq. 19 as the friction step forms it: held commands averaged, minus ``inertia`` times the central qdd."""
    dt = t[1] - t[0]
    y = np.empty_like(tau)
    y[1:] = 0.5 * (tau[1:] + tau[:-1])
    y[0] = tau[0]
    qdd = np.empty_like(q)
    qdd[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt**2
    qdd[0], qdd[-1] = qdd[1], qdd[-2]
    qd = np.gradient(q, t)
    return qd, y - inertia * qdd


def exact_recording(robot, seed, friction, *, duration, rate, noise, name, fraction=None):
    """A sine experiment of ``robot`` sampled exactly at ``rate`` [Hz]: its torque Pinocchio's ``rnea`` plus
    ``friction(qd)`` (the truth, written by the test) plus white noise of ``noise`` [N m]; ``fraction`` of the limits
    (the experiment's default when None)."""
    rng = np.random.default_rng(seed)
    limits = {} if fraction is None else {"fraction": fraction}
    experiment = sine_experiment(robot, duration=duration, rng=rng, **limits)
    t = np.arange(int(experiment.duration * rate)) / rate
    q, qd, qdd = experiment.sample(t)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + friction(qd) + rng.normal(scale=noise, size=q.shape)
    return Recording(t=t, q=q, tau=tau, name=name)
