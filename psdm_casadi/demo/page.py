"""The demo's ``report.html``: the loop in one screen (the hidden spring, whether the diagnosis found it, the
calibration before and after, the C code's check), then the details folded: Table 3's "All" R^2 per joint before
and after, the findings with a link to the diagnosis' own page, and the demo's plots (embedded, so the page opens
from disk). Every number is the run's ``summary.json``'s.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

from identification.report_html.page import Page, figure_div, table


def demo_page(robot_name: str, summary: dict, folder) -> Page:
    """The page of a demo run whose report folder (plots, ``diagnosis/``) is ``folder``."""
    page = Page(f"psdm demo: {robot_name} (virtual robot, seed {summary['seed']})")
    diagnosis, before, after = summary["diagnosis"], summary["identification"], summary["recalibration"]
    hidden = diagnosis["hidden"]
    spring = f"joint {hidden['joint']} (k = {hidden['stiffness']} N m/rad, rest {hidden['rest']} rad)"
    page.say(f"The virtual robot carries a hidden spring on {spring} that the robot file does not know about.")
    found = [f for f in diagnosis["findings"] if f["effect"] == "spring" and f["joints"] == [hidden["joint"]]]
    labels = ", ".join(f["label"] for f in diagnosis["findings"]) or "nothing"
    page.say(f"Diagnosis found: {labels}.", "good" if found else "bad")
    page.say(f'Calibration with the spring unknown: worst "All" R^2 {before["r2_min_all"]:.3f}, mass matrix '
             f"{'positive definite' if before['consistent'] else 'NOT positive definite'}.",
             "good" if before["consistent"] else "warn")  # fmt: skip
    if "skipped" in after:
        page.say(f"Recalibration not run: {after['skipped']}", "bad")
    else:
        page.say(f'With the spring as a known term: worst "All" R^2 {after["r2_min_all"]:.3f}, mass matrix '
                 f"{'positive definite' if after['consistent'] else 'NOT positive definite'}.",
                 "good" if after["consistent"] else "bad")  # fmt: skip
    codegen = summary.get("codegen") or {}
    if codegen:
        error = codegen["feedforward_c_vs_casadi_max_abs"]
        tone = "good" if codegen["consistent"] else "bad"
        page.say(f"C code of the {codegen['model']} model: equals the CasADi torque to {error:.1e} N m.", tone)
    page.say("Next: your own robot: psdm identify ROBOT --data A.csv --validate B.csv --out model.json, then "
             "psdm diagnose model.json --train A.csv --validate B.csv.")  # fmt: skip
    page.section('Table 3: "All" R^2 per joint, spring unknown and known', _r2(before, after), open_=True)
    page.section("Diagnosis", _findings(diagnosis))
    page.section("Plots", _images(Path(folder)))
    return page


def _r2(before: dict, after: dict) -> str:
    import plotly.graph_objects as go

    joints = [f"joint {j + 1}" for j in range(len(before["r2_all"]))]
    bars = [go.Bar(x=joints, y=before["r2_all"], name="spring unknown")]
    rows = [[joint, float(b)] for joint, b in zip(joints, before["r2_all"])]
    if "r2_all" in after and "skipped" not in after:
        bars.append(go.Bar(x=joints, y=after["r2_all"], name="spring known"))
        rows = [row + [float(a)] for row, a in zip(rows, after["r2_all"])]
    fig = go.Figure(bars)
    fig.update_layout(title='"All" R^2 per joint', height=340, margin={"t": 40, "b": 30})
    headers = ["joint", "spring unknown", "spring known"][: len(rows[0])]
    return figure_div(fig, "demo-r2", "demo-plot") + table(headers, rows)


def _findings(diagnosis: dict) -> str:
    rows = []
    for f in diagnosis["findings"]:
        j = f["joints"][0] - 1
        params = ", ".join(f"{k} = {v:.4g}" for k, v in f["parameters"].items())
        rows.append([f["label"], params, float(f["rmse_before"][j]), float(f["rmse_after"][j])])
    link = '<p>Each finding\'s plots, the residual analysis and the confounding: <a href="diagnosis/report.html">'
    link += "diagnosis/report.html</a>.</p>"
    headers = ["finding", "parameters", "RMSE before on its joint [N m]", "after [N m]"]
    return link + (table(headers, rows, text_columns=2) if rows else "<p>No finding.</p>")


def _images(folder: Path) -> str:
    """The demo's PNG plots, embedded as data URIs (the page needs no other file to show them)."""
    parts = []
    for name in ("excitation.png", "validation_before.png", "validation_after.png"):
        path = folder / name
        if path.is_file():
            data = base64.b64encode(path.read_bytes()).decode("ascii")
            parts.append(f"<h3>{html.escape(name)}</h3><img style='max-width:100%' src='data:image/png;base64,{data}'>")
    return "".join(parts)
