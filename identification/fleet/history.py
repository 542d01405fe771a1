"""The fleet's history in an embedded DuckDB file: runs, sessions, parameters with sigma, errors, findings.

Only the client writes (workers return :class:`~identification.fleet.session.SessionResult` values). Each
session is written in one transaction with its parameters and validation errors, so an interrupted run leaves
whole sessions only, and the next run skips every ``(robot_id, day, content_hash)`` already stored (ok or
failed: a failed recording is retried only when its content changes). Plain SQL reads it::

    SELECT day, value, sigma FROM parameters WHERE robot_id = 'r01' AND name = 'fc3' ORDER BY day;

Tables: ``runs``, ``sessions``, ``recordings``, ``parameters``, ``validation``, ``findings`` (see
``SCHEMA``); :meth:`History.export_parquet` writes one Parquet file per table.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

import duckdb

from identification.fleet.session import SessionResult

__all__ = ["History", "ParameterRow", "SCHEMA"]

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (run_id INTEGER PRIMARY KEY, started TIMESTAMP, finished TIMESTAMP, fleet VARCHAR,
    software_version VARCHAR, workers VARCHAR, planned INTEGER, processed INTEGER, failed INTEGER, skipped INTEGER,
    status VARCHAR);
CREATE TABLE IF NOT EXISTS sessions (robot_id VARCHAR, day DATE, content_hash VARCHAR, run_id INTEGER,
    status VARCHAR, error VARCHAR, n_samples INTEGER, seconds DOUBLE, software_version VARCHAR, written TIMESTAMP,
    PRIMARY KEY (robot_id, day, content_hash));
CREATE TABLE IF NOT EXISTS recordings (robot_id VARCHAR, day DATE, path VARCHAR, file_hash VARCHAR,
    duplicate_of VARCHAR, PRIMARY KEY (robot_id, day, path));
CREATE TABLE IF NOT EXISTS parameters (robot_id VARCHAR, day DATE, content_hash VARCHAR, name VARCHAR,
    joint INTEGER, value DOUBLE, sigma DOUBLE);
CREATE TABLE IF NOT EXISTS validation (robot_id VARCHAR, day DATE, content_hash VARCHAR, joint INTEGER,
    rmse_baseline DOUBLE, rmse_refit DOUBLE);
CREATE TABLE IF NOT EXISTS findings (run_id INTEGER, robot_id VARCHAR, joint INTEGER, parameter VARCHAR,
    test VARCHAR, onset DATE, size DOUBLE, size_sigma DOUBLE, relative_percent DOUBLE, z DOUBLE, text VARCHAR);
"""
TABLES = ("runs", "sessions", "recordings", "parameters", "validation", "findings")
# the latest session of each robot-day (a day whose recordings changed has several)
LATEST = """
SELECT robot_id, day, content_hash FROM (
    SELECT robot_id, day, content_hash, status,
           row_number() OVER (PARTITION BY robot_id, day ORDER BY written DESC) AS k FROM sessions)
WHERE k = 1 AND status = 'ok'
"""


@dataclass(frozen=True)
class ParameterRow:
    """One parameter of one robot-day as stored."""

    robot_id: str
    day: dt.date
    name: str
    joint: int
    value: float
    sigma: float


def _insert(con, table: str, rows: list, verb: str = "INSERT INTO") -> None:
    """Insert rows with one statement (DuckDB's executemany runs one statement per row: slow)."""
    if rows:
        values = ", ".join(["(" + ", ".join(["?"] * len(rows[0])) + ")"] * len(rows))
        con.execute(f"{verb} {table} VALUES {values}", [x for row in rows for x in row])


def _now() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc).replace(tzinfo=None)


class History:
    """An open history database (a DuckDB file, created with its tables when new)."""

    def __init__(self, path):
        self.path = Path(path)
        self.connection = duckdb.connect(str(self.path))
        self.connection.execute(SCHEMA)

    def close(self) -> None:
        self.connection.close()

    def __enter__(self) -> History:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --- runs and sessions --------------------------------------------------------------------
    def start_run(self, fleet: str, software_version: str, workers: str, planned: int) -> int:
        """A new run's id (its row says ``running`` until :meth:`finish_run`)."""
        row = self.connection.execute("SELECT coalesce(max(run_id), 0) + 1 FROM runs").fetchone()
        run_id = int(row[0])
        self.connection.execute(
            "INSERT INTO runs VALUES (?, ?, NULL, ?, ?, ?, ?, 0, 0, 0, 'running')",
            [run_id, _now(), fleet, software_version, workers, planned],
        )
        return run_id

    def finish_run(self, run_id: int, processed: int, failed: int, skipped: int, status: str = "done") -> None:
        self.connection.execute(
            "UPDATE runs SET finished = ?, processed = ?, failed = ?, skipped = ?, status = ? WHERE run_id = ?",
            [_now(), processed, failed, skipped, status, run_id],
        )

    def done_keys(self) -> set:
        """``(robot_id, day, content_hash)`` of every stored session (ok or failed)."""
        rows = self.connection.execute("SELECT robot_id, CAST(day AS VARCHAR), content_hash FROM sessions").fetchall()
        return {tuple(row) for row in rows}

    def record_recordings(self, hashes: dict, tasks, duplicates) -> None:
        """The recordings of the planned tasks and the duplicates dropped (idempotent)."""
        rows = [(t.robot_id, t.day, p, hashes[p], None) for t in tasks for p in t.paths]
        rows += [(d.robot_id, d.day, d.path, None, d.original) for d in duplicates]
        stored = set(self.connection.execute("SELECT robot_id, CAST(day AS VARCHAR), path FROM recordings").fetchall())
        rows = [row for row in rows if row[:3] not in stored]
        for start in range(0, len(rows), 500):
            _insert(self.connection, "recordings", rows[start : start + 500], "INSERT OR REPLACE INTO")

    def write_session(self, run_id: int, result: SessionResult) -> None:
        """One session with its parameters and errors, in one transaction (nothing when already stored)."""
        task, fit = result.task, result.fit
        con = self.connection
        con.execute("BEGIN TRANSACTION")
        try:
            con.execute("DELETE FROM parameters WHERE robot_id = ? AND day = ? AND content_hash = ?", list(task.key))
            con.execute("DELETE FROM validation WHERE robot_id = ? AND day = ? AND content_hash = ?", list(task.key))
            con.execute(
                "INSERT OR REPLACE INTO sessions VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [*task.key, run_id, result.status, result.error, None if fit is None else fit.n_samples,
                 result.seconds, result.software_version, _now()],
            )  # fmt: skip
            if fit is not None:
                _insert(
                    con,
                    "parameters",
                    [
                        (*task.key, n, int(j), float(v), float(s))
                        for n, j, v, s in zip(fit.names, fit.joints, fit.values, fit.sigmas)
                    ],
                )
                _insert(
                    con,
                    "validation",
                    [
                        (*task.key, j + 1, float(b), float(r))
                        for j, (b, r) in enumerate(zip(fit.rmse_baseline, fit.rmse_refit))
                    ],
                )
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise

    # --- reading ------------------------------------------------------------------------------
    def parameter_rows(self) -> list:
        """Every parameter of the latest ok session of each robot-day, by robot, name and day."""
        rows = self.connection.execute(
            f"SELECT p.robot_id, p.day, p.name, p.joint, p.value, p.sigma FROM parameters p "
            f"JOIN ({LATEST}) l USING (robot_id, day, content_hash) ORDER BY p.robot_id, p.name, p.day"
        ).fetchall()
        return [ParameterRow(*row) for row in rows]

    def validation_rows(self) -> list:
        """``(robot_id, day, joint, rmse_baseline, rmse_refit)`` of the latest ok sessions."""
        return self.connection.execute(
            f"SELECT v.robot_id, v.day, v.joint, v.rmse_baseline, v.rmse_refit FROM validation v "
            f"JOIN ({LATEST}) l USING (robot_id, day, content_hash) ORDER BY v.robot_id, v.joint, v.day"
        ).fetchall()

    def session_counts(self) -> list:
        """Per robot: ``(robot_id, ok sessions, failed sessions, last day)``."""
        return self.connection.execute(
            "SELECT robot_id, count(*) FILTER (WHERE status = 'ok'), count(*) FILTER (WHERE status = 'failed'), "
            "max(day) FROM sessions GROUP BY robot_id ORDER BY robot_id"
        ).fetchall()

    def failures(self) -> list:
        """``(robot_id, day, error)`` of the failed sessions."""
        return self.connection.execute(
            "SELECT robot_id, day, error FROM sessions WHERE status = 'failed' ORDER BY robot_id, day"
        ).fetchall()

    def replace_findings(self, run_id: int, findings) -> None:
        """The drift findings of the whole history (recomputed each run) replace the stored ones."""
        con = self.connection
        con.execute("BEGIN TRANSACTION")
        con.execute("DELETE FROM findings")
        if findings:
            con.executemany(
                "INSERT INTO findings VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [(run_id, f.robot_id, f.joint, f.parameter, f.test, f.onset, f.size, f.size_sigma,
                  f.relative_percent, f.z, f.text) for f in findings],
            )  # fmt: skip
        con.execute("COMMIT")

    def findings(self) -> list:
        return self.connection.execute(
            "SELECT robot_id, joint, parameter, test, onset, size, size_sigma, relative_percent, z, text "
            "FROM findings ORDER BY robot_id, onset"
        ).fetchall()

    def export_parquet(self, folder) -> list:
        """One ``TABLE.parquet`` per table in ``folder`` (created); returns the paths."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        paths = []
        for table in TABLES:
            path = folder / f"{table}.parquet"
            self.connection.execute(f"COPY {table} TO '{path.as_posix()}' (FORMAT PARQUET)")
            paths.append(path)
        return paths
