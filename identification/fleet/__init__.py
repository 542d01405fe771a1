"""Many robots over time: daily refits as Dask tasks, a DuckDB history, drift and wear tests, a report.

``layout`` (a fleet folder or manifest) -> ``plan`` (one task per robot-day, by content hash) -> ``session``
(the pure task: read, ``update`` refit with the ``baseline`` rigid body held, rows ``streamed`` into QR factors;
``day_check`` of the validation error against the robot's window, ``day_diagnosis`` of an unexplained rise) ->
``schedule`` (per robot: window days, later days, ``reidentify``) -> ``runner`` (Dask, the client writes
``history`` and each ``day_report``) -> ``drift`` (shift and CUSUM tests with ``phrases``) -> ``report`` (HTML).
It composes the readers, the calibration's columns, least squares and identification, and the diagnosis; it
copies none of them.
"""

from identification.fleet.day_check import CheckOptions, DayCheck
from identification.fleet.day_diagnosis import DayFinding
from identification.fleet.drift import DriftFinding, DriftOptions, detect_drift
from identification.fleet.history import History
from identification.fleet.layout import Fleet, FleetLayoutError, read_fleet
from identification.fleet.runner import RunOptions, RunSummary, dask_client, run_fleet
from identification.fleet.session import SessionResult, SessionTask, process_session

__all__ = [
    "CheckOptions",
    "DayCheck",
    "DayFinding",
    "DriftFinding",
    "DriftOptions",
    "Fleet",
    "FleetLayoutError",
    "History",
    "RunOptions",
    "RunSummary",
    "SessionResult",
    "SessionTask",
    "dask_client",
    "detect_drift",
    "process_session",
    "read_fleet",
    "run_fleet",
]
