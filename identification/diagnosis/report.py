"""DiagnosisReport: what is missing from the model, where, how big, and how much the fit improves with it.

The report holds the findings (most important first), per-joint validation RMSE and R^2 before and
after, the residual analysis of the nominal model and the augmented model; it renders as JSON
(``to_json``), Markdown (``to_markdown``) and plots (``save_plots``). Every gain it prints is computed by
``rmse_change`` from the RMSE pair printed beside it; a joint whose RMSE rises gets a sentence saying why
(``joint_notes``), and effects the nominal parameters absorb are listed with the parameters and the fraction
(``confounding``). Terms with a shape in the joint angle (a spring's polynomial) are plotted against the angle.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from identification.calibration.held_friction import HeldFriction
from psdm_casadi.fileio import OutputFolder, atomic_write, markdown_escape

NO_FINDING = "no significant missing physics"
IMAGES = (".png", ".svg", ".jpg")  # the written files the Markdown report shows as images; the others it links
POOR_R2 = 0.5  # a joint predicted below this R^2 is named beside "no significant missing physics"
#: The files ``DiagnosisReport.save`` writes (the plots only with ``plots=True``).
REPORT_FILES = (
    "report.md",
    "report.json",
    "residuals.png",
    "fit.png",
    "augmented_model.json",
    "augmented_inverse_dynamics.casadi",
    "torque_vs_angle.png",
    "unnamed_effects.png",
    "report.html",
)


def rmse_change(before: float, after: float) -> tuple:
    """``(gain, text)`` of a validation RMSE pair [N m]: gain ``1 - after / before`` and the text
    ``"before -> after N m (gain g %)"`` printed with it (one function, so the gain always matches the pair)."""
    gain = 1.0 - float(after) / max(float(before), 1e-300)
    return gain, f"{float(before):.3g} -> {float(after):.3g} N m (gain {gain:.1%})"


@dataclass(frozen=True)
class Finding:
    """One missing effect: key, joints (0-based), physical parameters, validation RMSE per joint before/after."""

    effect: str
    label: str
    joints: tuple
    parameters: dict
    coefficients: tuple
    feature_names: tuple
    explanation: str
    signature: str
    rmse_before: tuple
    rmse_after: tuple
    delta_bic: float
    validation_gain: float
    notes: tuple = ()
    shape_note: str = ""
    correction: str = ""  # a value of the nominal model that does not hold, said instead of an effect (a file's offset)

    def joint_gain(self, joint: int | None = None) -> float:
        """Validation gain on ``joint`` (default the first named one), from the pair the sentence prints."""
        j = self.joints[0] if joint is None else joint
        return rmse_change(self.rmse_before[j], self.rmse_after[j])[0]

    def to_dict(self) -> dict:
        return {
            "effect": self.effect,
            "label": self.label,
            "joints": [j + 1 for j in self.joints],
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "rmse_before": list(self.rmse_before),
            "rmse_after": list(self.rmse_after),
            "delta_bic": self.delta_bic,
            "validation_gain": self.validation_gain,
            "joint_gain": self.joint_gain(),
            "explanation": self.explanation,
            "notes": list(self.notes),
            "shape_note": self.shape_note,
            "correction": self.correction,
        }

    def sentence(self) -> str:
        j = self.joints[0]
        joints = ", ".join(str(x + 1) for x in self.joints)
        if self.correction:  # no missing effect: the nominal model's own value, found not to hold
            return f"joint {joints}: {self.correction}; validation RMSE on joint {j + 1} {self._change(j)}"
        params = ", ".join(f"{k} = {v:.4g}" for k, v in self.parameters.items())
        return (
            f"joint{'s' if len(self.joints) > 1 else ''} {joints}: {self.signature}; best explained by "
            f"`{self.effect}` ({self.explanation}), {params}; validation RMSE on joint {j + 1} {self._change(j)}"
        )

    def _change(self, j: int) -> str:
        return rmse_change(self.rmse_before[j], self.rmse_after[j])[1]


@dataclass(frozen=True, eq=False)
class DiagnosisReport:
    """Result of ``diagnose``. Joints are 0-based in attributes and 1-based in text and JSON."""

    robot_name: str
    n_dof: int
    friction: str
    rigid_body: str
    findings: tuple
    rmse_before: tuple
    rmse_after: tuple
    r2_before: tuple
    r2_after: tuple
    rmse_train_before: tuple
    rmse_train_after: tuple
    residual_findings: tuple
    candidates_tried: int
    augmented: object
    validation_t: np.ndarray
    validation_q: np.ndarray
    validation_qd: np.ndarray
    validation_tau: np.ndarray
    validation_nominal: np.ndarray
    validation_final: np.ndarray
    joint_notes: tuple = ()
    confounding: tuple = ()
    dropped: tuple = ()
    rigid_body_notes: tuple = ()  # ``rigid_body="auto"``: why the rigid body was identified (``rigid_body_choice``)
    nominal_model: str = ""  # the model the diagnosis started from (a calibrated model file, or the robot file)
    preparation: str = ""  # how the recordings were prepared (``model_preparation.Preparation.text``)
    model_file_rmse: tuple = ()  # a calibrated model's own validation RMSE per joint, as ``psdm validate`` computes it
    before_is_model_file: bool = False  # "before" is that model file as it is, on the samples validate judges it on
    unstable: tuple = ()  # ``second_opinion.UnstableFinding``: qualified on one recording, not on another; not kept
    rejected: tuple = ()  # (label, reason): would have qualified, but its parameters are physically meaningless
    opinion_route: str = ""  # how findings were checked beyond the validation recording (``second_opinion``)
    recordings: tuple = ()  # ``recording_checks.RecordingCheck`` per validation recording
    left_out: tuple = ()  # joints without a torque measurement, left out and not diagnosed (one sentence each)
    held_friction: tuple = ()  # (name, value): friction the nominal model holds at a model file's values (no refit)
    held_out: tuple = ()  # sentences: the parts of recordings held out for validation (``data.holdout``)
    after_source: str = ""  # which model the "after" is (a model file's: the one --apply writes, ``applied_after``)
    apply_file: str = ""  # ``diagnose --apply``'s output where it writes the model with the findings ("" otherwise)
    apply_refused: bool = False  # ``--apply`` was given and writes nothing (the gates refused, or nothing to add)
    applied: object = None  # that model (``applied_model.AppliedModel``), which ``diagnose --apply`` judges and writes
    refit_training: object = None  # the recordings that model trained on (``refit_training.RefitTraining``)
    payload_check: tuple = ()  # sentences: the load each validation recording carries that nothing states, by its file
    payload_check_as: str = ""  # how that check judges them (as ``psdm validate``, or as identify its held-out ones)
    payload_checks: tuple = ()  # per validation recording {"recording": file, "load": its load's dict or None}
    friction_temperature: str | None = None  # where the model file's friction law was read on the first (as validate)
    file_offsets: tuple = ()  # ``file_offsets.FileOffset``: a model file's data-chosen offsets fitted again
    carried_sizes: tuple = ()  # ``carried_sizes.CarriedSize``: a model file's carried findings read against its sizes
    nothing_applied: str = ""  # why a model file's diagnosis applies nothing (its findings the file's own, at its size)

    @property
    def findings_not_holding(self) -> tuple:
        """Labels of the findings whose torque does not lower its joints' error on some validation recording."""
        return tuple(sorted({f.label for r in self.recordings for f in r.findings if not f.holds}))

    @property
    def effects(self) -> tuple:
        return tuple(f.effect for f in self.findings)

    def summary(self) -> str:
        if not self.findings:
            return NO_FINDING
        return "; ".join(
            f"{f.effect} on joint{'s' if len(f.joints) > 1 else ''} {', '.join(str(j + 1) for j in f.joints)}"
            for f in self.findings
        )

    def to_dict(self) -> dict:
        return {
            "robot": self.robot_name,
            "friction": self.friction,
            "rigid_body": self.rigid_body,
            "summary": self.summary(),
            "findings": [f.to_dict() for f in self.findings],
            "rmse_before": _numbers(self.rmse_before),  # None for a joint without a torque measurement
            "rmse_after": _numbers(self.rmse_after),
            "r2_before": _numbers(self.r2_before),
            "r2_after": _numbers(self.r2_after),
            "rmse_train_before": list(self.rmse_train_before),
            "rmse_train_after": list(self.rmse_train_after),
            "candidates_tried": self.candidates_tried,
            "residual_analysis": [r.to_dict() for r in self.residual_findings],
            "joint_notes": list(self.joint_notes),
            "confounding": [c.to_dict() for c in self.confounding],
            "dropped": list(self.dropped),
            "rigid_body_notes": list(self.rigid_body_notes),
            "file_offsets": [o.to_dict() for o in self.file_offsets],
            "carried_sizes": [s.to_dict() for s in self.carried_sizes],
            "nothing_applied": self.nothing_applied or None,
            "nominal_model": self.nominal_model,
            "preparation": self.preparation,
            "held_out": list(self.held_out),
            "model_file_rmse": _numbers(self.model_file_rmse),
            "before_is_model_file": self.before_is_model_file,
            "second_opinion": self.opinion_route or None,
            "unstable": [u.to_dict() for u in self.unstable],
            "validation_recordings": [r.to_dict() for r in self.recordings],
            "rejected": [{"label": label, "reason": reason} for label, reason in self.rejected],
            "left_out": list(self.left_out),
            "held_friction": dict(self.held_friction),
            "after_source": self.after_source or None,
            "refit_training": None if self.refit_training is None else self.refit_training.to_dict(),
            "payload_check": self.payload_checks[0]["load"] if self.payload_checks else None,  # the first's
            "payload_checks": [dict(entry) for entry in self.payload_checks],  # every validation recording's
            "friction_temperature": self.friction_temperature,  # as psdm validate's field
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, default=float)

    def to_markdown(self, plots: dict | None = None) -> str:
        lines = [
            f"# Missing-physics diagnosis: {self.robot_name}",
            "",
            f"Nominal model: {self._nominal()} + {self.friction} friction fitted on the training recording"
            f"{self._held_text()}; {self.candidates_tried} candidate fits judged on the validation recording.",
            "",
            *([f"Preparation: {self.preparation}.", ""] if self.preparation else []),
            *([f"Held out: {'; '.join(self.held_out)}.", ""] if self.held_out else []),
            *(
                ["Not diagnosed (no torque measurement):", "", *(f"- {s}" for s in self.left_out), ""]
                if self.left_out
                else []
            ),  # fmt: skip
            *self._route_lines(),
            "## Findings",
            "",
        ]
        if not self.findings:
            lines.append(
                f"**{NO_FINDING}**: no candidate term lowered a joint's validation RMSE enough to earn its parameters."
            )
            lines += ["", caveat] if (caveat := self.no_finding_caveat()) else []
        for k, f in enumerate(self.findings, 1):
            lines.append(f"{k}. {f.sentence()} (dBIC {f.delta_bic:.0f}){self._model_file_note(f)}.")
            lines += [f"   - {note}" for note in f.notes + ((f.shape_note,) if f.shape_note else ())]
        lines += self._notes_markdown()
        lines += [
            "",
            "## Validation per joint",
            "",
            "| joint | RMSE before [N m] | RMSE after [N m] | R^2 before | R^2 after |",
            "|---|---|---|---|---|",
        ]
        for j in range(self.n_dof):
            lines.append(
                f"| {j + 1} | {self.rmse_before[j]:.4g} | {self.rmse_after[j]:.4g} | "
                f"{self.r2_before[j]:.4f} | {self.r2_after[j]:.4f} |"
            )
        if self.before_is_model_file:
            after = self.after_source or "the diagnosis's model with the findings"
            lines += ["", "RMSE before is the model file as it is, on the samples of its own preparation ('psdm "
                      f"validate' gives the same numbers); after: {after}."]  # fmt: skip
        elif self.model_file_rmse:
            own = ", ".join(f"joint {j + 1} {v:.4g}" for j, v in enumerate(self.model_file_rmse))
            lines += ["", "RMSE before is the nominal model refitted on the training recording; the model file as it "
                      f"is (as 'psdm validate' computes it): {own} N m."]  # fmt: skip
            lines += [f"RMSE after: {self.after_source}."] if self.after_source else []
        lines += ["", f"Refit: {self.refit_training.sentence()}."] if self.refit_training is not None else []
        lines += self._recordings_markdown()
        if self.payload_check:  # ``psdm diagnose``'s check of each validation recording (``cli.diagnose_loads``)
            lines += ["", f"## Payload check (as {self.payload_check_as})"]
            lines += [x for sentence in self.payload_check for x in ("", sentence)]
        lines += ["", "## Residual analysis of the nominal model (validation)", ""]
        for j in range(self.n_dof):
            items = [r for r in self.residual_findings if r.joint == j]
            lines.append("- " + "; ".join(r.text for r in items))
        images = {name: Path(path).name for name, path in (plots or {}).items() if Path(path).suffix in IMAGES}
        files = [Path(path).name for name, path in (plots or {}).items() if name not in images]
        lines += ["", "## Plots", "", *(f"![{name}]({file})" for name, file in images.items())] if images else []
        lines += ["", "## Files", "", *(f"- [{file}]({file})" for file in files)] if files else []
        return "\n".join(lines) + "\n"

    def no_finding_caveat(self) -> str:
        """Beside "no significant missing physics", what it does not mean ("" when nothing qualifies it): candidates
        that lowered the validation error but did not hold on every recording or training block, and the joints the
        model predicts poorly (the Kinova's robot file, defaults: torque_offset[j1] unstable, joint 7 at R^2 -6.76,
        was reported as nothing missing)."""
        poor = [f"{j + 1} (R^2 {v:.3g})" for j, v in enumerate(self.r2_after) if np.isfinite(v) and v < POOR_R2]
        if self.findings or (not self.unstable and not poor):
            return ""
        steps = "; ".join(
            f"{', '.join(f'`{u.label}`' for u in self.unstable if u.next_step() == step)}: {step}"
            for step in dict.fromkeys(u.next_step() for u in self.unstable)
        )
        parts = [
            f"{len(self.unstable)} candidate(s) lowered the validation error but did not hold on every "
            f"recording or training block (under Unstable; {steps})"
        ] * bool(self.unstable)
        parts += [f"the model predicts joint(s) {', '.join(poor)} poorly"] * bool(poor)
        return f"That is not a model that misses nothing: {'; '.join(parts)}."

    def _model_file_note(self, finding) -> str:
        """Where a finding's "before" on its joint is not the model file's own RMSE there (a finding after others, a
        rigid body identified again, the file's friction refitted on another training recording): the model file's,
        so that its before -> after is not read as the model file's improvement; said wherever the two differ in the
        digits printed, with the file's in the table's digits."""
        j = finding.joints[0] if finding.joints else None
        if j is None or j >= len(self.model_file_rmse) or not np.isfinite(self.model_file_rmse[j]):
            return ""
        own, before = float(self.model_file_rmse[j]), float(finding.rmse_before[j])
        if f"{before:.3g}" == f"{own:.3g}":  # the same number as printed: nothing to tell apart
            return ""
        table = " (the table's before)" if self.before_is_model_file else ""
        what = ("the diagnosis's nominal (the rigid body identified again and the friction refitted on the training "
                "recording)" if self.rigid_body != "prior" else "the diagnosis's model before this finding (the "
                "model file's friction refitted on the training recording, with the findings above it)")  # fmt: skip
        return f"; that before is {what}, the model file as it is gives joint {j + 1} {own:.4g} N m{table}"

    def _held_text(self) -> str:
        """The friction held at the model file's values, in words ("" when none)."""
        if not self.held_friction:
            return ""
        held = HeldFriction(self.held_friction)
        offsets, inertias = HeldFriction(held.offsets).describe(), HeldFriction(held.drive_inertias).describe()
        others = held.offsets + held.drive_inertias
        friction = HeldFriction(tuple(v for v in held.values if v not in others)).describe()
        text = (f", except the friction identify held (joints that move one way only in its training data): held at "
                f"the model file's values in every fit ({friction})") if friction else ""  # fmt: skip
        if offsets:
            text += f"; the model file's torque offsets held at its values in every fit ({offsets})"
            refitted = ", ".join(f"offset{o.joint + 1}" for o in self.file_offsets)
            text += (f", with a free offset beside each the data chose ({refitted}), fitted again in every fit (see "
                     "the notes)") if refitted else ""  # fmt: skip
        if inertias:
            text += (f"; the model file's drive inertias below 0 (a torque measured behind the gearbox) or outside the "
                     f"base parameters (its drive columns) held at its values in every fit, the recalibrated rigid "
                     f"body's too ({inertias} kg m^2)")  # fmt: skip
        return text

    def _nominal(self) -> str:
        """What the diagnosis started from: the model it names, else the robot file's rigid body (or identified)."""
        if self.nominal_model:
            return self.nominal_model
        return f"rigid body {'from the robot file' if self.rigid_body == 'prior' else 'identified'}"

    def _recordings_markdown(self) -> list:
        """With several validation recordings: each one's per-joint RMSE before -> after, and the findings whose
        torque does not lower their joints' error there."""
        if len(self.recordings) < 2:
            return []
        head = " | ".join(f"joint {j + 1}" for j in range(self.n_dof))
        lines = ["", "### Each validation recording (RMSE before -> after [N m])", "", f"| recording | {head} |"]
        lines.append("|---" * (self.n_dof + 1) + "|")
        for r in self.recordings:
            cells = " | ".join(f"{a:.4g} -> {b:.4g}" for a, b in zip(r.rmse_before, r.rmse_after))
            lines.append(f"| {markdown_escape(r.name)} | {cells} |")
        failing = self.findings_not_holding
        lines += [f"- `{label}` does not lower its joints' error on every recording" for label in failing]
        return lines

    def _route_lines(self) -> list:
        """The sentence saying how findings were checked beyond the validation recording (``second_opinion``)."""
        if not self.opinion_route:
            return []
        how = {
            "validation recordings": "each finding was kept only if it passes the gates on every validation recording",
            "block cross-validation": "one validation recording: each finding was kept only if it also holds on every "
            "block of the training recording held out in turn (block cross-validation)",
        }.get(self.opinion_route, self.opinion_route)
        return [f"Second opinion: {how}.", ""]

    def _notes_markdown(self) -> list:
        """The sections on joints whose RMSE rose, terms the backward check dropped, and confounding."""
        lines = (
            ["", "## Rigid body", ""] + [f"- {text}" for text in self.rigid_body_notes] if self.rigid_body_notes else []
        )
        if self.joint_notes or self.dropped:
            lines += ["", "## Why some joints fit worse", ""] if self.joint_notes else ["", "## Notes", ""]
            lines += [f"- {text}" for text in self.joint_notes + self.dropped]
        if self.unstable:
            lines += ["", "## Unstable (not kept: they do not hold on every recording)", ""]
            lines += [f"- {u.sentence()}" for u in self.unstable]
        if self.rejected:
            lines += ["", "## Rejected as physically meaningless", ""]
            lines += [f"- `{label}`: {reason}" for label, reason in self.rejected]
        if self.confounding:
            lines += [
                "",
                "## Confounding: effects the nominal parameters absorb",
                "",
                "Share of each effect's torque (training recording, joint-weighted) that a change of the nominal "
                "model's own parameters reproduces, and the parameters that take most of it. Such an effect is "
                "absorbed by those parameters on these recordings rather than reported as missing physics:",
                "",
            ]
            lines += [f"- {c.sentence()}." for c in self.confounding if c.kept]
            by_effect = {}
            for c in self.confounding:
                if not c.kept:
                    by_effect.setdefault(c.effect, []).append(c)
            for effect, items in by_effect.items():
                parts = [f"{c.label} {c.fraction:.0%} ({c.parameters_text()})" for c in items]
                lines.append(f"- `{effect}`: " + "; ".join(parts) + ".")
        return lines

    def save_plots(self, directory, overwrite: bool = False) -> dict:
        """Residual against time, position and velocity, and measured vs model torque before/after; PNG files
        (``report_plots.save_plots``)."""
        from identification.diagnosis.report_plots import save_plots

        return save_plots(self, directory, overwrite)

    def save(self, directory, overwrite: bool = False, plots: bool = True) -> dict:
        """Write report.md, report.json, plots and the augmented model into ``directory``; return their paths.

        Existing files are refused before anything is written (unless ``overwrite``); the files are written
        into a staging folder and moved into ``directory`` together, so that an error or an interrupt leaves
        the directory as it was. The robot name is escaped in report.md.
        """
        directory = Path(directory)
        names = [name for name in REPORT_FILES if plots or not name.endswith((".png", ".html"))]
        existing = [name for name in names if (directory / name).exists()]
        if existing and not overwrite:
            raise FileExistsError(
                f"{str(directory / existing[0])!r} exists; pass overwrite=True (or --overwrite) to replace it."
            )
        with OutputFolder(directory, names, shared=True).staging() as stage:
            paths = self.save_plots(stage) if plots else {}
            text = replace(self, robot_name=markdown_escape(self.robot_name)).to_markdown(paths)
            paths["markdown"] = atomic_write(stage / "report.md", lambda h: h.write(text))
            js = self.to_json()
            paths["json"] = atomic_write(stage / "report.json", lambda h: h.write(js + "\n"))
            paths.update(self.augmented.save(stage))
            if plots:  # the page a reader opens first (``report_html.diagnosis_page``)
                from identification.report_html.diagnosis_page import diagnosis_page

                paths["html"] = diagnosis_page(self).write(stage / "report.html")
        return {key: directory / Path(path).name for key, path in paths.items()}


def _numbers(values) -> list:
    """``values`` as a JSON list: None where there is no number (a joint without a torque measurement)."""
    return [None if v is None or not np.isfinite(v) else float(v) for v in values]
