"""The fleet's automatic diagnosis: the validation-error check's false-alarm rate, an unmodelled event diagnosed in
its own Dask task (healthy robots get none), the history's schema migration, and the per-day report pages linked
from the fleet report (rendered by headless Chromium where one is installed)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import duckdb
import numpy as np
import pytest

from identification.fleet.day_check import CheckOptions, check_day, error_reference, friction_changes
from identification.fleet.day_report import day_report_path
from identification.fleet.history import SCHEMA_VERSION, History
from identification.fleet.layout import read_fleet
from identification.fleet.report import write_report
from identification.fleet.runner import RunOptions, dask_client, run_fleet
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet
from psdm_casadi.errors import ParameterError

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
# r01: Coulomb friction wear (tracked); r02: an unmodelled current-sensor offset; r03 healthy
EVENTS = VirtualFleetOptions(n_robots=3, n_days=9, duration=6.0, baseline_days=5, kinds=("friction_wear",),
                             event_robots=1, unmodelled_robots=1, seed=1)  # fmt: skip


def test_false_alarm_rate_of_the_day_check_is_its_alpha(rng):
    """A healthy joint (log RMSE i.i.d. normal): the prediction test flags a day with probability alpha (Student's
    t with n - 1 degrees of freedom is exact); with six joints Bonferroni keeps the robot-day's rate below alpha."""
    options = CheckOptions(alpha=0.05, min_scatter=0.0)
    for n_dof, low, high in ((1, 0.04, 0.06), (6, 0.0, 0.05)):
        flagged, trials = 0, 3000
        for _ in range(trials):
            logs = 0.3 * rng.standard_normal((8, n_dof)) - 1.0
            rmse = np.exp(logs)
            rows = [(f"2026-10-{d + 1:02d}", j + 1, rmse[d, j], rmse[d, j]) for d in range(7) for j in range(n_dof)]
            reference = error_reference("r", rows, options)
            flagged += check_day(reference, rmse[7], rmse[7]).verdict != "quiet"
        assert low <= flagged / trials <= high, (n_dof, flagged / trials)


@pytest.fixture(scope="module")
def fleet_run(tmp_path_factory, denso_model):
    folder = tmp_path_factory.mktemp("fleet")
    truth = write_virtual_fleet(folder / "fleet", EVENTS)
    fleet = read_fleet(folder / "fleet")
    summary = run_fleet(fleet, folder / "h.duckdb", RunOptions(serial=True), derive=lambda robot: denso_model)
    return folder, truth, fleet, summary


def test_an_unmodelled_event_is_diagnosed_and_healthy_robots_are_not(fleet_run):
    folder, truth, _, summary = fleet_run
    wear, offset = truth["events"]
    assert (wear["robot_id"], offset["robot_id"], truth["healthy"]) == ("r01", "r02", ["r03"])
    assert (wear["kind"], offset["kind"], summary.failed) == ("friction_wear", "sensor_offset", 0)
    with History(folder / "h.duckdb") as history:
        checks = {(r[0], str(r[1])): r for r in history.checks()}
        diagnoses = history.diagnoses()
    assert len(checks) == 3 * (EVENTS.n_days - EVENTS.baseline_days)  # every day after the window is checked
    offset_days = {k for k in checks if k[0] == "r02" and k[1] >= offset["onset"]}
    wear_days = {k for k in checks if k[0] == "r01" and k[1] >= wear["onset"]}
    assert offset_days and wear_days
    for key, row in checks.items():
        if key in wear_days:  # the wear raises the baseline's error; the refit explains most of it
            assert row[2] == "quiet" or row[3] == str(wear["joint"]), row
        else:
            assert row[2] == ("unexplained" if key in offset_days else "quiet"), row
    named = {(d[0], str(d[1])) for d in diagnoses}
    assert offset_days <= named <= offset_days | wear_days  # never on a healthy robot or a quiet day
    true_offset = 0.5 * truth["truth"]["r02"]["fc"][offset["joint"] - 1]
    for _, _, effect, _, joints, parameters, gain, text in (d for d in diagnoses if d[0] == "r02"):
        assert (effect, joints) == ("torque_offset", str(offset["joint"])), text
        assert abs(parameters["offset"] - true_offset) < 0.1 * true_offset and gain > 0.5


def test_a_friction_wear_day_the_refit_does_not_explain_names_the_friction_drift(fleet_run):
    """Wear raises r01's static friction with its Coulomb friction (a hump the daily Coulomb-viscous refit does not
    follow): the day's rise is not left "unexplained" but named on its joint with the size against the window."""
    folder, truth, _, _ = fleet_run
    wear = truth["events"][0]
    with History(folder / "h.duckdb") as history:
        checks = {(r[0], str(r[1])): r for r in history.checks()}
        diagnoses = history.diagnoses()
    wear_days = sorted(k for k in checks if k[0] == "r01" and k[1] >= wear["onset"])
    assert all(checks[k][2] != "unexplained" for k in wear_days)
    drifted = [k for k in wear_days if checks[k][2] == "friction_drift"]
    assert wear_days[-1] in drifted, [checks[k] for k in wear_days]  # the last day: the full +50 %
    assert {checks[k][2] for k in checks if k[0] != "r01"} <= {"quiet", "unexplained"}  # no drift elsewhere
    named = [d for d in diagnoses if d[2] == "friction_drift"]
    assert {(d[0], str(d[1])) for d in named} <= set(wear_days) and named
    last = next(d for d in named if str(d[1]) == wear_days[-1][1])
    assert last[4] == str(wear["joint"]) and last[5]["z"] > checks[wear_days[-1]][6]
    assert abs(last[5]["relative_change_percent"] - 100 * wear["size"]) < 10, last  # the truth's ramp ends at +50 %
    assert last[7].startswith(f"joint {wear['joint']} Coulomb friction +") and "gearbox wear" in last[7]
    page = day_report_path(folder / "h.duckdb", "r01", wear_days[-1][1]).read_text()
    assert "<b>friction_drift</b>" in page and "Coulomb friction +" in page


def test_friction_changes_test_the_refitted_friction_against_the_window(rng):
    """The window's log Coulomb friction scatters by 1 %: +20 % on a day is named with its size, +1 % is not, and a
    joint without a window friction is not tested."""
    days = [f"2026-10-{d + 1:02d}" for d in range(7)]
    rows = [(day, j, 1.0, 1.0) for day in days for j in (1, 2)]
    friction = [(day, 1, 2.0 * np.exp(0.01 * rng.standard_normal())) for day in days]
    reference = error_reference("r", rows, CheckOptions(), friction)
    changes = friction_changes(reference, ("fc1", "fc2"), (2.4, 5.0), (1, 2))
    assert [c.joint for c in changes] == [1] and abs(changes[0].relative_percent - 20.0) < 2.0
    assert changes[0].z > reference.threshold and "joint 1 Coulomb friction +2" in changes[0].text
    assert friction_changes(reference, ("fc1",), (2.02,), (1,)) == ()
    assert friction_changes(error_reference("r", rows), ("fc1",), (2.4,), (1,)) == ()  # no window friction


def test_dask_runs_the_diagnosis_in_the_task_and_equals_serial(fleet_run, denso_model, tmp_path):
    """r02 alone (its window, then its later days with the diagnosis, on two workers): as the serial run."""
    folder = fleet_run[0]
    shutil.copytree(folder / "fleet" / "r02", tmp_path / "fleet" / "r02")
    shutil.copy(folder / "fleet" / "fleet.toml", tmp_path / "fleet")
    with dask_client(workers=2) as client:
        run_fleet(read_fleet(tmp_path / "fleet"), tmp_path / "dask.duckdb", derive=lambda robot: denso_model,
                  client=client)  # fmt: skip
    rows = []
    for db in (folder / "h.duckdb", tmp_path / "dask.duckdb"):
        with History(db) as history:
            rows.append(([c for c in history.checks() if c[0] == "r02"],
                         [d[:6] for d in history.diagnoses() if d[0] == "r02"]))  # fmt: skip
    (checks_a, diag_a), (checks_b, diag_b) = rows
    assert [c[:4] for c in checks_a] == [c[:4] for c in checks_b] and diag_a == diag_b and diag_a
    assert np.allclose([c[4:7] for c in checks_a], [c[4:7] for c in checks_b], rtol=1e-12)


def test_status_and_report_show_the_diagnosis_and_link_every_day(fleet_run, tmp_path, capsys):
    from psdm_casadi.cli import main

    folder = fleet_run[0]
    db = folder / "h.duckdb"
    assert main(["fleet", "status", "--db", str(db), "--json"]) == 0
    robots = {r["robot_id"]: r for r in json.loads(capsys.readouterr().out)["robots"]}
    assert robots["r02"]["status"] == "alarm" and "torque offset on joint" in robots["r02"]["diagnoses"][0]
    assert robots["r03"]["diagnoses"] == [] and robots["r03"]["status"] == "ok"
    report = tmp_path / "out" / "fleet.html"  # elsewhere than the history (a folder made for it): relative links
    with History(db) as history:
        write_report(history, report)
    page = report.read_text()
    hrefs = re.findall(r'<a class="day (\w+)" href="([^"]+)"', page)
    assert len(hrefs) == 3 * EVENTS.n_days
    for _, href in hrefs:
        assert (report.parent / href).resolve().is_file(), href
    assert sum(kind == "unexplained" for kind, _ in hrefs) >= 2 and "diagnosis: torque offset" in page
    day = day_report_path(db, "r02", "2026-10-09").read_text()
    assert "<b>unexplained</b>" in day and "torque_offset" in day and "<svg" in day and "<script" not in day


@pytest.mark.skipif(
    CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium) to render the page"
)
def test_a_day_page_renders_in_headless_chromium(fleet_run):
    page = day_report_path(fleet_run[0] / "h.duckdb", "r02", "2026-10-09")
    done = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=2000", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert [line for line in done.stderr.splitlines() if ":CONSOLE" in line] == []
    assert done.stdout.count("<rect") == 12 and "Refitted parameters" in done.stdout


def test_a_schema_1_history_is_migrated_and_a_newer_one_refused(tmp_path):
    old = tmp_path / "v1.duckdb"
    con = duckdb.connect(str(old))  # the tables of schema 1, as the first fleet release wrote them
    con.execute(
        "CREATE TABLE sessions (robot_id VARCHAR, day DATE, content_hash VARCHAR, run_id INTEGER, status VARCHAR, "
        "error VARCHAR, n_samples INTEGER, seconds DOUBLE, software_version VARCHAR, written TIMESTAMP, "
        "PRIMARY KEY (robot_id, day, content_hash));"
        "CREATE TABLE parameters (robot_id VARCHAR, day DATE, content_hash VARCHAR, name VARCHAR, joint INTEGER, "
        "value DOUBLE, sigma DOUBLE);"
        "INSERT INTO sessions VALUES ('r01', '2026-10-01', 'h', 1, 'ok', '', 100, 0.1, '0.1', '2026-10-01 10:00');"
        "INSERT INTO parameters VALUES ('r01', '2026-10-01', 'h', 'fc1', 1, 5.0, 0.1);"
    )
    con.close()
    with History(old) as history:
        assert history.schema_version == SCHEMA_VERSION == 2
        assert [(r.name, r.value) for r in history.parameter_rows()] == [("fc1", 5.0)]
        assert history.checks() == [] and history.diagnoses() == [] and history.baselines() == []
    with History(old) as history:  # opening again keeps it as it is
        assert history.connection.execute("SELECT value FROM meta").fetchall() == [("2",)]
        history.connection.execute("UPDATE meta SET value = '3'")
    with pytest.raises(ParameterError, match=r"schema 3, written by a newer psdm-casadi.*Upgrade"):
        History(old)
    assert Path(old).is_file()
