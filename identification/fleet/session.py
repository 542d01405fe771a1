"""One robot-day as a pure function: read the day's recordings, refit, return a result (the Dask task).

:func:`process_session` takes a :class:`SessionTask` (the robot, the day, the recording paths and their content
hash), the robot's :class:`~identification.fleet.baseline.Baseline` and its PSDM model, and returns a
:class:`SessionResult`; it writes nothing. A recording that does not read or does not pass the checks of the
identification (``trajectory_data.prepare_recordings``: the robot's joint count, plausible units, every joint
moving) fails its own session: the result holds the error text and ``status = "failed"``, and the fleet goes on.
The recordings are named ``ROBOT/DAY/FILE`` (``load_named``), so each message names the robot and the day.

Given the robot's :class:`~identification.fleet.day_check.ErrorReference` (its baseline window's validation
errors; the client passes it for the days after the window), the task also checks whether the day's error rose
(``day_check``) and, when the refit does not explain the rise, runs the diagnosis on the day's recordings in the
same task (``day_diagnosis``); its findings, or its error, come back in the result. An unexplained rise on joints
whose refitted Coulomb friction left the window's is named friction drift (``day_check.friction_changes``): a day
whose every unexplained joint drifted is ``friction_drift`` and not diagnosed further.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np

from identification.calibration.trajectory_data import prepare_recordings
from identification.data.io import load_recording
from identification.fleet.baseline import Baseline
from identification.fleet.day_check import DayCheck, ErrorReference, FrictionChange, check_day, friction_changes
from identification.fleet.day_diagnosis import DayFinding
from identification.fleet.update import DayFit, refit_day
from psdm_casadi.errors import PSDMError, RecordingError

__all__ = [
    "SessionResult",
    "SessionTask",
    "day_message",
    "load_named",
    "process_session",
    "read_session",
    "software_version",
]

logger = logging.getLogger(__name__)


@functools.cache
def software_version() -> str:
    """The installed psdm-casadi version (``unknown`` when it is not installed); read once per process (the
    package metadata lookup costs ~1 ms, a few % of a robot-day task)."""
    try:
        return metadata.version("psdm-casadi")
    except metadata.PackageNotFoundError:
        return "unknown"


@dataclass(frozen=True)
class SessionTask:
    """A robot-day to process: ``paths`` are its distinct recordings, ``content_hash`` their joint sha256."""

    robot_id: str
    day: str
    paths: tuple
    content_hash: str

    @property
    def key(self) -> tuple:
        return (self.robot_id, self.day, self.content_hash)


@dataclass(frozen=True)
class SessionResult:
    """The outcome of a robot-day: the fit (None when it failed) or the error, with provenance.

    Attributes
    ----------
    task : SessionTask
    status : {"ok", "failed"}
    fit : DayFit or None
    error : str
        The error's one-line text for a failed session, else empty.
    seconds : float
        Wall time of the task [s] (not part of the result's identity).
    software_version : str
    check : DayCheck or None
        The validation-error check (None without a reference: a baseline-window day).
    diagnosis : tuple of DayFinding
        The friction drifts named on a day whose rise the refit does not explain, then what the diagnosis named on
        an ``unexplained`` day (empty when it found nothing or did not run).
    diagnosis_error : str
        Why the diagnosis could not run on the day (its error text), else empty.
    """

    task: SessionTask
    status: str
    fit: DayFit | None
    error: str = ""
    seconds: float = field(default=0.0, compare=False)
    software_version: str = ""
    check: DayCheck | None = None
    diagnosis: tuple = ()
    diagnosis_error: str = ""


def read_session(task: SessionTask, baseline: Baseline) -> tuple:
    """(prepared recordings, currents?) of a task; all of one kind (joint torques, else currents)."""
    robot = baseline.robot
    recordings = load_named(task.paths, [f"{task.robot_id}/{task.day}/{Path(p).name}" for p in task.paths], robot)
    currents = all(rec.tau is None for rec in recordings)
    if not currents and any(rec.tau is None for rec in recordings):
        raise RecordingError(
            f"{task.robot_id} {task.day}: some recordings hold joint torques and some only currents; record one kind "
            "per day or split the day."
        )
    kt = np.ones(robot.n_dof) if currents else None  # currents stay in amperes: kt is refitted
    # the torque-scale check compares joint torques: the currents times the robot file's kt, which the refit starts from
    # (none in the file: the current's scale is not judged)
    constants = None if not currents else baseline.kt if robot.drives else np.full(robot.n_dof, np.nan)
    _, _, prepared = prepare_recordings(robot, recordings, kt, torque_constants=constants)
    return prepared, currents


def load_named(paths, names, robot) -> list:
    """The recordings at ``paths`` named ``names`` (``ROBOT/DAY/FILE``): every day of a fleet holds a ``health.csv``,
    so every message about one (a refusal, a warning) names the robot and the day; one that cannot be read is
    refused under its name too."""
    out = []
    for path, name in zip(paths, names):
        try:
            recording = load_recording(path, robot.n_dof, robot.joint_names)
        except RecordingError as exc:
            raise RecordingError(f"{name}: {str(exc).removeprefix(f'{Path(path).name}: ')}") from exc
        out.append(dataclasses.replace(recording, name=name))
    return out


def day_message(task: SessionTask, text: str) -> str:
    """``text`` about ``task``'s day naming its robot and day once: as it is when it already names them (a recording
    ``ROBOT/DAY/FILE``, the session's own refusals ``ROBOT DAY: ...``), else after ``ROBOT DAY: ``."""
    if any(f"{task.robot_id}{sep}{task.day}" in text for sep in ("/", " ")):
        return text
    return f"{task.robot_id} {task.day}: {text}"


def _diagnosis(task, baseline, model, prepared, currents, fit) -> tuple:
    """(findings, error text) of the day's diagnosis; a diagnosis that cannot run does not fail the session."""
    from identification.fleet.day_diagnosis import diagnose_day

    try:
        return diagnose_day(baseline, model, prepared, currents, fit), ""
    except (PSDMError, ValueError, np.linalg.LinAlgError) as exc:
        logger.warning("%s", day_message(task, f"the diagnosis did not run: {exc}"))
        return (), f"{type(exc).__name__}: {exc}"


def process_session(task: SessionTask, baseline: Baseline, model, reference: ErrorReference | None = None):
    """Refit one robot-day and, given the robot's ``reference``, check its validation error and diagnose an
    unexplained rise (module docstring); never raises for bad data: the error goes into the result."""
    start = time.perf_counter()
    version = software_version()
    try:
        prepared, currents = read_session(task, baseline)
        fit = refit_day(baseline, model, prepared, currents)
    except (PSDMError, OSError, ValueError, np.linalg.LinAlgError) as exc:
        logger.warning("%s", day_message(task, f"failed: {exc}"))
        error = f"{type(exc).__name__}: {exc}"
        return SessionResult(task, "failed", None, error, time.perf_counter() - start, version)
    check, findings, error = None, (), ""
    if reference is not None:
        check = check_day(reference, fit.rmse_baseline, fit.rmse_refit)
        drift = ()
        if check.verdict == "unexplained":
            drift = friction_changes(reference, fit.names, fit.values, check.joints)
            if {c.joint for c in drift} == set(check.joints):  # every unexplained joint's friction moved
                check = dataclasses.replace(check, verdict="friction_drift")
        if check.verdict == "unexplained" and reference.options.diagnose:
            findings, error = _diagnosis(task, baseline, model, prepared, currents, fit)
        findings = tuple(_friction_finding(c, fit) for c in drift) + tuple(findings)
    return SessionResult(task, "ok", fit, "", time.perf_counter() - start, version, check, findings, error)


def _friction_finding(change: FrictionChange, fit: DayFit) -> DayFinding:
    """A friction drift as a finding of the day (its gain: the part of the baseline's error the refit removes)."""
    j = change.joint - 1
    gain = 1.0 - float(fit.rmse_refit[j]) / max(float(fit.rmse_baseline[j]), 1e-300)
    parameters = {"relative_change_percent": change.relative_percent, "z": change.z}
    return DayFinding("friction_drift", "Coulomb friction drift", (change.joint,), parameters, max(gain, 0.0),
                      change.text)  # fmt: skip
