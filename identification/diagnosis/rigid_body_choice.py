"""``rigid_body="auto"``: a wrong prior is not missing physics.

With the robot file's inertia as the prior, inertial parameters that are off (CAD values typically are by
10-20 %) show up as a payload, a "last link too heavy" or a rotor inertia. ``diagnose`` with
``DiagnosisOptions.rigid_body="auto"`` therefore fits the prior model first; when it keeps any finding, the
diagnosis is also run with the rigid body recalibrated in full (the PSDM base parameters fitted with the
friction on the training recording), and the prior's findings are reported as missing physics only if the
prior model with them predicts the validation recording at least as well as the recalibrated model with its
own findings (``prior_wins``, within ``AUTO_TOLERANCE``). A payload- or inertia-type finding (``INERTIAL_TERMS``)
thus has to beat a full recalibration; so has a friction-type finding that only stands in for wrong
inertia. Otherwise the identified diagnosis is reported, with a note that the robot file's inertial
parameters are off, listing the base parameters that moved most (``moved_parameters``). A clean recording
with a right prior gives no finding and costs no recalibration.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.diagnosis.columns import BlockColumns, row_chunks

INERTIAL_TERMS = ("payload", "rotor_inertia")  # term keys (the payload term also reports last_link_mass_excess)
AUTO_TOLERANCE = 0.1  # the prior model with the finding may be this much (fraction) worse than the recalibration
MIN_SHARE = 0.95  # or its findings remove this share of the error the recalibration removes
N_MOVED = 5  # base parameters listed in the note


def with_regressor(context, model):
    """``context`` with its PSDM regressor (n_samples, n_dof, n_base), evaluated in chunks of rows."""
    if context.regressor is not None:
        return context
    q, qd, qdd = context.q, context.qd, context.qdd
    regressor = np.concatenate([model.regressor(q[r], qd[r], qdd[r]) for r in row_chunks(q.shape[0])])
    return replace(context, regressor=regressor)


def recalibration_parts(problem, model) -> dict:
    """The fields of the ``DiagnosisProblem`` with the identified rigid body, from a prior-mode ``problem``: the
    contexts with their regressor, the friction columns followed by the regressor's, and the whole torque."""
    ctx_t, ctx_v = with_regressor(problem.ctx_t, model), with_regressor(problem.ctx_v, model)
    return {
        "ctx_t": ctx_t,
        "ctx_v": ctx_v,
        "base_t": problem.base_t.concatenate(BlockColumns.from_dense(ctx_t.regressor)),
        "base_v": problem.base_v.concatenate(BlockColumns.from_dense(ctx_v.regressor)),
        "y_t": ctx_t.tau,
        "y_v": ctx_v.tau,
    }


def prior_wins(rmse_nominal, rmse_prior, rmse_recalibrated, weights, effects=(), recalibrated_effects=()) -> bool:
    """Whether the prior model with its findings (``effects``) is as good as the recalibrated one with its own
    (``recalibrated_effects``) on the validation recording: per-joint RMSE summed with ``weights`` (1 / the joint's
    torque RMS, so that every joint counts alike).

    It is when its error is clearly lower (by ``AUTO_TOLERANCE``); or within ``AUTO_TOLERANCE`` of the
    recalibrated one's with no more findings (findings that only stand in for wrong inertia are extra ones);
    or when its findings remove at least ``MIN_SHARE`` of the error that the recalibration removes from the prior
    nominal model (``rmse_nominal``): a large payload leaves a small residual of its own rotational inertia, which
    the point-mass payload term does not model, while wrong CAD inertia is only partly mimicked by findings. The
    share rule does not apply to a last link lighter than the file says (``last_link_mass_excess``): that is the
    file's inertia being off, not missing physics."""
    nominal, prior, recalibrated = (
        float(np.sum(np.asarray(x) * weights)) for x in (rmse_nominal, rmse_prior, rmse_recalibrated)
    )
    if prior * (1.0 + AUTO_TOLERANCE) < recalibrated:
        return True
    if prior <= (1.0 + AUTO_TOLERANCE) * recalibrated and len(effects) <= len(recalibrated_effects):
        return True
    if "last_link_mass_excess" in effects:
        return False
    return nominal > recalibrated and (nominal - prior) >= MIN_SHARE * (nominal - recalibrated)


def moved_parameters(model, robot, theta_identified, count: int = N_MOVED) -> list:
    """The base parameters that moved most from the robot file's values: ``(name, file, identified, relative)``,
    largest relative change first (relative to the larger of the file's value and 1 % of the largest one)."""
    prior = np.asarray(model.base_parameters(robot.nominal_dynamic_parameters()), dtype=float)
    theta = np.asarray(theta_identified, dtype=float)
    floor = 0.01 * max(float(np.max(np.abs(prior))), 1e-12)
    relative = np.abs(theta - prior) / np.maximum(np.abs(prior), floor)
    order = np.argsort(-relative)[:count]
    return [(str(model.base_names[k]), float(prior[k]), float(theta[k]), float(relative[k])) for k in order]


def inertial_note(effects, error_prior: float, error_recalibrated: float, moved) -> str:
    """The report's sentence when the recalibration beats the prior model's findings ``effects`` (effect names);
    the errors are the joint-weighted validation RMSE sums of ``prior_wins`` (fractions of the torque RMS)."""
    names = ", ".join(f"`{e}`" for e in effects) or "its findings"
    listed = "; ".join(f"{name} {a:.4g} -> {b:.4g} ({r:.0%})" for name, a, b, r in moved)
    return (
        f"the robot file's inertial parameters are off: with them the model needs {names} and still predicts the "
        f"validation recording worse (mean relative RMSE {error_prior:.3g}) than a full rigid-body recalibration "
        f"({error_recalibrated:.3g}), so those findings are not reported as missing physics and the rigid body is "
        f"identified. Base parameters that moved most (file -> identified, relative change): {listed}."
    )
