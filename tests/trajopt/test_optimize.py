"""optimize_excitation on the planar 2R arm: beats random trajectories, limits hold on a 20x grid, errors are clear."""

import csv
import warnings

import numpy as np
import pytest

from psdm_casadi.errors import ExcitationWarning, ParameterError
from tests.trajopt.conftest import PLANAR_GRAVITY_MASK, planar_regressor_numpy
from trajopt.constraints import JointLimits, KeepOut, build_dh_point_function
from trajopt.criteria import condition_number, stack_regressor
from trajopt.optimize import ExcitationOptions, optimize_excitation, random_feasible_parameters

FAST = dict(duration=4.0, harmonics=3, n_samples=60, n_starts=2, quiet=True)
THETA = np.array([1.2, 0.3, 0.15, 2.0, 0.5])


def _independent_margins(traj, limits, factor=20):
    t = np.linspace(0, traj.duration, 60 * factor * 4)
    q, qd, qdd = traj.sample(t)
    ok_q = np.all((q >= limits.q_min - 1e-12) & (q <= limits.q_max + 1e-12))
    ok = ok_q and np.all(np.abs(qd) <= limits.qd_max + 1e-12) and np.all(np.abs(qdd) <= limits.qdd_max + 1e-12)
    return ok, q, qd, qdd


@pytest.fixture(scope="module")
def planar_result(planar_robot, planar_regressor):
    options = ExcitationOptions(**FAST, columns=tuple(np.flatnonzero(~PLANAR_GRAVITY_MASK)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return optimize_excitation(planar_robot, planar_regressor, options, seed=3)


def test_beats_random_feasible_trajectories(planar_result, planar_robot, planar_regressor):
    traj = planar_result
    limits = JointLimits.from_robot(planar_robot)
    rng = np.random.default_rng(0)
    grid = traj.parametrization.default_grid(60)
    conds = []
    for _ in range(30):
        x = random_feasible_parameters(traj.parametrization, limits, rng, traj.parametrization.default_grid(600), 1.0)
        conds.append(
            condition_number(stack_regressor(planar_regressor, *traj.parametrization.evaluate(grid, x), traj.columns))
        )
    assert traj.cond < min(conds) / 1.5


def test_reported_cond_is_true_cond_of_raw_columns(planar_result):
    traj = planar_result
    t = traj.parametrization.default_grid(60)
    y = planar_regressor_numpy(*traj.sample(t))[:, :, list(traj.columns)].reshape(-1, len(traj.columns))
    assert traj.cond == pytest.approx(np.linalg.cond(y), rel=1e-9)


def test_limits_hold_on_a_much_finer_grid(planar_result, planar_robot):
    ok, *_ = _independent_margins(planar_result, JointLimits.from_robot(planar_robot))
    assert ok
    assert planar_result.worst_margin >= 0
    assert len(planar_result.start_conds) == 2


def test_same_seed_same_result(planar_result, planar_robot, planar_regressor):
    options = ExcitationOptions(**FAST, columns=tuple(np.flatnonzero(~PLANAR_GRAVITY_MASK)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        again = optimize_excitation(planar_robot, planar_regressor, options, seed=3)
    np.testing.assert_allclose(again.parameters, planar_result.parameters, rtol=1e-9, atol=1e-12)


def test_to_csv_roundtrip_and_no_overwrite(planar_result, tmp_path):
    path = tmp_path / "traj.csv"
    planar_result.to_csv(path, rate=50)
    with open(path) as handle:
        rows = list(csv.reader(line for line in handle if not line.startswith("#")))
    assert rows[0] == ["t", "q1", "q2", "qd1", "qd2", "qdd1", "qdd2"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (200, 7)
    q, qd, qdd = planar_result.sample(data[:, 0])
    np.testing.assert_allclose(data[:, 1:], np.hstack([q, qd, qdd]), rtol=1e-8, atol=1e-9)
    with pytest.raises(FileExistsError, match="overwrite"):
        planar_result.to_csv(path)
    planar_result.to_csv(path, rate=10, periods=2, overwrite=True)
    assert sum(1 for line in open(path) if not line.startswith(("#", "t"))) == 80


def test_torque_limits_hold(planar_robot, planar_regressor):
    limits = JointLimits(q_min=[-2, -2.5], q_max=[2, 2.5], qd_max=[2, 3], qdd_max=[6, 8], tau_max=[30.0, 6.0])
    options = ExcitationOptions(**{**FAST, "n_starts": 1}, limits=limits, torque_limits=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        traj = optimize_excitation(planar_robot, planar_regressor, options, nominal_parameters=THETA, seed=1)
    t = np.linspace(0, traj.duration, 4000)
    tau = planar_regressor_numpy(*traj.sample(t)) @ THETA
    assert np.all(np.abs(tau) <= limits.tau_max + 1e-9)
    assert np.abs(tau[:, 1]).max() > 0.5 * 6.0  # the limit matters: the optimum uses it


def test_keep_out_plane_holds(planar_robot, planar_regressor):
    fk = build_dh_point_function(planar_robot)
    floor = KeepOut(fk, normal=(0, 1, 0), offset=-0.3)  # the tip stays above y = -0.3
    options = ExcitationOptions(**{**FAST, "n_starts": 1})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        traj = optimize_excitation(planar_robot, planar_regressor, options, keep_out=floor, seed=2)
    q, _, _ = traj.sample(np.linspace(0, traj.duration, 4000))
    y = 0.5 * np.sin(q[:, 0]) + 0.4 * np.sin(q.sum(axis=1))
    assert y.min() >= -0.3 - 1e-9


def test_rest_to_rest(planar_robot, planar_regressor):
    options = ExcitationOptions(**{**FAST, "n_starts": 1}, rest_to_rest=True, criterion="logdet")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        traj = optimize_excitation(planar_robot, planar_regressor, options, seed=0)
    _, qd, qdd = traj.sample([0.0, traj.duration])
    np.testing.assert_allclose(qd, 0, atol=1e-7)
    np.testing.assert_allclose(qdd, 0, atol=1e-6)


def test_sum_of_sines_family_respects_limits(planar_robot, planar_regressor):
    options = ExcitationOptions(
        family="sum_of_sines",
        duration=4.0,
        n_terms=2,
        n_samples=40,
        n_starts=1,
        max_iter=15,
        sharpness=(8.0,),
        quiet=True,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        traj = optimize_excitation(planar_robot, planar_regressor, options, seed=0)
    ok, *_ = _independent_margins(traj, JointLimits.from_robot(planar_robot))
    assert ok and np.isfinite(traj.cond)


def test_zero_velocity_limit_is_a_clear_error(planar_robot, planar_regressor):
    with pytest.raises(ParameterError, match="qd_max"):
        limits = JointLimits(q_min=[-1, -1], q_max=[1, 1], qd_max=[0.0, 1.0], qdd_max=[1, 1])
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(limits=limits))


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(family="spline"), "family"),
        (dict(criterion="aopt"), "criterion"),
        (dict(n_starts=0), "n_starts"),
        (dict(duration=-1.0), "duration"),
        (dict(sharpness=()), "sharpness"),
        (dict(start_fill=2.0), "start_fill"),
    ],
)
def test_option_errors(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        ExcitationOptions(**kwargs)


def test_input_errors(planar_robot, planar_regressor):
    with pytest.raises(ParameterError, match="regressor"):
        optimize_excitation(planar_robot, lambda q: q)
    with pytest.raises(ParameterError, match="nominal_parameters"):
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(torque_limits=True, quiet=True))
    with pytest.raises(ParameterError, match="columns"):
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(columns=(9,), quiet=True))
    with pytest.raises(ParameterError, match="limit_backoff"):
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(limit_backoff=0.7, quiet=True))


def test_unreachable_torque_limit_is_a_clear_error(planar_robot, planar_regressor):
    # the arm cannot leave the horizontal region, where gravity alone exceeds the torque limit
    limits = JointLimits(q_min=[-0.5, -0.5], q_max=[0.5, 0.5], qd_max=[2, 3], qdd_max=[6, 8], tau_max=[0.01, 0.01])
    options = ExcitationOptions(**FAST, limits=limits, torque_limits=True)
    with pytest.raises(ParameterError, match="tau_max"):
        optimize_excitation(planar_robot, planar_regressor, options, nominal_parameters=THETA)


def test_unidentifiable_columns_are_a_clear_error(planar_robot, planar_regressor):
    import casadi as ca

    q, qd, qdd = (ca.SX.sym(n, 2) for n in ("q", "qd", "qdd"))
    y = ca.horzcat(planar_regressor(q, qd, qdd), ca.SX.zeros(2, 1))  # a sixth column that is always zero
    padded = ca.Function("regressor", [q, qd, qdd], [y])
    options = ExcitationOptions(**{**FAST, "n_starts": 1}, criterion="logdet", max_iter=5, columns=(0, 1, 5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        with pytest.raises(ParameterError, match="columns"):
            optimize_excitation(planar_robot, padded, options)


def test_limit_scale_error():
    with pytest.raises(ParameterError, match="limit_scale"):
        ExcitationOptions(limit_scale=0.0)


def test_time_limit_stops_ipopt_and_keeps_a_verified_iterate(planar_robot, planar_regressor):
    options = ExcitationOptions(
        family="sum_of_sines", duration=4.0, n_samples=40, n_starts=3, max_iter=100000, time_limit=0.3, quiet=True
    )
    with pytest.warns(ExcitationWarning, match="User_Requested_Stop"):
        traj = optimize_excitation(planar_robot, planar_regressor, options, seed=0)
    assert traj.status == "User_Requested_Stop" and len(traj.start_conds) == 1
    ok, *_ = _independent_margins(traj, JointLimits.from_robot(planar_robot))
    assert ok


def test_keep_out_of_another_robot_is_a_shape_error(planar_robot, planar_regressor):
    import casadi as ca

    from psdm_casadi.errors import ShapeError

    q = ca.SX.sym("q", 3)
    other = KeepOut(ca.Function("tool_point", [q], [q]), normal=(0, 0, 1))
    with pytest.raises(ShapeError, match="KeepOut.point"):
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(**FAST), keep_out=other)


def test_with_the_derived_psdm_regressor(planar_robot):
    derive = pytest.importorskip("psdm_casadi.derive")
    symbolic = pytest.importorskip("psdm_casadi.symbolic")
    model = derive.derive_psdm(planar_robot, seed=0)
    regressor = symbolic.build_functions(model).regressor
    options = ExcitationOptions(**FAST, columns=tuple(np.flatnonzero(~model.gravity_mask)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        traj = optimize_excitation(planar_robot, regressor, options, seed=0)
    t = traj.parametrization.default_grid(60)
    y = model.regressor(*traj.sample(t))[:, :, list(traj.columns)].reshape(-1, len(traj.columns))
    assert traj.cond == pytest.approx(np.linalg.cond(y), rel=1e-9)
    assert traj.worst_margin >= 0


def test_progress_goes_to_the_module_logger_and_quiet_silences_it(planar_robot, planar_regressor, caplog):
    base = dict(FAST, n_starts=1, max_iter=5, sharpness=(8.0,))
    with warnings.catch_warnings(), caplog.at_level("INFO", logger="trajopt.optimize"):
        warnings.simplefilter("ignore", ExcitationWarning)
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(**{**base, "quiet": False}), seed=0)
        loud = [r for r in caplog.records if r.name == "trajopt.optimize"]
        caplog.clear()
        optimize_excitation(planar_robot, planar_regressor, ExcitationOptions(**base), seed=0)
        quiet = [r for r in caplog.records if r.name == "trajopt.optimize"]
    assert loud and all(r.levelname == "INFO" and r.getMessage().startswith("excite: ") for r in loud)
    assert quiet == []
    # the line that ends a start carries (done, total) for the command line's progress bar
    assert [r.progress for r in loud if hasattr(r, "progress")] == [(1, 1)]


def test_each_start_shows_its_ipopt_iterations_on_a_terminal(planar_robot, planar_regressor):
    import logging

    from tests.psdm_casadi.progress_terminal import FakeTerminal, install_counting_handler

    parent = logging.getLogger("trajopt")
    saved = (parent.handlers[:], parent.level, parent.propagate)
    try:
        handler = install_counting_handler(FakeTerminal())
        options = ExcitationOptions(**{**FAST, "n_starts": 1, "max_iter": 5, "sharpness": (8.0,)})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            optimize_excitation(planar_robot, planar_regressor, options, seed=0)
    finally:
        parent.handlers[:], parent.level, parent.propagate = saved
        logging.getLogger("identification").handlers[:] = []
    assert "excite: start 1" in handler.stream.getvalue() and "(Ipopt)" in handler.stream.getvalue()
    assert [c for c in handler.counts if c][:5] == [1, 2, 3, 4, 5] and handler._inner is None  # of max_iter 5
