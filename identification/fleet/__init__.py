"""Many robots over time: daily refits as Dask tasks, a DuckDB history, drift and wear tests, a report.

``layout`` (a fleet folder or manifest) -> ``plan`` (one task per robot-day, by content hash) -> ``session``
(the pure task: read, ``update`` refit with the ``baseline`` rigid body held, rows ``streamed`` into QR factors;
``day_check`` of the validation error against the robot's window, ``day_diagnosis`` of an unexplained rise) ->
``schedule`` (per robot: window days, later days, ``reidentify``) -> ``runner`` (Dask, the client writes
``history`` and each ``day_report``) -> ``drift`` (shift and CUSUM tests with ``phrases``) -> ``report`` (HTML).
It composes the readers, the calibration's columns, least squares and identification, and the diagnosis; it
copies none of them.
"""

import importlib

#: each name's module, imported on first use (PEP 562): a Dask worker imports ``session`` alone, not the history
#: (DuckDB), the runner (Dask's client) or the report
_NAMES = {
    "CheckOptions": "day_check",
    "DayCheck": "day_check",
    "DayFinding": "day_diagnosis",
    "DriftFinding": "drift",
    "DriftOptions": "drift",
    "detect_drift": "drift",
    "History": "history",
    "Fleet": "layout",
    "FleetLayoutError": "layout",
    "read_fleet": "layout",
    "RunOptions": "runner",
    "RunSummary": "runner",
    "dask_client": "runner",
    "run_fleet": "runner",
    "SessionResult": "session",
    "SessionTask": "session",
    "process_session": "session",
}

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


def __getattr__(name: str):
    if name in _NAMES:
        return getattr(importlib.import_module(f"identification.fleet.{_NAMES[name]}"), name)
    raise AttributeError(f"module 'identification.fleet' has no attribute {name!r}")


def __dir__() -> list:
    return sorted(list(globals()) + __all__)
