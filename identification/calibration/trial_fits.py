"""The fits of identify's counterbalance and payload trials, each made once per distinct input within a run.

``psdm identify`` carries each fit its holds try (the one-way friction, the worse joints' friction and links) through
the counterbalance and payload routes (``written_model``), and each route fits the training recordings with and
without springs, whole and on the blocks of their cross-validation. Many of those fits have the same input: the cubic
spring fitted for the odd law's information criterion (``counterbalance_column.counterbalance_laws``) is the cubic
shape the trial then judges; the blocks' models without springs of the counterbalance trial are the payload trial's
models without the payload where no spring was kept. Inside a ``state_cache.remembering`` block (identify's run)
:func:`trial_fit` makes each once (``state_cache.BlockMemory``), keyed by what the fit depends on: the robot
description, the recordings' arrays and names, the options, the extra columns, the recordings' loads, and whether a
judge's shared solvers are open (``shared_barrier.sharing``: a shared solve's round-off differs from a solve of its
own), with the derived model kept beside the fit and compared (``BlockMemory.get_with``: an equal model fits the same),
so that the model identify writes is the same bit for bit. Outside such a block every fit is made anew. The LuGre
trial's fits (``lugre_trial``) are remembered by the same :func:`fit_key`.
"""

from __future__ import annotations

import numpy as np

from identification.calibration.shared_barrier import sharing
from identification.calibration.trajectory_fit import identify_trajectories
from psdm_casadi.state_cache import BlockMemory, StateCache

__all__ = ["fit_key", "trial_fit", "trial_fit_key"]

#: The trials' fits of the open ``remembering`` block, by :func:`trial_fit_key`, each with the derived model it used.
_FITS = BlockMemory(max_entries=64)


def fit_key(robot, recordings, options, configurations) -> tuple:
    """What a fit of the training recordings depends on besides the derived model and its own inputs (the extra
    columns here, the LuGre joints and start of ``lugre_trial``'s): the robot description (``model_key``), the
    training recordings (a digest of their arrays, their names and missing joints), the options chosen and the loads
    the recordings carry."""
    from psdm_casadi.model_cache import model_key

    arrays = [[getattr(r, f) for f in ("t", "q", "tau", "current", "qd", "qdd", "temperature")] for r in recordings]
    digests = tuple(StateCache.key(*[np.asarray(a) for a in group if a is not None]) for group in arrays)
    named = tuple((r.name, r.missing_torque) for r in recordings)
    return model_key(robot), digests, named, repr(options), repr(configurations)


def trial_fit_key(robot, recordings, options, extra=None, configurations=None) -> tuple | None:
    """What ``identify_trajectories(robot, model, recordings, options, extra, configurations)`` depends on besides the
    derived model (:func:`fit_key`: the robot description, the recordings' arrays and names, the options, the
    loads; the extra columns; whether shared solvers are open), or None where the extra columns refer to a torque
    function (load-dependent terms: no content to key on)."""
    if extra is not None and getattr(extra, "reference", None) is not None:
        return None
    return (*fit_key(robot, recordings, options, configurations), repr(extra), sharing())


def trial_fit(robot, model, recordings, options=None, extra=None, configurations=None):
    """``identify_trajectories(robot, model, recordings, options, extra, configurations)``, made once per distinct
    input in a ``remembering`` block (module docstring)."""
    recordings = list(recordings)

    def fit():
        return identify_trajectories(robot, model, recordings, options, extra, configurations)

    key = trial_fit_key(robot, recordings, options, extra, configurations)
    return fit() if key is None else _FITS.get_with(key, model, fit)  # another derivation of the robot: fitted again
