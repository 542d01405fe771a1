"""The Markdown of ``psdm diagnose --apply``: the calibration before and after the findings it wrote.

Split out of the ``diagnose`` command so that the command's module holds the flow and this one the words. The last
line says what the written file holds: the findings it applies, or, when every finding is only reported (a state of
the friction no model file holds), that nothing was written and the model file stays the model (:func:`adds_nothing`):
such a refit is the model file identified again on ``--train`` alone, which loses the other recordings identify had
(a virtual 7-joint cobot identified on two: joint 7 0.0333 -> 0.0391 N m).
"""

from __future__ import annotations

__all__ = ["ALONE", "adds_nothing", "apply_refusal", "better_alone", "recalibration_markdown", "written_line"]

#: What a refit on the diagnosis's training recording alone trained on (``refit_training.RefitTraining.short``).
ALONE = "--train alone"

#: The refit's fix for a joint that never reverses, as identify words it for its own --offset option.
IDENTIFY_OFFSET_FIX = "or identify without the torque offset (drop --offset)."
#: The same fix for 'diagnose --apply', which refits the offsets the model file holds on --train.
APPLY_OFFSET_FIX = (
    "or pass as --train a recording on which it reverses (the model file holds a torque offset on it, which the "
    "refit of --apply keeps and must tell from its Coulomb friction), or identify the model again with --offset off."
)


def adds_nothing(before: dict, after: dict) -> bool:
    """Whether every finding the refit ``after`` (a model-file document) adds to ``before`` (the model file it refits)
    is only reported, or none is left (the refit's gates dropped them all, ``no_gain`` among them), and no finding the
    file carries is written at another size (``resized_findings.resized_labels``): then ``diagnose --apply`` does not
    write it."""
    from identification.calibration.resized_findings import resized_labels

    carried = {entry["label"] for entry in before.get("findings") or []}
    new = [entry for entry in after.get("findings") or [] if entry["label"] not in carried]
    return all(entry["kind"] == "reported" for entry in new) and not resized_labels(before, after)


def recalibration_markdown(result, joint_names, path, source=None, trained_on=ALONE) -> str:
    """The calibration before and after the findings: per-joint validation RMSE, consistency, moved parameters.
    ``source``: the model file refitted, named by the closing line when nothing was written (:func:`written_line`);
    ``trained_on``: what the refit trained on (``refit_training.RefitTraining.short``)."""
    block = result.after.document["recalibration"]
    margin = block["never_worse"]["margin"]
    lines = [
        "",
        "## Recalibration with the findings",
        "",
        "| | " + " | ".join(joint_names) + " |",
        "|---" * (len(joint_names) + 1) + "|",
        "| validation RMSE before [N m] | " + " | ".join(f"{v:.4g}" for v in result.rmse_before) + " |",
        "| validation RMSE after [N m] | " + " | ".join(f"{v:.4g}" for v in result.rmse_after) + " |",
        "| noise margin [N m] | " + " | ".join(f"{v:.2g}" for v in margin) + " |",
        "",
        f"- never worse: {block['never_worse']['margin_rule']}; every joint of the model written is within it",
    ]
    lines += [f"- {block['never_worse']['margin_source'][j - 1]}"  # over it, the refits do not confirm
              for j in block["never_worse"].get("cleared_by_refits", [])]  # fmt: skip
    if block["never_worse"].get("search"):
        lines.append(f"- findings the never-worse gate drops: {block['never_worse']['search']}")
    lines += [f"- dropped {d['label']} (never worse): {d['reason']}; the model was refitted without it"
              for d in block["never_worse"]["dropped"]]  # fmt: skip
    for key in ("before", "after"):
        state = block[key]
        lines.append(
            f"- consistency {key}: {'consistent' if state['consistent'] else 'NOT consistent'} (smallest "
            f"pseudo-inertia eigenvalue {_significant(state['min_pseudo_inertia_eigenvalue'])})"
        )
    lines.append(f"- smallest mass-matrix eigenvalue after: {result.min_mass_eigenvalue:.4g}")
    moved = block["moved_parameters"]
    lines.append(f"- parameters that moved by more than 3 sigma: {len(moved) or 'none'}")
    lines += [f"  - {m['name']}: {m['before']:.5g} -> {m['after']:.5g} ({m['sigmas']:.1f} sigma)" for m in moved]
    for d in block.get("dropped_findings") or []:
        if "validation_rmse_with" not in d:  # physically meaningless coefficients: no RMSE pair to show
            lines.append(f"- dropped {d['label']}: {d['reason']}; the model was refitted without it")
            continue
        with_it, without = d["validation_rmse_with"], d["validation_rmse_without"]
        pairs = "; ".join(f"joint {j}: {a:.4g} -> {b:.4g}" for j, b, a in zip(d["joints"], with_it, without))
        refitted = "the model was refitted without it" if d.get("refitted", True) else "not written"
        lines.append(f"- dropped {d['label']}: {d['reason']} (validation RMSE [N m] without -> with it: {pairs}); "
                     f"{refitted}")  # fmt: skip
    for entry in result.after.document["findings"]:
        parameters = ", ".join(f"{k} = {v:.4g}" for k, v in entry["parameters"].items())
        absorbed = f"; absorbed: {', '.join(entry['absorbed'])}" if entry.get("absorbed") else ""
        note = "" if entry["kind"] == "torque" else "; " + entry["applied"]
        lines.append(f"- {entry['label']} ({entry['kind']}): {parameters}{absorbed}{note}")
        if (entry.get("resized") or {}).get("why"):  # the file's size replaced in place (``resized_findings``)
            lines.append(f"  - written at the data's size in place of the file's: {entry['resized']['why']}")
        if "validation_rmse_without" in entry:
            lines.append("  " + _contribution(entry))

    alone = trained_on == ALONE and better_alone(result.rmse_before, result.rmse_after, margin, joint_names)
    lines += [alone] if source is not None and alone else []  # the other recordings disagree with --train
    lines.append("\n" + written_line(result.after.document["findings"], path, source, trained_on))
    return "\n".join(lines)


def better_alone(rmse_before, rmse_after, margin, joint_names) -> str:
    """The note of a refit on ``--train`` alone (nothing added, so not written) that predicts the validation recording
    better than the model file on some joints beyond their never-worse ``margin``, naming them; empty when none.

    Identify fitted the model file on every training recording; a refit on one of them that does better on the held-out
    one says the recordings disagree (a virtual cobot whose joints warm up over a session: its friction 1.35x on the
    first recording, 1.07x on the one before the held-out), which the model file
    averages and no finding names."""
    better = [j for j, (b, a, m) in enumerate(zip(rmse_before, rmse_after, margin)) if a < b - m]
    if not better:
        return ""
    pairs = ", ".join(f"{joint_names[j]} {rmse_before[j]:.4g} -> {rmse_after[j]:.4g} N m" for j in better)
    return (f"- identified again on --train alone, the model predicts the validation recording better on joint(s) "
            f"{', '.join(str(j + 1) for j in better)} beyond their margins ({pairs}): there the other recordings "
            "identify had disagree with --train (a friction that changed between recordings, as when the joints warm "
            "up, or another load or temperature); identify again on the recordings taken as the validation one was "
            "and compare ('psdm identify ROBOT --data THOSE --validate VAL'); until then the model file stays as it "
            "is")  # fmt: skip


def apply_refusal(exc, model, apply) -> str:
    """The message of a refit ``diagnose --apply`` could not make: the refusal naming the model file, with a fix that
    names what the user of this command can do (identify's 'drop --offset' names an option neither command got)."""
    text = str(exc).replace(IDENTIFY_OFFSET_FIX, APPLY_OFFSET_FIX)
    return f"diagnose {model!r} --apply: {text} Nothing was written to {apply!r}."


def written_line(findings, path, source=None, trained_on=ALONE) -> str:
    """The closing line: the findings the file at ``path`` applies, or that it applies none (the gates dropped them),
    or, with ``source`` (the model file refitted on ``trained_on``), that ``path`` was not written (every finding only
    reported)."""
    applied = [entry["label"] for entry in findings if entry["kind"] != "reported"]
    if applied and source is None:
        return f"calibrated model with findings ({', '.join(applied)}) written to {path}"
    if applied:  # nothing added: the file's own findings (a coupling identify fitted) carried, not written again
        return (f"nothing to add to the findings the model file carries ({', '.join(applied)}): {path} was not "
                f"written; {source} stays the model to use (this table's 'after' row is it identified again on "
                f"{trained_on}, with nothing added)")  # fmt: skip
    reported = [entry["label"] for entry in findings if entry["kind"] == "reported"]
    why = f" ({', '.join(reported)}: reported only, not part of the model's torque)" if reported else ""
    if source is None:  # written: every finding the refit had was dropped by its gates
        return (f"no finding to apply{why}: {path} holds the model with none added (its validation RMSE is this "
                "table's 'after' row, not the diagnosis's 'after')")  # fmt: skip
    return (f"no finding to apply{why}: {path} was not written; {source} stays the model to use (this table's "
            f"'after' row is it identified again on {trained_on}, with nothing added)")  # fmt: skip


def _significant(value) -> str:
    """A number to 4 significant digits (9.999999999999176e-07 -> 1e-06); anything else (None) as it is."""
    return f"{value:.4g}" if isinstance(value, (int, float)) else str(value)


def _contribution(entry) -> str:
    """What a finding contributes on its joints: the validation RMSE with it and with it taken out (no refit)."""
    joints = entry["joints"] or list(range(1, len(entry["validation_rmse_after"]) + 1))
    parts = [
        f"joint {j}: {entry['validation_rmse_without'][j - 1]:.4g} -> {entry['validation_rmse_after'][j - 1]:.4g}"
        for j in joints
    ]
    helps = any(entry["validation_rmse_after"][j - 1] < entry["validation_rmse_without"][j - 1] for j in joints)
    verdict = "" if helps else " (it does NOT lower the validation error of its joints: consider dropping it)"
    head = "validation RMSE [N m] without -> with it (its torque taken out, not refitted): "
    return head + "; ".join(parts) + verdict
