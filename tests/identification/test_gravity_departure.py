"""A fitted gravity torque that leaves the robot file's on one joint alone is named; a tool or a file's errors are not.

Reference: Pinocchio's gravity torque of the virtual Denso's robot file and of that file with its links changed (the
fitted rigid body a counterbalance, a tool or CAD errors leave), on random poses inside the joint limits. The
departure the rule reports is the one Pinocchio gives for a change of link 2's first moment alone (a torque of joint
2's angle, which a balancer's first harmonic is).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.gravity_departure import FILE_GRAVITY_ERROR, gravity_departures
from identification.calibration.gravity_load import joints_carrying_gravity
from psdm_casadi.oracle import PinocchioOracle


def _changed(robot, changes):
    """``robot`` with ``{link: (mass factor, centre-of-mass shift [m])}`` applied to its links."""
    links = list(robot.links)
    for i, (factor, shift) in changes.items():
        link = links[i]
        links[i] = dataclasses.replace(link, mass=link.mass * factor, com=tuple(np.add(link.com, shift)))
    return robot.with_links(tuple(links), rotor_inertia=robot.rotor_inertia)


def _case(robot, model, changed, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max, size=(400, robot.n_dof))
    fit = SimpleNamespace(theta=model.base_parameters(changed.nominal_dynamic_parameters()))
    truth = PinocchioOracle(changed).gravity(q) - PinocchioOracle(robot).gravity(q)
    return gravity_departures(robot, model, [SimpleNamespace(q=np.repeat(q, 5, axis=0))], fit), truth


@pytest.mark.slow
def test_the_heavy_arms_counterbalance_the_links_took_is_named_with_its_share(benchmark_modules):
    """The heavy virtual arm at seed 1 (``benchmarks/heavy_arm.py``): no offset chosen, the balancer on joint 2 and a
    100-200 kg tool absorbed by the links inside their envelopes. Joint 2 is named, opposing its gravity torque by
    about the share the simulated balancer takes of the robot file's gravity torque on the recorded poses
    (``virtual.counterbalance.balance``, Pinocchio), the CAD-off truth's links apart."""
    from diagnosis import _scenario
    from heavy_arm import EFFECTS, heavy_industrial_arm

    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
    from identification.virtual.counterbalance import balance
    from psdm_casadi import derive_psdm

    robot = heavy_industrial_arm()
    model = derive_psdm(robot)
    truth, train, _ = _scenario("heavy", robot, EFFECTS, np.random.default_rng(1), 1)
    fit = identify_trajectories(robot, model, [train], TrajectoryOptions())
    found = gravity_departures(robot, model, [train], fit)
    assert list(found) == [1]
    cam = next(effect for _, _, effect, p in truth if "share" in p)
    share = balance(robot, cam, train.q[::20]).share
    assert found[1].share == pytest.approx(share, abs=0.15) and found[1].share >= FILE_GRAVITY_ERROR
    assert found[1].local > 0.9
    assert "joint 2" in found[1].sentence() and "counterbalance" in found[1].sentence()
    assert "inertia_departures" not in dict(fit.envelope_bounds)  # the data's own least squares depart there too


def test_only_the_joints_gravity_gives_a_torque_can_depart():
    """The joints carrying gravity (``gravity_load.joints_carrying_gravity``) are those Pinocchio's gravity torque of
    the robot file with a tool at the flange moves on random poses: the SCARA's vertical axes (joints 1, 2, 4) carry
    none, so no departure is read there; the virtual Denso's file puts gravity along x0, across joint 1's axis, and its
    flange link is massless, yet a tool loads joint 6 (the file alone gives it nil: not the reading)."""
    from psdm_casadi.robot import load_robot
    from tests.catalogue.model_files import SCARA_FILE
    from tests.conftest import DENSO_FILE

    for path, carrying in ((SCARA_FILE, [False, False, True, False]), (DENSO_FILE, [True] * 6)):
        robot = load_robot(path)
        q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, size=(200, robot.n_dof))
        tool = robot.nominal_dynamic_parameters().copy()
        tool[-1, :4] += (0.5, 0.02, 0.01, 0.03)  # 0.5 kg, its centre of mass a few cm off the flange's axes
        reference = np.abs(PinocchioOracle(robot, tool).gravity(q)).max(axis=0)
        found = joints_carrying_gravity(robot, q)
        assert found.tolist() == (reference > 1e-9 * reference.max()).tolist() == carrying, path
    file_only = np.abs(PinocchioOracle(robot).gravity(q)).max(axis=0)
    assert file_only[5] == 0.0  # the Denso file's own weight gives joint 6 nothing


@pytest.mark.parametrize(
    "changes",
    [
        {4: (4.0, (0.0, 0.0, 0.1))},  # a heavy tool on the last link with mass: the flange body's share is taken out
        {i: (1.2, (0.0, 0.0, 0.0)) for i in range(1, 6)},  # CAD masses 20 % heavy: several joints, a fifth
        {i: (0.8, (0.0, 0.0, 0.0)) for i in range(1, 6)},  # 20 % light: opposing gravity, on several joints
        {1: (0.75, (0.02, 0.0, 0.0))},  # link 2 a quarter lighter, its centre of mass 2 cm off
    ],
)
def test_a_tool_or_the_files_errors_are_not_named(denso, denso_model, changes):
    found, truth = _case(denso, denso_model, _changed(denso, changes))
    assert np.sqrt(np.mean(truth**2)) > 0.5  # the gravity torque did move [N m]
    assert found == {}


def _balancer_fit(robot, model, share, swing=0.5, seed=0, tool_mass=2.0):
    """(fit, poses, balancer): the static torques of the virtual Denso with a gas-spring balancer on joint 2 taking
    ``share`` of its gravity and a ``tool_mass`` [kg] tool, on poses within ``swing`` [rad] of the arm's centre,
    fitted as the consistent fit can hold them without a spring: the tool by the last link with mass, the balancer by
    links 2 and 3's masses and first moments (every joint's torque, least squares) and joint 2's torque offset."""
    from identification.virtual.counterbalance import gas_spring_counterbalance

    gas = gas_spring_counterbalance(robot, 1, np.zeros(robot.n_dof), share, a=0.05, b=0.15, stiffening=0.5)
    rng = np.random.default_rng(seed)
    q = np.clip(rng.uniform(-swing, swing, (400, robot.n_dof)), robot.q_min, robot.q_max)
    zero = np.zeros_like(q)
    load = np.zeros_like(q)
    load[:, 1] = [gas.torque(0.0, row, zero[0], None)[1] for row in q]
    columns = [11 * link + k for link in (1, 2) for k in range(4)]  # links 2 and 3: mass and first moment
    regressor = np.stack([model.inverse_dynamics(q, zero, zero, model.parameter_map[:, c]) for c in columns], -1)
    constant = np.zeros((*q.shape, 1))
    constant[:, 1] = 1.0
    a = np.concatenate([regressor, constant], axis=-1).reshape(-1, len(columns) + 1)
    coefficients, *_ = np.linalg.lstsq(a, load.ravel(), rcond=None)
    bodies = np.abs(model.parameter_map).reshape(model.n_base, robot.n_dof, 11)[:, :, :4].max(axis=(0, 2))
    last = int(np.flatnonzero(bodies > 0)[-1])
    tool = np.zeros(11)
    tool[:4] = (tool_mass, 0.0, 0.0, tool_mass * 0.1)  # 10 cm out on the last link's z axis
    theta = (model.base_parameters(robot.nominal_dynamic_parameters()) + model.parameter_map[:, columns] @
             coefficients[:-1] + model.parameter_map[:, 11 * last : 11 * last + 11] @ tool)  # fmt: skip
    fit = SimpleNamespace(theta=theta, drive=np.array([1.0, coefficients[-1]]), drive_names=("fc2", "offset2"))
    return fit, q, gas


@pytest.mark.parametrize("share", [0.5, 0.8])
def test_a_balancer_the_offset_and_links_2_and_3_share_is_named(denso, denso_model, share):
    """Over a half-radian swing near horizontal a gas spring's torque is mostly a constant: joint 2's offset takes it,
    links 2 and 3 its swing (the unseen HX-210 traced by its controller, seeds 1-2: links 2-3 off by up to 1.8 times,
    nothing named). Their sum is named on joint 2 with the share of the file's gravity torque the balancer takes
    there (``virtual.counterbalance.balance``, Pinocchio); the links' part alone does not reach the file's error."""
    from identification.calibration.gravity_departure import theta_departures
    from identification.virtual.counterbalance import balance

    fit, q, gas = _balancer_fit(denso, denso_model, share)
    recordings = [SimpleNamespace(q=np.repeat(q, 5, axis=0))]
    found = gravity_departures(denso, denso_model, recordings, fit)
    assert list(found) == [1]
    assert found[1].share == pytest.approx(balance(denso, gas, q).share, abs=0.05)
    assert found[1].offset == pytest.approx(fit.drive[1]) and found[1].local > 0.95
    assert "torque offset" in found[1].sentence() and "joint 2" in found[1].evidence
    assert theta_departures(denso, denso_model, recordings, fit.theta) == {}  # the links' swing alone: no


def _flange_mass(robot, model, q, theta, joint):
    """[kg] the mass of the body at the last link with mass whose gravity torque best fits the fitted minus the robot
    file's gravity torque of every joint but ``joint`` (least squares, the model's own gravity columns)."""
    zero = np.zeros_like(q)
    difference = model.inverse_dynamics(q, zero, zero, theta) - model.inverse_dynamics(
        q, zero, zero, model.base_parameters(robot.nominal_dynamic_parameters())
    )
    last = max(i for i, link in enumerate(robot.links) if link.mass > 0)
    columns = np.stack([model.inverse_dynamics(q, zero, zero, model.parameter_map[:, 11 * last + k]) for k in range(4)],
                       axis=-1)  # fmt: skip
    others = [k for k in range(robot.n_dof) if k != joint]
    body, *_ = np.linalg.lstsq(columns[:, others].reshape(-1, 4), difference[:, others].ravel(), rcond=None)
    return float(body[0])


@pytest.mark.parametrize("share", [0.5, 0.8])
def test_a_balancer_on_an_arm_without_a_tool_is_named_where_the_flange_body_comes_out_a_trace_negative(
    denso, denso_model, share
):
    """The balancer of the test above on an arm with no tool: the other joints' departures (link 3's first moment,
    which joint 3 also feels) hold no tool, and the flange body fitted to them comes out a trace of mass below zero.
    Joint 2 is named all the same, with the balancer's share of its gravity torque (``virtual.counterbalance``,
    Pinocchio); before, a negative flange mass skipped the joint unread."""
    from identification.virtual.counterbalance import balance

    fit, q, gas = _balancer_fit(denso, denso_model, share, tool_mass=0.0)
    assert -0.05 < _flange_mass(denso, denso_model, q, fit.theta, 1) < 0.0  # the case: a trace of negative mass
    found = gravity_departures(denso, denso_model, [SimpleNamespace(q=np.repeat(q, 5, axis=0))], fit)
    assert list(found) == [1]
    assert found[1].share == pytest.approx(balance(denso, gas, q).share, abs=0.05) and found[1].local > 0.95


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_clean_arms_least_squares_fit_is_not_named(denso, denso_model, seed):
    """A clean arm (no balancer, no tool): the base parameters fitted by least squares to its static torques with
    noise (Pinocchio's gravity torque, 0.3 N m), on the narrow swing near the centre. The flange bodies fitted to the
    other joints' departures come out a trace either side of zero (negative on some joint at each of seeds 0, 1, 3);
    nothing is named either way."""
    rng = np.random.default_rng(seed)
    q = np.clip(rng.uniform(-0.5, 0.5, (400, denso.n_dof)), denso.q_min, denso.q_max)
    zero = np.zeros_like(q)
    tau = PinocchioOracle(denso).gravity(q) + rng.normal(0.0, 0.3, q.shape)
    regressor = np.stack([denso_model.inverse_dynamics(q, zero, zero, e) for e in np.eye(denso_model.n_base)], -1)
    regressor = regressor.reshape(-1, denso_model.n_base)
    file_theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    step, *_ = np.linalg.lstsq(regressor, tau.ravel() - regressor @ file_theta, rcond=1e-8)
    theta = file_theta + step
    masses = [_flange_mass(denso, denso_model, q, theta, j) for j in range(denso.n_dof)]
    assert max(abs(m) for m in masses) < 0.05  # a trace of mass: the fit is clean
    found = gravity_departures(denso, denso_model, [SimpleNamespace(q=np.repeat(q, 5, axis=0))],
                               SimpleNamespace(theta=theta))  # fmt: skip
    assert found == {}


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("changes", [{}, {4: (4.0, (0.0, 0.0, 0.1))}, {i: (1.2, (0.0, 0.0, 0.0)) for i in range(1, 6)}])
def test_a_sensors_zero_error_is_not_named(denso, denso_model, changes, sign):
    """A torque sensor's or current measurement's zero error (``offset_reading.SENSOR_SHARE`` of the joint's peak
    gravity torque, either sign) on joint 2, beside a tool or the file's errors, on the same narrow swing where
    gravity is nearly constant: not named."""
    from identification.calibration.gravity_departure import theta_departures
    from identification.calibration.offset_reading import SENSOR_SHARE

    q = np.clip(np.random.default_rng(0).uniform(-0.5, 0.5, (400, denso.n_dof)), denso.q_min, denso.q_max)
    offsets = np.zeros(denso.n_dof)
    offsets[1] = sign * SENSOR_SHARE * np.abs(PinocchioOracle(denso).gravity(q)[:, 1]).max()
    theta = denso_model.base_parameters(_changed(denso, changes).nominal_dynamic_parameters())
    assert theta_departures(denso, denso_model, [SimpleNamespace(q=np.repeat(q, 5, axis=0))], theta, offsets) == {}
