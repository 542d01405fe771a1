"""The plausibility rules on synthetic data with known faults, and on the real recordings they must let through.

``check_plausible_recording`` (positions near the limits, speeds below them, time in seconds),
``check_reversals`` (Coulomb friction told from an offset), ``fit_warnings`` (negative friction, masses,
training R^2), ``NormalEquations.r2`` against numpy, and ``not_held_out`` (one file named twice).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.trajectory_checks import (
    FRICTION_Z,
    MASS_RATIO,
    MIN_TRAINING_R2,
    fit_warnings,
    unit_factor,
)
from identification.calibration.trajectory_data import NormalEquations
from identification.data.excitation_check import check_reversals
from identification.data.io import not_held_out
from identification.data.plausibility import DEGREE, PlausibilityThresholds, check_plausible_recording
from identification.data.recording import Recording
from psdm_casadi.errors import InsufficientExcitationError, ParameterError, RecordingError
from tests.conftest import DATASETS, example_robot_urdf

RATE = 200.0


def _recording(robot, amplitude, frequency=0.3, rate=RATE, duration=6.0, time_scale=1.0, name="run.csv"):
    """Every joint on a sine about the middle of its range: ``amplitude`` (n_dof,) [rad], ``frequency`` [Hz]."""
    t = np.arange(0.0, duration, 1.0 / rate)
    home = 0.5 * (robot.q_min + robot.q_max)
    q = home + np.asarray(amplitude) * np.sin(2 * np.pi * frequency * t[:, None] + np.arange(robot.n_dof))
    return Recording(t=time_scale * t, q=q, tau=np.zeros_like(q), name=name)


def _half_range(robot):
    return 0.5 * (robot.q_max - robot.q_min)


def test_a_recording_within_the_limits_passes_and_a_small_overshoot_too(denso):
    check_plausible_recording(_recording(denso, 0.8 * _half_range(denso)), denso)
    check_plausible_recording(_recording(denso, 1.08 * _half_range(denso), frequency=0.2), denso)  # 4 % beyond


def test_positions_far_beyond_a_limit_are_refused_naming_the_column(denso):
    amplitude = 0.5 * _half_range(denso)
    amplitude[2] = 1.25 * _half_range(denso)[2]  # joint 3 goes 12.5 % of its range beyond each limit
    with pytest.raises(RecordingError, match="column q3") as info:
        check_plausible_recording(_recording(denso, amplitude, frequency=0.2), denso)
    message = str(info.value)
    assert "column q1" not in message and "run.csv" in message and "degrees?" not in message
    assert "the unit of q3 (rad or m), the joint order" in message


def test_positions_in_degrees_are_refused_with_the_unit_named(denso):
    degrees = _recording(denso, 0.5 * _half_range(denso))
    degrees = degrees.with_signals(q=degrees.q / DEGREE)
    with pytest.raises(RecordingError, match="degrees\\?") as info:
        check_plausible_recording(degrees, denso)
    assert "column q1" in str(info.value) and "Convert q1 to radians" in str(info.value)


def test_speeds_several_times_the_limit_are_refused_and_below_the_factor_pass(denso):
    factor = PlausibilityThresholds().speed_factor
    amplitude = 0.2 * _half_range(denso)
    base = _recording(denso, amplitude, frequency=1.0)
    peak = 2 * np.pi * 1.0 * amplitude  # [rad/s]
    # the same positions played faster: the peak speed at 0.8 and at 2 x factor times qd_max on every joint
    slow = float(np.min(0.8 * factor * denso.qd_max / peak))
    check_plausible_recording(Recording(t=base.t / slow, q=base.q, tau=base.tau, name="ok.csv"), denso)
    fast = float(np.max(2.0 * factor * denso.qd_max / peak))
    with pytest.raises(RecordingError, match="speed limit qd_max"):
        check_plausible_recording(Recording(t=base.t / fast, q=base.q, tau=base.tau, name="fast.csv"), denso)


def test_a_time_column_in_milliseconds_is_named_and_a_slow_log_in_seconds_is_not(denso):
    millis = _recording(denso, 0.4 * _half_range(denso), rate=500.0, time_scale=1000.0)
    with pytest.raises(RecordingError, match="milliseconds"):
        check_plausible_recording(millis, denso)
    check_plausible_recording(_recording(denso, 0.4 * _half_range(denso), rate=500.0), denso)
    # a robot holding still, logged at 1 Hz in seconds: slow, but not a thousand times too slow
    still = _recording(denso, 1e-7 * np.ones(denso.n_dof), rate=1.0, duration=60.0)
    check_plausible_recording(still, denso)


def test_thresholds_are_checked():
    with pytest.raises(ParameterError, match="speed_factor"):
        PlausibilityThresholds(speed_factor=0.0)


def _real(folder):
    if not folder.exists():
        pytest.skip(f"{folder} is absent")


@pytest.mark.real_data
def test_the_real_tx40_and_panda_recordings_pass():
    """The Staubli TX40 (FIGAROH) and Franka Panda (Gaz et al.) logs, converted as their READMEs say, pass."""
    from psdm_casadi.robot import load_robot

    tx40 = DATASETS / "staubli_tx40_figaroh"
    _real(tx40)
    theta_m = np.loadtxt(tx40 / "pos_read_data.csv", delimiter=",", skiprows=1)
    ratios = np.diag([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
    ratios[5, 4] = 32.0
    q = np.linalg.solve(ratios, theta_m.T).T + np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])
    robot = load_robot(tx40 / "tx40_mdh_modified.urdf")
    t = np.arange(q.shape[0]) * 2e-4
    check_plausible_recording(Recording(t=t, q=q, tau=np.zeros_like(q), name="tx40"), robot)
    panda = DATASETS / "panda_gaz2019"
    _real(panda)
    from psdm_casadi import from_urdf

    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    panda_robot = from_urdf(urdf, locked_joints=("panda_finger_joint1", "panda_finger_joint2"))
    t = np.loadtxt(panda / "exciting_traj_time.txt")
    q = np.loadtxt(panda / "exciting_traj_positions.txt").reshape(-1, 7)
    keep = np.concatenate([[True], np.diff(t) > 0])
    check_plausible_recording(Recording(t=t[keep], q=q[keep], tau=np.zeros_like(q[keep]), name="panda"), panda_robot)


def _prepared(qd, name="r.csv"):
    t = np.arange(qd.shape[0]) / RATE
    return Recording(
        t=t, q=np.cumsum(qd, axis=0) / RATE, tau=np.zeros_like(qd), qd=qd, qdd=np.zeros_like(qd), name=name
    )


def test_reversals_refuse_a_one_way_joint_and_pool_the_recordings(denso):
    t = np.arange(0.0, 10.0, 1.0 / RATE)
    both = np.column_stack([np.sin(t), np.cos(t)])
    one_way = both.copy()
    one_way[:, 1] = -0.5 - 0.4 * np.abs(np.sin(t))
    check_reversals([_prepared(both)], [0, 1], speed=0.05, min_fraction=0.02, purpose="p", fix="fix {joints}")
    with pytest.raises(InsufficientExcitationError, match="joint 2") as info:
        check_reversals([_prepared(one_way, "a.csv")], [0, 1], speed=0.05, min_fraction=0.02, purpose="p",
                        fix="fix {joints}")  # fmt: skip
    assert info.value.joints == (1,) and "a.csv" in str(info.value) and "0 % of the samples positive" in str(info.value)
    # pooled: the other recording reverses joint 2 for long enough
    check_reversals([_prepared(one_way), _prepared(both)], [0, 1], speed=0.05, min_fraction=0.02, purpose="p",
                    fix="")  # fmt: skip


def _fit(robot, drive_names=(), ols=(), std=(), masses=None, r2=None, r2_ols=None, checked=True, torque_ratio=()):
    standard = robot.nominal_dynamic_parameters().copy()
    if masses is not None:
        standard[:, 0] = masses
    ones = tuple([1.0] * robot.n_dof)
    return SimpleNamespace(
        drive_names=tuple(drive_names), drive_ols=np.array(ols, float), drive_std=np.array(std, float),
        standard=standard, checked=checked, training_r2=r2 or ones, training_r2_ols=r2_ols or ones,
        torque_ratio=torque_ratio, envelope=(),
    )  # fmt: skip


def test_fit_warnings_flag_friction_the_data_want_negative_by_many_sigma(denso):
    z = FRICTION_Z
    fit = _fit(denso, ("fc1", "fv1", "fc2", "Ia3"), (-1.2 * z, -0.8 * z, 3.0, -0.1), (1.0, 1.0, 1.0, 1.0))
    warnings = fit_warnings(denso, fit)
    assert len(warnings) == 1 and "joint 1" in warnings[0] and "fc1" in warnings[0] and "fv1" not in warnings[0]
    assert "Torque sign or joint mapping wrong?" in warnings[0]
    assert fit_warnings(denso, _fit(denso, ("fc1",), (2.0,), (0.1,))) == ()


def test_a_negative_coulomb_beside_a_clearly_positive_viscous_is_not_blamed_on_the_torque_sign(denso):
    """A flipped torque turns the viscous term negative too; the heavy arm's refit (fc2 = -746 +- 38, fs2 = -1254 +-
    83 beside fv2 = +728 +- 4.2) has its sign right, and the warning says what the negative terms mean instead."""
    fit = _fit(denso, ("fc2", "fs2", "fv2"), (-746.0, -1254.0, 728.0), (38.0, 83.0, 4.2))
    (warning,) = fit_warnings(denso, fit)
    assert "joint 2" in warning and "fc2" in warning and "fs2" in warning
    assert "Torque sign" not in warning and "fv2 = +728" in warning and "psdm diagnose" in warning
    # a viscous term within FRICTION_Z sigma of zero does not vouch for the sign
    (blamed,) = fit_warnings(denso, _fit(denso, ("fc2", "fv2"), (-746.0, 0.5 * FRICTION_Z), (38.0, 1.0)))
    assert "Torque sign or joint mapping wrong?" in blamed


def test_fit_warnings_flag_masses_an_order_of_magnitude_off(denso):
    prior = denso.nominal_dynamic_parameters()[:, 0]
    masses = prior.copy()
    masses[1] *= 1.2 * MASS_RATIO
    masses[2] *= 0.8 * MASS_RATIO
    masses[3] /= 1.2 * MASS_RATIO
    warnings = fit_warnings(denso, _fit(denso, masses=masses, torque_ratio=(1.3, 0.9, 2.5, 1.1, 1.0, 1.2)))
    assert [w.split(" ")[1] for w in warnings] == ["2", "4"]
    # not a unit: the torques are not off by a unit factor on every joint; an unmodelled effect or a payload is
    assert all("mN m" not in w and "counterbalance" in w and "payload" in w and "psdm diagnose" in w for w in warnings)
    assert fit_warnings(denso, _fit(denso, masses=masses, checked=False)) == ()  # no standard parameters identified


@pytest.mark.parametrize(
    ("factor", "named"), [(1000.0, "mN m?"), (1e-3, "kN m?"), (180 / np.pi, "180/pi"), (np.pi / 180, "pi/180")]
)
def test_fit_warnings_blame_units_only_for_a_unit_factor_on_every_joint(denso, factor, named):
    ratios = factor * np.array([1.1, 0.8, 1.3, 0.9, 1.2, 1.0])
    warnings = fit_warnings(denso, _fit(denso, torque_ratio=tuple(ratios)))
    assert len(warnings) == 1 and named in warnings[0] and "Convert the torques" in warnings[0]
    ratios[2] = 1.0  # one joint in N m: not a unit of the signal
    assert unit_factor(ratios) is None and not any(
        named in w for w in fit_warnings(denso, _fit(denso, torque_ratio=tuple(ratios)))
    )


def test_fit_warnings_flag_joints_the_model_does_not_explain(denso):
    r2 = [0.99] * denso.n_dof
    r2[0], r2[4] = 0.9 * MIN_TRAINING_R2, 0.1
    r2_ols = list(r2)
    r2_ols[4] = 0.98
    warnings = fit_warnings(denso, _fit(denso, r2=tuple(r2), r2_ols=tuple(r2_ols)))
    assert len(warnings) == 2
    assert "joint 1" in warnings[0] and "Joint mapping wrong" in warnings[0]
    assert "joint 5" in warnings[1] and "unphysical" in warnings[1]


def test_normal_equations_r2_is_numpys(rng):
    a = rng.normal(size=(200, 2, 3))
    y = a @ np.array([1.0, -2.0, 0.5]) + 3.0 + 0.3 * rng.normal(size=(200, 2))
    equations = NormalEquations(2, 3)
    equations.add(a[:120], y[:120])
    equations.add(a[120:], y[120:])
    x = np.array([0.9, -2.1, 0.4])
    residual = y - a @ x
    expected = 1.0 - np.sum(residual**2, axis=0) / np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    np.testing.assert_allclose(equations.r2(x), expected, rtol=1e-10)
    np.testing.assert_allclose(equations.subset([0, 1, 2]).r2(x), expected, rtol=1e-10)


def test_not_held_out_finds_one_file_named_twice_a_link_and_a_copy(tmp_path):
    a, b, c = (tmp_path / n for n in ("a.csv", "b.csv", "c.csv"))
    a.write_text("t,q1,tau1\n0,0,0\n")
    b.write_text("t,q1,tau1\n0,0,1\n")  # same size, other bytes
    c.write_bytes(a.read_bytes())
    (tmp_path / "link.csv").symlink_to(a)
    assert not_held_out([a], [b]) == []
    assert len(not_held_out([a], [a, b, c, tmp_path / "link.csv"], "--train")) == 3
    assert "--train" in not_held_out([a], [a], "--train")[0] and "NOT held out" in not_held_out([a], [a])[0]
