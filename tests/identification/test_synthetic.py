"""The virtual robot against independent references: Pinocchio rnea, the LuGre steady state, step halving."""

import json
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from identification.data.io import load_recording
from identification.virtual.effects import (
    GravityTilt,
    JointCoupling,
    Payload,
    SignalDelay,
    Spring,
    TorqueOffset,
    TorqueRipple,
)
from identification.virtual.simulation import SimulationOptions, simulate_recording
from identification.virtual.truth import read_truth, write_recording
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.oracle import PinocchioOracle

CLEAN = dict(encoder_resolution=None, current_resolution=None, current_noise_std=0.0, record_tau=True)
A = np.array([0.3, 0.25, 0.3, 0.5, 0.4, 0.6])
W = 2 * np.pi * np.array([0.5, 0.6, 0.7, 0.8, 0.9, 1.0])


def sines(t):
    t = np.asarray(t)[:, None]
    return A * np.sin(W * t), A * W * np.cos(W * t), -A * W**2 * np.sin(W * t)


@pytest.fixture(scope="module")
def frictionless(denso):
    return simulate_recording(denso, sines, SimulationOptions(duration=1.0, friction=False, **CLEAN))


def test_torque_equals_rnea_of_true_motion(denso, frictionless):
    rec, truth = frictionless
    expected = PinocchioOracle(denso).rnea(truth.q, truth.qd, truth.qdd)
    np.testing.assert_allclose(rec.tau, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(rec.current, rec.tau / truth.kt, rtol=1e-12)


def test_torque_matches_rnea_of_differenced_recording(denso, frictionless):
    rec, _ = frictionless
    dt = 1e-3
    qd = (rec.q[2:] - rec.q[:-2]) / (2 * dt)
    qdd = (rec.q[2:] - 2 * rec.q[1:-1] + rec.q[:-2]) / dt**2
    expected = PinocchioOracle(denso).rnea(rec.q[1:-1], qd, qdd)
    scale = np.abs(rec.tau).max(axis=0)
    assert np.all(np.abs(rec.tau[1:-1] - expected).max(axis=0) < 0.02 * scale)


def test_tracks_the_reference(denso):
    rec, truth = simulate_recording(denso, sines, SimulationOptions(duration=1.0))
    q_ref, _, _ = sines(rec.t)
    assert np.abs(rec.q - q_ref).max() < 5e-3
    assert rec.tau is None and rec.current is not None


def test_lugre_steady_state_at_constant_velocity(denso):
    v = np.array([0.05, -0.02, 0.3, -0.5, 0.1, 1.0])

    def ramp(t):
        t = np.asarray(t)[:, None]
        return v * t, np.tile(v, (t.shape[0], 1)), np.zeros((t.shape[0], 6))

    _, truth = simulate_recording(denso, ramp, SimulationOptions(duration=0.5, **CLEAN))
    d = denso.drives
    fc, fs, vs, fv, dv = (np.array([getattr(x, k) for x in d]) for k in ("fc", "fs", "vs", "fv", "dv"))
    expected = (fc + (fs - fc) * np.exp(-((v / vs) ** 2))) * np.sign(v) + fv * np.abs(v) ** dv * np.sign(v)
    np.testing.assert_allclose(truth.qd[-1], v, rtol=1e-3)
    np.testing.assert_allclose(truth.tau_friction[-1], expected, rtol=2e-3)


def test_step_halving_converges(denso):
    def run(substeps):
        opts = SimulationOptions(duration=0.5, substeps=substeps, **CLEAN)
        return simulate_recording(denso, sines, opts)[1]

    fine = run(16)
    errors = [np.abs(run(s).tau_motor - fine.tau_motor).max() for s in (1, 2, 4)]
    assert errors[1] < 0.7 * errors[0] and errors[2] < 0.7 * errors[1]
    assert errors[2] < 0.3  # N m, against torques of tens of N m


def test_quantisation_levels(denso):
    opts = SimulationOptions(duration=0.2, encoder_resolution=1e-4, current_resolution=0.01)
    rec, _ = simulate_recording(denso, sines, opts, np.random.default_rng(0))
    np.testing.assert_allclose(rec.q / 1e-4, np.round(rec.q / 1e-4), atol=1e-6)
    np.testing.assert_allclose(rec.current / 0.01, np.round(rec.current / 0.01), atol=1e-6)
    assert len(np.unique(rec.current[:, 0])) > 5


def test_same_seed_same_recording(denso):
    opts = SimulationOptions(duration=0.2, current_noise_std=0.05, q_noise_std=1e-4)
    a, _ = simulate_recording(denso, sines, opts, np.random.default_rng(7))
    b, _ = simulate_recording(denso, sines, opts, np.random.default_rng(7))
    c, _ = simulate_recording(denso, sines, opts, np.random.default_rng(8))
    np.testing.assert_array_equal(a.current, b.current)
    np.testing.assert_array_equal(a.q, b.q)
    assert not np.array_equal(a.current, c.current)


def test_spring_shows_up_as_k_q_minus_q0(denso):
    spring = Spring(joint=1, stiffness=80.0, q0=0.1)
    rec, truth = simulate_recording(
        denso, sines, SimulationOptions(duration=0.5, friction=False, **CLEAN), extras=[spring]
    )
    extra = rec.tau - PinocchioOracle(denso).rnea(truth.q, truth.qd, truth.qdd)
    expected = np.zeros_like(extra)
    expected[:, 1] = 80.0 * (truth.q[:, 1] - 0.1)
    np.testing.assert_allclose(extra, expected, atol=1e-8 * np.abs(rec.tau).max())


def _hold_still(t):
    """The reference of a robot holding a pose (the calibration experiments start at rest)."""
    q = np.tile(0.5 * A, (np.asarray(t).size, 1))
    return q, np.zeros_like(q), np.zeros_like(q)


def test_a_settled_controller_holds_a_hidden_torque_from_the_first_sample(denso):
    """A hidden spring the feed-forward does not know: with the controller settled before the recording
    (the default, as a robot holding its pose before a run) the arm does not move, and the recorded torque is
    the gravity torque of the pose plus the spring's, from the first sample (Pinocchio's gravity, the spring
    law); with the integral term starting at zero the arm sags first, as a controller switched on at t = 0."""
    spring = Spring(joint=1, stiffness=80.0, q0=-0.5)  # 50 N m at the pose
    options = SimulationOptions(duration=1.0, friction=False, **CLEAN)
    rec, truth = simulate_recording(denso, _hold_still, options, extras=[spring])
    q_pose = 0.5 * A
    assert np.abs(truth.q - q_pose).max() < 1e-9
    expected = PinocchioOracle(denso).rnea(truth.q, 0 * truth.q, 0 * truth.q)
    expected[:, 1] += 80.0 * (q_pose[1] + 0.5)
    np.testing.assert_allclose(rec.tau, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    cold, _ = simulate_recording(denso, _hold_still, replace(options, settled_start=False), extras=[spring])
    assert np.abs(cold.q[:, 1] - q_pose[1]).max() > 1e-3  # the sag of a cold start (settled: below 1e-9)
    # without a hidden torque there is nothing to hold: both starts give the same recording
    clean = [simulate_recording(denso, sines, replace(options, settled_start=s))[0].tau for s in (True, False)]
    np.testing.assert_allclose(clean[0], clean[1], rtol=1e-9, atol=1e-9 * np.abs(clean[1]).max())


def test_torque_ripple_and_coupling(denso):
    terms = [TorqueRipple(joint=2, amplitude=1.5, harmonic=4.0), JointCoupling(matrix=0.5 * np.eye(6)[::-1])]
    rec, truth = simulate_recording(
        denso, sines, SimulationOptions(duration=0.3, friction=False, **CLEAN), extras=terms
    )
    extra = rec.tau - PinocchioOracle(denso).rnea(truth.q, truth.qd, truth.qdd)
    expected = 0.5 * truth.qd[:, ::-1]
    expected[:, 2] += 1.5 * np.sin(4.0 * truth.q[:, 2])
    np.testing.assert_allclose(extra, expected, atol=1e-7)
    np.testing.assert_allclose(truth.tau_extra, expected, atol=1e-9)


def test_torque_offset_and_delay_are_signal_level(denso):
    offset = np.arange(6.0)
    rec, truth = simulate_recording(
        denso,
        sines,
        SimulationOptions(duration=0.2, **CLEAN),
        extras=[TorqueOffset(offset=offset), SignalDelay(samples=3)],
    )
    np.testing.assert_allclose(rec.tau[3:], truth.tau_motor[:-3] + offset, atol=1e-12)
    np.testing.assert_allclose(rec.q, truth.q)


def test_payload_torque_is_jacobian_transpose_of_weight(denso):
    """Paper eq. 16-17: a point mass at the flange adds J(q)^T f_w to the static torque."""

    def hold(t):
        q = np.tile([0.3, -0.4, 0.5, 0.2, 0.6, 0.1], (len(t), 1))
        return q, np.zeros_like(q), np.zeros_like(q)

    opts = SimulationOptions(duration=0.2, friction=False, payload=Payload(mass=2.5), **CLEAN)
    loaded, truth = simulate_recording(denso, hold, opts)
    oracle = PinocchioOracle(denso)
    residual = loaded.tau[-1] - oracle.rnea(truth.q[-1], truth.qd[-1], truth.qdd[-1])
    model, data = oracle.model, oracle.model.createData()
    q, last = truth.q[-1], oracle.model.njoints - 1
    pin.computeJointJacobians(model, data, q)
    jac = pin.getJointJacobian(model, data, last, pin.LOCAL_WORLD_ALIGNED)
    flange = data.oMi[last].act(np.array([0.0, 0.0, denso.joints[-1].d]))  # DH frame 6 origin
    lever = flange - data.oMi[last].translation
    skew = np.array([[0, -lever[2], lever[1]], [lever[2], 0, -lever[0]], [-lever[1], lever[0], 0]])
    jac_point = jac[:3] - skew @ jac[3:]
    expected = -jac_point.T @ (2.5 * denso.gravity)  # torque holding the weight
    np.testing.assert_allclose(residual, expected, atol=1e-3)
    assert truth.payload.mass == 2.5


def test_gravity_tilt_rotates_gravity(denso):
    _, truth = simulate_recording(
        denso, sines, SimulationOptions(duration=0.05, **CLEAN), extras=[GravityTilt(angle=0.02, axis=(0, 0, 1))]
    )
    assert np.isclose(np.linalg.norm(truth.gravity), np.linalg.norm(denso.gravity))
    assert np.isclose(np.arccos(truth.gravity @ denso.gravity / np.linalg.norm(denso.gravity) ** 2), 0.02)


def test_array_reference_and_shape_errors(denso):
    t = np.linspace(0, 0.3, 31)
    q, _, _ = sines(t)
    rec, truth = simulate_recording(denso, (t, q), SimulationOptions(**CLEAN))
    assert np.isclose(rec.duration, 0.3) and rec.n_samples == 301
    with pytest.raises(ShapeError, match=r"reference q must have shape \(n_samples, 6\).*got \(301, 4\)"):
        simulate_recording(denso, (t, q[:, :4]), SimulationOptions())
    with pytest.raises(ParameterError, match="duration"):
        simulate_recording(denso, sines, SimulationOptions())
    with pytest.raises(ParameterError, match="reference"):
        simulate_recording(denso, 3.0, SimulationOptions(duration=1.0))


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(rate=0.0), "rate"),
        (dict(substeps=0), "substeps"),
        (dict(duration=-1.0), "duration"),
        (dict(integrator="rk4"), "integrator"),
        (dict(feedforward="pid"), "feedforward"),
        (dict(encoder_resolution=0.0), "encoder_resolution"),
        (dict(current_noise_std=-1.0), "current_noise_std"),
        (dict(record_current=False), "record_current"),
        (dict(payload=2.0), "payload"),
        (dict(bandwidth_hz=-1.0), "bandwidth_hz"),
    ],
)
def test_bad_options(kwargs, field):
    with pytest.raises(ParameterError, match=f"SimulationOptions.{field}"):
        SimulationOptions(**kwargs)


@pytest.mark.parametrize(
    "term, field",
    [
        (Spring(joint=6, stiffness=1.0), "Spring.joint"),
        (TorqueOffset(offset=[1.0, 2.0]), "TorqueOffset.offset"),
        (Payload(mass=-1.0), "Payload.mass"),
        (SignalDelay(samples=-1), "SignalDelay.samples"),
        (JointCoupling(matrix=np.eye(2)), "JointCoupling.matrix"),
        (GravityTilt(angle=0.1, axis=(0, 0, 0)), "GravityTilt.axis"),
    ],
)
def test_bad_extras(denso, term, field):
    with pytest.raises(ParameterError, match=field):
        simulate_recording(denso, sines, SimulationOptions(duration=0.01), extras=[term])


def test_robot_without_drives(denso):
    with pytest.raises(ParameterError, match="RobotDescription.drives"):
        simulate_recording(replace(denso, drives=None), sines, SimulationOptions(duration=0.01))


def test_write_recording_with_truth(denso, tmp_path):
    rec, truth = simulate_recording(denso, sines, SimulationOptions(duration=0.1), extras=[Spring(0, 5.0)])
    paths = write_recording(rec, truth, tmp_path / "out", name="run")
    back = load_recording(paths["recording"], n_dof=6)
    np.testing.assert_allclose(back.current, rec.current)
    data = read_truth(paths["truth"])
    np.testing.assert_allclose(data["kt"], [d.kt for d in denso.drives])
    assert data["extras"][0] == {"term": "Spring", "joint": 0, "stiffness": 5.0, "q0": 0.0}
    assert json.loads(paths["truth"].read_text())["friction_fields"][-1] == "sigma1"
    states = np.load(paths["states"])
    np.testing.assert_allclose(states["tau_motor"], truth.tau_motor)
    with pytest.raises(FileExistsError, match="overwrite"):
        write_recording(rec, truth, tmp_path / "out", name="run")


class _Design:
    """A minimal CalibrationDesign: short references of plain arrays, recording how it was called."""

    def __init__(self, n_dof):
        self.t = np.linspace(0.0, 0.2, 101)
        self.q = np.zeros((self.t.size, n_dof))
        self.calls = []

    def _ref(self, joint=None, scale=0.01):
        q = self.q.copy()
        if joint is not None:
            q[:, joint] = scale * np.sin(2 * np.pi * 5 * self.t)
        return self.t, q

    def motor_reference(self, robot, joint, load_torque, rng):
        self.calls.append(("motor", joint, load_torque(self.q[:2]).shape))
        return self._ref(joint)

    def gravity_reference(self, robot, rng):
        self.calls.append(("gravity",))
        return self._ref()

    def friction_reference(self, robot, joint):
        self.calls.append(("friction", joint))
        return self._ref(joint, 1e-4)

    def friction_validation_reference(self, robot, joint):
        return None if joint == 1 else self._ref(joint, 2e-4)

    def excitation_references(self, robot, rng):
        return (self._ref(), self._ref(0))


def test_simulate_calibration_runs_the_designs_references(denso, caplog):
    """The virtual robot runs what the plan hands it, in order, friction experiments without friction feed-forward."""
    import logging

    from identification.virtual.calibration import (
        VirtualCalibrationOptions,
        friction_simulation_options,
        simulate_calibration,
    )

    design = _Design(denso.n_dof)
    with caplog.at_level(logging.INFO, logger="identification.virtual.calibration"):
        data = simulate_calibration(denso, design, VirtualCalibrationOptions(), np.random.default_rng(0), joints=[0, 1])
    assert design.calls == [("motor", 0, (2, 6)), ("motor", 1, (2, 6)), ("gravity",), ("friction", 0), ("friction", 1)]
    assert [j for j, *_ in data.motor] == [0, 1] and data.motor[1][1].name == "motor_j2_nominal"
    assert [j for j, _ in data.friction_validation] == [0]
    assert [r.name for r in data.excitation] == ["excitation_1", "excitation_2"]
    assert data.friction[0][1].n_samples == 201 and "simulate: gravity" in caplog.text
    still = friction_simulation_options(SimulationOptions(substeps=2))
    assert not still.friction_feedforward and still.substeps == 4 and still.integrator == "leapfrog"
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="identification.virtual.calibration"):
        simulate_calibration(denso, _Design(6), VirtualCalibrationOptions(quiet=True), joints=[0])
    assert caplog.text == ""
    with pytest.raises(ParameterError, match="payload"):
        VirtualCalibrationOptions(payload=2.0)


def test_default_encoder_resolves_presliding():
    """A 20-bit motor encoder behind a 1:100 gear: far below the friction design's 5 urad pre-sliding amplitudes."""
    from trajopt.friction_design import FrictionDesign

    assert SimulationOptions().encoder_resolution == pytest.approx(2 * np.pi / 2**20 / 100)
    assert SimulationOptions().encoder_resolution < 0.02 * FrictionDesign().presliding_amplitudes[0]


def test_exact_z_step_matches_stiff_ode_solver(denso):
    from scipy.integrate import solve_ivp

    from identification.virtual.lugre_exact import LuGreArrays, friction_torque, z_rate, z_step

    p = LuGreArrays.from_drives(denso.drives)
    qd = np.array([0.01, -0.2, 0.5, -1.0, 0.05, 2.0])
    z0 = np.zeros(6)
    sol = solve_ivp(lambda t, z: z_rate(z, qd, p), (0, 1e-3), z0, method="Radau", rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(z_step(z0, qd, 1e-3, p), sol.y[:, -1], rtol=1e-6, atol=1e-12)
    # at rest state the torque is the steady-state friction
    z_rest = z_step(z0, qd, 10.0, p)
    np.testing.assert_allclose(
        friction_torque(z_rest, qd, p),
        (p.fc + (p.fs - p.fc) * np.exp(-((qd / p.vs) ** 2)) + p.fv * np.abs(qd) ** p.dv) * np.sign(qd),
    )


def test_leapfrog_held_command_obeys_continuous_time_relation(denso):
    """Joint 6 alone, no friction: M66 (q[k+1] - 2 q[k] + q[k-1]) / T^2 = (tau[k-1] + tau[k]) / 2 with leapfrog.

    Symplectic Euler weights the held commands (S - 1)/2S and (S + 1)/2S instead (half a sub-step late),
    which biased the sigma1 fits of heavy joints.
    """
    w = 2 * np.pi * 4.0

    def wrist(t):
        t = np.asarray(t)[:, None]
        unit = np.eye(6)[5]
        return 0.3 * np.sin(w * t) * unit, 0.3 * w * np.cos(w * t) * unit, -0.3 * w**2 * np.sin(w * t) * unit

    m66 = pin.crba(*_model_and_data(denso), np.zeros(6))[5, 5]
    errors = {}
    for integrator in ("leapfrog", "symplectic-euler"):
        opts = SimulationOptions(duration=0.5, friction=False, substeps=4, integrator=integrator, **CLEAN)
        rec, _ = simulate_recording(denso, wrist, opts)
        lhs = m66 * (rec.q[2:, 5] - 2 * rec.q[1:-1, 5] + rec.q[:-2, 5]) / 1e-6
        rhs = 0.5 * (rec.tau[:-2, 5] + rec.tau[1:-1, 5])
        errors[integrator] = np.abs(lhs - rhs).max() / np.abs(rhs).max()
    assert errors["leapfrog"] < 1e-6
    assert errors["symplectic-euler"] > 1e-3


def _model_and_data(robot):
    from psdm_casadi.oracle import build_pinocchio_model

    model = build_pinocchio_model(robot, robot.nominal_dynamic_parameters())
    return model, model.createData()
