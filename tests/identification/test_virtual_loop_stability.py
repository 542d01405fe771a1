"""The virtual robot's sampled joint loop stays stable on robots whose axes couple strongly (a tree of arms)."""

from pathlib import Path

import numpy as np
import pinocchio as pin

from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi import load_robot
from psdm_casadi.oracle import PinocchioOracle, build_pinocchio_model

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def zero_centred_sines(n):
    w = 2 * np.pi * 0.3 * (1 + np.arange(n) / n)

    def reference(t):
        phase = np.outer(t, w)
        return 0.5 * np.sin(phase), 0.5 * w * np.cos(phase), -0.5 * w**2 * np.sin(phase)

    return reference


def sampled_loop_damping(robot, q, kd, dt):
    """Spectral radius of dt M(q)^-1 Kd from Pinocchio's mass matrix, independent of the simulator's gains."""
    mass = PinocchioOracle(robot).crba(q)
    return float(np.max(np.abs(np.linalg.eigvals(np.linalg.solve(mass, np.diag(kd)))))) * dt


def test_the_torso_with_two_arms_tracks_instead_of_diverging():
    robot = load_robot(EXAMPLES / "dual_arm_torso.toml")
    omega, dt = 2 * np.pi * 10.0, 1e-3
    model = build_pinocchio_model(robot, robot.nominal_dynamic_parameters())
    mass_diagonal = pin.crba(model, model.createData(), np.zeros(robot.n_dof)).diagonal()
    # gains from the mass-matrix diagonal alone make the held derivative term kick beyond 2 per period: unstable
    assert sampled_loop_damping(robot, np.zeros(robot.n_dof), 2 * mass_diagonal * omega, dt) > 2.0
    reference = zero_centred_sines(robot.n_dof)
    rec, truth = simulate_recording(
        robot, reference, SimulationOptions(duration=2.0, friction=False, record_tau=True, current_noise_std=0.0)
    )
    assert np.all(np.isfinite(rec.q)) and np.all(np.isfinite(rec.tau))
    assert np.abs(truth.q - reference(truth.t)[0]).max() < 0.05


def test_robots_with_a_stable_loop_keep_their_gains(denso):
    # the Denso's loop is far inside the limit: its recordings are those of gains from the mass-matrix diagonal,
    # reproduced here by a plain PD + integral loop on Pinocchio's aba
    n = denso.n_dof
    reference = zero_centred_sines(n)
    options = SimulationOptions(duration=0.2, friction=False, record_tau=True, current_noise_std=0.0, substeps=1)
    rec, _ = simulate_recording(denso, reference, options)
    model = build_pinocchio_model(denso, denso.nominal_dynamic_parameters())
    data = model.createData()
    t = rec.t
    q_ref, qd_ref, qdd_ref = reference(t)
    inertia = pin.crba(model, data, q_ref[0]).diagonal().copy()
    omega = 2 * np.pi * options.bandwidth_hz
    kp, kd, ki = inertia * omega**2, 2 * inertia * omega, options.integral_gain * inertia * omega**3
    q, qd, integral, dt = q_ref[0].copy(), qd_ref[0].copy(), np.zeros(n), 1e-3
    for k in range(t.size):
        error = q_ref[k] - q
        tau = pin.rnea(model, data, q_ref[k], qd_ref[k], qdd_ref[k]) + kp * error + kd * (qd_ref[k] - qd)
        tau = tau + ki * integral
        integral = integral + dt * error
        np.testing.assert_allclose(rec.tau[k], tau, rtol=1e-9, atol=1e-9)
        qd = qd + dt * pin.aba(model, data, q, qd, tau)
        q = q + dt * qd
