"""The diagnosis report's plots (``DiagnosisReport.save_plots``): the validation residual against time, position and
velocity, measured against model torque before and after, and the torque of each finding with a shape in its joint's
angle (a spring's polynomial) over that joint's residual; PNG files written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from psdm_casadi.fileio import atomic_write


def save_plots(report, directory, overwrite: bool = False) -> dict:
    """Residual against time, position and velocity, and measured vs model torque before/after; PNG files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    n = report.n_dof
    t = report.validation_t
    residual = report.validation_tau - report.validation_nominal
    after = report.validation_tau - report.validation_final
    paths = {}
    fig, axes = plt.subplots(n, 3, figsize=(13, 2.0 * n), squeeze=False)
    for j in range(n):
        for c, (x, xl) in enumerate(
            (
                (t, "t [s]"),
                (report.validation_q[:, j], f"q{j + 1} [rad]"),
                (report.validation_qd[:, j], f"qd{j + 1} [rad/s]"),
            )
        ):
            ax = axes[j, c]
            ax.plot(x, residual[:, j], ".", ms=1, label="nominal")
            ax.plot(x, after[:, j], ".", ms=1, label="augmented")
            ax.set_xlabel(xl)
            ax.set_ylabel(f"res {j + 1} [N m]")
    axes[0, 0].legend(markerscale=8)
    fig.tight_layout()
    paths["residuals"] = _save(fig, directory / "residuals.png", overwrite)
    fig, axes = plt.subplots(n, 1, figsize=(10, 1.8 * n), squeeze=False, sharex=True)
    for j in range(n):
        ax = axes[j, 0]
        ax.plot(t, report.validation_tau[:, j], "k", lw=1, label="measured")
        ax.plot(t, report.validation_nominal[:, j], lw=1, label=f"nominal (RMSE {report.rmse_before[j]:.3g})")
        ax.plot(t, report.validation_final[:, j], lw=1, label=f"augmented (RMSE {report.rmse_after[j]:.3g})")
        ax.set_ylabel(f"tau{j + 1} [N m]")
        ax.legend(fontsize=6, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    paths["fit"] = _save(fig, directory / "fit.png", overwrite)
    shaped = shaped_terms(report)
    if shaped:
        paths["torque_vs_angle"] = _plot_shapes(report, plt, shaped, directory / "torque_vs_angle.png", overwrite)
    unnamed = [f for f in report.findings if f.effect == "unnamed_effect"]
    if unnamed:  # the sparse terms beyond the library (``sparse_terms``)
        from identification.diagnosis.unnamed_plot import plot_unnamed_effects

        figure = plot_unnamed_effects(plt, report, unnamed)
        paths["unnamed_effects"] = _save(figure, directory / "unnamed_effects.png", overwrite)
    plt.close("all")
    return paths


def shaped_terms(report) -> list:
    """``(finding, term, coefficients)`` of the findings whose term is a torque of its joint's angle."""
    augmented = getattr(report.augmented, "terms", ())
    by_label = {t.label: (t, c) for t, c in zip(augmented, getattr(report.augmented, "coefficients", ()))}
    out = []
    for f in report.findings:
        term, c = by_label.get(f.label, (None, None))
        if term is not None and hasattr(term, "torque_of_angle"):
            out.append((f, term, c))
    return out


def _plot_shapes(report, plt, shaped, path: Path, overwrite: bool) -> Path:
    """The identified torque against the joint angle over the recorded range, over the nominal model's
    validation residual of that joint."""
    fig, axes = plt.subplots(1, len(shaped), figsize=(5.0 * len(shaped), 3.6), squeeze=False)
    for ax, (finding, term, c) in zip(axes[0], shaped):
        j = term.joint
        q = report.validation_q[:, j]
        lo, hi = term.q_range if getattr(term, "q_range", None) else (float(np.min(q)), float(np.max(q)))
        grid = np.linspace(min(lo, float(np.min(q))), max(hi, float(np.max(q))), 200)
        residual = report.validation_tau[:, j] - report.validation_nominal[:, j]
        ax.plot(q, residual - np.mean(residual), ".", ms=1, color="0.6", label="nominal residual (centred)")
        shape = term.torque_of_angle(grid, c)
        ax.plot(grid, shape - np.mean(term.torque_of_angle(q, c)), lw=2, label=finding.label)
        ax.set_xlabel(f"q{j + 1} [rad]")
        ax.set_ylabel(f"tau{j + 1} [N m]")
        ax.legend(fontsize=7, markerscale=6)
    fig.tight_layout()
    return _save(fig, path, overwrite)


def _save(fig, path: Path, overwrite: bool) -> Path:
    return atomic_write(path, lambda handle: fig.savefig(handle, dpi=90, format="png"), overwrite=overwrite, mode="wb")
