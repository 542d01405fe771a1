"""Each validation recording's verdict on the final diagnosis model (``DiagnosisReport.recordings``).

For every validation recording (the one the report's errors are computed on first, then the further ones of
``diagnose(..., validation=[A, B])``): the per-joint RMSE of the nominal and the final model, and for each finding
whether it still lowers the joint-weighted error of the joints it acts on there (a robot-wide term such as a payload
or a delay: of every joint, as the selection judged it), its torque taken out of the final model without a refit.
The selection judged each finding when it was kept (``second_opinion``); this judges the model as it is written,
after later terms, the refinement and the backward check, on every recording.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.diagnosis.design import WeightedDesign, joint_weights, left_out
from identification.metrics import rmse


@dataclass(frozen=True)
class FindingOnRecording:
    """A finding on one recording: the RMSE [N m] of the joints it is judged on without it (its torque taken out) and
    with it, and whether their joint-weighted error is lower with it."""

    label: str
    joints: tuple
    rmse_without: tuple
    rmse_with: tuple
    holds: bool

    def to_dict(self) -> dict:
        return {
            "label": self.label,
            "joints": [j + 1 for j in self.joints],
            "rmse_without": list(self.rmse_without),
            "rmse_with": list(self.rmse_with),
            "holds": self.holds,
        }


@dataclass(frozen=True)
class RecordingCheck:
    """One validation recording: per-joint RMSE of the nominal and the final model, and each finding's verdict;
    ``mean_after`` the final model's mean residual per joint [N m] (what a constant torque would take there: how far
    an offset the diagnosis fits is off on this recording, ``file_offsets``)."""

    name: str
    rmse_before: tuple
    rmse_after: tuple
    findings: tuple
    mean_after: tuple = ()

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "rmse_before": list(self.rmse_before),
            "rmse_after": list(self.rmse_after),
            "findings": [f.to_dict() for f in self.findings],
        }


def term_torques(final, ctx) -> list:
    """The torque (n_samples, n_dof) of each term of the final fit ``final`` (``diagnose.FinalFit``) on a recording's
    context ``ctx``, with its final coefficients."""
    return [term.columns(ctx) @ np.asarray(c, dtype=float) for term, c in zip(final.terms, final.coefficients)]


def predict_recording(final, ctx, base) -> np.ndarray:
    """The final fit's prediction (n_samples, n_dof) of a validation recording from its context and nominal columns
    ``base`` (``BlockColumns``): the nominal columns with the final coefficients plus every term's torque."""
    return base.predict(final.friction_coefficients) + sum(term_torques(final, ctx), 0.0)


def check_recordings(problem, final, findings) -> tuple:
    """The ``RecordingCheck`` of every validation recording of ``problem`` (``diagnose.DiagnosisProblem``) for the
    final fit ``final`` (``diagnose.FinalFit``) and its ``findings`` (``report.Finding``, matched by label)."""
    sigma = joint_weights(problem.ctx_t.tau, left_out(problem.ctx_t))
    nominal = WeightedDesign(problem.base_t, problem.base_t, problem.y_t, problem.y_t, sigma).fit()[0]
    joints_of = {f.label: tuple(f.joints) for f in findings}
    recordings = [(problem.ctx_v, problem.base_v, problem.y_v), *problem.extra_v]
    out = []
    for i, (ctx, base, y) in enumerate(recordings):
        parts = term_torques(final, ctx)
        predicted = base.predict(final.friction_coefficients) + sum(parts, np.zeros_like(y))
        if i == 0:
            predicted = final.prediction_v  # the refined fit as the report shows it
        after = rmse(y, predicted)
        verdicts = []
        for term, part in zip(final.terms, parts):
            joints = joints_of.get(term.label)
            if not joints:
                continue
            without = rmse(y, predicted - part)
            js = list(joints) if term.joints else list(range(y.shape[1]))  # robot-wide: every joint, as selected
            holds = bool(np.sum(after[js] ** 2 / sigma[js] ** 2) < np.sum(without[js] ** 2 / sigma[js] ** 2))
            verdicts.append(
                FindingOnRecording(term.label, joints, tuple(without[js].tolist()), tuple(after[js].tolist()), holds)
            )
        name = f"validation recording {i + 1}" + (f" ({ctx.name})" if getattr(ctx, "name", "") else "")
        before = rmse(y, base.predict(nominal))
        residual = np.asarray(y - predicted, dtype=float)
        mean = [float(np.mean(r[np.isfinite(r)])) if np.isfinite(r).any() else float("nan") for r in residual.T]
        out.append(RecordingCheck(name, tuple(before.tolist()), tuple(after.tolist()), tuple(verdicts), tuple(mean)))
    return tuple(out)
