"""The page of ``psdm diagnose``: what is missing from the model and how much the fit gains with it, then each
finding with its torque against its joint angle and its per-joint validation RMSE before and after, the
validation per joint, and the confounding as a small table.

Every number comes from the ``DiagnosisReport`` (``identification.diagnosis.report``): the findings' RMSE pairs,
the validation recording's measured torque and the nominal and augmented models' predictions of it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from identification.report_html.page import Page, figure_div, paragraphs, table

#: Most validation samples plotted per finding (every k-th sample of a longer recording).
MAX_PLOTTED = 4000


def diagnosis_page(report) -> Page:
    """The report page of a ``DiagnosisReport``."""
    page = Page(f"Missing-physics diagnosis: {report.robot_name}")
    _summary(page, report)
    for k, finding in enumerate(report.findings, 1):
        page.section(f"Finding {k}: {finding.label}", _finding_body(report, finding, k), open_=k == 1)
    page.section("Validation RMSE per joint, before and after", _validation(report))
    if report.confounding:
        page.section("Confounding: effects the nominal parameters absorb", _confounding(report.confounding))
    notes = tuple(report.rigid_body_notes) + tuple(report.joint_notes) + tuple(report.dropped)
    if notes:
        page.section("Notes (rigid body, joints that fit worse, terms dropped)", paragraphs(notes))
    residual = [r.text for r in report.residual_findings]
    if residual:
        page.section("Residual analysis of the nominal model (validation)", paragraphs(residual))
    return page


def _summary(page: Page, report) -> None:
    before, after = np.asarray(report.rmse_before, dtype=float), np.asarray(report.rmse_after, dtype=float)
    page.say(f"Nominal model: {report.nominal_model or report.rigid_body + ' rigid body'} with {report.friction} "
             f"friction; {report.candidates_tried} candidate fits judged on the validation recording.")  # fmt: skip
    if not report.findings:
        caveat = report.no_finding_caveat()  # unstable candidates or poorly predicted joints: not "all explained"
        page.say("No significant missing physics: no candidate lowered a joint's validation RMSE enough.",
                 "warn" if caveat else "good")  # fmt: skip
        page.say(caveat or "Next: the model explains these recordings; use it, or diagnose a recording that moves "
                 "differently.", "warn" if caveat else "")  # fmt: skip
        return
    page.say(f"Found: {report.summary()}.", "warn")
    page.say(f"Validation RMSE summed over joints {before.sum():.4g} -> {after.sum():.4g} N m with the findings; "
             f"lower on {int(np.sum(after < before))} of {len(before)} joints.",
             "good" if np.all(after <= before) else "warn")  # fmt: skip
    if any(c.kept for c in report.confounding):
        page.say("Some findings are partly absorbed by the nominal parameters (Confounding below).", "warn")
    if report.apply_file:  # --apply writes the model with the findings it keeps: that file is the one to use now
        f, stem = report.apply_file, str(Path(report.apply_file).with_suffix(""))
        page.say(f"Next: use the model --apply wrote, {f} (the findings the never-worse gate kept: Recalibration in "
                 f"the command's output): psdm codegen {f} --out {stem}_c (C), psdm export-urdf {f} "
                 f"{stem}_identified.urdf or psdm export-mjcf {f} {stem}_identified.xml.")  # fmt: skip
    elif report.apply_refused:
        page.say("Next: --apply wrote nothing (the command's output says why: a finding refused by the never-worse "
                 "gate, or nothing the model file lacks); the model file stays the model to use.")  # fmt: skip
    elif report.model_file_rmse:
        validate = "" if report.held_out else "--validate ... "  # a model's stored held-out part needs none
        page.say(f"Next: identify the model again with the findings: psdm diagnose MODEL.json --train ... {validate}"
                 "--apply NEW.json (it keeps a finding only if no joint gets worse).")  # fmt: skip
    else:
        page.say("Next: identify a calibrated model (psdm identify), then apply the findings to it with "
                 "psdm diagnose MODEL.json ... --apply NEW.json.")  # fmt: skip


def _finding_body(report, finding, k: int) -> str:
    text = paragraphs(
        [finding.sentence().replace("`", ""), *finding.notes, *([finding.shape_note] if finding.shape_note else [])]
    )
    return text + _angle_figure(report, finding, k) + _finding_rmse(report, finding, k)


def _shape(report, finding):
    """(term, coefficients) of a finding whose term is a torque of its joint's angle, else (None, None)."""
    augmented = report.augmented
    for term, c in zip(getattr(augmented, "terms", ()), getattr(augmented, "coefficients", ())):
        if term.label == finding.label and hasattr(term, "torque_of_angle"):
            return term, c
    return None, None


def _angle_figure(report, finding, k: int) -> str:
    """The finding's joint: the nominal and augmented residuals (centred) against its angle, and the term's shape."""
    import plotly.graph_objects as go

    term, c = _shape(report, finding)
    j = term.joint if term is not None else finding.joints[0]
    step = max(1, len(report.validation_t) // MAX_PLOTTED)
    q = report.validation_q[::step, j]
    before = report.validation_tau[::step, j] - report.validation_nominal[::step, j]
    after = report.validation_tau[::step, j] - report.validation_final[::step, j]
    fig = go.Figure()
    fig.add_scatter(x=q, y=before - np.mean(before), mode="markers", name="residual before (nominal)",
                      marker={"size": 3, "color": "#999"})  # fmt: skip
    fig.add_scatter(x=q, y=after - np.mean(after), mode="markers", name="residual after (with the findings)",
                      marker={"size": 3, "color": "#1f77b4"})  # fmt: skip
    if term is not None:
        grid = np.linspace(float(np.min(q)), float(np.max(q)), 200)
        shape = term.torque_of_angle(grid, c) - np.mean(term.torque_of_angle(report.validation_q[:, j], c))
        fig.add_scatter(x=grid, y=shape, mode="lines", name=finding.label, line={"width": 3, "color": "#cf222e"})
    title = f"joint {j + 1}: torque against its angle (validation recording)"
    fig.update_layout(title=title, height=380, margin={"t": 40, "b": 30})
    fig.update_layout(xaxis_title=f"q{j + 1} [rad]", yaxis_title=f"tau{j + 1} [N m]")
    return figure_div(fig, f"finding-{k}-angle", "finding-plot")


def _finding_rmse(report, finding, k: int) -> str:
    """The finding's per-joint validation RMSE before and after, as bars and as a table."""
    import plotly.graph_objects as go

    joints = [f"joint {j + 1}" for j in range(report.n_dof)]
    fig = go.Figure([go.Bar(x=joints, y=list(finding.rmse_before), name="before"),
                     go.Bar(x=joints, y=list(finding.rmse_after), name="after")])  # fmt: skip
    fig.update_layout(title="validation RMSE [N m] per joint", height=320, margin={"t": 40, "b": 30})
    rows = [[f"{j + 1}", float(b), float(a)] for j, (b, a) in enumerate(zip(finding.rmse_before, finding.rmse_after))]
    headers = ["joint", "RMSE before (the diagnosis's nominal) [N m]", "RMSE after [N m]"]
    if report.model_file_rmse:  # the file as it is, beside the nominal the diagnosis refitted (Panda joint 6)
        headers.append("model file as is [N m]")
        rows = [row + [float(v)] for row, v in zip(rows, report.model_file_rmse)]
    return figure_div(fig, f"finding-{k}-rmse", "finding-rmse") + table(headers, rows)


def _validation(report) -> str:
    rows = [[f"{j + 1}", float(report.rmse_before[j]), float(report.rmse_after[j]), float(report.r2_before[j]),
             float(report.r2_after[j])] for j in range(report.n_dof)]  # fmt: skip
    headers = ["joint", "RMSE before [N m]", "RMSE after [N m]", "R^2 before", "R^2 after"]
    if report.model_file_rmse:
        headers.append("model file as is [N m]")
        rows = [row + [float(v)] for row, v in zip(rows, report.model_file_rmse)]
    return table(headers, rows)


def _confounding(confounding) -> str:
    rows = [[c.label, "kept" if c.kept else "candidate", f"{c.fraction:.0%}", c.parameters_text().replace("`", "")]
            for c in confounding]  # fmt: skip
    return table(["effect", "status", "absorbed", "by the nominal parameters"], rows, text_columns=4)
