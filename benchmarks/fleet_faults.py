"""Fault cases of the fleet benchmark (``fleet.py``): a killed worker, an interrupted run resumed, a corrupt
recording, the same recording under two names. Each runs on a copy of the first days of a few robots of the
benchmark's fleet (the bookkeeping under test, without the day pages and the diagnosis) and is compared with a
serial run of the clean copy: every key says what was lost (robot-days missing) and what was counted twice (a
robot-day or a recording stored more than once), and how far the parameters are from the reference."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from identification.fleet.day_check import CheckOptions
from identification.fleet.history import History
from identification.fleet.layout import read_fleet
from identification.fleet.runner import RunOptions, dask_client, run_fleet

QUIET = CheckOptions(diagnose=False)


def _copy(fleet_folder: Path, out: Path, robots: int, days: int = 10) -> Path:
    """The first ``days`` recording days of the first ``robots`` robots of a fleet folder, with its settings."""
    out.mkdir(parents=True)
    shutil.copy(fleet_folder / "fleet.toml", out)
    for robot in sorted(p for p in fleet_folder.iterdir() if p.is_dir())[:robots]:
        (out / robot.name).mkdir()
        shutil.copy(robot / "robot.toml", out / robot.name)
        for day in sorted(p for p in robot.iterdir() if p.is_dir())[:days]:
            shutil.copytree(day, out / robot.name / day.name)
    return out


def _stored(db: Path) -> dict:
    """Sessions, distinct robot-days, ok and failed sessions, and the latest parameters of a history."""
    with History(db) as history:
        con = history.connection
        sessions, days = con.execute("SELECT count(*), count(DISTINCT (robot_id, day)) FROM sessions").fetchone()
        failed = con.execute("SELECT count(*) FROM sessions WHERE status = 'failed'").fetchone()[0]
        rows = con.execute("SELECT count(*), count(DISTINCT (robot_id, day, content_hash, name)) FROM parameters")
        n_rows, distinct_rows = rows.fetchone()
        parameters = {(r.robot_id, str(r.day), r.name): r.value for r in history.parameter_rows()}
    return {"sessions": sessions, "days": days, "failed": failed, "parameter_rows": n_rows,
            "distinct_parameter_rows": distinct_rows, "parameters": parameters}  # fmt: skip


def _verdict(stored: dict, reference: dict, expected_days: int, expected_failed: int = 0) -> dict:
    common = [k for k in reference["parameters"] if k in stored["parameters"]]
    diff = max((abs(stored["parameters"][k] - reference["parameters"][k]) / max(abs(reference["parameters"][k]), 1e-12)
                for k in common), default=0.0)  # fmt: skip
    return {
        "lost": expected_days - stored["days"],
        "counted_twice": (stored["sessions"] - stored["days"])
        + (stored["parameter_rows"] - stored["distinct_parameter_rows"]),
        "failed": stored["failed"],
        "unexpected_failures": stored["failed"] - expected_failed,
        "max_relative_difference": float(diff),
    }


def _killed_worker(folder: Path, db: Path, derive) -> bool:
    """A LocalCluster of 2 whose first worker kills its own process in its first robot-day's refit (so the kill
    falls inside a task, never on an idle worker); True when it did die (its nanny restarts it)."""

    def die_in_the_refit(die: bool) -> None:
        from identification.fleet import session, update

        def killed(*args, **kwargs):
            os._exit(1)

        session.refit_day = killed if die else update.refit_day

    with dask_client(workers=2) as client:
        victim = sorted(client.scheduler_info()["workers"])[0]
        client.run(die_in_the_refit, True, workers=[victim])
        try:
            run_fleet(read_fleet(folder), db, RunOptions(check=QUIET, day_reports=False), derive=derive, client=client)
        finally:
            client.run(die_in_the_refit, False)
        return victim not in client.scheduler_info()["workers"]


def run_faults(fleet_folder: Path, out: Path, derive, robots: int = 3) -> dict:
    """The four fault cases (module docstring) on ``robots`` robots of the fleet; one dict of keys per case."""
    clean = _copy(fleet_folder, out / "clean", robots)
    fleet = read_fleet(clean)
    n_days = fleet.n_sessions
    run_fleet(fleet, out / "reference.duckdb", RunOptions(serial=True, check=QUIET, day_reports=False), derive=derive)
    reference = _stored(out / "reference.duckdb")
    result = {}
    killed = _killed_worker(clean, out / "killed.duckdb", derive)
    result["killed_worker"] = {**_verdict(_stored(out / "killed.duckdb"), reference, n_days), "worker_died": killed}
    first = run_fleet(
        fleet,
        out / "resume.duckdb",
        RunOptions(serial=True, stop_after=n_days // 3, check=QUIET, day_reports=False),
        derive=derive,
    )
    second = run_fleet(
        fleet, out / "resume.duckdb", RunOptions(serial=True, check=QUIET, day_reports=False), derive=derive
    )
    result["interrupted_and_resumed"] = {**_verdict(_stored(out / "resume.duckdb"), reference, n_days),
                                         "first_run": first.processed, "resumed": second.processed,
                                         "skipped": second.skipped}  # fmt: skip
    broken = _copy(clean, out / "broken", robots)
    first_robot = sorted(p for p in broken.iterdir() if p.is_dir())[0]
    day = sorted(p for p in first_robot.iterdir() if p.is_dir())[-1]
    next(day.iterdir()).write_text("t,q1,q2\n0,1\nnot numbers\n")  # a corrupt recording among good ones
    second_robot = sorted(p for p in broken.iterdir() if p.is_dir())[1]
    days = sorted(p for p in second_robot.iterdir() if p.is_dir())
    recording = next(days[1].iterdir())
    shutil.copy(recording, days[1] / "same_recording_again.csv")  # the same recording under another name
    shutil.copy(recording, days[2] / "copied_into_the_next_day.csv")  # and into another day
    summary = run_fleet(
        read_fleet(broken),
        out / "broken.duckdb",
        RunOptions(serial=True, check=QUIET, day_reports=False),
        derive=derive,
    )
    stored = _stored(out / "broken.duckdb")
    verdict = _verdict(stored, reference, n_days, expected_failed=1)
    result["corrupt_file"] = {"failed": verdict["failed"], "others_ok": verdict["unexpected_failures"] == 0,
                              "lost": verdict["lost"],
                              "max_relative_difference_of_the_others": verdict["max_relative_difference"]}  # fmt: skip
    result["duplicate_recording"] = {"duplicates_dropped": summary.duplicates,
                                     "counted_twice": verdict["counted_twice"],
                                     "days_unchanged": verdict["max_relative_difference"] < 1e-12}  # fmt: skip
    result["nothing_lost_nothing_counted_twice"] = (
        all(case.get("lost", 0) == 0 and case.get("counted_twice", 0) == 0 for case in result.values())
        and result["killed_worker"]["failed"] == 0
        and result["killed_worker"]["worker_died"]
        and result["duplicate_recording"]["duplicates_dropped"] == 2
        and result["corrupt_file"]["failed"] == 1
    )
    return result
