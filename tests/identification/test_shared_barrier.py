"""Consistent fits of one structure sharing one barrier-path solver, their data as its parameters
(``calibration.shared_barrier``, issue 25: the column check's cost).

Reference: each fit solved on its own (the solver built with its data as constants, as every fit outside the scope
is): inside the scope the answers must be the same convex problem's, to a small share of their standard deviations,
with one solver built per structure instead of one per pass.
"""

from __future__ import annotations

import numpy as np

import identification.calibration.barrier_path as barrier_path
from identification.calibration.shared_barrier import shared_problem, shared_solvers
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment


def _recording(denso, seed, extras=()):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(denso, duration=6.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    return simulate_recording(denso, reference, options, rng, extras=list(extras))[0]


def _builds(monkeypatch) -> list:
    """One entry per Ipopt solver of the barrier path built, filled as the fits run."""
    built, solver = [], barrier_path._solver
    monkeypatch.setattr(barrier_path, "_solver", lambda *a: built.append(1) or solver(*a))
    return built


def test_fits_of_one_structure_share_one_solver_and_find_what_each_finds_alone(denso, denso_model, monkeypatch):
    recordings = [_recording(denso, seed) for seed in (3, 4)]  # two motions: other data, one structure
    options = TrajectoryOptions(friction=("fc", "fv"))
    built = _builds(monkeypatch)
    alone = [identify_trajectories(denso, denso_model, [r], options) for r in recordings]
    assert len(built) == 4  # two passes per fit, each its own solver with its data as constants
    built.clear()
    with shared_solvers():
        shared = [identify_trajectories(denso, denso_model, [r], options) for r in recordings]
    assert len(built) == 1  # both passes of both fits: one structure
    for fit, reference in zip(shared, alone):
        assert {fit.solver_status, reference.solver_status} <= {"Solve_Succeeded", "Solved_To_Acceptable_Level"}
        assert np.max(np.abs(fit.theta - reference.theta) / reference.theta_std) < 1e-3
        np.testing.assert_allclose(fit.drive, reference.drive, rtol=1e-5, atol=1e-6 * np.max(np.abs(fit.drive)))
        np.testing.assert_allclose(fit.training_r2, reference.training_r2, atol=1e-9)
    assert shared_problem({}, None, 0.0) == (None, None)  # outside the scope: nothing kept, nothing shared


def test_fits_of_other_structures_do_not_share(denso, denso_model, monkeypatch):
    """Other columns (a viscous-only friction) make other variables: their own solver, their own answer."""
    recording = _recording(denso, 3)
    built = _builds(monkeypatch)
    with shared_solvers():
        coulomb = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(friction=("fc", "fv")))
        viscous = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(friction=("fv",)))
    assert len(built) == 2 and coulomb.drive_names != viscous.drive_names
