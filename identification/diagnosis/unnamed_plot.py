"""The plot of the unnamed effects (``sparse_terms``) of a ``DiagnosisReport``: the found torque against the joint's
angle and velocity, over the validation residual it explains (``unnamed_effects.png``)."""

from __future__ import annotations

import casadi as ca
import numpy as np


def unnamed_torque(report, term, coefficients) -> np.ndarray:
    """The term's torque on its joint along the report's validation recording (n_samples,) [N m], from its CasADi
    expression (the acceleration, which the report does not keep, by differences of the velocity)."""
    n = report.n_dof
    q, qd, qdd = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd"))
    expression = term.casadi_expression(q, qd, qdd, ca.SX.sym("t"), q, coefficients)
    f = ca.Function("unnamed", [q, qd, qdd], [expression[term.joint]])
    qdd_v = np.gradient(report.validation_qd, report.validation_t, axis=0)
    mapped = f.map(report.validation_t.size)
    return np.asarray(mapped(report.validation_q.T, report.validation_qd.T, qdd_v.T), dtype=float).ravel()


def plot_unnamed_effects(plt, report, findings):
    """A figure with one row per unnamed finding: torque and residual against q_j and against qd_j."""
    by_label = dict(
        zip((t.label for t in report.augmented.terms), zip(report.augmented.terms, report.augmented.coefficients))
    )
    fig, axes = plt.subplots(len(findings), 2, figsize=(10.0, 3.4 * len(findings)), squeeze=False)
    for row, finding in zip(axes, findings):
        term, c = by_label[finding.label]
        j = term.joint
        torque = unnamed_torque(report, term, c)
        residual = report.validation_tau[:, j] - report.validation_final[:, j] + torque
        for ax, x, label in (
            (row[0], report.validation_q[:, j], f"q{j + 1} [rad]"),
            (row[1], report.validation_qd[:, j], f"qd{j + 1} [rad/s]"),
        ):
            ax.plot(x, residual, ".", ms=1, color="0.6", label="residual without the term")
            ax.plot(x, torque, ".", ms=1, label=f"{finding.label} (gain {finding.validation_gain:.0%})")
            ax.set_xlabel(label)
            ax.set_ylabel(f"tau{j + 1} [N m]")
            ax.legend(fontsize=7, markerscale=6)
        row[0].set_title(term.formula(c), fontsize=6, loc="left")
    fig.tight_layout()
    return fig
