"""What of a calibrated model's findings a URDF cannot hold (``urdf_export``): torque terms, measurement corrections.

``psdm diagnose MODEL --apply`` adds findings to a model: torque-type terms (a spring, a ripple, a coupling, ...)
that ``psdm validate`` and the C export add to the rigid-body torque, and measurement corrections (a delay, a
joint elasticity, a backlash) that ``psdm validate`` applies to the recorded signals. A URDF has no element for
either, so the URDF's torque differs from the one the report shows. These functions name each finding left
out, with its parameters, for the per-joint comments and the warning ``psdm export-urdf`` prints (as
``urdf_friction`` does for the friction shapes URDF cannot hold). Rigid-body findings (a payload) are part of
the standard parameters, and so of the URDF's inertials; findings only reported were never part of the model.
"""

from __future__ import annotations

from psdm_casadi.values import exact_text

__all__ = ["LEFT_OUT_KINDS", "findings_left_out", "findings_not_representable"]

#: The finding kinds (``findings.FINDING_KINDS``) that change the model's torque or its signals, but not its body.
LEFT_OUT_KINDS = ("torque", "signal")


def _left_out_entries(calibrated) -> list:
    return [e for e in calibrated.document.get("findings") or [] if e.get("kind") in LEFT_OUT_KINDS]


def _values_text(entry: dict, number) -> str:
    """``name = value`` of a finding's coefficients (torque) and physical parameters."""
    pairs = []
    if entry.get("kind") == "torque":
        for name, value in zip(entry.get("feature_names") or (), entry.get("coefficients") or ()):
            pairs.append(f"{name} = {'absorbed' if value is None else number(value)}")
    for name, value in (entry.get("parameters") or {}).items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            pairs.append(f"{name} = {number(value)}")
    return ", ".join(pairs) or "no parameters"


def _describe(entry: dict, number) -> str:
    what = "torque term" if entry.get("kind") == "torque" else "measurement correction"
    return f"{entry.get('label', '?')} ({what}, NOT in the URDF): {_values_text(entry, number)}"


def findings_left_out(calibrated) -> tuple:
    """(per joint (0-based) the comment texts of its findings, the texts of findings on no joint (a delay)).

    Parameters
    ----------
    calibrated : CalibratedModel

    Returns
    -------
    tuple of (dict, list)
        ``{joint: [text, ...]}`` and ``[text, ...]``; both empty for a model without such findings.
    """
    per_joint, general = {}, []
    for entry in _left_out_entries(calibrated):
        text = _describe(entry, exact_text)
        joints = [int(j) - 1 for j in entry.get("joints") or () if isinstance(j, int) and 1 <= j <= calibrated.n_dof]
        for j in joints:
            per_joint.setdefault(j, []).append(text)
        if not joints:
            general.append(text)
    return per_joint, general


def findings_not_representable(calibrated) -> str | None:
    """The warning for a model with findings URDF cannot hold (module docstring), naming each; else None."""
    entries = _left_out_entries(calibrated)
    if not entries:
        return None
    named = "; ".join(_describe(entry, lambda v: f"{float(v):.4g}") for entry in entries)
    return (
        f"the model has {len(entries)} finding(s) a URDF cannot hold, left out of it (their parameters are in the "
        f"URDF's comments): {named}. The URDF's torque therefore differs from 'psdm validate' and "
        "'psdm codegen' of this model"
    )
