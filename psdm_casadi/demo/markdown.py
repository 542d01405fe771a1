"""The demo's ``report.md``: the loop told in order, with Table 3 before and after the diagnosis."""

from __future__ import annotations


def report_markdown(robot, model, excitation, before, after, diagnosis, summary) -> str:
    """The report of one demo run (identical for a given seed; timings live in ``speed.md``)."""
    hidden = summary["diagnosis"]["hidden"]
    lines = [
        f"# psdm demo: {robot.name} (virtual robot, seed {summary['seed']})",
        "",
        f"The virtual robot carries a hidden spring on joint {hidden['joint']} (k = {hidden['stiffness']} N m/rad, "
        f"rest {hidden['rest']} rad), a stand-in for a cable harness that the robot file does not know about. "
        "The report follows the loop: calibration with the spring unknown, diagnosis, calibration with the "
        "spring, C code of the corrected model.",
        "",
        *_gate_warning(summary),
        "## 1. Derived model",
        "",
        f"p = {model.n_functions} functions, l = {model.n_base} base parameters, {model.n_gravity} of them gravity "
        f"parameters (the paper: 1318, 32, 9). Max relative error against Pinocchio's rnea: "
        f"{summary['model']['max_rel_error_vs_pinocchio']:.1e}.",
        "",
        "## 2. Excitation",
        "",
        f"Fourier series, {excitation.duration:g} s period, inertial columns: condition number "
        f"{excitation.cond:.3g}; worst limit margin on a 10x finer grid {excitation.worst_margin:.3g}.",
        "",
        "![excitation](excitation.png)",
        "",
        "## 3. Identification with the spring unknown (the paper's Table 3)",
        "",
        before.result_.report.to_markdown(),
        "",
        _consistency_sentence(summary["identification"]),
        "",
        "![before](validation_before.png)",
        "",
        "## 4. Diagnosis of missing physics",
        "",
        *_diagnosis_brief(diagnosis),
        "",
        "## 5. Identification again with the spring as a known term",
        "",
        *_recalibration(after, summary),
        "## 6. Before and after, against the virtual robot's truth",
        "",
        _comparison_table(summary, robot.n_dof),
        "",
        "## 7. C code of the corrected model",
        "",
        *_codegen(summary),
    ]
    return "\n".join(lines)


def _diagnosis_brief(diagnosis) -> list:
    """The findings and the per-joint validation RMSE; the residual analysis, the confounding and the plots are in
    ``diagnosis/report.html`` (and the full ``diagnosis/report.md``), so that this file stays short."""
    lines = [f"{k}. {f.sentence()} (dBIC {f.delta_bic:.0f})." for k, f in enumerate(diagnosis.findings, 1)]
    lines = lines or ["No significant missing physics."]
    lines += ["", "| joint | validation RMSE before [N m] | after [N m] |", "|---|---|---|"]
    lines += [
        f"| {j + 1} | {b:.4g} | {a:.4g} |" for j, (b, a) in enumerate(zip(diagnosis.rmse_before, diagnosis.rmse_after))
    ]
    return lines + ["", "Plots, residual analysis and confounding: [diagnosis/report.html](diagnosis/report.html) "
                    "(full text: [diagnosis/report.md](diagnosis/report.md))."]  # fmt: skip


def _gate_warning(summary) -> list:
    if summary["final_model_consistent"]:
        return []
    return [
        "> **WARNING: the exported model is NOT physically consistent** (its mass matrix is not positive definite "
        f"at some configurations, eigenvalue {summary['recalibration']['min_eigenvalue']:.3g}). The C code in "
        "`c_code/` computes wrong torques there; do not deploy it.",
        "",
    ]


def _consistency_sentence(calibration) -> str:
    state = "positive definite" if calibration["consistent"] else "**NOT positive definite**"
    return (
        f'Worst "All" R^2 {calibration["r2_min_all"]:.3f}; mass matrix {state} over random configurations '
        f"(smallest eigenvalue {calibration['min_eigenvalue']:.3g})."
    )


def _recalibration(after, summary) -> list:
    calibration = summary["recalibration"]
    if "skipped" in calibration:
        return [f"Not run: {calibration['skipped']}", ""]
    lines = [
        "Each step's least squares gets the spring's columns (`q_j` and `1`: `k (q - q0) = k q - k q0`) beside its "
        "own parameters; the friction step removes the spring's torque, and the gravity and inertial steps "
        "alternate until the spring settles.",
        "",
        after.result_.report.to_markdown(),
        "",
        _consistency_sentence(calibration),
        "",
        "| term | parameter | identified | sigma |",
        "|---|---|---|---|",
    ]
    for term in calibration["extra_terms"] or []:
        for name, value, sigma in zip(term["feature_names"], term["coefficients"], term.get("std", [])):
            lines.append(f"| {term['label']} | {name} | {value:.5g} | {sigma:.2g} |")
        physical = ", ".join(f"{k} = {v:.4g}" for k, v in term["physical"].items())
        lines.append(f"| {term['label']} | {physical} | | |")
    return lines + ["", "![after](validation_after.png)", ""]


def _comparison_table(summary, n_dof: int) -> str:
    before, after = summary["identification"], summary["recalibration"]
    lines = [
        "| quantity | spring unknown | spring known |",
        "|---|---|---|",
        f'| worst "All" R^2 | {before["r2_min_all"]:.3f} | {after["r2_min_all"]:.3f} |',
        f"| mass matrix positive definite | {before['consistent']} | {after['consistent']} |",
        f"| smallest mass-matrix eigenvalue | {before['min_eigenvalue']:.3g} | {after['min_eigenvalue']:.3g} |",
        f"| worst Kt error | {max(before['kt_rel_err']):.2%} | {max(after['kt_rel_err']):.2%} |",
        f"| worst gravity parameter error (scaled) | {before['gravity_max_scaled_err']:.3g} | "
        f"{after['gravity_max_scaled_err']:.3g} |",
        f"| worst inertial parameter error (scaled) | {before['inertial_max_scaled_err']:.3g} | "
        f"{after['inertial_max_scaled_err']:.3g} |",
    ]
    for j in range(n_dof):
        lines.append(f'| joint {j + 1} "All" R^2 | {before["r2_all"][j]:.3f} | {after["r2_all"][j]:.3f} |')
    lines += [
        "",
        "Errors are relative to the virtual robot's truth (the robot file); a gravity or inertial error is scaled "
        "by max(|truth|, 5 % of the largest parameter of its kind).",
    ]
    return "\n".join(lines)


def _codegen(summary) -> list:
    codegen = summary["codegen"]
    warning = []
    if not codegen["consistent"]:
        warning = ["**Exported anyway, for inspection: this model is NOT physically consistent (see above).**", ""]
    return warning + [
        f"Exported {', '.join(codegen['functions'])} from the {codegen['model']} model. "
        "`psdm_feedforward_torque(q, qd, qdd)` is its whole torque: the rigid body (Newton-Euler on the identified "
        "base parameters), each joint's friction (the steady-state curve of its LuGre model) and the spring; "
        "the compiled function equals the CasADi one to "
        f"{codegen['feedforward_c_vs_casadi_max_abs']:.1e} N m on random states. The other functions are the rigid "
        "body alone; the compiled inverse dynamics equals the PSDM sum Y(q, qd, qdd) theta to "
        f"{codegen['c_vs_python_max_abs']:.1e} N m.",
        "",
        "Measured speed against Pinocchio and the step timings: [speed.md](speed.md) (measurements vary from "
        "run to run, so they live outside this file, which is identical for a given seed).",
        "",
    ]
