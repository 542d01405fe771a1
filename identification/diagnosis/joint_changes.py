"""Why a joint's validation RMSE rose: one sentence per joint whose augmented model fits worse than the nominal one.

The selection keeps a term only if it lowers the validation RMSE of every joint it names, but the final fit can
still raise another joint's error: a robot-wide term (payload, tilt, delay) is fitted to all joints at once and
trades one joint for the others, identified base parameters shared between joints move when they are refitted
with the kept terms, and the nonlinear refinement refits the friction on the training recording.
``explain_joint_changes`` names the cause that applies, so that no rise goes unexplained in the report.

A rise within the never-worse gate's noise margin (``paired_margin.noise_margin``, ``calibration.never_worse``'s
``MARGIN_RULE``: ``MARGIN_SIGMAS`` standard errors of the paired RMSE difference on the validation samples, at least
``MARGIN_FLOOR`` of the RMSE before; ``rise_margin``) is not a rise: another stretch of the same motion could as well
show a drop, and ``--apply`` would write such a model. It is not explained; the numbers of a rise beyond it are
printed with the digits that show it.
"""

from __future__ import annotations

import numpy as np

from identification.paired_margin import MARGIN_FLOOR, noise_margin, paired_rmse_margin


def rise_sentence(joint: int, before: float, after: float, cause: str) -> str:
    """``joint J: validation RMSE rises from a to b N m (+x %): cause`` (four significant digits: a rise worth a
    sentence exceeds the margin's floor, ``MARGIN_FLOOR`` of the RMSE before)."""
    rise = 100.0 * (after / max(before, 1e-300) - 1.0)
    return f"joint {joint + 1}: validation RMSE rises from {before:.4g} to {after:.4g} N m (+{rise:.2g} %): {cause}"


def rise_margin(residual_before, residual_after) -> np.ndarray:
    """The never-worse gate's margin [N m] per joint (n_dof,) of a rise from the residuals ``residual_before`` to
    ``residual_after`` (n_samples, n_dof) on the same validation samples (``paired_margin.noise_margin``); NaN where a
    joint has no torque measurement (NaN residuals)."""
    before, after = np.asarray(residual_before, dtype=float), np.asarray(residual_after, dtype=float)
    margin = np.full(before.shape[1], np.nan)
    measured = np.flatnonzero(np.all(np.isfinite(before), axis=0) & np.all(np.isfinite(after), axis=0))
    if measured.size:
        rmse_before, _, se = paired_rmse_margin(before[:, measured], after[:, measured])
        margin[measured] = noise_margin(rmse_before, se)
    return margin


def _cause(joint: int, findings, rigid_body: str, refined: bool) -> str:
    """The reason that applies to ``joint`` (see the module docstring)."""
    own = [f for f in findings if joint in f.joints]
    wide = [f for f in findings if "[" not in f.label and joint not in f.joints]  # robot-wide terms
    if wide:
        names = ", ".join(f"`{f.label}`" for f in wide)
        helped = sorted({j + 1 for f in wide for j in f.joints})
        return (
            f"the robot-wide term {names} is fitted to all joints at once and acts on joint {joint + 1} too; "
            f"it trades this joint's fit for that of joint(s) {', '.join(map(str, helped))}"
        )
    if rigid_body == "identified":
        helped = sorted({j + 1 for f in findings for j in f.joints})
        return (
            f"no kept term names joint {joint + 1}; the identified base parameters it shares with joint(s) "
            f"{', '.join(map(str, helped)) or '-'} moved when they were refitted together with the kept terms"
        )
    if own:
        names = ", ".join(f"`{f.label}`" for f in own)
        return (
            f"{names} lowered it when kept, but the final joint fit with the terms kept later"
            + (" and the nonlinear refinement on the training recording" if refined else "")
            + " does not carry over to validation as well"
        )
    if refined:
        return (
            f"no kept term acts on joint {joint + 1}; its friction was refitted jointly with the nonlinear terms on "
            "the training recording, which carries over slightly worse to validation"
        )
    return f"no kept term acts on joint {joint + 1}; the change is the joint's share of the jointly weighted fit"


def explain_joint_changes(rmse_before, rmse_after, findings, rigid_body: str, refined: bool, margin=None) -> tuple:
    """One sentence (``rise_sentence``) per joint whose final validation RMSE is above the nominal model's by more than
    ``margin``.

    Parameters
    ----------
    rmse_before, rmse_after : sequences (n_dof,)
        Validation RMSE of the nominal and of the augmented model [N m].
    findings : sequence of Finding
    rigid_body : {"prior", "identified"}
    refined : bool
        Whether the nonlinear refinement replaced the linear fit.
    margin : sequence (n_dof,), optional
        The never-worse margin [N m] of each joint's rise (``rise_margin``); default (or NaN) its floor,
        ``MARGIN_FLOOR`` of the RMSE before.
    """
    before, after = np.asarray(rmse_before, dtype=float), np.asarray(rmse_after, dtype=float)
    floor = MARGIN_FLOOR * before
    margin = floor if margin is None else np.where(np.isfinite(margin), np.asarray(margin, dtype=float), floor)
    return tuple(
        rise_sentence(j, before[j], after[j], _cause(j, findings, rigid_body, refined))
        for j in range(before.size)
        if after[j] > before[j] + margin[j]
    )
