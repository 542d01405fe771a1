"""The fleet report: a self-contained page (fleet table, one trend plot per robot, onset markers), rendered by
a real headless Chromium without console errors where one is installed."""

from __future__ import annotations

import datetime as dt
import re
import shutil
import subprocess

import numpy as np
import pytest

from identification.fleet.drift import detect_drift
from identification.fleet.history import History
from identification.fleet.report import write_report
from identification.fleet.session import SessionResult, SessionTask
from identification.fleet.update import DayFit

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


@pytest.fixture
def report(tmp_path, rng):
    """A history of two robots x 14 days (r02's joint-3 Coulomb friction steps up 30 % on day 9) and its page."""
    db = tmp_path / "h.duckdb"
    with History(db) as history:
        run_id = history.start_run("synthetic", "test", "serial", 28)
        for robot_id in ("r01", "r02"):
            for day in range(14):
                fc = 5.0 * (1.3 if robot_id == "r02" and day >= 9 else 1.0) + 0.05 * rng.standard_normal(3)
                fit = DayFit(("fc1", "fc2", "fc3"), (1, 2, 3), fc, np.full(3, 0.05), np.ones(3), np.ones(3), 100)
                date = (dt.date(2026, 10, 1) + dt.timedelta(days=day)).isoformat()
                task = SessionTask(robot_id, date, (f"{robot_id}/{date}/a.csv",), f"{robot_id}{day}")
                history.write_session(run_id, SessionResult(task, "ok", fit, "", 0.1, "test"))
        bad = SessionTask("r01", "2026-10-15", ("r01/2026-10-15/a.csv",), "bad")
        history.write_session(run_id, SessionResult(bad, "failed", None, "RecordingError: line 3 is not numbers"))
        history.replace_findings(run_id, detect_drift(history.parameter_rows(), baseline_days=5))
        path = write_report(history, tmp_path / "report.html")
    return path


def test_report_page_is_self_contained_with_table_plots_and_onsets(report):
    page = report.read_text()
    assert page.count("Plotly.newPlot") == 4  # two figures per robot: the parameters, the validation error
    assert not re.search(r"<script[^>]+src=", page)  # plotly inlined: opens from disk without network
    assert page.count("plotly.js (basic - minified)") == 1 and len(page) < 1_500_000  # the 1.2 MB bundle, once
    assert re.search(r'<tr class="alarm"><td><a href="#r02">r02', page)
    found = re.search(r"joint 3 Coulomb friction \+(\d+) % since 2026-10-10 .*: gearbox wear or lubrication", page)
    assert found and abs(int(found.group(1)) - 30) <= 2 and "onset fc3" in page
    assert "RecordingError: line 3 is not numbers" in page


def _render(path) -> tuple:
    """(DOM after the scripts ran, console lines) of a page in headless Chromium."""
    done = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=3000", "--dump-dom", path.as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    return done.stdout, [line for line in done.stderr.splitlines() if ":CONSOLE" in line]


@pytest.mark.skipif(
    CHROMIUM is None, reason="no Chromium on this machine (apt-get install chromium) to render the page"
)
def test_report_renders_in_headless_chromium_without_console_errors(report, tmp_path):
    dom, console = _render(report)
    assert console == []
    assert dom.count('class="main-svg"') >= 2 * 4  # plotly drew the four figures (its SVG layers)
    control = tmp_path / "bad.html"  # the check sees a console error when there is one
    control.write_text("<html><body><script>console.error('boom'); missing();</script></body></html>")
    assert any("boom" in line for line in _render(control)[1])
