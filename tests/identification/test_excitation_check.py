"""The excitation checks on synthetic arrays: still, dithering and sub-step joints, singular regressors, sliding.

Each refusal is an InsufficientExcitationError (a RecordingError, so the command line exits 2) whose message
names the recording, the joints or parameters and the fix; well-excited data passes unchanged.
"""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.excitation import check_calibration_data, thresholds_of
from identification.calibration.friction_step import FrictionExperiment, FrictionIdentifier
from identification.calibration.refinement import RefinementBlock, refine_parameters
from identification.calibration.steps import GravityIdentifier, InertialIdentifier
from identification.data.dataset import CalibrationData
from identification.data.excitation_check import (
    ExcitationThresholds,
    check_joint_motion,
    check_sliding,
    estimate_resolution,
    joint_label,
    joint_motion,
)
from identification.data.payload import Payload
from identification.data.recording import Recording
from identification.data.regressor_check import base_parameter_joints, check_regressor
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.friction.models import LuGreParameters, check_slides_both_ways
from identification.friction.shooting import fit_lugre_multiple_shooting
from identification.friction.start import fit_high_speed
from psdm_casadi.errors import InsufficientExcitationError, ParameterError, RecordingError

RATE = 200.0


def _moving(robot, duration=4.0, rate=RATE, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """``t, q``: every joint on two sines about the middle of its range, a quarter of the range, fast."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    centre, span = 0.5 * (robot.q_min + robot.q_max), robot.q_max - robot.q_min
    q = np.empty((t.size, robot.n_dof))
    for j in range(robot.n_dof):
        f = rng.uniform(0.4, 0.8, 2)
        q[:, j] = centre[j] + 0.12 * span[j] * (np.sin(2 * np.pi * f[0] * t) + 0.5 * np.sin(2 * np.pi * f[1] * t + 1))
    return t, q


def _rec(t, q, name="run.csv") -> Recording:
    return Recording(t=t, q=q, tau=np.zeros_like(q), name=name)


# --- per-joint motion ------------------------------------------------------------------------------
def test_a_well_excited_recording_passes_with_margin(denso):
    t, q = _moving(denso)
    motion = check_joint_motion(_rec(t, q), range(6), robot=denso, purpose="a test", fix="Move.")
    span = denso.q_max - denso.q_min
    assert np.all(motion.range > 10 * 0.01 * span)
    assert np.all(motion.speed > 10 * 0.005 * denso.qd_max)


def test_a_still_joint_is_named_with_the_recording_and_the_fix(denso):
    t, q = _moving(denso)
    q[:, 2] = 0.3  # joint 3 held
    with pytest.raises(InsufficientExcitationError, match=r"Recording A\.csv: joint 3 \(J3\) must move") as info:
        check_joint_motion(_rec(t, q, "A.csv"), range(6), robot=denso, purpose="a test", fix="Record {joints} moving.")
    assert info.value.joints == (2,)
    assert "range 0 rad" in str(info.value) and "Record joint 3 (J3) moving." in str(info.value)
    assert isinstance(info.value, RecordingError) and isinstance(info.value, ParameterError)


def test_a_motionless_recording_names_every_joint(denso):
    t = np.arange(0.0, 2.0, 0.01)
    q = np.tile(0.5 * (denso.q_min + denso.q_max), (t.size, 1)) + 1e-6 * np.random.default_rng(0).standard_normal(
        (t.size, 6)
    )
    with pytest.raises(InsufficientExcitationError, match="every joint must move .*joint 1 .*joint 6") as info:
        check_joint_motion(_rec(t, q), range(6), robot=denso, purpose="a test", fix="")
    assert info.value.joints == tuple(range(6))


def test_a_tiny_dither_fails_range_and_speed(denso):
    t, q = _moving(denso)
    q[:, 4] = 0.1 + 1e-4 * np.sin(2 * np.pi * 2.0 * t)
    with pytest.raises(InsufficientExcitationError, match=r"joint 5 \(J5\): range 0\.0002 rad \(needs >= 0\.0419"):
        check_joint_motion(_rec(t, q), range(6), robot=denso, purpose="a test", fix="")


def test_a_joint_moving_less_than_a_quantisation_step_fails_without_limits():
    """No robot: only the encoder-resolution threshold applies, estimated from the quantised positions."""
    step = 1e-3
    t = np.arange(0.0, 2.0, 1e-3)
    fine = np.column_stack([0.7 * np.sin(2 * np.pi * t), 0.4 * step * np.sin(2 * np.pi * 3 * t) + 0.3 * step])
    q = step * np.round(fine / step)
    np.testing.assert_allclose(estimate_resolution(q), [step, step], rtol=1e-9)
    assert np.ptp(q[:, 1]) == pytest.approx(step)  # one step: the joint toggles between two encoder counts
    with pytest.raises(InsufficientExcitationError, match=r"joint 2: range 0\.001 rad \(needs >= 0\.1\)"):
        check_joint_motion(_rec(t, q, "coarse.csv"), [0, 1], purpose="a test", fix="")
    check_joint_motion(_rec(t, q, "coarse.csv"), [0], purpose="a test", fix="")  # joint 1 moves 1400 steps


def test_a_given_resolution_and_thresholds_are_options(denso):
    t, q = _moving(denso)
    rec = _rec(t, q)
    loose = ExcitationThresholds(min_range_fraction=0.0, min_speed_fraction=0.0, resolution=0.0)
    q_small = q.copy()
    q_small[:, 0] = 1e-4 * np.sin(2 * np.pi * t)
    check_joint_motion(_rec(t, q_small), range(6), robot=denso, purpose="a test", fix="", thresholds=loose)
    strict = ExcitationThresholds(resolution=0.05)  # 100 steps = 5 rad
    with pytest.raises(InsufficientExcitationError, match="encoder steps"):
        check_joint_motion(rec, range(6), robot=denso, purpose="a test", fix="", thresholds=strict)
    assert joint_motion(rec, strict).resolution.tolist() == [0.05] * 6


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"min_range_fraction": -0.1}, "min_range_fraction"),
        ({"speed_window": np.nan}, "speed_window"),
        ({"max_condition": 0.5}, "max_condition"),
        ({"resolution": -1.0}, "resolution"),
    ],
    ids=str,
)
def test_thresholds_are_validated(kwargs, field):
    with pytest.raises(ParameterError, match=f"ExcitationThresholds.{field}"):
        ExcitationThresholds(**kwargs)


def test_estimators_refuse_other_thresholds_types():
    with pytest.raises(ParameterError, match="GravityIdentifier.excitation must be an ExcitationThresholds"):
        thresholds_of("GravityIdentifier", {"max_condition": 1e6})
    with pytest.raises(ParameterError, match="DiagnosisOptions.excitation"):
        DiagnosisOptions(excitation=0.01)


def test_joint_label_uses_the_robot_names(denso):
    assert joint_label(0) == "joint 1"
    assert joint_label(5, denso) == "joint 6 (J6)"


# --- regressor -------------------------------------------------------------------------------------
def test_a_well_excited_regressor_passes(rng):
    a = rng.standard_normal((500, 4)) * [1.0, 1e3, 1e-3, 10.0]  # units do not count: columns are scaled
    result = check_regressor(a, names=list("abcd"), owner="fit", source="x", fix="")
    assert result.rank == 4 and result.condition < 10


def test_a_rank_deficient_regressor_names_the_columns_and_joints(rng):
    x = rng.standard_normal((300, 2))
    a = np.column_stack([x[:, 0], x[:, 1], 2.0 * x[:, 0] - x[:, 1]])  # column c = 2 a - b
    with pytest.raises(InsufficientExcitationError, match=r"got rank 2 of 3, condition number .*: c, a, b") as info:
        check_regressor(
            a,
            names=["a", "b", "c"],
            column_joints=[(0,), (1,), (4,)],
            owner="InertialIdentifier",
            source="excitation.csv",
            fix="Record {joints} moving.",
        )
    assert info.value.joints == (0, 1, 4) and set(info.value.columns) == {"a", "b", "c"}
    assert "Record joint 1, joint 2, joint 5 moving." in str(info.value)


def test_an_ill_conditioned_regressor_is_refused_above_the_bound(rng):
    x = rng.standard_normal((300, 3))
    a = np.column_stack([x[:, 0], x[:, 1], x[:, 0] + 1e-10 * x[:, 2]])
    with pytest.raises(InsufficientExcitationError, match=r"condition number <= 1e\+08 .*got rank 3 of 3"):
        check_regressor(a, names=["p", "q", "r"], owner="fit", source="x", fix="")
    assert check_regressor(a, names=["p", "q", "r"], owner="fit", source="x", fix="", max_condition=1e12).rank == 3


def test_a_zero_column_and_too_few_weighted_rows(rng):
    a = np.column_stack([rng.standard_normal(50), np.zeros(50)])
    with pytest.raises(InsufficientExcitationError, match="zero on every row with weight > 0.*: theta2"):
        check_regressor(a, names=["theta1", "theta2"], owner="GravityIdentifier", source="gravity.csv", fix="")
    weights = np.zeros(50)
    weights[0] = 1.0
    with pytest.raises(InsufficientExcitationError, match="1 rows with weight > 0 for 2 columns"):
        check_regressor(rng.standard_normal((50, 2)), weights, names=["a", "b"], owner="fit", source="x", fix="")


def test_base_parameters_map_to_the_links_they_hold(denso_model):
    owners = base_parameter_joints(denso_model)
    assert len(owners) == denso_model.n_base
    assert all(owners) and all(0 <= j < 6 for joints in owners for j in joints)
    assert {j for joints in owners for j in joints} == set(range(6))


# --- friction --------------------------------------------------------------------------------------
def _oscillation(rate=1000.0, duration=4.0, amplitude=0.5, frequency=0.5):
    t = np.arange(0.0, duration, 1.0 / rate)
    q = np.zeros((t.size, 6))
    q[:, 0] = amplitude * np.sin(2 * np.pi * frequency * t)
    return t, q


def test_sliding_both_ways_passes_and_one_way_or_noise_fails(denso):
    t, q = _oscillation()
    speed = check_sliding(_rec(t, q, "friction_j1.csv"), 0, robot=denso, fix="")
    assert speed == pytest.approx(0.05 * denso.qd_max[0])
    one_way = q.copy()
    one_way[:, 0] = np.minimum(t, 2.0) * 0.5  # out at 0.5 rad/s, then held
    with pytest.raises(InsufficientExcitationError, match=r"friction_j1\.csv: joint 1 \(J1\) must slide in both"):
        check_sliding(_rec(t, one_way, "friction_j1.csv"), 0, robot=denso, fix="Record friction_j{k} again.")
    noise = q.copy()
    noise[:, 0] = 1e-3 * np.random.default_rng(1).standard_normal(t.size)
    with pytest.raises(InsufficientExcitationError, match=r"got 0\.0\d* s positive and 0\.0\d* s negative"):
        check_sliding(_rec(t, noise), 0, fix="")


def test_friction_step_refuses_a_still_joint_before_fitting(denso, denso_model):
    t, q = _oscillation()
    q[:, 0] = 1e-5 * np.random.default_rng(2).standard_normal(t.size)
    rec = Recording(t=t, q=q, tau=np.zeros_like(q), qd=np.gradient(q, t, axis=0), qdd=np.zeros_like(q), name="f.csv")
    theta = np.zeros(denso_model.n_base)
    with pytest.raises(InsufficientExcitationError, match=r"Recording f\.csv: joint 1 \(J1\) must move"):
        FrictionIdentifier(model=denso_model, theta=theta, robot=denso).fit(FrictionExperiment(0, rec))


def test_low_level_friction_fits_refuse_noise():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 2.0, 1e-3)
    qd = 1e-3 * rng.standard_normal(t.size)
    tau = rng.standard_normal(t.size)
    with pytest.raises(InsufficientExcitationError, match="qd must slide in both directions"):
        check_slides_both_ways(qd, owner="fit")
    p = LuGreParameters(fc=1.0, fs=1.2, vs=0.01, fv=1.0, dv=1.0, sigma0=1e4, sigma1=1.0)
    with pytest.raises(InsufficientExcitationError, match="fit_lugre_multiple_shooting.qd must slide"):
        fit_lugre_multiple_shooting(t, qd, tau, p)
    one_way = np.abs(np.sin(2 * np.pi * t))
    with pytest.raises(InsufficientExcitationError, match="fit_high_speed.qd must exceed the threshold"):
        fit_high_speed(one_way, one_way)
    check_slides_both_ways(np.sin(2 * np.pi * t))


# --- steps, refinement, pipeline and diagnosis -----------------------------------------------------
def test_gravity_step_refuses_a_jog_that_leaves_joints_still(denso, denso_model):
    t, q = _moving(denso)
    q[:, 1:] = q[0, 1:]  # only joint 1 moves: no gravity joint does
    rec = Recording(t=t, q=q, tau=np.zeros_like(q), qd=np.ones_like(q), qdd=np.zeros_like(q), name="gravity.csv")
    with pytest.raises(InsufficientExcitationError, match=r"gravity\.csv: joint 2 \(J2\).*must move for the gravity"):
        GravityIdentifier(model=denso_model, robot=denso, min_speed=0.0).fit(rec)
    # every joint moves, but no row is faster than min_speed: the regressor check refuses the empty regression
    t, q = _moving(denso)
    moving = rec.with_signals(t=t, q=q, tau=np.zeros_like(q), qd=np.gradient(q, t, axis=0), qdd=np.zeros_like(q))
    with pytest.raises(
        InsufficientExcitationError, match=r"GravityIdentifier: the regressor of gravity\.csv .* 0 rows"
    ):
        GravityIdentifier(model=denso_model, robot=denso, min_speed=100.0).fit(moving)


def test_inertial_step_refuses_an_excitation_with_a_still_joint(denso, denso_model):
    t, q = _moving(denso)
    q[:, 5] = 0.2
    qd, qdd = np.gradient(q, t, axis=0), np.gradient(np.gradient(q, t, axis=0), t, axis=0)
    rec = Recording(t=t, q=q, tau=np.zeros_like(q), qd=qd, qdd=qdd, name="excitation.csv")
    lugre = (LuGreParameters(fc=1.0, fs=1.2, vs=0.01, fv=1.0, dv=1.0, sigma0=1e4, sigma1=1.0),) * 6
    step = InertialIdentifier(model=denso_model, theta=np.zeros(denso_model.n_base), lugre=lugre, robot=denso)
    with pytest.raises(InsufficientExcitationError, match=r"excitation\.csv: joint 6 \(J6\) must move") as info:
        step.fit(rec)
    assert "psdm excite" in str(info.value)


def test_refinement_refuses_rows_that_excite_nothing(denso_model):
    t = np.arange(0.0, 1.0, 0.02)
    q = np.zeros((t.size, 6))
    rec = Recording(t=t, q=q, tau=np.zeros_like(q), qd=q, qdd=q, name="still")
    lugre = (LuGreParameters(fc=1.0, fs=1.2, vs=0.01, fv=1.0, dv=1.0, sigma0=1e4, sigma1=1.0),) * 6
    with pytest.raises(InsufficientExcitationError, match="refine_parameters: the regressor .* 0 rows with weight"):
        refine_parameters(denso_model, [RefinementBlock(rec)], np.zeros(denso_model.n_base), np.ones(6), lugre)


def test_calibration_data_is_checked_before_any_step(denso, denso_model):
    t, q = _moving(denso)
    moving = Recording(t=t, q=q, current=np.zeros_like(q), name="excitation.csv")
    friction_q = np.tile(q[0], (t.size, 1))
    friction_q[:, 0] = 0.5 * np.sin(2 * np.pi * 0.5 * t)
    friction = Recording(t=t, q=friction_q, current=np.zeros_like(q), name="friction_j1.csv")
    still = moving.with_signals(q=np.tile(q[0], (t.size, 1)), name="excitation.csv")

    def data(excitation):
        return CalibrationData(
            payload=Payload(mass=2.0, com=(0.05, 0.0, 0.05)),
            motor=((0, moving, moving),),
            gravity=(moving,),
            friction=((0, friction),),
            excitation=(excitation,),
        )

    check_calibration_data(denso, denso_model, data(moving))
    with pytest.raises(
        InsufficientExcitationError, match=r"excitation\.csv: every joint must move .*joint 6 \(J6\): range 0"
    ):
        check_calibration_data(denso, denso_model, data(still))


def test_diagnosis_refuses_a_still_recording_before_deriving_the_model(denso):
    t, q = _moving(denso)
    good = Recording(t=t, q=q, tau=np.zeros_like(q), name="A.csv")
    still = good.with_signals(q=np.tile(q[0], (t.size, 1)), name="B.csv")
    with pytest.raises(
        InsufficientExcitationError,
        match=r"Recording B\.csv: every joint must move for the diagnosis \(validation recording\)",
    ):
        diagnose(denso, good, still)  # model=None: the refusal comes before the derivation
