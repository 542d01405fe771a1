"""The fits of identify's counterbalance and payload trials, each made once per distinct input within a run.

``psdm identify`` carries each fit its holds try (the one-way friction, the worse joints' friction and links) through
the counterbalance and payload routes (``written_model``), and each route fits the training recordings with and
without springs, whole and on the blocks of their cross-validation. Many of those fits have the same input: the cubic
spring fitted for the odd law's information criterion (``counterbalance_column.counterbalance_laws``) is the cubic
shape the trial then judges; the blocks' models without springs of the counterbalance trial are the payload trial's
models without the payload where no spring was kept. Inside a ``state_cache.remembering`` block (identify's run)
:func:`trial_fit` makes each once (``state_cache.BlockMemory``), keyed by what the fit depends on: the robot
description and its derived model, the recordings' arrays and names, the options, the extra columns, the recordings'
loads, and whether a judge's shared solvers are open (``shared_barrier.sharing``: a shared solve's round-off differs
from a solve of its own), so that the model identify writes is the same bit for bit. Outside such a block every fit is
made anew.
"""

from __future__ import annotations

from identification.calibration.lugre_trial import fit_key
from identification.calibration.shared_barrier import sharing
from identification.calibration.trajectory_fit import identify_trajectories
from psdm_casadi.state_cache import BlockMemory

__all__ = ["trial_fit", "trial_fit_key"]

#: The trials' fits of the open ``remembering`` block, by :func:`trial_fit_key`, each with the derived model it used.
_FITS = BlockMemory(max_entries=64)


def trial_fit_key(robot, recordings, options, extra=None, configurations=None) -> tuple | None:
    """What ``identify_trajectories(robot, model, recordings, options, extra, configurations)`` depends on besides the
    derived model (``lugre_trial.fit_key``: the robot description, the recordings' arrays and names, the options, the
    loads; the extra columns; whether shared solvers are open), or None where the extra columns refer to a torque
    function (load-dependent terms: no content to key on)."""
    if extra is not None and getattr(extra, "reference", None) is not None:
        return None
    return (*fit_key(robot, recordings, options, configurations), repr(extra), sharing())


def trial_fit(robot, model, recordings, options=None, extra=None, configurations=None):
    """``identify_trajectories(robot, model, recordings, options, extra, configurations)``, made once per distinct
    input in a ``remembering`` block (module docstring)."""
    recordings = list(recordings)

    def fit() -> tuple:
        return model, identify_trajectories(robot, model, recordings, options, extra, configurations)

    key = trial_fit_key(robot, recordings, options, extra, configurations)
    if key is None:
        return fit()[1]
    fitted, found = _FITS.get(key, fit)
    if fitted is not model:  # another derivation of the robot: fitted again
        fitted, found = fit()
    return found
