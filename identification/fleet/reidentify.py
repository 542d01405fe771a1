"""A robot's full re-identification (on a schedule or on demand): a new calibrated baseline from its recent days.

:func:`reidentify` is a pure task (a Dask task like a robot-day): it identifies the robot again
(``trajectory_fit.identify_trajectories``, the everyday identification: base parameters, Coulomb and viscous
friction, drive inertias, physically consistent) on the recordings of its last baseline-window days, with the
fleet's tracked terms (springs, ripples, offsets) fitted jointly and stored as the model's torque findings, and
returns the calibrated-model document. The client writes it beside the history (:func:`baseline_file`) and records
it in the history's ``baselines`` table with ``since``, the first day it judges: later days are refitted on its
rigid body, checked against its own window, and their drift tests restart there.
"""

from __future__ import annotations

import datetime as dt
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from identification.fleet.baseline import Baseline, tracked_finding_terms
from psdm_casadi.errors import PSDMError

__all__ = ["ReidentifyResult", "ReidentifyTask", "baseline_file", "next_day", "reidentify"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReidentifyTask:
    """Re-identify ``robot_id`` from the recordings ``paths`` of ``days``; the new baseline judges ``since`` on."""

    robot_id: str
    since: str
    days: tuple
    paths: tuple


@dataclass(frozen=True)
class ReidentifyResult:
    """The new calibrated model's document (None when the identification failed, with ``error``)."""

    task: ReidentifyTask
    document: dict | None
    error: str = ""
    seconds: float = field(default=0.0, compare=False)


def next_day(day) -> str:
    """The ISO date after ``day``."""
    return (dt.date.fromisoformat(str(day)) + dt.timedelta(days=1)).isoformat()


def baseline_file(db_path, robot_id: str, since: str) -> Path:
    """Where a robot's baseline from ``since`` goes: ``HISTORY_baselines/ROBOT/SINCE.json`` beside the history."""
    db_path = Path(db_path)
    return db_path.parent / f"{db_path.stem}_baselines" / robot_id / f"{since}.json"


def reidentify(task: ReidentifyTask, baseline: Baseline, model, track) -> ReidentifyResult:
    """Identify the robot again (module docstring); never raises for bad data: the error goes into the result."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.findings import FindingColumns, filled_entries
    from identification.calibration.lugre_recordings import split_findings
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
    from identification.fleet.session import load_named

    start = time.perf_counter()
    robot = baseline.robot
    try:
        recordings = load_named(task.paths, [str(path) for path in task.paths], robot)  # messages: the full path
        terms = tracked_finding_terms(track)
        columns = FindingColumns(terms) if terms else None
        fit = identify_trajectories(robot, model, recordings, TrajectoryOptions(), extra=columns)
        plain, extra = split_findings(fit, len(columns.names) if columns else 0)
        calibrated = CalibratedModel.from_fit(robot, model, plain, robot_source=baseline.robot_source,
                                              recordings=list(task.paths))  # fmt: skip
        entries = [{"effect": t.effect, "label": t.label, "kind": "torque", "joints": [t.joint + 1],
                    "term": t.to_dict()} for t in terms]  # fmt: skip
        calibrated.document["findings"] = filled_entries(entries, terms, columns, extra) if terms else []
    except (PSDMError, OSError, ValueError, np.linalg.LinAlgError) as exc:
        logger.warning("%s: re-identification from %s failed: %s", task.robot_id, task.since, exc)
        return ReidentifyResult(task, None, f"{type(exc).__name__}: {exc}", time.perf_counter() - start)
    return ReidentifyResult(task, calibrated.document, "", time.perf_counter() - start)
