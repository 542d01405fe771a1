"""Friction on joints that move one way only in training, held to the robot file's fit where the data do not determine
it (``calibration.one_way_friction``, ``calibration.held_friction``).

Reference: a virtual SCARA whose robot file is its truth, Coulomb 0.3 N m and viscous 0.2 N m s/m (or N m s/rad)
friction on every joint, noise 0.02 N m. Its prismatic joint 3 carries a constant gravity load: moving it one way only
(2 s, upwards at 0.08 m/s) its Coulomb friction is a constant the gravity parameters take as well, and the free fit
trades the two (validated on a 6 s recording on which every joint reverses: 0.25 N m on joint 3 against 0.008 for the
robot file with friction fitted). Held to the robot file's friction fit, joint 3 is back at the file's error; joint 4,
also one-way but carrying no gravity, has its friction determined and keeps it fitted.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.column_candidates import prepare_training
from identification.calibration.held_friction import check_held_friction
from identification.calibration.identify_route import identify_recordings
from identification.calibration.one_way_friction import (
    OneWayFriction,
    check_one_way_mode,
    held_options,
    hold_one_way_friction,
)
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.recording import Recording
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.errors import ParameterError, SolverError
from psdm_casadi.oracle import PinocchioOracle

FC, FV, NOISE = 0.3, 0.2, 0.02


@pytest.fixture(scope="module")
def scara():
    robot = load_robot("scara")
    return robot, derive_psdm(robot)


def recording(robot, seed, one_way=(), duration=6.0, rate=200.0, fv=FV, fc=FC) -> Recording:
    """Sums of two sines per joint about the middle of its range; the ``one_way`` joints' sines are a tenth as large
    and ride on a steady motion (0.08 m/s on joint 3, 0.8 rad/s on joint 4) that keeps them moving one way. ``fv``:
    the viscous friction, one for every joint or one per joint; ``fc`` the Coulomb friction, likewise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    centre, amplitude, drift = np.array([0, 0, 0.1, 0]), np.array([0.6, 0.6, 0.035, 1.0]), np.array([0, 0, 0.08, 0.8])
    q, qd, qdd = (np.zeros((t.size, robot.n_dof)) for _ in range(3))
    for j in range(robot.n_dof):
        w, phase = rng.uniform(1.5, 3.0, 2), rng.uniform(0.0, 2 * np.pi, 2)
        a = amplitude[j] * (0.1 if j in one_way else 1.0) / w
        arg = w[:, None] * t + phase[:, None]
        q[:, j] = centre[j] + (a[:, None] * np.sin(arg)).sum(0) + (drift[j] * (t - duration / 2) if j in one_way else 0)
        qd[:, j] = (a[:, None] * w[:, None] * np.cos(arg)).sum(0) + (drift[j] if j in one_way else 0.0)
        qdd[:, j] = -(a[:, None] * w[:, None] ** 2 * np.sin(arg)).sum(0)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + np.asarray(fc) * np.tanh(qd / 0.05) + np.asarray(fv) * qd
    return Recording(t=t, q=q, tau=tau + rng.normal(scale=NOISE, size=tau.shape), name=f"scara{seed}")


@pytest.fixture(scope="module")
def one_way_case(scara):
    robot, model = scara
    train, held = [recording(robot, 0, one_way=(2, 3), duration=2.0)], [recording(robot, 1)]
    run = {mode: identify_recordings(robot, model, train, validation=held, counterbalance=False, one_way=mode,
                                     worse_joint="hold" if mode == "mended" else "report")
           for mode in ("auto", "fit", "hold")}  # fmt: skip
    run["mended"] = identify_recordings(robot, model, train, validation=held, counterbalance=False, one_way="fit")
    return train, held, run


def test_the_default_is_not_worse_than_the_robot_file_on_the_joints_that_move_one_way(one_way_case):
    """Joints 3 and 4 move one way only; by default neither is worse than the robot file with friction fitted on the
    held-out recording (on main, joint 3 was: 0.25 against 0.008 N m)."""
    _, _, run = one_way_case
    check = run["auto"].file_check
    assert check.one_way == (2, 3) and check.comparison is not None
    c = check.comparison
    for j in check.one_way:
        assert c.after[j] <= c.before[j] + c.margin[j], (j, c.after[j], c.before[j], c.margin[j])
    assert c.after[2] < 2 * c.before[2]  # the file's error, not the fitted friction's (30 x)


def test_without_the_rule_the_joint_whose_friction_trades_with_gravity_is_worse(one_way_case):
    _, _, run = one_way_case
    check = run["fit"].file_check
    assert 2 in check.worse and check.comparison.after[2] > 10 * check.comparison.before[2]
    assert run["fit"].one_way.held == () and "--one-way-friction fit" in run["fit"].one_way.reason


def test_only_the_undetermined_joint_is_held_near_the_true_friction_and_said_so(one_way_case):
    """Joint 3's friction is undetermined (a standard deviation above its value), joint 4's is not: only joint 3 is
    held, at the robot file's fit (the file is the truth: the simulated friction), which the written model holds."""
    _, _, run = one_way_case
    result = run["auto"]
    decided = result.one_way
    assert [j for j, _ in decided.undetermined] == [2] and decided.held_joints == (2,) and decided.worse == (2,)
    held = dict(decided.held)
    # at the one speed joint 3 moves at (0.08 m/s) its Coulomb and viscous columns are one: the held pair gives the
    # true friction there (0.292 N m), whichever way it splits it
    speed, smoothing = 0.08, result.options.coulomb_velocity
    truth = FC * np.tanh(speed / smoothing) + FV * speed
    assert held["fc3"] * np.tanh(speed / smoothing) + held["fv3"] * speed == pytest.approx(truth, abs=0.02)
    names = result.fit.drive_names
    assert result.fit.drive[names.index("fc3")] == held["fc3"] and result.fit.drive_std[names.index("fc3")] == 0.0
    text = decided.describe()
    assert text in result.describe() and "one way only in training (3, 4)" in text and "joint 3: fc3" in text
    assert "worse than the robot file" in text and "--one-way-friction fit" in text
    stored = result.calibrated.document["identification"]["one_way_friction"]
    assert stored["held_joints"] == [3] and stored["one_way_joints"] == [3, 4] and set(stored["held"]) == {"fc3", "fv3"}
    document = result.calibrated.document["drive"]
    assert document["values"][document["names"].index("fc3")] == pytest.approx(held["fc3"])


def test_without_a_held_out_recording_the_undetermined_friction_is_held(scara, one_way_case):
    robot, model = scara
    train, _, run = one_way_case
    alone = identify_recordings(robot, model, train, counterbalance=False)
    assert 2 in alone.one_way.held_joints and "no held-out recording tells" in alone.one_way.reason
    held, checked = dict(alone.one_way.held), dict(run["auto"].one_way.held)
    assert [held["fc3"], held["fv3"]] == pytest.approx([checked["fc3"], checked["fv3"]], abs=1e-3)


def test_hold_holds_every_one_way_joint_without_asking_the_held_out_recording(one_way_case):
    _, _, run = one_way_case
    decided = run["hold"].one_way
    assert decided.held_joints == (2, 3) and decided.worse == () and decided.reason == "--one-way-friction hold"
    assert dict(decided.held)["fc3"] == pytest.approx(dict(run["auto"].one_way.held)["fc3"])
    assert run["hold"].file_check.comparison.after[2] < 2 * run["hold"].file_check.comparison.before[2]


def test_a_one_way_joint_the_held_out_check_finds_worse_is_held_though_its_friction_is_determined(scara, one_way_case):
    """Joint 4's friction is determined (each standard deviation below its value) and the robot-file check of the
    real held-out recording leaves it alone; a check that finds it worse holds it with the undetermined joint 3, at
    the robot file's fit (the truth: 0.46 N m at the 0.8 rad/s it moves at), and the record says the held-out
    recordings decided it."""
    from identification.calibration.never_worse import JointComparison
    from identification.calibration.robot_file_check import FileCheck

    robot, model = scara
    train, _, run = one_way_case
    result = run["fit"]
    prepared = prepare_training(robot, train, result.options).prepared
    before = np.full(robot.n_dof, 0.1)
    after = before.copy()
    after[3] = 0.2  # joint 4 worse, beyond any margin
    worse = FileCheck(JointComparison(before, after, np.full(robot.n_dof, 0.01)), recordings=1)
    refits = []

    def refit(options):
        refits.append(options)
        return identify_trajectories(robot, model, train, options)

    problem = (robot, model, train, result.options, None, refit)
    fit, decided = hold_one_way_friction(problem, result.fit, prepared, "auto", lambda _: worse)
    assert decided.held_joints == (2, 3) and decided.worse == (3,) and decided.decided_by_held_out
    assert [j for j, _ in decided.undetermined] == [2]  # joint 4 was not a candidate on its own
    held = dict(decided.held)
    speed, smoothing = 0.8, result.options.coulomb_velocity
    assert held["fc4"] * np.tanh(speed / smoothing) + held["fv4"] * speed == pytest.approx(
        FC * np.tanh(speed / smoothing) + FV * speed, abs=0.03
    )
    assert "joint 4 0.1 -> 0.2 N m" in decided.reason and "decided this hold" in decided.describe()
    assert decided.to_dict()["decided_by_held_out"] is True and len(refits) == 1
    # the real held-out recording finds joint 4 no worse: by default only joint 3 is held, and not for joint 4
    assert run["auto"].one_way.held_joints == (2,) and 3 not in run["auto"].file_check.worse


def test_a_held_joint_is_coulomb_viscous_and_a_model_without_a_stribeck_joint_left_has_no_static_friction():
    """A model file's Stribeck velocities have one positive or none: holding the only Stribeck joint drops ``fs``."""
    stribeck = TrajectoryOptions(friction=("fc", "fs", "fv", "offset"), stribeck_joints=(2, 3), offset_joints=(0,))
    one = held_options(stribeck, (("fc3", 0.3), ("fv3", 0.2)), 4)
    assert one.stribeck_joints == (3,) and one.friction == stribeck.friction and dict(one.held_friction)["fv3"] == 0.2
    both = held_options(stribeck, (("fc3", 0.3), ("fc4", 0.1)), 4)
    assert both.friction == ("fc", "fv", "offset") and both.stribeck_joints is None
    every = held_options(replace(stribeck, stribeck_joints=None), (("fc3", 0.3),), 4)
    assert every.stribeck_joints == (0, 1, 3)
    plain = held_options(TrajectoryOptions(), (("fc3", 0.3),), 4)
    assert plain.friction == ("fc", "fv") and plain.held_friction == (("fc3", 0.3),)


def test_a_held_fit_that_does_not_converge_leaves_the_fitted_friction_and_says_why(scara, one_way_case):
    robot, model = scara
    train, _, run = one_way_case
    result = run["fit"]
    prepared = prepare_training(robot, train, result.options).prepared

    def refit(options):
        assert dict(options.held_friction).keys() == {"fc3", "fv3"}
        raise SolverError("Ipopt stopped at its iteration cap")

    problem = (robot, model, train, result.options, None, refit)
    fit, decided = hold_one_way_friction(problem, result.fit, prepared, "auto")
    assert (
        fit is result.fit and decided.held == () and decided.describe().endswith("(Ipopt stopped at its iteration cap)")
    )
    assert "held did not converge" in decided.reason


def test_a_held_column_is_not_fitted_and_bad_holds_are_refused(scara, one_way_case):
    robot, model = scara
    train, _, _ = one_way_case
    options = TrajectoryOptions(held_friction=(("fc3", 0.3), ("fv3", 0.2)))
    fit = identify_trajectories(robot, model, train, options)
    names = fit.drive_names
    for name, value in options.held_friction:
        k = names.index(name)
        assert fit.drive[k] == value and fit.drive_ols[k] == value and fit.drive_std[k] == 0.0
    assert fit.drive_std[names.index("fc4")] > 0
    with pytest.raises(ParameterError, match="held_friction must hold"):
        TrajectoryOptions(held_friction=(("offset3", 0.1),))
    with pytest.raises(ParameterError, match="finite"):
        TrajectoryOptions(held_friction=(("fc3", float("nan")),))
    with pytest.raises(ParameterError, match="Coulomb-viscous"):
        TrajectoryOptions(friction=("fc", "fs", "fv"), held_friction=(("fc3", 0.3),))
    check_held_friction(
        TrajectoryOptions(friction=("fc", "fs", "fv"), stribeck_joints=(0,), held_friction=(("fc3", 1),))
    )
    with pytest.raises(ParameterError, match="--one-way-friction must be one of auto, hold, fit"):
        check_one_way_mode("yes")
    assert OneWayFriction().describe() == ""  # no joint moves one way: nothing to say


def test_diagnose_model_keeps_the_friction_the_file_holds_in_every_refit(scara, one_way_case):
    """``diagnose MODEL`` of the held model: the diagnosis's nominal model predicts the held joint 3 as ``psdm
    validate`` predicts the file (0.0066 N m; its friction held at the file's values, not refitted on the one-way
    training recording, which gave 0.053 on main), the report names what it held, and the augmented model computes
    the held friction as the file does."""
    from identification.calibration.calibrated_model import LoadedModel, calibrated_robot
    from identification.calibration.finding_value import validation_rmse
    from identification.diagnosis.candidates import SpringTerm, TorqueOffsetTerm
    from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
    from identification.diagnosis.model_file import diagnose_model, model_file_options

    robot, model = scara
    train, held, run = one_way_case
    calibrated = run["auto"].calibrated
    own = validation_rmse(calibrated, model, held[0])[0]
    quick = DiagnosisOptions(rigid_body="prior", library=SpringTerm() + TorqueOffsetTerm(), sparse=False, cv_folds=0)
    options = model_file_options(calibrated, quick)  # the nominal fit does not depend on the candidates
    assert options.held_friction.joints == (2,) and options.held_friction.values == run["auto"].one_way.held
    nominal = diagnose(calibrated_robot(calibrated, robot), train[0], held[0], options, model=model)
    assert nominal.rmse_before[2] == pytest.approx(own[2], rel=1e-6), (nominal.rmse_before, own)
    free = diagnose(calibrated_robot(calibrated, robot), train[0], held[0],
                    replace(options, held_friction=type(options.held_friction)()), model=model)  # fmt: skip
    # the friction refitted where the data do not determine it: 0.0080 (0.053 with the sign smoothed over 0.02 rad/s)
    assert free.rmse_before[2] > 1.15 * own[2]
    report = diagnose_model(LoadedModel(calibrated, robot, model), train[0], held[0], replace(quick, rigid_body="auto"))
    assert report.held_friction == run["auto"].one_way.held and np.isfinite(report.rmse_after[2])
    assert report.rmse_after[2] <= own[2] * 1.01 or any(2 in f.joints for f in report.findings)
    assert "held at the model file's values" in report.to_markdown() and "joint 3: fc3" in report.to_markdown()
    function = report.augmented.build_function()
    states = recording(robot, 5, duration=1.5)
    prepared, predicted = calibrated.predict_recording(model, states)
    k = len(prepared.t) // 2
    tau = np.asarray(function(prepared.q[k], prepared.qd[k], prepared.qdd[k], 0.0)).ravel()
    assert tau[2] == pytest.approx(predicted[k, 2], abs=1e-9)


def test_the_robot_files_friction_fit_is_bounded_as_identify_bounds_its_own(scara):
    """Joint 4 moves one way only (0.8 rad/s, a tenth-size sine on it) with Coulomb friction and no viscous friction:
    the unbounded least squares on the file's rigid body (the truth) trades the two into a negative viscous friction
    (seeded noise), which identify's own model cannot have; the baseline identify checks against
    (``robot_file_check.file_friction``) is bounded as identify's friction is, recovers the truth and never goes below
    zero, and on the training recording no joint of it is worse than the file's rigid body alone."""
    from identification.calibration.robot_file_check import file_friction
    from identification.calibration.trajectory_data import drive_columns

    robot, model = scara
    train = [recording(robot, 12, one_way=(3,), duration=2.0, fv=[FV, FV, FV, 0.0])]
    result = identify_recordings(robot, model, train, counterbalance=False, one_way="fit")
    fit, prepared = result.fit, prepare_training(robot, train, result.options).prepared
    oracle = PinocchioOracle(robot)
    baseline = file_friction(oracle, fit, prepared)
    residual = np.concatenate([r.tau - oracle.rnea(r.q, r.qd, r.qdd) for r in prepared])
    keep, x = baseline.coefficients[3]
    names = [fit.drive_names[k] for k in keep]
    stribeck = np.asarray(fit.stribeck_velocity, dtype=float) if fit.stribeck_velocity else None
    columns = np.concatenate([drive_columns(r.qd, r.qdd, fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity,
                                            stribeck) for r in prepared])[:, 3, keep]  # fmt: skip
    free = dict(zip(names, np.linalg.lstsq(columns, residual[:, 3], rcond=None)[0]))
    found = dict(zip(names, x))
    assert free["fv4"] < -0.01  # the unbounded fit: negative viscous friction
    assert found["fv4"] == pytest.approx(0.0, abs=1e-9) and found["fc4"] == pytest.approx(FC, rel=0.05)
    for j, (keep, x) in enumerate(baseline.coefficients):
        assert all(v >= 0 for k, v in zip(keep, x) if not fit.drive_names[k].startswith("offset")), j
    tau = np.concatenate([r.tau for r in prepared])
    q, qd, qdd = (np.concatenate([getattr(r, a) for r in prepared]) for a in ("q", "qd", "qdd"))
    fitted = np.sqrt(np.mean((tau - baseline.predict(oracle, q, qd, qdd)) ** 2, axis=0))
    alone = np.sqrt(np.mean(residual**2, axis=0))
    assert np.all(fitted <= alone * (1 + 1e-9)) and np.all(fitted < 0.5 * alone)  # the friction is most of it


def test_a_joint_worse_than_the_robot_file_is_held_to_it_and_said_so(scara, one_way_case):
    """With the one-way joints' friction fitted (``--one-way-friction fit``), joint 3's Coulomb friction trades with
    its gravity load and the model is worse than the robot file (the truth) with friction fitted on the held-out
    recording (``report`` names it only: 0.25 against 0.007 N m). By default identify acts (``worse_joint_hold``): the
    worse joints' friction held at the file's fit, then the links they carry at the file's, each step kept only if
    fewer joints are worse and none new; at the end no joint is worse, joint 3 is back at the file's error, and the
    report and the model file say what was held, the steps and that the held-out recording decided it."""
    from identification.calibration.held_friction import HeldFriction

    robot, _ = scara
    _, _, run = one_way_case
    named, mended = run["fit"], run["mended"]
    assert 2 in named.file_check.worse and not named.worse_joints.decided_by_held_out
    assert "--worse-joint report" in named.worse_joints.reason
    record = mended.worse_joints
    assert record.worse == named.file_check.worse and mended.file_check.worse == () and record.left == ()
    assert record.decided_by_held_out and record.steps and record.steps[-1][2]  # the last step tried was kept
    c = mended.file_check.comparison
    assert c.after[2] < 2 * c.before[2] < named.file_check.comparison.after[2] / 5  # the file's error again
    held = list(record.held_links)
    truth = robot.nominal_dynamic_parameters()
    np.testing.assert_allclose(mended.fit.standard[held, :10], truth[held, :10], rtol=1e-9, atol=1e-12)
    text = record.describe()
    assert (
        text in mended.describe()
        and "decided this hold" in text
        and text.count("refused") == sum(not kept for _, _, kept, _ in record.steps)
    )
    stored = mended.calibrated.document["identification"]["worse_joints"]
    assert stored["worse_joints"] == [j + 1 for j in record.worse] and stored["decided_by_held_out"] is True
    assert (
        stored["held_links"] == [i + 1 for i in held]
        and mended.file_check.to_dict()["held_links"] == stored["held_links"]
    )
    kept = dict(HeldFriction.of_document(mended.calibrated.document).values)
    assert all(kept[n] == v for n, v in stored["held_friction"].items())


def test_the_baseline_is_the_robot_file_alone_where_its_friction_fit_predicts_the_held_out_motion_worse(scara):
    """Joint 4 has no friction (the robot file is the truth) and moves one way only in training, where its torque reads
    0.3 N m high (that recording's sensor bias): the robot file's friction fit on the training recording (bounded:
    friction >= 0) takes the bias as friction, which on the held-out recording, where joint 4 reverses, predicts a
    torque that is not there. The check judges joint 4 against the file alone, which is better there, and says so;
    the identified model, whose friction took the bias as well, is held to that baseline (its friction at 0)."""
    from identification.calibration.robot_file_check import file_friction

    robot, model = scara
    fc, fv = [FC, FC, FC, 0.0], [FV, FV, FV, 0.0]
    train = recording(robot, 12, one_way=(3,), duration=2.0, fv=fv, fc=fc)
    train = replace(train, tau=train.tau + np.array([0.0, 0.0, 0.0, 0.3]))
    held = [recording(robot, 13, fv=fv, fc=fc)]
    result = identify_recordings(robot, model, [train], validation=held, counterbalance=False)
    check = result.file_check
    assert check.baselines == ("friction", "friction", "friction", "alone")
    oracle = PinocchioOracle(robot)
    prepared = prepare_training(robot, [train], result.options).prepared
    keep, x = file_friction(oracle, result.fit, prepared).coefficients[3]
    assert np.all(x >= 0) and x.sum() > 0.2  # the bias taken as friction
    ready = prepare_training(robot, held, result.options).prepared[0]
    alone = np.sqrt(np.mean((ready.tau - oracle.rnea(ready.q, ready.qd, ready.qdd))[:, 3] ** 2))
    assert check.comparison.before[3] == pytest.approx(alone, rel=0.2) and alone < 3 * NOISE
    assert "on joint(s) 4 the robot file alone" in check.describe() and check.to_dict()["baselines"][3] == "alone"
    assert 3 not in check.worse and 3 in result.worse_joints.worse  # named worse first, then held
    assert dict(result.worse_joints.held_friction)["fc4"] == 0.0
    assert dict(zip(result.fit.drive_names, result.fit.drive))["fc4"] == pytest.approx(0.0, abs=1e-12)
