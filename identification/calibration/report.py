"""ValidationReport: the paper's Table 3 (RMSE and R^2 per joint per step, plus "All" on a fast path) and its plots.

Built by the pipeline from the validation parts (15 %) of every experiment; rendered as Markdown
and plotted (observed vs predicted torque, matplotlib with the Agg backend).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from psdm_casadi.errors import ParameterError

__all__ = ["StepScore", "ValidationReport", "plot_observed_predicted", "STEPS"]

STEPS = ("motor", "gravity", "friction", "inertial", "all")


@dataclass(frozen=True, eq=False)
class StepScore:
    """Validation scores of one step.

    Attributes
    ----------
    step : str
        One of ``STEPS``.
    rmse : array, shape (n_dof,)
        [N m]; NaN where the step has no rows for a joint.
    r2 : array, shape (n_dof,)
    """

    step: str
    rmse: np.ndarray
    r2: np.ndarray

    def __post_init__(self):
        if self.step not in STEPS:
            raise ParameterError(f"StepScore.step must be one of {STEPS}; got {self.step!r}.")
        object.__setattr__(self, "rmse", np.asarray(self.rmse, dtype=float))
        object.__setattr__(self, "r2", np.asarray(self.r2, dtype=float))


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Table 3 of the paper: per step and joint, RMSE [N m] and R^2 on validation data.

    Attributes
    ----------
    scores : tuple of StepScore
    joint_names : tuple of str
    """

    scores: tuple
    joint_names: tuple

    def __getitem__(self, step: str) -> StepScore:
        for score in self.scores:
            if score.step == step:
                return score
        raise KeyError(f"ValidationReport has no step {step!r}; it has {[s.step for s in self.scores]}.")

    def min_r2(self, step: str) -> float:
        """Smallest defined R^2 of a step over the joints."""
        return float(np.nanmin(self[step].r2))

    def to_markdown(self) -> str:
        """The report as a Markdown table (one row per joint, RMSE and R^2 per step)."""
        steps = [s.step for s in self.scores]
        head = "| joint | " + " | ".join(f"{s} RMSE | {s} R^2" for s in steps) + " |"
        rule = "|---|" + "---|---|" * len(steps)
        lines = [head, rule]

        def cell(x, digits):
            return "" if not np.isfinite(x) else f"{x:.{digits}f}"

        for j, name in enumerate(self.joint_names):
            cells = []
            for s in self.scores:
                cells += [cell(s.rmse[j], 3), cell(s.r2[j], 3)]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
        lines.append('RMSE in N m on the validation parts (15 %); "all" is the full model on the fast excitation path.')
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {
            "joint_names": list(self.joint_names),
            "steps": {s.step: {"rmse": _nan_list(s.rmse), "r2": _nan_list(s.r2)} for s in self.scores},
        }

    @classmethod
    def from_dict(cls, data: dict) -> ValidationReport:
        scores = tuple(StepScore(step, _from_list(v["rmse"]), _from_list(v["r2"])) for step, v in data["steps"].items())
        return cls(scores=scores, joint_names=tuple(data["joint_names"]))


def _nan_list(a):
    return [None if not np.isfinite(x) else float(x) for x in a]


def _from_list(a):
    return np.array([np.nan if x is None else x for x in a], dtype=float)


def plot_observed_predicted(t, observed, predicted, path, title: str = "", joint_names=None) -> Path:
    """Plot observed and predicted torques per joint (one subplot each) into a PNG file.

    Parameters
    ----------
    t : array, shape (n_samples,)
    observed, predicted : array, shape (n_samples, n_dof)
    path : str or Path
        Output ``.png`` (parent folders created).
    title : str
    joint_names : sequence of str, optional

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    observed = np.atleast_2d(np.asarray(observed, dtype=float))
    predicted = np.atleast_2d(np.asarray(predicted, dtype=float))
    n = observed.shape[1]
    names = joint_names or [f"J{j + 1}" for j in range(n)]
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.6 * n + 0.6), sharex=True, squeeze=False)
    for j in range(n):
        ax = axes[j, 0]
        ax.plot(t, observed[:, j], lw=0.8, label="observed")
        ax.plot(t, predicted[:, j], lw=0.8, ls="--", label="predicted")
        ax.set_ylabel(f"{names[j]} [N m]")
    axes[0, 0].legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel("t [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
