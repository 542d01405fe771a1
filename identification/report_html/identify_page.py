"""The page of ``psdm identify``: is the calibrated model consistent, plausible and better than the robot file,
and what to do next; then per-joint measured vs predicted torque with the residual, and the parameters with their
standard deviations as error bars.

Every number comes from the calibrated-model document (``CalibratedModel.document``: ``validation``,
``warnings``, ``base``, ``drive``, ``standard``) or from the model's own prediction of a recording
(``CalibratedModel.predict_recording``, as ``psdm validate``), so the page says what the file says.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identification.report_html.page import Page, figure_div, paragraphs, table

#: Most samples per joint plotted (a longer recording is plotted every k-th sample; the RMSE uses all).
MAX_PLOTTED = 4000
#: The validation columns of the model file shown in the table, with their headings.
VALIDATION_COLUMNS = (
    ("rmse", "identified"),
    ("rmse_ols", "unconstrained"),
    ("rmse_prior", "robot file"),
    ("r2", "R^2 identified"),
)


@dataclass(frozen=True)
class TorqueSeries:
    """Measured and predicted joint torques [N m] of one recording, on the prepared samples the RMSE uses; ``taken_off``
    names the load whose torque the measured one is shown without, as the validation (held out) or the fit (training)
    took it off (empty: none)."""

    name: str
    held_out: bool
    t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    taken_off: str = ""


def torque_series(calibrated, model, robot, recordings, names, held_out: bool) -> list:
    """``TorqueSeries`` of ``recordings`` (raw, joint side) predicted by ``calibrated`` as ``psdm validate`` does. A
    held-out recording is shown as the report's and the JSON's validation judge it (``held_out_load.judge_recording``):
    the load it states, or a plausible one nothing states, taken off the measured torque, so that the plot's residual
    is the one whose RMSE they report (with the load left in, the load's torque would fill the plot). A training
    recording is shown as the fit weighed it: the load it states (known, or unknown as the model identified it) taken
    off, nothing else looked for."""
    from identification.data.torque_constants import recording_kt

    out = []
    for name, recording in zip(names, recordings):
        kt = recording_kt(robot, recording)
        prepared, predicted, with_load, taken_off = judged_load(robot, calibrated, model, recording, kt, name, held_out)
        measured = prepared.tau - (with_load - predicted)
        out.append(TorqueSeries(Path(str(name)).name, held_out, prepared.t, measured, np.asarray(predicted),
                                taken_off))  # fmt: skip
    return out


def judged_load(robot, calibrated, model, recording, kt, name, unstated=True) -> tuple:
    """``(prepared recording, prediction, prediction with the load's torque, what was taken off)`` of a recording as
    ``psdm validate`` and identify's validation judge it (``held_out_load.judge_recording``): the load its sidecar (or
    the model file's list for it) states (``payload_fit.stated_payload``), else (``unstated``: a held-out recording) a
    plausible one nothing states; without a load the prediction twice and ``""``."""
    from identification.calibration.held_out_load import judge_recording
    from identification.calibration.payload_fit import stated_payload
    from identification.calibration.refit_training import listed_configuration

    listed = listed_configuration(calibrated.document, name)
    stated, _ = stated_payload(listed, calibrated.configurations, "the model")
    if stated is None and not unstated:
        prepared, predicted = calibrated.predict_recording(model, recording, kt)
        return prepared, predicted, predicted, ""
    check = judge_recording(robot, calibrated, model, recording, kt, stated, str(name))
    if stated is not None:
        taken_off = f"the stated load {listed.name!r} ({float(stated[0]):.3g} kg)"
    elif check.taken_off:
        taken_off = f"the {check.load.found.mass:.3g} kg load nothing states"
    else:
        return check.prepared, check.predicted, check.predicted, ""
    _, predicted = calibrated.predict_recording(model, recording, kt)  # the model's own, the load's torque left out
    return check.prepared, predicted, check.predicted, taken_off


@dataclass(frozen=True)
class NextFiles:
    """The files the page's next step names: the model file identify wrote (``model``) and the ``psdm diagnose``
    command with this run's recordings (``diagnose``, as identify prints it; empty: a placeholder command). Without
    them (the Python API, which writes no file) the page says ``MODEL.json``."""

    model: str = "MODEL.json"
    diagnose: str = ""

    def diagnose_command(self) -> str:
        """``psdm diagnose`` of the model file with the run's recordings, writing the next model beside it."""
        command = self.diagnose or f"psdm diagnose {self.model} --train TRAIN.csv --validate OTHER.csv"
        return f"{command} --apply {_beside(self.model, '_2.json')}"

    def exports(self) -> str:
        """The three exports of the model file, each to a file named after it."""
        m = self.model
        return (f"psdm codegen {m} --out {_beside(m, '_c')} (C), psdm export-urdf {m} {_beside(m, '_identified.urdf')} "
                f"or psdm export-mjcf {m} {_beside(m, '_identified.xml')}")  # fmt: skip


def _beside(model: str, suffix: str) -> str:
    """A file named after the model file, in its folder (``out/kinova.json``, ``_identified.urdf`` ->
    ``out/kinova_identified.urdf``: never the robot's own ``kinova.urdf``)."""
    path = Path(model)
    return str(path.with_name(path.stem + suffix))


def identify_page(document: dict, series=(), files: NextFiles | None = None) -> Page:
    """The report page of a calibrated-model ``document`` and the ``TorqueSeries`` it predicted; ``files`` names the
    model file and the recordings in the next step's commands."""
    names = document["robot"]["joint_names"]
    page = Page(f"Identified model: {document['robot']['name']}")
    _summary(page, document, files or NextFiles())
    warnings = list(document.get("warnings") or [])
    if warnings:
        page.section(f"Warnings stored with the fit ({len(warnings)})", paragraphs(warnings), open_=True)
    validation = (document.get("validation") or {}).get("recordings") or []
    if validation:
        page.section("Validation RMSE per joint", _validation_tables(validation, names))
    for s in series:
        kind = "held-out recording" if s.held_out else "training recording"
        judged = "the validation judged" if s.held_out else "the fit weighed"
        kind += f", {s.taken_off} taken off as {judged} it" if s.taken_off else ""
        divs = [_joint_figure(s, j, name) for j, name in enumerate(names)]
        page.section(f"Measured vs predicted torque: {s.name} ({kind})", "".join(divs))
    page.section("Parameters with their standard deviation (1 sigma error bars)", _parameter_figures(document))
    return page


def _summary(page: Page, document: dict, files: NextFiles) -> None:
    ident, standard = document.get("identification", {}), document.get("standard", {})
    n_rec = len(document.get("provenance", {}).get("recordings") or [])
    cutoff = ", ".join(f"{c:g}" for c in ident.get("cutoff_hz") or [])
    counts = f"{len(document['base']['values'])} base parameters and {len(document['drive']['values'])} drive"
    samples = f"{ident.get('n_samples', '?')} samples after filtering at {cutoff or '?'} Hz"
    condition = f"condition number {_number(ident.get('condition_number'))}"
    page.say(
        f"{counts} parameters identified from {n_rec} recording{'s' if n_rec != 1 else ''} ({samples}; {condition})."
    )
    mass = (document.get("validation") or {}).get("min_mass_eigenvalue")
    eigen = f"smallest pseudo-inertia eigenvalue {_number(standard.get('min_pseudo_inertia_eigenvalue'))}"
    eigen += "" if mass is None else f", smallest mass-matrix eigenvalue {_number(mass)}"
    if not standard.get("checked", True):
        page.say("NOT checked for physical consistency (--no-consistency): the mass matrix may be indefinite.", "bad")
    elif standard.get("consistent"):
        page.say(f"Physically consistent ({eigen}).", "good")
    else:
        page.say(f"NOT physically consistent ({eigen}): do not simulate or control the robot with it.", "bad")
    warnings = document.get("warnings") or []
    if warnings:
        first = warnings[0].split(". ")[0]
        page.say(f"Plausibility: {len(warnings)} warning{'s' if len(warnings) != 1 else ''} stored with the fit "
                 f"(section below); the first: {first}.", "warn")  # fmt: skip
    elif _poorly_predicted(document, document["robot"]["joint_names"]):
        page.say("Plausibility: no warning stored, but a validated joint is predicted worse than by its mean torque "
                 "(below).", "warn")  # fmt: skip
    else:
        page.say("Plausibility: no warning (friction, masses and each joint's fit within the checks).", "good")
    for entry in (document.get("validation") or {}).get("recordings") or []:
        page.say(*_comparison(entry, document["robot"]["joint_names"]))
    page.say(_next_step(document, files))


def _number(value) -> str:
    """A number of the file as ``%.3g``; "n/a" where the file holds none (an unchecked model's eigenvalues)."""
    return "n/a" if value is None else f"{float(value):.3g}"


def _comparison(entry: dict, names) -> tuple:
    """(sentence, tone): the validation RMSE against the robot file's and the unconstrained fit's, per joint."""
    ours = np.asarray(entry["rmse"], dtype=float)
    name = _recording_name(entry)
    if "rmse_prior" not in entry:
        return (
            f"Validation on {name}: RMSE summed over joints {ours.sum():.4g} N m (no robot-file prior to compare).",
            "",
        )
    prior = np.asarray(entry["rmse_prior"], dtype=float)
    better = int(np.sum(ours < prior))
    text = (f"Validation on {name}: better than the robot file on {better} of {len(ours)} joints (RMSE summed over "
            f"joints {prior.sum():.4g} -> {ours.sum():.4g} N m).")  # fmt: skip
    text += _against_baseline(entry, ours)
    ols = np.asarray(entry.get("rmse_ols", ours), dtype=float)
    worse = [f"{names[j]} ({ours[j]:.3g} vs {ols[j]:.3g} N m)" for j in range(len(ours)) if ours[j] > 1.5 * ols[j]]
    if worse:
        text += " The physically consistent model fits clearly worse than the unconstrained fit on " + ", ".join(worse)
        text += ": the model lacks something there (see the warnings)."
    return text, "good" if better == len(ours) and not worse else "warn"


def _against_baseline(entry: dict, ours) -> str:
    """The same against the model identify replaces, the robot file's rigid body with its friction fitted (the
    validation table's file baseline, which identify's check judges): the robot file alone states no friction, so
    "better on 7 of 7" against it said nothing of the Kinova's joints 1, 5 and 6, where the baseline was better."""
    if entry.get("rmse_robot_file_baseline") is None:
        return ""
    base = np.array([np.nan if v is None else v for v in entry["rmse_robot_file_baseline"]], dtype=float)
    better, worse = int(np.sum(ours < base)), [str(j + 1) for j in range(len(ours)) if ours[j] > base[j]]
    above = f"; the baseline is lower on joint{'s' if len(worse) > 1 else ''} {', '.join(worse)}" if worse else ""
    return (
        f" Against its rigid body with friction fitted (the file baseline, which the never-worse check judges): "
        f"better on {better} of {len(ours)} joints ({np.nansum(base):.4g} -> {ours.sum():.4g} N m{above})."
    )


def _recording_name(entry: dict) -> str:
    """A validation recording's name; for one ``--holdout`` cut, which part of it (``the held-out last 30 % of
    run.csv``): the page must not read as validated on the training recording."""
    name, part = Path(entry["recording"]).name, entry.get("held_out")
    return f"the held-out last {100 * float(part['fraction']):g} % of {name}" if part else name


def _poorly_predicted(document: dict, names) -> list:
    """``"joint_5 on NAME (R^2 -12)"`` for each validated joint predicted worse than by its mean torque."""
    out = []
    for entry in (document.get("validation") or {}).get("recordings") or []:
        r2 = entry.get("r2") or []
        out += [f"{names[j]} on {_recording_name(entry)} (R^2 {v:.3g})" for j, v in enumerate(r2)
                if v is not None and v < 0]  # fmt: skip
    return out


def _next_step(document: dict, files: NextFiles) -> str:
    """What to do next, from what the page found (the advice identify prints, not a contrary one), with the model file
    and the recordings of this run in its commands."""
    if not document.get("standard", {}).get("consistent", True):
        return "Next: record a better-exciting trajectory and identify again."
    if document.get("warnings"):
        return "Next: act on the warnings (each names its check and, where one helps, the command to run)."
    if not (document.get("validation") or {}).get("recordings"):
        return (f"Next: validate on a held-out recording (psdm validate {files.model} OTHER.csv), or, with one "
                "recording, identify again with --holdout 0.3 (its last 30 % held out).")  # fmt: skip
    poor = _poorly_predicted(document, document["robot"]["joint_names"])
    if poor:
        return (f"Next: diagnose it before using it: {', '.join(poor)} predicted worse than by the mean torque, a "
                f"torque the model lacks (a coupling, a spring, a load); {files.diagnose_command()} names it and adds "
                "it.")  # fmt: skip
    return f"Next: use it: {files.exports()}."


def _validation_tables(validation, names) -> str:
    parts = []
    for entry in validation:
        columns = [(k, label) for k, label in VALIDATION_COLUMNS if k in entry]
        rows = [[name] + [np.nan if entry[k][j] is None else float(entry[k][j]) for k, _ in columns]  # None: no torque
                for j, name in enumerate(names)]  # fmt: skip
        headers = ["joint"] + [f"{label}" + ("" if k == "r2" else " RMSE [N m]") for k, label in columns]
        parts.append(f"<h3>{html.escape(Path(entry['recording']).name)}</h3>" + table(headers, rows))
    return "".join(parts)


def _joint_figure(series: TorqueSeries, j: int, name: str) -> str:
    """Measured and predicted torque of joint ``j`` over time, and the residual below."""
    from plotly.subplots import make_subplots

    step = max(1, len(series.t) // MAX_PLOTTED)
    t, measured, predicted = series.t[::step], series.measured[::step, j], series.predicted[::step, j]
    rmse = float(np.sqrt(np.mean((series.measured[:, j] - series.predicted[:, j]) ** 2)))
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=[0.7, 0.3], vertical_spacing=0.05)
    label = f"measured, {series.taken_off} taken off" if series.taken_off else "measured"
    fig.add_scatter(x=t, y=measured, name=label, line={"color": "black", "width": 1}, row=1, col=1)
    fig.add_scatter(x=t, y=predicted, name="predicted", line={"width": 1, "color": "#1f77b4"}, row=1, col=1)
    fig.add_scatter(x=t, y=measured - predicted, name="residual", line={"width": 1, "color": "#cf222e"}, row=2, col=1)
    judged = f" (the arm's: {series.taken_off} taken off, as judged)" if series.taken_off else ""
    fig.update_layout(title=f"joint {j + 1} ({name}): RMSE {rmse:.4g} N m{judged}", height=380,
                      margin={"t": 40, "b": 30})  # fmt: skip
    fig.update_yaxes(title_text="torque [N m]", row=1, col=1)
    fig.update_yaxes(title_text="residual", row=2, col=1)
    fig.update_xaxes(title_text="t [s]", row=2, col=1)
    return figure_div(fig, f"joint-{j + 1}-{series.name}", "joint-plot")


def _parameter_figures(document: dict) -> str:
    """Base and drive parameters as points with 1-sigma error bars (drive parameters held at 0 left out)."""
    import plotly.graph_objects as go

    divs = []
    for key, title in (("base", "base parameters"), ("drive", "drive parameters (friction, offsets, inertias)")):
        block = document[key]
        keep = [k for k, n in enumerate(block["names"]) if not (n.startswith("offset") and block["std"][k] == 0)]
        fig = go.Figure(go.Scatter(
            x=[block["names"][k] for k in keep], y=[block["values"][k] for k in keep], mode="markers", name=title,
            error_y={"type": "data", "array": [block["std"][k] for k in keep], "visible": True}))  # fmt: skip
        fig.update_layout(title=title, height=380, margin={"t": 40, "b": 30}, yaxis_title="value (SI units)")
        divs.append(figure_div(fig, f"parameters-{key}", "parameter-plot"))
    return "".join(divs)
