"""The fleet report: one self-contained HTML page (plotly inlined), opened from disk without a server.

A fleet table (robot, last recording day, sessions ok and failed, status, alarms), then per robot the trend of
every tracked parameter that alarmed (or, for a quiet robot, its friction and the baseline's validation error)
with its sigma band and the onset marker of each finding, the baseline model's validation RMSE per joint over the
days (the cheapest drift signal), and the failed sessions with their errors. Plots, not walls of numbers: the page
holds two plotly figures per robot. Each robot lists its days as links to each day's own page (``day_report``,
beside the history), coloured by the day's validation-error check (window, quiet, explained, friction_drift,
unexplained, failed), and what the automatic diagnosis named on the days whose error rose unexplained.
"""

from __future__ import annotations

import html
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identification.fleet.day_report import day_report_path
from identification.fleet.history import History
from identification.report_html.page import plotly_bundle
from psdm_casadi.fileio import atomic_write

__all__ = ["FleetRow", "fleet_rows", "write_report"]

QUIET_PARAMETERS = ("fc", "kt")  # what a quiet robot's plot shows (the first of each joint's)
MAX_TRACES = 8


@dataclass(frozen=True)
class FleetRow:
    """One line of the fleet table."""

    robot_id: str
    last_day: str
    ok: int
    failed: int
    status: str
    alarms: tuple
    diagnoses: tuple = ()


def diagnosis_lines(history: History) -> dict:
    """{robot_id: lines}: each effect the automatic diagnosis named on a robot, with its days and parameters (those
    of its first day)."""
    effects: dict = {}
    for robot_id, day, effect, label, joints, parameters, gain, _ in history.diagnoses():
        entry = effects.setdefault(robot_id, {}).setdefault((label, joints), [effect, [], parameters, gain])
        entry[1].append(str(day))
    out = {}
    for robot_id, named in effects.items():
        lines = []
        for (_, joints), (effect, days, parameters, gain) in named.items():
            values = ", ".join(f"{k} = {v:.3g}" for k, v in list(parameters.items())[:3])
            plural = "s" if len(days) > 1 else ""
            lines.append(f"diagnosis: {effect.replace('_', ' ')} on joint {joints} ({values}; removes "
                         f"{100 * gain:.0f} % of its error) on {len(days)} day{plural} from {days[0]}")  # fmt: skip
        out[robot_id] = tuple(lines)
    return out


def fleet_rows(history: History) -> list:
    """The fleet table: status ``alarm`` with findings or diagnoses, ``failed`` with failed sessions only, else
    ``ok``."""
    findings: dict = {}
    for row in history.findings():
        findings.setdefault(row[0], []).append(row[-1])
    diagnoses = diagnosis_lines(history)
    rows = []
    for robot_id, ok, failed, last in history.session_counts():
        alarms, named = tuple(findings.get(robot_id, ())), diagnoses.get(robot_id, ())
        status = "alarm" if alarms or named else ("failed sessions" if failed else "ok")
        rows.append(FleetRow(robot_id, str(last), int(ok), int(failed), status, alarms, named))
    return rows


def _day_links(history: History, robot_id: str, report_dir: Path, verdicts: dict) -> str:
    """Each day of a robot as a link to its page (when written), coloured by its check's verdict."""
    links = []
    for day, status in history.connection.execute(
        "SELECT DISTINCT day, status FROM sessions WHERE robot_id = ? ORDER BY day", [robot_id]
    ).fetchall():
        kind = "failed" if status == "failed" else verdicts.get((robot_id, str(day)), "window")
        page = day_report_path(history.path, robot_id, str(day))
        label = f"{str(day)[5:]}"
        if page.is_file():
            href = Path(os.path.relpath(page, report_dir)).as_posix()
            links.append(f'<a class="day {kind}" href="{html.escape(href)}" title="{day}: {kind}">{label}</a>')
        else:
            links.append(f'<span class="day {kind}" title="{day}: {kind}">{label}</span>')
    return '<p class="days">Days (each links to its report): ' + " ".join(links) + "</p>"


def _series(history: History) -> dict:
    """{robot_id: {parameter: (days, values, sigmas)}} of the latest ok sessions."""
    out: dict = {}
    for row in history.parameter_rows():
        days, values, sigmas = out.setdefault(row.robot_id, {}).setdefault(row.name, ([], [], []))
        days.append(str(row.day))
        values.append(row.value)
        sigmas.append(row.sigma)
    return out


def _figure(robot_id: str, series: dict, findings: list):
    """A plotly figure of a robot: each chosen parameter relative to its first day, with a 1-sigma band."""
    import plotly.graph_objects as go

    alarmed = [f[2] for f in findings if f[2] in series]  # a validation-error finding has its own figure
    names = alarmed or [n for n in series if n.rstrip("0123456789") in QUIET_PARAMETERS]
    fig = go.Figure()
    for name in names[:MAX_TRACES]:
        days, values, sigmas = (np.asarray(x) for x in series[name])
        ref = values[0] if abs(values[0]) > 0 else 1.0
        scale = 100.0 / abs(ref)
        rel, band = (values - ref) * scale, sigmas * scale
        fig.add_trace(go.Scatter(x=list(days) + list(days[::-1]), y=list(rel + band) + list((rel - band)[::-1]),
                                 fill="toself", opacity=0.2, line={"width": 0}, showlegend=False, hoverinfo="skip",
                                 name=f"{name} +-1 sigma"))  # fmt: skip
        fig.add_trace(go.Scatter(x=list(days), y=list(rel), mode="lines+markers", name=name))
    for f in findings:
        if f[4] is not None:
            fig.add_vline(x=str(f[4]), line_dash="dash", line_color="red")
            fig.add_annotation(x=str(f[4]), y=1.0, yref="paper", text=f"onset {f[2]}", showarrow=False,
                               font={"color": "red"})  # fmt: skip
    fig.update_layout(
        title=f"{robot_id}: change from the first day [%] (band: 1 sigma)",
        height=360,
        margin={"l": 50, "r": 20, "t": 40, "b": 40},
        xaxis_title="day",
        yaxis_title="change [%]",
    )
    return fig


def _validation_figure(robot_id: str, rows: list):
    """The baseline model's validation RMSE per joint over the days: the cheapest drift signal."""
    import plotly.graph_objects as go

    fig = go.Figure()
    for joint in sorted({r[2] for r in rows}):
        mine = [r for r in rows if r[2] == joint]
        fig.add_trace(go.Scatter(x=[str(r[1]) for r in mine], y=[r[3] for r in mine], mode="lines",
                                 name=f"joint {joint}"))  # fmt: skip
    title = f"{robot_id}: the baseline model's torque RMSE per joint [N m]"
    margin = {"l": 50, "r": 20, "t": 40, "b": 40}
    fig.update_layout(title=title, height=260, margin=margin, xaxis_title="day", yaxis_title="RMSE [N m]")
    return fig


def _table(rows: list) -> str:
    lines = ["<table><tr><th>robot</th><th>last recording</th><th>sessions ok</th><th>failed</th><th>status</th>"
             "<th>alarms</th></tr>"]  # fmt: skip
    for r in rows:
        alarms = "<br>".join(html.escape(a) for a in (*r.alarms, *r.diagnoses)) or "-"
        lines.append(f'<tr class="{r.status.split()[0]}"><td><a href="#{r.robot_id}">{html.escape(r.robot_id)}</a>'
                     f"</td><td>{r.last_day}</td><td>{r.ok}</td><td>{r.failed}</td><td>{r.status}</td>"
                     f"<td>{alarms}</td></tr>")  # fmt: skip
    return "\n".join(lines + ["</table>"])


STYLE = (
    "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:1px solid #ccc;"
    "padding:4px 8px;text-align:left;vertical-align:top}tr.alarm td{background:#fde2e2}tr.failed td{background:#fff4d6}"
    ".day{display:inline-block;padding:1px 4px;margin:1px;border-radius:3px;font-size:80%;text-decoration:none;"
    "color:#000}.window{background:#eee}.quiet{background:#dff0d8}.explained{background:#fcf8e3}"
    ".unexplained{background:#f2dede;font-weight:bold}.friction_drift{background:#fcf8e3;font-weight:bold}"
    ".failed{background:#f0ad4e}"
)


def write_report(history: History, path, title: str = "Fleet report") -> Path:
    """Write the report page to ``path``; returns it. The plotly library is inlined once (no network needed)."""
    import plotly.io as pio

    rows = fleet_rows(history)
    series = _series(history)
    by_robot: dict = {}
    for f in history.findings():
        by_robot.setdefault(f[0], []).append(f)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{STYLE}</style><script type='text/javascript'>{plotly_bundle()}</script></head>",
             f"<body><h1>{html.escape(title)}</h1>", _table(rows)]  # fmt: skip
    validation: dict = {}
    for row in history.validation_rows():
        validation.setdefault(row[0], []).append(row)
    verdicts = {(row[0], str(row[1])): row[2] for row in history.checks()}
    report_dir = Path(path).resolve().parent
    for r in rows:
        parts.append(f'<h2 id="{r.robot_id}">{html.escape(r.robot_id)}: {r.status}</h2>')
        parts.append(_day_links(history, r.robot_id, report_dir, verdicts))
        if r.diagnoses:
            parts.append("<ul>" + "".join(f"<li>{html.escape(d)}</li>" for d in r.diagnoses) + "</ul>")
        if r.robot_id in series:
            figures = [_figure(r.robot_id, series[r.robot_id], by_robot.get(r.robot_id, [])),
                       _validation_figure(r.robot_id, validation.get(r.robot_id, []))]  # fmt: skip
            for fig in figures:  # scatter traces: plotly's basic bundle in the head draws them
                parts.append(pio.to_html(fig, full_html=False, include_plotlyjs=False))
    failures = history.failures()
    if failures:
        parts.append("<h2>Failed sessions</h2><ul>")
        parts += [f"<li>{html.escape(str(rid))} {day}: {html.escape(str(err))}</li>" for rid, day, err in failures]
        parts.append("</ul>")
    parts.append("</body></html>")
    data = "\n".join(parts).encode("utf-8")
    return atomic_write(path, lambda handle: handle.write(data), overwrite=True, mode="wb")
