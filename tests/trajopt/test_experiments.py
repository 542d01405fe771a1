"""Calibration experiments (paper 3.1-3.3): shape of the motion, limits, reversibility, errors."""

import numpy as np
import pytest

from psdm_casadi.errors import ParameterError
from trajopt.constraints import JointLimits, limit_margins
from trajopt.experiments import friction_experiment, gravity_experiment, motor_experiment


def _dense(exp, rate=500.0):
    t = exp.time_grid(rate)
    return (t, *exp.sample(t))


def _fd_consistent(t, q, qd, qdd):
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(q, h, axis=0)[2:-2], qd[2:-2], atol=5e-3)


def test_motor_sweeps_one_joint_at_constant_speed(planar_robot):
    exp = motor_experiment(planar_robot, 2, speed_fraction=0.2, range_fraction=0.8)
    t, q, qd, qdd = _dense(exp)
    assert np.ptp(q[:, 0]) == 0 and np.all(qd[:, 0] == 0)
    limits = JointLimits.from_robot(planar_robot)
    np.testing.assert_allclose([q[:, 1].min(), q[:, 1].max()], [-0.8 * 2.5, 0.8 * 2.5], atol=1e-5)
    cruise = 0.2 * limits.qd_max[1]
    assert np.isclose(qd[:, 1].max(), cruise) and np.isclose(qd[:, 1].min(), -cruise)
    # forward and back: most of the sweep at the constant cruise speed in both directions
    assert np.mean(np.isclose(qd[:, 1], cruise)) > 0.3 and np.mean(np.isclose(qd[:, 1], -cruise)) > 0.3
    assert np.abs(qdd[:, 1]).max() <= 0.3 * limits.qdd_max[1] + 1e-12
    _fd_consistent(t, q, qd, qdd)
    assert exp.worst_margin >= 0 and exp.joints == (2,)


def test_gravity_path_is_run_back_exactly(planar_robot):
    exp = gravity_experiment(planar_robot, speed_fraction=0.1, n_waypoints=6, seed=4)
    t, q, qd, qdd = _dense(exp, 200.0)
    q_back, qd_back, _ = exp.sample(exp.duration - t)
    np.testing.assert_allclose(q, q_back, atol=1e-9)
    np.testing.assert_allclose(qd, -qd_back, atol=1e-9)
    limits = JointLimits.from_robot(planar_robot)
    assert np.all(np.abs(qd) <= 0.1 * limits.qd_max + 1e-12)
    assert np.all(np.ptp(q, axis=0) > 0.5 * (limits.q_max - limits.q_min))  # covers most of the range
    again = gravity_experiment(planar_robot, speed_fraction=0.1, n_waypoints=6, seed=4)
    np.testing.assert_array_equal(again.sample(t[:50])[0], q[:50])
    _fd_consistent(t, q, qd, qdd)


def test_friction_from_presliding_to_near_speed_limit(planar_robot):
    exp = friction_experiment(planar_robot, 1, n_levels=6, amplitude_min=1e-4, cycles=3)
    t, q, qd, qdd = _dense(exp, 2000.0)
    assert np.all(q[:, 1] == q[0, 1])
    amps = [s.amplitude for s in exp.segments]
    assert amps[0] == pytest.approx(1e-4) and amps == sorted(amps)
    limits = JointLimits.from_robot(planar_robot)
    assert np.abs(qd[:, 0]).max() >= 0.8 * limits.qd_max[0]
    m = limit_margins(limits, q, qd, qdd)
    assert min(m["q"], m["qd"], m["qdd"]) >= 0
    starts = np.cumsum([0] + [s.duration for s in exp.segments])[1:-1]
    _, qd_join, qdd_join = exp.sample(starts)
    np.testing.assert_allclose(qd_join, 0, atol=1e-9)  # each level starts and ends at rest
    np.testing.assert_allclose(qdd_join, 0, atol=1e-9)


def test_experiment_csv(planar_robot, tmp_path):
    exp = motor_experiment(planar_robot, 1)
    path = exp.to_csv(tmp_path / "m.csv", rate=20)
    data = np.loadtxt(path, delimiter=",", skiprows=2)
    assert data.shape[1] == 7 and data[-1, 0] <= exp.duration
    with pytest.raises(FileExistsError):
        exp.to_csv(path)


@pytest.mark.parametrize("call, field", [
    (lambda r: motor_experiment(r, 0), "joint"),
    (lambda r: motor_experiment(r, 3), "joint"),
    (lambda r: motor_experiment(r, 1, speed_fraction=0.0), "speed_fraction"),
    (lambda r: motor_experiment(r, 1, pose=[5.0, 0.0]), "pose"),
    (lambda r: gravity_experiment(r, n_waypoints=1), "n_waypoints"),
    (lambda r: friction_experiment(r, 1, amplitudes=[10.0]), "amplitudes"),
    (lambda r: friction_experiment(r, 1, amplitudes=[0.1, 0.2], peak_speeds=[1.0]), "peak_speeds"),
    (lambda r: friction_experiment(r, 1, cycles=1), "cycles"),
])
def test_experiment_errors(planar_robot, call, field):
    with pytest.raises(ParameterError, match=field):
        call(planar_robot)
