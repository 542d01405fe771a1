"""The consistent fit solved as the convex problem it is (``calibration.barrier_path``, issue 25).

References: the unconstrained least squares where it is inside the envelope (the constraint must then cost nothing),
the virtual robot's truth, and the log-Cholesky chart solve run to convergence (the barrier path must reach its
optimum, in far fewer Ipopt iterations, where the data push links against their envelope).
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

import identification.calibration.barrier_path as barrier_path
from identification.calibration.barrier_path import log_det_barrier, pivots
from identification.calibration.identify_route import identify_recordings
from identification.calibration.pseudo_inertia import pseudo_inertia
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi import derive_psdm, load_robot
from tests.identification.diagnosis_data import scara_recording
from trajopt.experiments import sine_experiment


def _recording(denso, extras=(), seed=3, duration=8.0):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(denso, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    return simulate_recording(denso, reference, options, rng, extras=list(extras))[0]


def test_the_barrier_is_minus_log_det_inside_the_cone_and_refuses_outside(denso):
    v = ca.SX.sym("v", 10)
    barrier = ca.Function("b", [v], [log_det_barrier(v, 1e-6, 2.0)])
    steps = ca.Function("p", [v], pivots(v, 1e-6, 2.0))
    link = denso.nominal_dynamic_parameters()[2, :10]
    expected = -np.log(np.linalg.det((pseudo_inertia(link) - 1e-6 * np.eye(4)) / 2.0))
    assert float(barrier(link)) == pytest.approx(expected, rel=1e-10)
    # a centre of mass far outside the link: the pseudo-inertia has a negative eigenvalue (its determinant may be
    # positive with two), so a pivot is negative and the barrier is not a number
    outside = link.copy()
    outside[1:4] = link[0] * np.array([3.0, 3.0, 3.0])
    assert np.linalg.eigvalsh(pseudo_inertia(outside))[0] < 0
    assert min(float(p) for p in steps(outside)) < 0 and not np.isfinite(float(barrier(outside)))


def _path_statuses(monkeypatch) -> list:
    """Ipopt's status of every solve along the barrier path (both passes), filled as the fits run."""
    statuses, follow = [], barrier_path._follow_path

    class Recorded:
        def __init__(self, solver):
            self.solver = solver

        def __call__(self, **kwargs):
            out = self.solver(**kwargs)
            statuses.append(self.solver.stats()["return_status"])
            return out

        def stats(self):
            return self.solver.stats()

    monkeypatch.setattr(barrier_path, "_follow_path", lambda solver, *args: follow(Recorded(solver), *args))
    return statuses


def test_inside_the_envelope_the_consistent_fit_is_the_least_squares_one_and_near_the_truth(
    denso, denso_model, monkeypatch
):
    statuses = _path_statuses(monkeypatch)
    fit = identify_trajectories(denso, denso_model, [_recording(denso)], TrajectoryOptions(friction=()))
    # the convex path, not the chart at its cap (Maximum_Iterations_Exceeded); nothing pressed against a bound, so
    # every solve converges to Ipopt's tol (with the data term around its least squares and acceptable only after 15
    # iterations; 3 of its 8 solves stopped at Solved_To_Acceptable_Level before, at the gradient's round-off floor)
    assert statuses == ["Solve_Succeeded"] * 2 * len(barrier_path.MU_PATH), statuses
    assert fit.solver_status == "Solve_Succeeded" and fit.consistent
    assert not fit.envelope  # nothing pushed: the least squares is inside and the constraint costs nothing
    np.testing.assert_allclose(fit.training_r2, fit.training_r2_ols, atol=5e-5)  # the pull and the barrier only
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    sigma = np.maximum(fit.theta_std, 1e-3 * np.abs(truth).max())
    assert np.max(np.abs(fit.theta - truth) / sigma) < 5.0


def test_where_the_data_push_links_against_the_envelope_the_path_reaches_the_charts_optimum(
    denso, denso_model, monkeypatch
):
    """A hidden cam counterbalance on joint 2 and a payload the robot file does not hold: the data push links
    against their envelope and towards degenerate pseudo-inertias, where the chart solve creeps."""
    import identification.calibration.consistent_fit as consistent_fit

    extras = [xp.CamCounterbalance(joint=1, amplitude=12.0, lobe=0.3), xp.Payload(mass=1.5, com=(0.0, 0.0, 0.05))]
    recording = _recording(denso, extras)
    options = TrajectoryOptions(friction=())
    charted, solve = [], consistent_fit._solve
    monkeypatch.setattr(consistent_fit, "_solve", lambda *a, **k: charted.append(1) or solve(*a, **k))
    fit = identify_trajectories(denso, denso_model, [recording], options)
    assert fit.consistent and fit.envelope and not charted  # pushed against the envelope, and solved by the path
    monkeypatch.setitem(barrier_path.BARRIER_OPTIONS, "ipopt.max_iter", 0)  # no path: the chart alone
    chart = identify_trajectories(denso, denso_model, [recording], options)
    assert len(charted) == 2  # both passes
    # the convex solution explains the training data at least as well as the chart's, joint by joint
    assert np.all(np.asarray(fit.training_r2) >= np.asarray(chart.training_r2) - 1e-4)


@pytest.mark.slow
def test_the_pandas_consistent_fit_converges_and_the_stop_rule_does_not_move_it(benchmark_modules, monkeypatch):
    """The Panda's defaults (shared recording, first 70 %): every solve of the written model's path ends
    Solve_Succeeded; with the acceptable stop after 5 iterations (before), solves stop at Solved_To_Acceptable_Level,
    at the same parameters to a fiftieth of their standard deviations.

    The written model's fit is identify's columns fitted once more (``identify_trajectories`` with the route's
    options), whose solves are the ones counted there. The route also makes the column check's eight fits on three
    quarters of the training recording (``column_check``, joint 5's Stribeck shape): judges, each converged, every
    solve of their paths converged on the judges' shared solvers (``shared_barrier``), none solved again alone. One of
    them stopped at its cap at the first weight of its second pass while that pass started from the first pass's end
    (``barrier_path``: where a pass's path starts), and the chart finished it. With a path's later solves started at
    Ipopt's defaults (before ``barrier_path.WARM_OPTIONS``), shared solves at the last weight stopped in the
    restoration phase or at their cap (after the inertia floors, on four or five of the sixteen fold paths) and those
    fits were solved again with solvers of their own."""
    from real_data_diagnosis import PANDA, load_panda_real, split

    import identification.calibration.column_check as column_check
    from identification.calibration.identify_route import identify_recordings
    from psdm_casadi import derive_psdm

    if not PANDA.exists():
        pytest.skip(f"the Panda's recording ({PANDA}) is absent")
    robot, recording = load_panda_real()
    train, _ = split(recording)
    model = derive_psdm(robot)
    statuses, folds, fold_fit = _path_statuses(monkeypatch), [], column_check.identify_trajectories
    monkeypatch.setattr(
        column_check, "identify_trajectories", lambda *a, **k: folds.append(fold_fit(*a, **k)) or folds[-1]
    )
    route = identify_recordings(robot, model, [train])
    assert route.fit.solver_status == "Solve_Succeeded"
    assert [e.term for e in route.choice.departures] == ["stribeck"]  # checked by 8 fold fits, 2 passes each
    assert len(folds) == 8 and {f.solver_status for f in folds} <= {"Solve_Succeeded", "Solved_To_Acceptable_Level"}
    assert set(statuses) == {"Solve_Succeeded"}, statuses  # every solve of the route converged on its path
    assert len(statuses) == 9 * 2 * len(barrier_path.MU_PATH)  # 9 fits, 2 passes each: none solved again alone
    statuses.clear()
    again = identify_trajectories(robot, model, [train], route.options)
    assert statuses == ["Solve_Succeeded"] * 2 * len(barrier_path.MU_PATH), statuses
    assert np.array_equal(again.theta, route.fit.theta)  # the written model's fit, solve for solve
    statuses.clear()
    monkeypatch.setitem(barrier_path.BARRIER_OPTIONS, "ipopt.acceptable_iter", 5)
    before = identify_trajectories(robot, model, [train], route.options)
    assert "Solved_To_Acceptable_Level" in statuses  # what the stop rule changed
    assert np.max(np.abs(before.theta - route.fit.theta) / route.fit.theta_std) < 2e-2  # of a standard deviation


def test_torques_equal_to_round_off_give_the_same_consistent_model(monkeypatch):
    """A spring on the SCARA's joint 1 (2 N m/rad about 0.4 rad) added to the torque in two algebraically equal ways
    (the torques differ by round-off): both fits converge to the same model, every solve of their paths ending its
    weight. With the path's later solves started at Ipopt's defaults (before ``barrier_path.WARM_OPTIONS``), the last
    weight's solve stopped at its cap in one pass and in the restoration phase in the other, and the chart from the
    weight before ended at Ipopt's Infeasible_Problem_Detected in one of the two forms (a feasible problem: every
    iterate was feasible); solves of the route stopped at their cap or in the restoration phase after that too."""
    statuses = _path_statuses(monkeypatch)
    robot = load_robot("scara")
    model = derive_psdm(robot)
    offset, k, rest = np.array([0.5, 0.0, 0.0, 0.0]), 2.0, 0.4
    fits = []
    for form in range(2):
        recordings = []
        for seed in (0, 1):
            r = scara_recording(robot, seed, offset)
            if form:
                tau = r.tau + np.outer(k * (r.q[:, 0] - rest), [1, 0, 0, 0]) - offset
            else:
                tau = r.tau.copy()
                tau[:, 0] += k * (r.q[:, 0] - rest) - offset[0]
            recordings.append(replace(r, tau=tau))
        result = identify_recordings(
            robot, model, recordings[:1], validation=recordings[1:], counterbalance=False, worse_joint="report"
        )
        fits.append(result.calibrated.document)
    assert fits[0]["drive"]["names"] == fits[1]["drive"]["names"]
    assert set(statuses) <= {"Solve_Succeeded", "Solved_To_Acceptable_Level", barrier_path.STALLED}, statuses
    for block in ("base", "drive", "standard"):
        a, b = (np.asarray(fit[block]["values"], dtype=float).reshape(-1) for fit in fits)
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6 * np.abs(a).max())
    # the spring's rest torque, -k rest, is taken as joint 1's offset
    names = fits[0]["drive"]["names"]
    assert fits[0]["drive"]["values"][names.index("offset1")] == pytest.approx(-k * rest, rel=0.05)


def _stats(status, inf_du, inf_pr=0.0):
    return {"return_status": status, "iterations": {"inf_du": [1e-1, inf_du], "inf_pr": [0.0, inf_pr]}}


def test_a_solve_whose_steps_stall_at_the_round_off_floor_ends_its_weight():
    """A solve Ipopt stops at ``Search_Direction_Becomes_Too_Small`` whose last iterate is feasible and within the
    acceptable tolerance ends its weight as acceptable (the 4-joint MJCF arm with its inertia floors: the weight 1e-3's
    solve stalled at a dual infeasibility of 1e-9 against the tol 1e-10, the path stopped there and the chart, from
    the weight before, failed with Error_In_Step_Computation); one that stalls far from it, or infeasible, fails."""
    status = barrier_path.solve_status
    acceptable = barrier_path.BARRIER_OPTIONS["ipopt.acceptable_tol"]
    assert status(_stats("Solve_Succeeded", 1e-11)) == "Solve_Succeeded"
    assert status(_stats("Solved_To_Acceptable_Level", 1e-7)) == "Solved_To_Acceptable_Level"
    assert status(_stats(barrier_path.STALLED, 1e-9)) == "Solved_To_Acceptable_Level"
    assert status(_stats(barrier_path.STALLED, 10 * acceptable)) is None
    assert status(_stats(barrier_path.STALLED, 1e-9, inf_pr=1e-3)) is None
    assert status({"return_status": barrier_path.STALLED, "iterations": {}}) is None
    assert status(_stats("Restoration_Failed", 1e-9)) is None
    assert status(_stats("Maximum_Iterations_Exceeded", 1e-9)) is None
