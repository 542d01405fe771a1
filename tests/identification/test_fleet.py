"""The fleet: layout, the robot-day task against the virtual fleet's truth, Dask == serial, the history's
idempotence, resume, corrupt and duplicate recordings, the CLI."""

from __future__ import annotations

import json
import logging
import shutil

import numpy as np
import pytest

from identification.fleet.baseline import SharedModels, build_baseline
from identification.fleet.history import History
from identification.fleet.layout import FleetLayoutError, read_fleet
from identification.fleet.plan import plan_run
from identification.fleet.runner import RunOptions, dask_client, run_fleet
from identification.fleet.session import day_message, process_session
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet

TINY = VirtualFleetOptions(n_robots=3, n_days=6, duration=3.0, rate=200.0, baseline_days=3, seed=3)


@pytest.fixture(scope="module")
def tiny_fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet") / "fleet"
    truth = write_virtual_fleet(folder, TINY)
    return folder, truth


@pytest.fixture(scope="module")
def derive(denso_model):
    return lambda robot: denso_model  # every virtual robot is a Denso: one PSDM model (SharedModels' point)


#: How long [s] a test waits for Dask to restart the workers it killed before the next test runs on them: a nanny
#: restarts a worker within seconds on an idle machine, but beside other jobs on 2 cores a restart took over 60 s.
WORKER_RESTART_S = 300


@pytest.fixture(scope="module")
def cluster():
    with dask_client(workers=2) as client:
        yield client


def _parameters(db) -> dict:
    with History(db) as history:
        return {(r.robot_id, str(r.day), r.name): (r.value, r.sigma) for r in history.parameter_rows()}


def _copy(tiny_fleet, tmp_path):
    folder = tmp_path / "fleet"
    shutil.copytree(tiny_fleet[0], folder)
    return folder


# --- layout --------------------------------------------------------------------------------------
def test_layout_folder_and_manifest_agree(tiny_fleet, tmp_path):
    folder, truth = tiny_fleet
    fleet = read_fleet(folder)
    assert [r.robot_id for r in fleet.robots] == truth["robots"]
    assert fleet.n_sessions == TINY.n_robots * TINY.n_days
    assert fleet.track.spring == (TINY.spring_joint,) and fleet.track.ripple == ((4, 12),)
    manifest = tmp_path / "fleet.toml"
    lines = [(folder / "fleet.toml").read_text()]
    for robot_id in truth["robots"]:
        lines.append(f'[[robot]]\nid = "{robot_id}"\nrobot = "{folder / robot_id / "robot.toml"}"\n'
                     f'recordings = "{folder / robot_id}"\n')  # fmt: skip
    manifest.write_text("\n".join(lines))
    listed = read_fleet(manifest)
    assert [(r.robot_id, r.days) for r in listed.robots] == [(r.robot_id, r.days) for r in fleet.robots]
    days = fleet.robots[0].days[:2]  # recordings listed one by one with their day
    listed_days = "".join(f'[[robot.recordings]]\nday = "{d.day}"\npath = "{d.paths[0]}"\n' for d in days)
    manifest.write_text(f'[[robot]]\nid = "solo"\nrobot = "{folder / "r01" / "robot.toml"}"\n{listed_days}')
    solo = read_fleet(manifest).robots[0]
    assert solo.robot_id == "solo" and solo.days == days


def test_layout_errors_name_the_path_and_fix(tiny_fleet, tmp_path):
    folder = _copy(tiny_fleet, tmp_path)
    (folder / "r02" / "robot.toml").unlink()
    with pytest.raises(FleetLayoutError, match=r"r02.*no baseline.*baseline.json"):
        read_fleet(folder)
    shutil.copy(tiny_fleet[0] / "r02" / "robot.toml", folder / "r02" / "robot.toml")
    (folder / "r01" / "yesterday").mkdir()
    (folder / "r01" / "yesterday" / "a.csv").write_text("t,q1\n")
    with pytest.raises(FleetLayoutError, match="'yesterday' is not a date YYYY-MM-DD"):
        read_fleet(folder)
    with pytest.raises(FleetLayoutError, match="no such fleet"):
        read_fleet(tmp_path / "missing")


# --- the robot-day task --------------------------------------------------------------------------
def test_session_recovers_the_virtual_robots_truth(tiny_fleet, derive):
    """Day 1 of r03 (a spring on joint 2, a ripple on joint 4): the refit finds the truth within 4 sigma."""
    folder, truth = tiny_fleet
    fleet = read_fleet(folder)
    entry = fleet.robots[2]
    baseline, model = build_baseline(entry, fleet.track, SharedModels(derive))
    task = next(t for t in plan_run(fleet).tasks if t.robot_id == entry.robot_id)
    result = process_session(task, baseline, model)
    assert result.status == "ok", result.error
    fit = dict(zip(result.fit.names, zip(result.fit.values, result.fit.sigmas)))
    true = truth["truth"][entry.robot_id]
    for name, expected in (("spring_k_2", true["spring_stiffness"]), ("ripple_amp12_4", true["ripple_amplitude"]),
                           ("kt2", true["kt"][1]), ("kt3", true["kt"][2])):  # fmt: skip
        value, sigma = fit[name]
        assert abs(value - expected) < 4 * sigma + 0.02 * abs(expected), (name, value, sigma, expected)
    assert abs(fit["payload_mass"][0]) < 4 * fit["payload_mass"][1] + 0.05
    assert np.all(result.fit.rmse_refit <= result.fit.rmse_baseline + 1e-12)


def test_a_refused_day_names_its_robot_and_day_in_the_message(tiny_fleet, derive, tmp_path, caplog):
    """Every day's recording is a health.csv: r02's second day logged in mA (its currents 1000 times the file's)
    is refused by the torque-magnitude check, its third cannot be read; each message names the robot and the day,
    the warning once (it prefixed them again to a message that held them), and the days left alone pass."""
    folder = _copy(tiny_fleet, tmp_path)
    scaled = folder / "r02" / "2026-10-02" / "health.csv"
    lines = scaled.read_text().splitlines()
    header = lines[1].split(",")
    data = np.loadtxt(scaled, delimiter=",", skiprows=2)
    data[:, [k for k, name in enumerate(header) if name.startswith("i")]] *= 1000.0
    np.savetxt(scaled, data, delimiter=",", header="\n".join(lines[:2]), comments="", fmt="%.17g")
    (folder / "r02" / "2026-10-03" / "health.csv").write_text("t,q1,q2\n0,1\nnot numbers\n")
    fleet = read_fleet(folder)
    entry = fleet.robots[1]
    baseline, model = build_baseline(entry, fleet.track, SharedModels(derive))
    tasks = {t.day: t for t in plan_run(fleet).tasks if t.robot_id == "r02"}
    with caplog.at_level(logging.WARNING, logger="identification.fleet.session"):
        refused = process_session(tasks["2026-10-02"], baseline, model)
        unread = process_session(tasks["2026-10-03"], baseline, model)
    assert refused.status == "failed"
    assert "Recording r02/2026-10-02/health.csv: the recorded torque is about " in refused.error
    assert unread.status == "failed" and unread.error.startswith("RecordingError: r02/2026-10-03/health.csv: ")
    warned = [r.getMessage() for r in caplog.records if r.name == "identification.fleet.session"]
    assert len(warned) == 2 and all("failed" in w for w in warned), warned
    for day, warning in zip(("2026-10-02", "2026-10-03"), warned):
        assert warning.count("r02") == 1 and warning.count(day) == 1, warning
    assert day_message(tasks["2026-10-02"], "failed: singular matrix") == "r02 2026-10-02: failed: singular matrix"
    assert process_session(tasks["2026-10-01"], baseline, model).status == "ok"


def test_corrupt_recording_fails_its_own_day_and_duplicates_count_once(tiny_fleet, derive, tmp_path):
    folder = _copy(tiny_fleet, tmp_path)
    bad = folder / "r01" / "2026-10-03" / "health.csv"
    bad.write_text("t,q1,q2\n0,1\nnot numbers\n")
    day = folder / "r02" / "2026-10-02"
    shutil.copy(day / "health.csv", day / "health_copy.csv")  # the same recording under two names
    shutil.copy(day / "health.csv", folder / "r02" / "2026-10-05" / "again.csv")  # and under another day
    summary = run_fleet(read_fleet(folder), tmp_path / "h.duckdb", RunOptions(serial=True), derive=derive)
    assert (summary.processed, summary.failed, summary.duplicates) == (18, 1, 2)
    with History(tmp_path / "h.duckdb") as history:
        failures = history.failures()
        counts = {r[0]: r[1:3] for r in history.session_counts()}
        dup = history.connection.execute("SELECT count(*) FROM recordings WHERE duplicate_of IS NOT NULL").fetchone()
    assert [(r, str(d)) for r, d, _ in failures] == [("r01", "2026-10-03")]
    assert "r01/2026-10-03/health.csv" in failures[0][2]  # the robot and the day: every day holds a health.csv
    assert counts == {"r01": (5, 1), "r02": (6, 0), "r03": (6, 0)} and dup == (2,)
    clean = _parameters(tmp_path / "h.duckdb")
    assert ("r02", "2026-10-02", "fc1") in clean


# --- Dask, the history ---------------------------------------------------------------------------
def test_serial_one_worker_and_two_workers_agree(tiny_fleet, derive, cluster, tmp_path):
    fleet = read_fleet(tiny_fleet[0])
    run_fleet(fleet, tmp_path / "serial.duckdb", RunOptions(serial=True), derive=derive)
    run_fleet(fleet, tmp_path / "two.duckdb", derive=derive, client=cluster)
    run_fleet(fleet, tmp_path / "one.duckdb", RunOptions(workers=1), derive=derive)
    serial, two, one = (_parameters(tmp_path / f"{n}.duckdb") for n in ("serial", "two", "one"))
    assert serial.keys() == two.keys() == one.keys() and len(serial) > 100
    for key, (value, sigma) in serial.items():
        for other in (one, two):
            assert other[key][0] == pytest.approx(value, rel=1e-12, abs=1e-12)
            assert other[key][1] == pytest.approx(sigma, rel=1e-12, abs=1e-12)


def test_incremental_idempotent_and_resume(tiny_fleet, derive, cluster, tmp_path):
    fleet = read_fleet(tiny_fleet[0])
    db = tmp_path / "h.duckdb"
    first = run_fleet(fleet, db, RunOptions(stop_after=5), derive=derive, client=cluster)  # interrupted
    assert first.interrupted and first.processed == 5
    second = run_fleet(fleet, db, derive=derive, client=cluster)
    assert (second.processed, second.skipped) == (13, 5)
    third = run_fleet(fleet, db, RunOptions(serial=True), derive=derive)
    assert (third.processed, third.skipped) == (0, 18)
    with History(db) as history:
        n_sessions = history.connection.execute("SELECT count(*) FROM sessions").fetchone()[0]
        runs = history.connection.execute("SELECT status FROM runs ORDER BY run_id").fetchall()
        paths = history.export_parquet(tmp_path / "parquet")
    assert n_sessions == 18 and [r[0] for r in runs] == ["interrupted", "done", "done"]
    reference = tmp_path / "ref.duckdb"
    run_fleet(fleet, reference, RunOptions(serial=True), derive=derive)
    assert _close(db, reference)
    import duckdb

    assert duckdb.connect().execute(f"SELECT count(*) FROM '{paths[1]}'").fetchone()[0] == 18


def _close(a, b) -> bool:
    pa, pb = _parameters(a), _parameters(b)
    return pa.keys() == pb.keys() and all(np.allclose(pa[k], pb[k], rtol=1e-12, atol=1e-12) for k in pa)


# --- the command line ----------------------------------------------------------------------------
def test_cli_run_status_report(tiny_fleet, tmp_path, capsys):
    from psdm_casadi.cli import main

    db = tmp_path / "h.duckdb"
    code = main(["fleet", "run", str(tiny_fleet[0]), "--db", str(db), "--serial", "--json",
                 "--export-parquet", str(tmp_path / "pq")])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and out["processed"] == 18 and out["failed"] == 0
    assert (tmp_path / "pq" / "parameters.parquet").is_file()
    assert main(["fleet", "status", "--db", str(db), "--json"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert [r["robot_id"] for r in status["robots"]] == ["r01", "r02", "r03"]
    assert main(["fleet", "report", "--db", str(db), "--out", str(tmp_path / "r.html")]) == 0
    page = (tmp_path / "r.html").read_text()
    assert page.count("Plotly.newPlot") == 6 and "<script" in page and "r03" in page
    assert main(["fleet", "run", str(tmp_path / "nowhere")]) == 2
    assert "no such fleet folder" in capsys.readouterr().err


def _break_refit(broken: bool) -> None:
    """On a worker: the robot-day's refit raises an error no task expects (``broken``), or is the real one again."""
    from identification.fleet import session, update

    calls = session.__dict__.setdefault("exploded_calls", [])  # the count the test reads back (``_explosions``)
    calls.clear()

    def exploded(*args, **kwargs):
        calls.append(1)
        raise RuntimeError("refit exploded")

    session.refit_day = exploded if broken else update.refit_day


def _explosions() -> int:
    from identification.fleet import session

    return len(session.__dict__.get("exploded_calls", []))


def test_a_task_that_raises_on_the_workers_is_stored_as_failed(tiny_fleet, derive, cluster, tmp_path):
    """An error inside the task (not a bad recording: Dask returns it as the future's error) fails that robot-day in
    the history with its text, once: it is the task's own error, not the cluster's, so it is not submitted again
    (each robot-day's refit ran once); the run goes on and ends."""
    fleet = read_fleet(tiny_fleet[0])
    cluster.run(_break_refit, True)
    try:
        summary = run_fleet(fleet, tmp_path / "h.duckdb", RunOptions(day_reports=False), derive=derive, client=cluster)
        calls = sum(cluster.run(_explosions).values())
    finally:
        cluster.run(_break_refit, False)
    assert calls == 18
    assert (summary.processed, summary.failed) == (18, 18)
    with History(tmp_path / "h.duckdb") as history:
        errors = {row[2] for row in history.failures()}
    assert errors == {"RuntimeError: refit exploded"}


def test_the_cli_on_a_local_cluster_writes_no_dask_noise(tiny_fleet, tmp_path):
    """``psdm fleet run --workers 2`` in a process of its own: its stderr holds the command's progress lines only,
    no traceback and no Dask log line (the client, then the cluster, close with Dask's loggers silent)."""
    import subprocess
    import sys

    code = "import sys; from psdm_casadi.cli import main; sys.exit(main())"
    command = [sys.executable, "-c", code, "fleet", "run", str(tiny_fleet[0]), "--db", str(tmp_path / "h.duckdb"),
               "--workers", "2"]  # fmt: skip
    result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert result.returncode in (0, 1), result.stderr
    assert "robot-days processed (0 failed)" in result.stdout
    lines = result.stderr.splitlines()
    assert "Traceback" not in result.stderr and not [x for x in lines if "distributed." in x or "Error" in x], lines
    assert lines[0].startswith("fleet ") and "running on LocalCluster(2)" in lines[1], lines


def _die_in_the_refit(die: bool) -> None:
    """On a worker: its next robot-day's refit kills the worker process (``die``), or the refit is the real one."""
    import os

    from identification.fleet import session, update

    def killed(*args, **kwargs):
        os._exit(1)

    session.refit_day = killed if die else update.refit_day


def test_a_killed_worker_loses_and_duplicates_nothing(tiny_fleet, derive, cluster, tmp_path, monkeypatch, caplog):
    """A worker process killed in the middle of a robot-day (its nanny restarts it): every robot-day once, none
    failed, as the serial run.

    The worker kills itself in its first refit, so the kill falls inside a task whatever the machine's speed (a
    kill from the client, between two writes, could find the worker idle). The scheduler's allowed failures are 0
    for the run: Dask gives up at once on the tasks the worker was running (``KilledWorker``: what a loaded machine
    met, with a worker dying again as it restarted), and the runner must submit them again, not fail them.

    Dask's active memory manager is held still for the run: every 2 s it drops the copies of scattered data no
    pending task needs on a worker, so on a loaded machine (a long first refit) the baseline and the model could be
    left on the victim alone and die with it, and a task still waiting for them was cancelled, not killed (the flaky
    "cancelled" in place of ``KilledWorker``). With the runner's broadcast copies kept, one worker's death loses no
    data, unless the broadcast had not reached the other worker yet (a starved machine: the clean-clone CI met it,
    with the memory manager held); the scheduler's own record of the removal says which, and the test asks of the
    resubmissions what that route owes. Losing every copy is the next test's case.
    """
    import logging

    fleet = read_fleet(tiny_fleet[0])
    scheduler = cluster.cluster.scheduler
    victim = sorted(cluster.scheduler_info()["workers"])[0]
    allowed = scheduler.allowed_failures
    original, written = History.write_sessions, []

    def write(self, run_id, results):
        written.extend(result.task.key for result in results)
        original(self, run_id, results)

    monkeypatch.setattr(History, "write_sessions", write)
    caplog.set_level(logging.WARNING, logger="identification.fleet.runner")
    cluster.run(_die_in_the_refit, True, workers=[victim])
    scheduler.allowed_failures = 0
    memory_manager = cluster.amm.running()
    cluster.amm.stop()
    try:
        summary = run_fleet(fleet, tmp_path / "h.duckdb", derive=derive, client=cluster)
    finally:
        scheduler.allowed_failures = allowed
        if memory_manager:
            cluster.amm.start()
        cluster.run(_die_in_the_refit, False)  # the victim's successor is a fresh process; the others are restored
    monkeypatch.undo()
    removals = [
        e for _, e in scheduler.get_events(victim) if isinstance(e, dict) and e.get("action") == "remove-worker"
    ]
    assert removals, "the victim was never removed"
    with History(tmp_path / "h.duckdb") as history:
        failures = history.failures()
    assert (summary.processed, summary.failed) == (18, 0), failures
    assert len(written) == len(set(written)) == 18
    again = [r.getMessage() for r in caplog.records if "submitted again" in r.getMessage()]
    assert again, "nothing was submitted again"
    if any(e["lost-scattered-tasks"] for e in removals):
        # a starved machine: the broadcast had not reached the other worker when the victim died (the scheduler's
        # record names the scattered data lost), so Dask cancelled the tasks waiting for it; the runner scatters the
        # data again and submits them again (the next test's route), still every robot-day once
        assert all("KilledWorker" in text or "cancelled" in text for text in again), again
    else:
        assert all("KilledWorker" in text for text in again), again
    assert victim not in cluster.scheduler_info()["workers"]  # the victim did die
    reference = tmp_path / "ref.duckdb"
    run_fleet(fleet, reference, RunOptions(serial=True), derive=derive)
    assert _close(tmp_path / "h.duckdb", reference)
    cluster.wait_for_workers(2, timeout=WORKER_RESTART_S)


def test_every_worker_killed_loses_the_shared_data_and_the_run_scatters_it_again(tiny_fleet, derive, cluster, tmp_path,
                                                                                 caplog):  # fmt: skip
    """Every worker dies in its first refit: the baselines and the model scattered to them die too (no copy is
    left), Dask cancels the tasks needing them, and the runner scatters the data again to the restarted workers and
    submits the tasks again: every robot-day once, none failed, as the serial run."""
    import logging

    fleet = read_fleet(tiny_fleet[0])
    before = set(cluster.scheduler_info()["workers"])
    caplog.set_level(logging.WARNING, logger="identification.fleet.runner")
    cluster.run(_die_in_the_refit, True)
    try:
        summary = run_fleet(fleet, tmp_path / "h.duckdb", RunOptions(day_reports=False), derive=derive, client=cluster)
    finally:
        cluster.wait_for_workers(2, timeout=WORKER_RESTART_S)
        cluster.run(_die_in_the_refit, False)
    with History(tmp_path / "h.duckdb") as history:
        failures = history.failures()
    assert (summary.processed, summary.failed) == (18, 0), failures
    assert not before & set(cluster.scheduler_info()["workers"])  # both workers died
    again = [r.getMessage() for r in caplog.records if "submitted again" in r.getMessage()]
    assert any("cancelled" in text for text in again), again
    reference = tmp_path / "ref.duckdb"
    run_fleet(fleet, reference, RunOptions(serial=True, day_reports=False), derive=derive)
    assert _close(tmp_path / "h.duckdb", reference)


def test_a_calibrated_model_is_a_baseline(tiny_fleet, derive, denso_model, tmp_path):
    """r01's baseline is a calibrated-model file identified from its first days: the fleet refits on top of it."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
    from identification.data.io import load_recording
    from psdm_casadi.robot import load_robot

    folder = _copy(tiny_fleet, tmp_path)
    robot = load_robot(folder / "r01" / "robot.toml")
    days = read_fleet(folder).robots[0].days[:3]
    recordings = [load_recording(d.paths[0], robot.n_dof) for d in days]
    fit = identify_trajectories(robot, denso_model, recordings, TrajectoryOptions(consistency=False))
    calibrated = CalibratedModel.from_fit(robot, denso_model, fit, robot_source=folder / "r01" / "robot.toml")
    calibrated.save(folder / "r01" / "baseline.json", allow_inconsistent=True)
    fleet = read_fleet(folder)
    assert fleet.robots[0].baseline_kind == "calibrated"
    run_fleet(fleet, tmp_path / "h.duckdb", RunOptions(serial=True), derive=derive)
    with History(tmp_path / "h.duckdb") as history:
        rows = history.validation_rows()
        counts = {r[0]: r[1:3] for r in history.session_counts()}
    assert counts["r01"] == (6, 0)
    first = [r for r in rows if r[0] == "r01" and str(r[1]) == days[0].day]
    # on a day it was identified from, the calibrated model explains the torque about as well as the refit
    assert all(baseline < 1.5 * refit + 0.05 for _, _, _, baseline, refit in first), first


def test_ctrl_c_keeps_the_written_days_and_the_next_run_resumes(tiny_fleet, derive, tmp_path, monkeypatch):
    """Ctrl-C during the fourth write: three robot-days stay, the run says interrupted, the next run does the rest."""
    fleet = read_fleet(tiny_fleet[0])
    db = tmp_path / "h.duckdb"
    original = History.write_sessions
    calls = []

    def interrupted(self, run_id, results):
        calls.extend(result.task.key for result in results)
        if len(calls) == 4:
            raise KeyboardInterrupt
        original(self, run_id, results)

    monkeypatch.setattr(History, "write_sessions", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_fleet(fleet, db, RunOptions(serial=True), derive=derive)
    monkeypatch.setattr(History, "write_sessions", original)
    with History(db) as history:
        assert history.done_keys() == set(calls[:3])
        assert history.connection.execute("SELECT status FROM runs").fetchall() == [("interrupted",)]
    resumed = run_fleet(fleet, db, RunOptions(serial=True), derive=derive)
    assert (resumed.processed, resumed.skipped) == (15, 3)
    reference = tmp_path / "ref.duckdb"
    run_fleet(fleet, reference, RunOptions(serial=True), derive=derive)
    assert _close(db, reference)
