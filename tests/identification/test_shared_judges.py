"""The judges fitted over blocks of the training recordings share one barrier-path solver per structure
(``calibration.shared_barrier``, issue 25: the never-worse gate's refits of ``psdm diagnose --apply`` and identify's
counterbalance folds).

Reference: the same judges with every fit solved on its own (the solver built with its data as constants, as every
fit outside the scope is). The verdicts must be the same (the joints over their margin, the RMSE changes equal to 4
digits), with one solver built per structure instead of two per fit, kept between the judge's turns; a fit of the
written model between those turns still builds its own.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import identification.calibration.barrier_path as barrier_path
import identification.calibration.shared_barrier as shared_barrier
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.counterbalance_folds import block_folds
from identification.calibration.finding_value import validation_rmse
from identification.calibration.refit_folds import training_refits
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment

#: Two structures: a model with Coulomb and viscous friction, and one without the Coulomb columns (other variables).
OPTIONS = {"with": TrajectoryOptions(friction=("fc", "fv")), "without": TrajectoryOptions(friction=("fv",))}


def _recording(denso, seed: int, duration: float):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(denso, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=500.0)
    return simulate_recording(denso, reference, options, rng, extras=[xp.Spring(joint=1, stiffness=20.0, q0=0.3)])[0]


def _fitter(denso, denso_model, options):
    def fit(pieces):
        result = identify_trajectories(denso, denso_model, list(pieces), options)
        assert result.solver_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        return CalibratedModel.from_fit(denso, denso_model, result, robot_source=denso.source)

    return fit


@pytest.fixture(scope="module")
def alone(denso, denso_model):
    """(training, validation, its blocks, {options: the blocks' models}): 6 s (four blocks of 1.5 s) and 4 s with
    friction and a spring on joint 2; each block's two models fitted on their own (the reference)."""
    train, validation = _recording(denso, 5, 6.0), _recording(denso, 6, 4.0)
    folds = block_folds([train])
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(shared_barrier, "shared_problem", lambda *a: (None, None))  # every fit solved on its own
        models = {o: [_fitter(denso, denso_model, OPTIONS[o])(p) for p in folds.training] for o in ("with", "without")}
    return train, validation, folds, models


def _builds(monkeypatch) -> list:
    """One entry per Ipopt solver of the barrier path built, filled as the fits run."""
    built, solver = [], barrier_path._solver
    monkeypatch.setattr(barrier_path, "_solver", lambda *a: built.append(1) or solver(*a))
    return built


def test_the_gate_s_refits_without_each_block_share_a_solver_per_structure(denso, denso_model, alone, monkeypatch):
    """``psdm diagnose --apply``'s second opinion (``refit_folds.training_refits``): 4 blocks x 2 structures, and the
    written model fitted between the gate's turns."""
    train, validation, _, models = alone
    options = {(): OPTIONS["with"], ("coulomb",): OPTIONS["without"]}

    def refit_on(pieces):
        return lambda labels: (_fitter(denso, denso_model, options[tuple(labels)])(pieces), None)

    built = _builds(monkeypatch)
    refits = training_refits([train], refit_on, ("coulomb",))
    changes = refits.changes((), denso_model, [validation])  # per block: with the Coulomb columns against without
    assert len(built) == 2  # 8 fits of two passes, two structures: one solver each (16 on their own)
    written = _fitter(denso, denso_model, OPTIONS["with"])([train])
    assert len(built) == 4 and written.consistent  # outside the scope: its own solvers
    first = refits.models.pop((frozenset(), 0))
    assert refits.model((), 0).document["drive"] == first.document["drive"]  # a solver taken again: the same answer
    assert len(built) == 4  # the judge's solvers kept between its turns
    reference = [[validation_rmse(models[o][k], denso_model, validation)[0] for o in ("without", "with")]
                 for k in range(4)]  # fmt: skip
    reference = np.array([after - before for before, after in reference])
    np.testing.assert_allclose(changes, reference, rtol=0, atol=1e-4 * np.max(np.abs(reference)))
    assert np.all(changes[:, 1] < 0)  # the data have Coulomb friction: each block's refit with it lowers joint 2


def test_the_counterbalance_s_blocks_and_refits_share_a_solver_per_structure(denso, denso_model, alone, monkeypatch):
    """identify's counterbalance judge (``counterbalance_folds.BlockFolds``): its block comparison, then its
    never-worse refits on the same blocks (``BlockFolds.refits``), one solver per structure over both."""
    _, _, folds, models = alone

    def reference(name):
        return lambda pieces: models[name][next(k for k, p in enumerate(folds.training) if p is pieces)]

    expected = replace(folds, baselines={}, solvers={}).compare(reference("without"), reference("with"), denso_model)
    built = _builds(monkeypatch)
    without, with_it = (_fitter(denso, denso_model, OPTIONS[name]) for name in ("without", "with"))
    folds = replace(folds, baselines={}, solvers={})
    together, each = folds.compare(without, with_it, denso_model)
    assert len(built) == 2  # 8 fits, two structures
    refits = folds.refits(without, with_it)  # a held-out recording's second opinion: the blocks' models again
    assert refits.model((), 0) is not refits.model(("springs",), 0)  # with the columns refitted, without taken
    assert len(built) == 2  # from the blocks' solvers: no new one
    for shared, reference_ in zip((together, *each), (expected[0], *expected[1])):
        for name in ("before", "after", "margin"):
            np.testing.assert_allclose(getattr(shared, name), getattr(reference_, name), rtol=1e-4)
        assert shared.worse == reference_.worse
    assert np.all(together.after[1:3] < together.before[1:3])  # the verdict: the Coulomb columns lower joints 2-3


class _Stopped:
    """A barrier-path solver whose every solve reports Ipopt's ``Restoration_Failed``."""

    def __init__(self, solver):
        self.solver = solver

    def __call__(self, **kwargs):
        return self.solver(**kwargs)

    def stats(self) -> dict:
        return {**self.solver.stats(), "return_status": "Restoration_Failed", "success": False}


def test_a_fold_fit_whose_shared_solver_fails_is_solved_as_alone(denso, denso_model, alone, monkeypatch):
    """A fold fit whose shared solve ends worse than alone (here every one: ``Restoration_Failed`` at the path's first
    weight, which alone would leave to the chart fallback and its other answer) is solved again with a solver of its
    own: the gate's refits of the first block, both structures, predict exactly as the fits alone."""
    train, validation, _, models = alone
    options = {(): OPTIONS["with"], ("coulomb",): OPTIONS["without"]}
    follow = barrier_path._follow_path

    def shared_fails(solver, bodies, start, bounds, margin, steps):
        return follow(_Stopped(solver) if len(steps[1]) else solver, bodies, start, bounds, margin, steps)

    monkeypatch.setattr(barrier_path, "_follow_path", shared_fails)
    built = _builds(monkeypatch)

    def refit_on(pieces):
        return lambda labels: (_fitter(denso, denso_model, options[tuple(labels)])(pieces), None)

    refits = training_refits([train], refit_on, ("coulomb",))
    for labels, name in (((), "with"), (("coulomb",), "without")):
        rmse = validation_rmse(refits.model(labels, 0), denso_model, validation)[0]
        np.testing.assert_array_equal(rmse, validation_rmse(models[name][0], denso_model, validation)[0])
    assert len(built) == 2 + 4  # per structure the shared solver, then per pass the fit's own
