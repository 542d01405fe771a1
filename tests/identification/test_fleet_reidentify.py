"""Scheduled and on-demand re-identification: a new calibrated baseline recorded with its day, later days judged
against it (their validation error, their window), the drift tests restarted there."""

from __future__ import annotations

import json

import pytest

from identification.calibration.calibrated_model import read_calibrated_model
from identification.fleet.history import History
from identification.fleet.layout import read_fleet
from identification.fleet.runner import RunOptions, dask_client, run_fleet
from identification.virtual.fleet import VirtualFleetOptions, write_virtual_fleet

# one robot whose counterbalance loses 30 % of its stiffness on 2026-10-07 (a step), 12 days, a 3-day window
SPRING = VirtualFleetOptions(n_robots=1, n_days=12, duration=4.0, baseline_days=3, kinds=("spring_loss",), seed=1)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet") / "fleet"
    truth = write_virtual_fleet(folder, SPRING)
    assert truth["events"][0]["onset"] == "2026-10-07"
    return read_fleet(folder)


@pytest.fixture(scope="module")
def runs(fleet, denso_model, tmp_path_factory):
    """The fleet without, and with a re-identification every 8 recording days."""
    folder = tmp_path_factory.mktemp("runs")
    plain = run_fleet(fleet, folder / "plain.duckdb", RunOptions(serial=True), derive=lambda r: denso_model)
    every = run_fleet(fleet, folder / "every.duckdb", RunOptions(serial=True, reidentify_every=8),
                      derive=lambda r: denso_model)  # fmt: skip
    return folder, plain, every


def test_a_scheduled_reidentification_is_the_baseline_of_the_later_days(runs, denso_model):
    folder, plain, every = runs
    assert every.reidentified == ("r01 from 2026-10-09",) and plain.reidentified == ()
    with History(folder / "every.duckdb") as history:
        baselines = history.baselines()
        spring = {str(r[1]): r[3] for r in history.validation_rows() if r[2] == 2}
        checks = {str(r[1]): str(r[8]) for r in history.checks()}
    [(robot_id, since, source)] = baselines
    assert (robot_id, str(since)) == ("r01", "2026-10-09")
    loaded = read_calibrated_model(source, derive=lambda r: denso_model)  # a calibrated model, days 10-06 .. 10-08
    assert loaded.calibrated.consistent and loaded.calibrated.document["provenance"]["recordings"]
    assert [e["effect"] for e in loaded.calibrated.document["findings"]] == ["spring", "torque_ripple"]
    # the robot file has no counterbalance; the new baseline carries it: joint 2's error falls from day 10-09 on
    assert max(spring[d] for d in spring if d >= "2026-10-09") < 0.2 * min(
        spring[d] for d in spring if d < "2026-10-09"
    )
    # the window restarts: 10-09 .. 10-11 define the new reference, 10-12 is judged against it
    assert checks == {**{f"2026-10-0{d}": "2026-10-01" for d in range(4, 9)}, "2026-10-12": "2026-10-09"}


def test_the_drift_tests_restart_at_the_new_baseline(runs):
    folder, plain, every = runs
    with History(folder / "plain.duckdb") as history:
        found = [f for f in history.findings() if f[2] == "spring_k_2"]
    assert found and str(found[0][4]) == "2026-10-07"  # without re-identification: the step is an alarm
    assert every.findings == 0  # with it: the step is before the new baseline, which holds it


def test_reidentify_on_demand_from_the_command_line(fleet, runs, tmp_path, capsys):
    import shutil

    from psdm_casadi.cli import main

    db = tmp_path / "h.duckdb"
    shutil.copy(runs[0] / "every.duckdb", db)
    code = main(["fleet", "run", str(fleet.source), "--db", str(db), "--serial", "--reidentify", "r01", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["processed"] == 0 and out["reidentified"] == ["r01 from 2026-10-13"]
    with History(db) as history:
        assert [str(b[1]) for b in history.baselines()] == ["2026-10-09", "2026-10-13"]
    assert main(["fleet", "status", "--db", str(db), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["robots"][0]["baseline"][0] == "2026-10-13"
    assert main(["fleet", "run", str(fleet.source), "--db", str(db), "--reidentify", "r99"]) == 2
    assert "--reidentify r99: no such robot" in capsys.readouterr().err
    assert main(["fleet", "run", str(fleet.source), "--db", str(db), "--reidentify-every", "1"]) == 2


@pytest.mark.slow
def test_dask_reidentifies_as_the_serial_run(fleet, runs, denso_model, tmp_path):
    with dask_client(workers=2) as client:
        summary = run_fleet(fleet, tmp_path / "h.duckdb", RunOptions(reidentify_every=8), derive=lambda r: denso_model,
                            client=client)  # fmt: skip
    assert summary.reidentified == runs[2].reidentified
    rows = []
    for db in (runs[0] / "every.duckdb", tmp_path / "h.duckdb"):
        with History(db) as history:
            rows.append({(r.day, r.name): r.value for r in history.parameter_rows()})
    assert rows[0].keys() == rows[1].keys()
    assert all(rows[1][k] == pytest.approx(v, rel=1e-9, abs=1e-9) for k, v in rows[0].items())
