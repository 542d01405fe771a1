"""The report of one robot-day's update: a small self-contained HTML page written beside the history.

The client writes it as it stores the day (``runner``), at :func:`day_report_path`
(``HISTORY_days/ROBOT/YYYY-MM-DD/report.html`` beside ``HISTORY.duckdb``), and the fleet report links each
robot-day to it. It shows what the update found that day: the recordings, the baseline's and the refit's
validation RMSE per joint (an inline SVG bar chart: no script, no network), the validation-error check and the
diagnosis it ran, and every refitted parameter with its standard deviation; a failed day shows its error.
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from identification.fleet.session import SessionResult
from psdm_casadi.fileio import atomic_write

__all__ = ["day_report_path", "write_day_report"]

STYLE = (
    "body{font-family:sans-serif;margin:2em;max-width:60em}table{border-collapse:collapse}td,th{border:1px solid "
    "#ccc;padding:3px 8px;text-align:right}td:first-child,th:first-child{text-align:left}.bad{color:#b00}"
)
VERDICTS = {
    "quiet": "the baseline model's validation error is within its window's spread",
    "explained": "the baseline model's validation error rose, and the day's refit of the tracked terms explains it "
    "(see the drift findings of the fleet report)",
    "unexplained": "the validation error rose and the day's refit does not explain it: the diagnosis ran on the "
    "day's recordings",
    "friction_drift": "the validation error rose, the day's refit does not explain all of it, and the refitted "
    "Coulomb friction of every such joint left its window's: friction drift",
}


def day_report_path(db_path, robot_id: str, day: str) -> Path:
    """Where the report of a robot-day of the history ``db_path`` goes."""
    db_path = Path(db_path)
    return db_path.parent / f"{db_path.stem}_days" / robot_id / str(day) / "report.html"


def _bars(base: np.ndarray, refit: np.ndarray) -> str:
    """An inline SVG of the two RMSE per joint (grey: the baseline model, blue: the day's refit)."""
    width, row, top = 420, 22, max(float(np.max(base)), float(np.max(refit)), 1e-12)
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width + 160}" height="{row * len(base) + 10}">']
    for j, (b, r) in enumerate(zip(base, refit)):
        y = 5 + j * row
        parts.append(f'<text x="0" y="{y + 14}" font-size="12">joint {j + 1}</text>')
        parts.append(f'<rect x="60" y="{y}" width="{width * b / top:.1f}" height="9" fill="#999"/>')
        parts.append(f'<rect x="60" y="{y + 9}" width="{width * r / top:.1f}" height="9" fill="#36c"/>')
        parts.append(f'<text x="{width + 66}" y="{y + 14}" font-size="11">{b:.3g} / {r:.3g} N m</text>')
    return "".join(parts + ["</svg>"])


def _check(result: SessionResult) -> list:
    c = result.check
    if c is None:
        return ["<p>No validation-error check: a day of the baseline window (it defines the reference).</p>"]
    joints = f" (joint {', '.join(map(str, c.joints))})" if c.joints else ""
    out = [f"<p>Check against the window from {c.since}: <b>{c.verdict}</b>{joints}: {VERDICTS[c.verdict]}. "
           f"Largest statistic {c.statistic:.2f} (refit {c.refit_statistic:.2f}), critical value "
           f"{c.threshold:.2f}.</p>"]  # fmt: skip
    if c.verdict == "friction_drift":
        out.append("<h2>Friction drift</h2><ul>")
        out += [f"<li>{html.escape(f.text)}</li>" for f in result.diagnosis]
        out.append("</ul>")
    if c.verdict == "unexplained":
        if result.diagnosis_error:
            out.append(f'<p class="bad">The diagnosis did not run: {html.escape(result.diagnosis_error)}</p>')
        elif result.diagnosis:
            out.append("<h2>Diagnosis</h2><ul>")
            out += [f"<li>{html.escape(f.text)}</li>" for f in result.diagnosis]
            out.append("</ul>")
        else:
            out.append("<p>The diagnosis named no effect of its library.</p>")
    return out


def write_day_report(result: SessionResult, path) -> Path:
    """Write the day's page (module docstring) to ``path`` (folders created); returns it."""
    task, fit = result.task, result.fit
    title = f"{task.robot_id} {task.day}"
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{STYLE}</style></head><body><h1>{html.escape(title)}: {result.status}</h1>",
             f"<p>Software {html.escape(result.software_version)}, {result.seconds:.2f} s; recordings (content "
             f"sha256 {task.content_hash[:12]}...):</p><ul>"]  # fmt: skip
    parts += [f"<li>{html.escape(str(p))}</li>" for p in task.paths]
    parts.append("</ul>")
    if fit is None:
        parts.append(f'<p class="bad">{html.escape(result.error)}</p>')
    else:
        parts.append(f"<h2>Validation RMSE per joint</h2><p>{fit.n_samples} prepared samples; grey: the baseline "
                     "model, blue: the day's refit.</p>" + _bars(fit.rmse_baseline, fit.rmse_refit))  # fmt: skip
        parts += _check(result)
        parts.append("<h2>Refitted parameters</h2><table><tr><th>parameter</th><th>joint</th><th>value</th>"
                     "<th>sigma</th></tr>")  # fmt: skip
        parts += [f"<tr><td>{html.escape(n)}</td><td>{j}</td><td>{v:.6g}</td><td>{s:.3g}</td></tr>"
                  for n, j, v, s in zip(fit.names, fit.joints, fit.values, fit.sigmas)]  # fmt: skip
        parts.append("</table>")
    parts.append("</body></html>")
    data = "\n".join(parts).encode("utf-8")
    return atomic_write(path, lambda handle: handle.write(data), overwrite=True, mode="wb")
