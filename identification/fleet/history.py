"""The fleet's history in an embedded DuckDB file: runs, sessions, parameters with sigma, errors, findings.

Only the client writes (workers return :class:`~identification.fleet.session.SessionResult` values). Each
session is written in one transaction with its parameters and validation errors, so an interrupted run leaves
whole sessions only, and the next run skips every ``(robot_id, day, content_hash)`` already stored (ok or
failed: a failed recording is retried only when its content changes). Plain SQL reads it::

    SELECT day, value, sigma FROM parameters WHERE robot_id = 'r01' AND name = 'fc3' ORDER BY day;

Tables: ``runs``, ``sessions``, ``recordings``, ``parameters``, ``validation``, ``findings``, and since schema 2
``checks`` (each robot-day's validation-error check, ``day_check``), ``diagnoses`` (what the automatic diagnosis
named on a day whose error rose unexplained), ``baselines`` (each robot's re-identifications: the model file and
the first day it judges) and ``meta`` (``schema_version``); see ``SCHEMA``. A file of schema 1 (no ``meta``) is
migrated on opening: the new tables are added, its rows stay as they are (its days show as not checked).
:meth:`History.export_parquet` writes one Parquet file per table.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path

import duckdb

from identification.fleet.session import SessionResult
from psdm_casadi.errors import ParameterError

__all__ = ["History", "ParameterRow", "SCHEMA", "SCHEMA_VERSION"]

SCHEMA_VERSION = 2

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
CREATE TABLE IF NOT EXISTS meta (key VARCHAR PRIMARY KEY, value VARCHAR);
CREATE TABLE IF NOT EXISTS checks (robot_id VARCHAR, day DATE, content_hash VARCHAR, verdict VARCHAR,
    joints VARCHAR, statistic DOUBLE, refit_statistic DOUBLE, threshold DOUBLE, since DATE, diagnosis_error VARCHAR);
CREATE TABLE IF NOT EXISTS diagnoses (robot_id VARCHAR, day DATE, content_hash VARCHAR, effect VARCHAR,
    label VARCHAR, joints VARCHAR, parameters VARCHAR, gain DOUBLE, text VARCHAR);
CREATE TABLE IF NOT EXISTS baselines (robot_id VARCHAR, since DATE, source VARCHAR, run_id INTEGER,
    created TIMESTAMP, PRIMARY KEY (robot_id, since));
"""
TABLES = ("runs", "sessions", "recordings", "parameters", "validation", "findings", "checks", "diagnoses",
          "baselines")  # fmt: skip
KEYED = ("parameters", "validation", "checks", "diagnoses")  # rows of one session, by (robot_id, day, content_hash)
# the latest session of each robot-day (a day whose recordings changed has several)
LATEST = """
SELECT robot_id, day, content_hash FROM (
    SELECT robot_id, day, content_hash, status,
           row_number() OVER (PARTITION BY robot_id, day ORDER BY written DESC) AS k FROM sessions)
WHERE k = 1 AND status = 'ok'
"""


# a robot's window: (day, content_hash) of its first ok days (from a day on, when given), the latest session of each;
# parameters robot_id, since, days (filtered by robot first: a query per robot does not rank the whole fleet's days)
WINDOW = """
SELECT day, content_hash FROM (
    SELECT day, content_hash, status,
           row_number() OVER (PARTITION BY day ORDER BY written DESC) AS k FROM sessions WHERE robot_id = ?)
WHERE k = 1 AND status = 'ok' AND day >= coalesce(CAST(? AS DATE), DATE '0001-01-01') ORDER BY day LIMIT ?
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


def _insert(con, table: str, rows: list, types: list, verb: str = "INSERT INTO") -> None:
    """Insert rows with one statement, column by column (each column one list parameter of its SQL ``types``,
    unnested): binding one parameter per value costs ~0.1 ms a row and DuckDB's executemany runs one statement
    per row."""
    if rows:
        select = ", ".join(f"unnest(?::{t}[])" for t in types)
        con.execute(f"{verb} {table} SELECT {select}", [list(column) for column in zip(*rows)])


def _column_types(con, table: str) -> list:
    """The SQL types of a table's columns, in order."""
    rows = con.execute(
        "SELECT data_type FROM information_schema.columns WHERE table_name = ? ORDER BY ordinal_position", [table]
    ).fetchall()
    return [row[0] for row in rows]


def _now() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc).replace(tzinfo=None)


def _session_row(run_id: int, result: SessionResult, now) -> tuple:
    fit = result.fit
    return (*result.task.key, run_id, result.status, result.error, None if fit is None else fit.n_samples,
            result.seconds, result.software_version, now)  # fmt: skip


def _parameter_rows(result: SessionResult) -> list:
    fit = result.fit
    if fit is None:
        return []
    return [(*result.task.key, n, int(j), float(v), float(s))
            for n, j, v, s in zip(fit.names, fit.joints, fit.values, fit.sigmas)]  # fmt: skip


def _validation_rows(result: SessionResult) -> list:
    fit = result.fit
    if fit is None:
        return []
    return [(*result.task.key, j + 1, float(b), float(r))
            for j, (b, r) in enumerate(zip(fit.rmse_baseline, fit.rmse_refit))]  # fmt: skip


def _check_rows(result: SessionResult) -> list:
    """The day's validation-error check (none for a day of the baseline window)."""
    c = result.check
    if c is None:
        return []
    return [(*result.task.key, c.verdict, ",".join(map(str, c.joints)), c.statistic, c.refit_statistic,
             c.threshold, c.since, result.diagnosis_error)]  # fmt: skip


def _diagnosis_rows(result: SessionResult) -> list:
    """What the day's diagnosis named."""
    return [(*result.task.key, f.effect, f.label, ",".join(map(str, f.joints)), json.dumps(f.parameters), f.gain,
             f.text) for f in result.diagnosis]  # fmt: skip


class History:
    """An open history database (a DuckDB file, created with its tables when new)."""

    def __init__(self, path):
        self.path = Path(path)
        self.connection = duckdb.connect(str(self.path))
        self.schema_version = self._migrate()
        self.types = {table: _column_types(self.connection, table) for table in TABLES}
        self.stored_keys: set | None = None

    def _migrate(self) -> int:
        """Create the tables (new file) or add schema 2's to a schema-1 file; refuse a newer schema."""
        con = self.connection
        tables = {row[0] for row in con.execute("SELECT table_name FROM information_schema.tables").fetchall()}
        if "meta" in tables:
            version = int(con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()[0])
            if version > SCHEMA_VERSION:
                con.close()
                raise ParameterError(
                    f"{self.path}: a fleet history of schema {version}, written by a newer psdm-casadi (this one "
                    f"reads up to {SCHEMA_VERSION}). Upgrade psdm-casadi, or pass another --db."
                )
        con.execute(SCHEMA)
        con.execute("INSERT OR REPLACE INTO meta VALUES ('schema_version', ?)", [str(SCHEMA_VERSION)])
        return SCHEMA_VERSION

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
            _insert(
                self.connection,
                "recordings",
                rows[start : start + 500],
                self.types["recordings"],
                "INSERT OR REPLACE INTO",
            )

    def write_session(self, run_id: int, result: SessionResult) -> None:
        """One session with its parameters and errors, in one transaction (:meth:`write_sessions`)."""
        self.write_sessions(run_id, [result])

    def write_sessions(self, run_id: int, results: list) -> None:
        """Sessions with their parameters, errors, checks and diagnoses, in one transaction (a session stored
        again replaces its rows). One statement per table whatever the number of sessions: a transaction's commit
        costs milliseconds, so the client writes what has finished since its last write as one batch."""
        if not results:
            return
        con = self.connection
        stored = self._stored()
        again = [list(column) for column in zip(*(r.task.key for r in results if r.task.key in stored))]
        con.execute("BEGIN TRANSACTION")
        try:
            for table in KEYED + ("sessions",) if again else ():  # a session stored again replaces its rows
                con.execute(
                    f"DELETE FROM {table} WHERE (robot_id, day, content_hash) IN "
                    "(SELECT unnest(?::VARCHAR[]), unnest(?::DATE[]), unnest(?::VARCHAR[]))",
                    again,
                )
            now = _now()
            _insert(
                con,
                "sessions",
                [_session_row(run_id, r, now) for r in results],
                self.types["sessions"],
            )
            _insert(con, "parameters", [row for r in results for row in _parameter_rows(r)], self.types["parameters"])
            _insert(con, "validation", [row for r in results for row in _validation_rows(r)], self.types["validation"])
            _insert(con, "checks", [row for r in results for row in _check_rows(r)], self.types["checks"])
            _insert(con, "diagnoses", [row for r in results for row in _diagnosis_rows(r)], self.types["diagnoses"])
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            self.stored_keys = None  # read again from the file
            raise
        stored.update(r.task.key for r in results)

    def _stored(self) -> set:
        """The keys of the stored sessions, read once and kept up to date by :meth:`write_sessions` (this
        connection is the file's only writer: DuckDB locks it): a delete scans its table, a batch of new sessions
        needs none."""
        if self.stored_keys is None:
            self.stored_keys = self.done_keys()
        return self.stored_keys

    def record_baseline(self, robot_id: str, since: str, source: str, run_id: int) -> None:
        """A robot's new baseline (a re-identification's model file) that judges the days from ``since`` on."""
        self.connection.execute("INSERT OR REPLACE INTO baselines VALUES (?, ?, ?, ?, ?)",
                                [robot_id, since, source, run_id, _now()])  # fmt: skip

    def baselines(self) -> list:
        """``(robot_id, since, source)`` of every recorded re-identification, by robot and day."""
        return self.connection.execute(
            "SELECT robot_id, since, source FROM baselines ORDER BY robot_id, since"
        ).fetchall()

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

    def window_rows(self, robot_id: str, days: int, since=None) -> list:
        """``(day, joint, rmse_baseline, rmse_refit)`` of a robot's first ``days`` ok recording days (from ``since``
        on, when given): the window its days' validation errors are judged against (``day_check``)."""
        return self.connection.execute(
            f"SELECT v.day, v.joint, v.rmse_baseline, v.rmse_refit FROM validation v JOIN ({WINDOW}) w "
            "USING (day, content_hash) WHERE v.robot_id = ? ORDER BY v.day, v.joint",
            [robot_id, since, days, robot_id],
        ).fetchall()

    def window_parameters(self, robot_id: str, days: int, since=None, prefix: str = "fc") -> list:
        """``(day, joint, value)`` of the parameters ``<prefix><joint>`` (default the Coulomb friction) on the same
        window days as :meth:`window_rows`."""
        return self.connection.execute(
            f"SELECT p.day, p.joint, p.value FROM parameters p JOIN ({WINDOW}) w USING (day, content_hash) "
            "WHERE p.robot_id = ? AND p.name = ? || CAST(p.joint AS VARCHAR) ORDER BY p.day, p.joint",
            [robot_id, since, days, robot_id, prefix],
        ).fetchall()

    def checks(self) -> list:
        """``(robot_id, day, verdict, joints, statistic, refit_statistic, threshold, diagnosis_error, since)`` of the
        latest sessions' checks (``since``: the first day of the window they were judged against), by robot and day."""
        return self.connection.execute(
            f"SELECT c.robot_id, c.day, c.verdict, c.joints, c.statistic, c.refit_statistic, c.threshold, "
            f"c.diagnosis_error, c.since FROM checks c JOIN ({LATEST}) l USING (robot_id, day, content_hash) "
            f"ORDER BY c.robot_id, c.day"
        ).fetchall()

    def diagnoses(self) -> list:
        """``(robot_id, day, effect, label, joints, parameters (dict), gain, text)`` of the latest sessions."""
        rows = self.connection.execute(
            f"SELECT d.robot_id, d.day, d.effect, d.label, d.joints, d.parameters, d.gain, d.text FROM diagnoses d "
            f"JOIN ({LATEST}) l USING (robot_id, day, content_hash) ORDER BY d.robot_id, d.day, d.gain DESC"
        ).fetchall()
        return [(*row[:5], json.loads(row[5]), *row[6:]) for row in rows]

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
