"""The counterbalance and payload trials' fits made once per distinct input within identify's run (``trial_fits``).

Reference: the fit made anew. The memory hands back the fit ``identify_trajectories`` makes for the same input; a
fit of another input (other recordings, options, extra columns, loads, derived model, or a shared solver open) is made
again, and outside a ``remembering`` block every fit is. ``identify_trajectories`` is counted here with a stand-in
returning a fresh object per call (so a fit handed back from memory is the very object made first); the written model
identify makes with the memory is compared bit for bit with the one made without it by the benchmarks (the commit's
figures), not here: a full identify with the trials open costs minutes.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration import trial_fits
from identification.calibration.shared_barrier import shared_solvers
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.data.recording import Recording
from psdm_casadi.robot import load_robot
from psdm_casadi.state_cache import remembering
from tests.conftest import DENSO_FILE


@pytest.fixture
def counted(monkeypatch):
    """The calls made to ``identify_trajectories`` (its inputs), each answered with a new object."""
    calls = []

    def fake(robot, model, recordings, options=None, extra=None, configurations=None):
        calls.append((robot.name, len(recordings), options, extra, configurations))
        return SimpleNamespace(call=len(calls))

    monkeypatch.setattr(trial_fits, "identify_trajectories", fake)
    return calls


def _recording(seed: int) -> Recording:
    rng = np.random.default_rng(seed)
    t = np.arange(200) * 0.01
    q = rng.normal(size=(200, 6))
    return Recording(t=t, q=q, tau=rng.normal(size=(200, 6)), name="run.csv")


def test_the_same_input_is_fitted_once_in_a_run_and_anew_outside(counted):
    robot, model = load_robot(DENSO_FILE), object()
    data, options = [_recording(0)], TrajectoryOptions()
    with remembering():
        first = trial_fits.trial_fit(robot, model, data, options)
        again = trial_fits.trial_fit(robot, model, [_recording(0)], TrajectoryOptions())  # equal, not the same objects
        assert again is first and len(counted) == 1
    after = trial_fits.trial_fit(robot, model, data, options)  # the block ended: the memory is empty
    assert after is not first and len(counted) == 2
    assert trial_fits.trial_fit(robot, model, data, options) is not after and len(counted) == 3  # none outside


def test_any_other_input_is_fitted_again(counted):
    robot, model = load_robot(DENSO_FILE), object()
    data, options = [_recording(0)], TrajectoryOptions()
    spring = SimpleNamespace(reference=None, terms=("spring",))
    with remembering():
        base = trial_fits.trial_fit(robot, model, data, options)
        others = [
            trial_fits.trial_fit(robot, model, [_recording(1)], options),  # other recordings
            trial_fits.trial_fit(robot, model, data, replace(options, held_links=(1,))),  # other options
            trial_fits.trial_fit(robot, model, data, options, extra=spring),  # extra columns
            trial_fits.trial_fit(robot, model, data, options, configurations=("loaded",)),  # loads
            trial_fits.trial_fit(robot, object(), data, options),  # another derived model
            trial_fits.trial_fit(replace(robot, name="other"), model, data, options),  # another robot description
        ]
        with shared_solvers():  # a judge's shared solver: its round-off differs from a solve of its own
            others.append(trial_fits.trial_fit(robot, model, data, options))
        assert len(counted) == 1 + len(others) and all(o is not base for o in others)
        assert trial_fits.trial_fit(robot, model, data, options) is base  # the first input is still remembered


def test_columns_that_refer_to_a_torque_function_are_not_remembered(counted):
    robot, model, data = load_robot(DENSO_FILE), object(), [_recording(0)]
    load_dependent = SimpleNamespace(reference=lambda q, qd, qdd: q, terms=("load_dependent_friction",))
    assert trial_fits.trial_fit_key(robot, data, TrajectoryOptions(), load_dependent) is None
    with remembering():
        a = trial_fits.trial_fit(robot, model, data, TrajectoryOptions(), load_dependent)
        b = trial_fits.trial_fit(robot, model, data, TrajectoryOptions(), load_dependent)
    assert a is not b and len(counted) == 2
