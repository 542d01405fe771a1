"""Limits: validation, margins, repair by scaling, DH point kinematics against the analytic planar arm."""

import numpy as np
import pytest

from psdm_casadi.errors import ParameterError, ShapeError
from tests.trajopt.conftest import A1
from trajopt.constraints import (
    JointLimits,
    KeepOut,
    build_dh_point_function,
    limit_margins,
    scale_into_limits,
    verify_limits,
)
from trajopt.parametrization import FourierTrajectory, SumOfSinesTrajectory


def _limits():
    return JointLimits(q_min=[-1.0, -2.0], q_max=[1.0, 0.0], qd_max=[2.0, 3.0], qdd_max=[5.0, 6.0])


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(qd_max=[0.0, 1.0]), "qd_max"),
        (dict(qdd_max=[1.0, -1.0]), "qdd_max"),
        (dict(q_min=[1.0, -1.0]), "q_min"),
        (dict(tau_max=[1.0, 0.0]), "tau_max"),
    ],
)
def test_limit_errors_name_field(kwargs, field):
    base = dict(q_min=[-1.0, -1.0], q_max=[1.0, 1.0], qd_max=[1.0, 1.0], qdd_max=[1.0, 1.0])
    with pytest.raises(ParameterError, match=field):
        JointLimits(**{**base, **kwargs})


def test_limit_shape_error():
    with pytest.raises(ShapeError, match="qd_max"):
        JointLimits(q_min=[-1, -1], q_max=[1, 1], qd_max=[1, 1, 1], qdd_max=[1, 1])


def test_from_robot_and_shrunk(planar_robot):
    limits = JointLimits.from_robot(planar_robot, torque=True, scale=0.5)
    np.testing.assert_allclose(limits.qd_max, 0.5 * planar_robot.qd_max)
    np.testing.assert_allclose(limits.q_max - limits.q_min, 0.5 * (planar_robot.q_max - planar_robot.q_min))
    np.testing.assert_allclose(limits.tau_max, 0.5 * planar_robot.tau_max)
    tight = limits.shrunk(0.1)
    np.testing.assert_allclose(tight.qdd_max, 0.9 * limits.qdd_max)
    with pytest.raises(ParameterError, match="scale"):
        JointLimits.from_robot(planar_robot, scale=0.0)


def test_margins_known_values():
    limits = _limits()
    q = np.array([[0.5, -1.0], [0.0, -0.5]])
    qd = np.array([[1.0, 0.0], [0.0, -2.7]])
    qdd = np.array([[0.0, 0.0], [-6.0, 0.0]])
    m = limit_margins(limits, q, qd, qdd)
    assert m["q"] == pytest.approx(0.5)  # joint 1 at 0.5 of half-range 1; joint 2 at -0.5 -> 0.5
    assert m["qd"] == pytest.approx(0.1)
    assert m["qdd"] == pytest.approx(-0.2)
    assert m["joint"]["qd"] == 2


@pytest.mark.parametrize(
    "family",
    [
        FourierTrajectory(n_dof=2, n_harmonics=4, period=3.0),
        SumOfSinesTrajectory(n_dof=2, duration=3.0, frequency_max=6.0),
    ],
)
def test_scale_into_limits_gives_feasible_trajectory(family, rng):
    limits = _limits()
    x = family.random_parameters(rng, [3.0, 3.0]) * 10  # far outside, offsets too
    t = family.default_grid(4000)
    fixed = scale_into_limits(family, x, limits, t, fill=0.9)
    m = limit_margins(limits, *family.evaluate(t, fixed))
    assert min(m["q"], m["qd"], m["qdd"]) >= 0.1 - 1e-9
    assert verify_limits(family, fixed, limits, 400)["worst"] >= 0.1 - 1e-6


def test_scale_into_limits_needs_offset_inside_range(rng):
    family = SumOfSinesTrajectory(n_dof=2, duration=3.0, offset=False)
    limits = JointLimits(q_min=[0.5, -1], q_max=[1.0, 1], qd_max=[1, 1], qdd_max=[1, 1])
    with pytest.raises(ParameterError, match="offset"):
        scale_into_limits(family, family.random_parameters(rng, [0, 0]), limits, family.default_grid(50))


def test_dh_point_matches_planar_kinematics(planar_robot, rng):
    fk = build_dh_point_function(planar_robot, tool_point=(0.0, 0.0, 0.0))
    for q in rng.uniform(-2, 2, (5, 2)):
        expected = [A1 * np.cos(q[0]) + 0.4 * np.cos(q.sum()), A1 * np.sin(q[0]) + 0.4 * np.sin(q.sum()), 0.0]
        np.testing.assert_allclose(np.asarray(fk(q)).ravel(), expected, atol=1e-12)


def test_keep_out_distance_and_errors(planar_robot):
    fk = build_dh_point_function(planar_robot)
    floor = KeepOut(fk, normal=(0, 2, 0), offset=-0.5)
    d = floor.distance(np.array([[np.pi / 2, 0.0], [-np.pi / 2, 0.0]]))
    np.testing.assert_allclose(d, [0.9 + 0.5, -0.9 + 0.5], atol=1e-12)
    with pytest.raises(ParameterError, match="normal"):
        KeepOut(fk, normal=(0, 0, 0))
    with pytest.raises(ParameterError, match="point"):
        KeepOut("not a function", normal=(0, 0, 1))
