"""Calibration experiments (paper 3.1-3.3): shape of the motion, limits, reversibility, plan, errors."""

import inspect
import warnings

import numpy as np
import pytest

from psdm_casadi.errors import ExcitationWarning, ParameterError, ShapeError
from trajopt.calibration_plan import CalibrationPlan
from trajopt.constraints import JointLimits
from trajopt.experiments import (
    ExperimentTrajectory,
    choose_motor_pose,
    friction_experiment,
    gravity_experiment,
    home_pose,
    motor_experiment,
    oscillation_experiment,
    sine_experiment,
)
from trajopt.friction_design import FrictionDesign, tuned_friction_signal


def _dense(exp, rate=500.0):
    t = exp.time_grid(rate)
    return (t, *exp.sample(t))


def _fd_consistent(t, q, qd):
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(q, h, axis=0)[2:-2], qd[2:-2], atol=5e-3)


def test_motor_sweeps_one_joint_at_constant_speed(planar_robot):
    exp = motor_experiment(planar_robot, 1, speed=0.3, range_fraction=0.8)
    t, q, qd, qdd = _dense(exp)
    assert np.ptp(q[:, 0]) == 0 and np.all(qd[:, 0] == 0)
    # from the low end of the range share; the cosine turn adds a little travel at the high end
    assert q[:, 1].min() == pytest.approx(-0.8 * 2.5, abs=1e-9) and 2.0 < q[:, 1].max() < 2.0 + 0.1 * 0.3
    assert np.isclose(qd[:, 1].max(), 0.3, rtol=1e-3) and np.isclose(qd[:, 1].min(), -0.3, rtol=1e-3)
    # forward and back: most of the sweep at the constant speed in both directions
    assert np.mean(np.isclose(qd[:, 1], 0.3)) > 0.3 and np.mean(np.isclose(qd[:, 1], -0.3)) > 0.3
    _fd_consistent(t, q, qd)
    assert exp.worst_margin >= 0 and exp.joints == (1,) and exp.name == "motor"
    assert q[0, 1] == pytest.approx(q[-1, 1], abs=1e-6)  # ends where it started


def test_sample_is_the_spline_of_the_knots(denso):
    """What a user records (the CSV) is the spline the virtual robot interpolates: it passes through the knots."""
    exp = motor_experiment(denso, 2)
    t, q = exp.reference()
    np.testing.assert_array_equal(exp.sample(t)[0], q)
    assert exp.duration == t[-1] and exp.n_dof == denso.n_dof
    with pytest.raises(ValueError):
        q[0, 0] = 1.0  # the knots are read-only


def test_choose_motor_pose_loads_the_swept_joint(denso):
    """The chosen pose maximises the score of the load torque; the home pose is the first candidate."""
    arm = np.eye(denso.n_dof)[2]

    def load_torque(q):  # a load that only joint 3 feels, largest at q3 = 1
        return np.outer(1.0 - np.abs(q[:, 2] - 1.0), arm)

    pose = choose_motor_pose(denso, 2, load_torque, np.random.default_rng(0), n_candidates=5)
    assert pose.shape == (denso.n_dof,)
    same = choose_motor_pose(denso, 2, load_torque, np.random.default_rng(0), n_candidates=5)
    np.testing.assert_array_equal(pose, same)
    np.testing.assert_array_equal(
        choose_motor_pose(denso, 2, load_torque, np.random.default_rng(0), n_candidates=1), home_pose(denso)
    )


def test_gravity_path_is_run_back_exactly(denso):
    exp = gravity_experiment(denso, duration=20.0)
    t, q = exp.reference()
    np.testing.assert_allclose(q, q[::-1], atol=1e-2)  # back along the same path
    assert np.all(np.ptp(q, axis=0) > 0) and exp.joints == tuple(range(denso.n_dof))
    again = gravity_experiment(denso, duration=20.0, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(again.q, q)
    only = gravity_experiment(denso, duration=20.0, joints=[0, 2])
    assert np.ptp(only.q[:, 1]) == 0 and np.ptp(only.q[:, 0]) > 0 and only.joints == (0, 2)


def test_experiments_respect_limits(denso):
    with warnings.catch_warnings():  # the spline the robot tracks, checked on a fine grid, keeps every limit too
        warnings.simplefilter("error", ExcitationWarning)
        friction = [friction_experiment(denso, j).reference() for j in range(denso.n_dof)]
        for j in range(denso.n_dof):
            friction_experiment(denso, j, FrictionDesign().validation())
    others = (
        motor_experiment(denso, 1),
        oscillation_experiment(denso, 5, amplitudes=(1e-3, 0.05)),
        sine_experiment(denso, duration=10.0),
    )
    for t, q in (*(e.reference() for e in others), *friction):
        assert np.all(np.diff(t) > 0)
        assert np.all(q >= denso.q_min - 1e-9) and np.all(q <= denso.q_max + 1e-9)
        qd = np.gradient(q, t, axis=0)
        assert np.all(np.abs(qd).max(axis=0) <= denso.qd_max)
    for j, (t, q) in enumerate(friction):
        qdd = np.gradient(np.gradient(q[:, j], t), t)
        assert np.abs(qdd).max() <= denso.qdd_max[j]


def test_oscillation_experiment_runs_large_amplitudes_slower_instead_of_leaving_the_acceleration_limit(denso):
    """The quick plan's amplitudes (the demo's, up to 0.3 rad) on every joint: the speed and acceleration of the
    sampled path, by finite differences on a fine grid, stay within the robot's limits, and no limit warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)
        for j in range(denso.n_dof):
            exp = oscillation_experiment(denso, j, amplitudes=(1e-3, 0.03, 0.3))
            t = exp.time_grid(2000.0)
            q = exp.sample(t)[0][:, j]
            qd = np.gradient(q, t)
            qdd = np.gradient(qd, t)
            assert np.abs(qd).max() <= denso.qd_max[j] * 1.001
            assert np.abs(qdd).max() <= denso.qdd_max[j] * 1.001
            # the largest block uses most of the acceleration limit: it is slowed down, not stopped
            assert np.abs(qdd).max() >= 0.5 * denso.qdd_max[j]


def test_out_and_back_experiments_keep_every_limit_through_the_turn(denso, planar_robot):
    # round durations put a knot exactly at the end of the turn, where a wrong speed sign would spike qdd
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)
        experiments = [
            gravity_experiment(denso),
            gravity_experiment(denso, duration=20.0),
            *(motor_experiment(denso, j) for j in range(denso.n_dof)),
            *(motor_experiment(planar_robot, j) for j in range(planar_robot.n_dof)),
        ]
    for exp in experiments:
        assert exp.worst_margin >= 0, exp.name


def test_leaving_a_limit_warns(planar_robot):
    tight = JointLimits(q_min=[-2.0, -2.5], q_max=[2.0, 2.5], qd_max=[2.0, 0.1], qdd_max=[6.0, 8.0])
    with pytest.warns(ExcitationWarning, match="qd on joint 2"):
        exp = motor_experiment(planar_robot, 1, speed=0.3, limits=tight)
    assert exp.worst_margin < 0


def test_friction_design_content(denso):
    """Segments rest to rest; pre-sliding amplitudes and Stribeck speeds as designed; validation at 1.3x."""
    design = FrictionDesign()
    assert design.presliding_amplitudes[0] == pytest.approx(5e-6)
    assert design.presliding_amplitudes[-1] == pytest.approx(5e-3)
    exp = friction_experiment(denso, 0, design)
    t, q = exp.reference()
    pose = home_pose(denso)
    room = 0.95 * max(denso.q_max[0] - pose[0], pose[0] - denso.q_min[0])
    segments = design.segments(denso.qd_max[0], denso.qdd_max[0], room)
    assert t[-1] == pytest.approx(sum(n / f + design.pause for _, f, n in segments), abs=2e-3)
    assert t[-1] == pytest.approx(design.duration, rel=0.12)  # the base joint's acceleration limit slows a segment
    x = q[:, 0] - q[0, 0]
    first = t < design.presliding_periods / design.presliding_hz
    assert np.ptp(x[first]) == pytest.approx(2 * design.presliding_amplitudes[0], rel=1e-3)
    qd = np.gradient(x, t)
    peak = np.abs(qd[first]).max()  # rest to rest: q = A (1 - cos), zero speed at both ends
    assert abs(x[0]) < 1e-12 and abs(qd[0]) < 0.1 * peak and abs(x[-1]) < 1e-9 and abs(qd[-1]) < 1e-6
    assert np.ptp(q[:, 1:]) == 0 and exp.joints == (0,)
    tv, _ = friction_experiment(denso, 0, design.validation()).reference()
    assert tv[-1] < t[-1]
    segments = design.validation().segments(denso.qd_max[0], denso.qdd_max[0], 2.0)
    assert segments[0][1] == pytest.approx(13.0)
    assert FrictionDesign.quick().duration < 0.6 * design.duration


def test_tuned_friction_signal_is_rest_to_rest():
    class Truth:
        fc, sigma0, vs = 5.0, 1e5, 0.02

    t, q, qd = tuned_friction_signal(Truth(), 3.0)
    assert t[1] - t[0] == pytest.approx(1e-3) and q.shape == qd.shape == t.shape
    assert q.min() >= 0 and abs(q[0]) < 1e-15 and abs(qd[-1]) < 1e-12
    assert np.abs(qd).max() == pytest.approx(0.9 * 3.0, rel=1e-3)
    assert q[t < 0.4].max() == pytest.approx(2 * 0.3 * Truth.fc / Truth.sigma0, rel=1e-3)


def test_experiment_csv(planar_robot, tmp_path):
    exp = motor_experiment(planar_robot, 0)
    path = exp.to_csv(tmp_path / "m.csv", rate=20)
    assert "joints [1]" in path.read_text().splitlines()[0]  # 1-based in the file
    data = np.loadtxt(path, delimiter=",", skiprows=2)
    assert data.shape[1] == 7 and data[-1, 0] <= exp.duration
    with pytest.raises(FileExistsError):
        exp.to_csv(path)


def test_plan_defaults_are_the_experiment_defaults():
    plan = CalibrationPlan()

    def default(function, name):
        return inspect.signature(function).parameters[name].default

    assert plan.motor_speed == default(motor_experiment, "speed")
    assert plan.motor_range_fraction == default(motor_experiment, "range_fraction")
    assert plan.motor_range_fraction == default(choose_motor_pose, "range_fraction")
    assert plan.gravity_duration == default(gravity_experiment, "duration")
    assert plan.gravity_speed == default(gravity_experiment, "speed")
    assert plan.excitation_duration == default(sine_experiment, "duration")
    assert plan.friction_design == FrictionDesign()


def test_plan_hands_out_the_experiments_knots(denso):
    plan = CalibrationPlan(gravity_duration=10.0, excitation_duration=5.0, friction_design=FrictionDesign.quick())
    t, q = plan.friction_reference(denso, 3)
    exp = friction_experiment(denso, 3, FrictionDesign.quick())
    np.testing.assert_array_equal(t, exp.t)
    np.testing.assert_array_equal(q, exp.q)
    tv, _ = plan.friction_validation_reference(denso, 3)
    assert tv[-1] < t[-1]
    ((te, qe),) = plan.excitation_references(denso, np.random.default_rng(1))
    np.testing.assert_array_equal(qe, sine_experiment(denso, duration=5.0, rng=np.random.default_rng(1)).q)
    quick = CalibrationPlan(friction_amplitudes=(1e-3, 0.05))
    assert quick.friction_validation_reference(denso, 0) is None
    np.testing.assert_array_equal(
        quick.friction_reference(denso, 0)[1], oscillation_experiment(denso, 0, amplitudes=(1e-3, 0.05)).q
    )


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda r: motor_experiment(r, 2), "joint"),
        (lambda r: motor_experiment(r, -1), "joint"),
        (lambda r: motor_experiment(r, True), "joint"),
        (lambda r: motor_experiment(r, 1, speed=0.0), "speed"),
        (lambda r: motor_experiment(r, 1, range_fraction=1.5), "range_fraction"),
        (lambda r: motor_experiment(r, 1, pose=[5.0, 0.0]), "pose"),
        (lambda r: gravity_experiment(r, duration=-1.0), "duration"),
        (lambda r: gravity_experiment(r, joints=[3]), "joint"),
        (lambda r: friction_experiment(r, 0, design=(1e-3,)), "design"),
        (lambda r: friction_experiment(r, 9), "joint"),
        (lambda r: oscillation_experiment(r, 0, amplitudes=[10.0]), "amplitudes"),
        (lambda r: sine_experiment(r, fraction=2.0), "fraction"),
        (lambda r: choose_motor_pose(r, 0, None, np.random.default_rng(0), n_candidates=0), "n_candidates"),
        (lambda r: CalibrationPlan(friction_design=(1e-3, 0.1)), "friction_design"),
        (lambda r: CalibrationPlan(gravity_speed=0.0), "gravity_speed"),
        (lambda r: CalibrationPlan(friction_amplitudes=(0.1, -1.0)), "friction_amplitudes"),
        (lambda r: ExperimentTrajectory("motor", [0.0, 1.0], np.zeros((2, 3)), JointLimits.from_robot(r), (0,)), "q"),
        (lambda r: ExperimentTrajectory("motor", [0.5, 1.0], np.zeros((2, 2)), JointLimits.from_robot(r), (0,)), "t"),
    ],
)
def test_experiment_errors(planar_robot, call, field):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        with pytest.raises((ParameterError, ShapeError), match=field):
            call(planar_robot)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(presliding_amplitudes=()), "presliding_amplitudes"),
        (dict(stribeck_speeds=(0.1, -1.0)), "stribeck_speeds"),
        (dict(sliding_fractions=(0.5, 1.5)), "sliding_fractions"),
        (dict(presliding_hz=0.0), "presliding_hz"),
        (dict(sliding_periods=0), "sliding_periods"),
        (dict(pause=-1.0), "pause"),
    ],
)
def test_friction_design_errors(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        FrictionDesign(**kwargs)


@pytest.mark.parametrize("fraction", [0.5, 1.0])
def test_sine_stays_inside_every_range_and_moves_every_joint_of_the_panda(fraction):
    """The Panda's joint 4 ranges over [-3.07, -0.07] rad and joint 6 over [-0.02, 3.75] rad: zero clipped into the
    range left joint 4 no room at all (it stood still) and a full ``fraction`` swung the others out of their range.
    Every joint's path, sampled densely from the spline a controller tracks, stays inside its limits and moves."""
    from psdm_casadi.robot_file import load_robot
    from tests.conftest import example_robot_urdf
    from trajopt.experiments import motion_centre

    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    panda = load_robot(urdf, locked_joints=("panda_finger_joint1", "panda_finger_joint2"))
    with warnings.catch_warnings():  # at the default fraction no limit at all is left (a full one may speed past)
        warnings.simplefilter("error" if fraction == 0.5 else "ignore", ExcitationWarning)
        exp = sine_experiment(panda, duration=20.0, rng=np.random.default_rng(3), fraction=fraction)
    _, q, _, _ = _dense(exp, rate=1000.0)
    assert np.all(q >= panda.q_min - 1e-12) and np.all(q <= panda.q_max + 1e-12)
    span = panda.q_max - panda.q_min
    assert np.all(np.ptp(q, axis=0) > 0.1 * fraction * span)  # joint 4 included (it stood still before)
    centre = motion_centre(panda)
    assert centre[3] == pytest.approx(panda.q_max[3] - 0.25 * span[3]) and centre[5] > 0.0  # a quarter inside
    np.testing.assert_allclose(q[0], centre, atol=1e-12)


def test_sine_keeps_zero_as_centre_where_the_range_holds_it_well_inside(denso):
    """Zero stays the centre of a joint whose range holds it in its middle half (every Denso joint): the Denso's
    designs are unchanged."""
    from trajopt.experiments import motion_centre

    np.testing.assert_array_equal(motion_centre(denso), np.zeros(denso.n_dof))
    np.testing.assert_array_equal(motion_centre(denso), home_pose(denso))
