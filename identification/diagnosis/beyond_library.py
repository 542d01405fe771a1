"""Beyond the library, in the diagnosis: sparse terms (``sparse_fit``) added to the final fit as unnamed effects.

Two places where the named library falls short are looked at, after the selection and refinement:

- a joint whose residual stays structured gets a sparse term when it explains enough of it on every validation
  recording (``propose_sparse_terms``, ``SparseProposal.holds``);
- a joint on which the selection kept two or more shapes of the angle alone (springs, ripples) is a joint where
  the library composes a shape it has no name for (four ripples standing in for a cam lobe): those terms are taken
  out and a sparse term is fitted in their place, which replaces them when it predicts each of the joint's validation
  recordings as well (within ``VALIDATION_SLACK``) with fewer coefficients. The report says which terms it replaced.

With several validation recordings (``diagnose(..., validation=[A, B])``) a term is kept only if it holds on each, as
the library's candidates are (``second_opinion``); the report's numbers are those of the first recording.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from identification.diagnosis.carried_terms import carried_labels
from identification.diagnosis.nominal import friction_feature_names
from identification.diagnosis.recording_checks import predict_recording
from identification.diagnosis.report import Finding
from identification.diagnosis.rigid_body_choice import Claim, inertia_in_question, stand_in_note, standing_in
from identification.diagnosis.sparse_fit import (
    MIN_TORQUE_FRACTION,
    VALIDATION_SLACK,
    fit_sparse_term,
    propose_sparse_terms,
)
from identification.metrics import rms, rmse

logger = logging.getLogger(__name__)

SHAPE_KEYS = ("torque_ripple", "spring")  # library terms that are a torque of one joint's angle alone


def look_beyond_library(problem, selection, final, options, identified=None) -> tuple:
    """``(selection, final, unnamed, notes)``: the selection and final fit (``diagnose.FinalFit``) of a
    ``DiagnosisProblem`` with composite shapes replaced (module docstring) and the sparse terms of
    ``propose_sparse_terms`` added (one per joint whose residual they explain, ``DiagnosisOptions.sparse_min_gain``),
    the unnamed ``Finding`` values, and the sentences on sparse terms left out as stand-ins.

    ``identified`` (a ``rigid_body_choice.IdentifiedDiagnosis``, given by ``rigid_body="auto"`` when the prior
    won) is the diagnosis with the rigid body identified: when the prior model kept an inertial finding, a sparse
    term proposed on a joint's residual is reported only if it is not a stand-in for the robot file's inertia
    (``_drop_stand_ins``), the rule its library findings obey. A term that replaces composite library shapes is
    not judged again: those shapes already passed that rule."""
    if not options.sparse:
        return selection, final, (), ()
    logger.info("diagnose: looking beyond the library (sparse regression of the residual) ...")
    n_friction = _friction_column_count(problem, options)
    nuisance, columns = [], []
    for j in range(problem.ctx_t.n_dof):
        mask = problem.base_t.index[j] < n_friction
        columns.append(problem.base_t.index[j][mask])
        nuisance.append((problem.base_t.values[j][:, mask], problem.base_v.values[j][:, mask]))
    extra_nuisance = [
        [base.values[j][:, problem.base_t.index[j] < n_friction] for j in range(problem.ctx_t.n_dof)]
        for _, base, _ in problem.extra_v
    ]
    selection, final, replacing = _replace_composite_shapes(
        problem, selection, final, nuisance, extra_nuisance, options
    )
    residual_t, residual_v = problem.y_t - final.prediction_t, problem.y_v - final.prediction_v
    more = [
        (ctx, y - predict_recording(final, ctx, base), n) for (ctx, base, y), n in zip(problem.extra_v, extra_nuisance)
    ]
    proposals = propose_sparse_terms(
        problem.ctx_t, problem.ctx_v, residual_t, residual_v, options.sparse_min_gain, nuisance, more
    )
    done = {p.term.joint for p in replacing}
    proposals = tuple(p for p in proposals if p.term.joint not in done)
    notes = ()
    if proposals and identified is not None and inertia_in_question(selection, carried_labels(options)):
        proposals, notes = _drop_stand_ins(problem, final, proposals, identified)
    proposals = replacing + proposals
    if not proposals:
        return selection, final, (), notes
    final, findings = _add_proposals(problem, final, proposals, columns)
    return selection, final, findings, notes


def _drop_stand_ins(problem, final, proposals, identified) -> tuple:
    """``(proposals, notes)``: the sparse ``proposals`` of the prior fit without those that stand in for the robot
    file's inertia (``rigid_body_choice.standing_in``): a proposal stands if the diagnosis with the rigid body
    identified, beyond the library too, keeps a finding on its joint, or if the prior model with it predicts its
    joint's validation recording better than that diagnosis by ``STAND_IN_MARGIN``."""
    logger.info("diagnose: judging the unnamed terms against the diagnosis with the rigid body identified ...")
    ref = identified
    _, final_i, unnamed_i, _ = look_beyond_library(ref.problem, ref.selection, ref.final, ref.options)
    rmse_recalibrated = rmse(ref.problem.y_v, final_i.prediction_v)
    rmse_prior = rmse(problem.y_v, final.prediction_v)
    for p in proposals:
        rmse_prior[p.term.joint] = p.rmse_after  # a sparse term changes its own joint's prediction only
    claims = [Claim(key=p.term.key, joints=(p.term.joint,)) for p in proposals]
    supporting = [Claim.of_step(step) for step in ref.selection.steps]
    supporting += [Claim(key=f.effect, joints=tuple(f.joints)) for f in unnamed_i]
    joints, _ = standing_in(claims, supporting, rmse_prior, rmse_recalibrated)
    if not joints:
        return proposals, ()
    labels = [p.term.label for p in proposals if p.term.joint in joints]
    action = "the sparse term was left out"
    note = stand_in_note(labels, joints, rmse_prior, rmse_recalibrated, action, ref.options.nominal)
    logger.info(f"diagnose: {note}")
    return tuple(p for p in proposals if p.term.joint not in joints), (note,)


def _add_proposals(problem, final, proposals, columns) -> tuple:
    """``(final, findings)``: the final fit with the proposals' terms added, and one ``Finding`` per proposal."""
    prediction_t, prediction_v = final.prediction_t.copy(), final.prediction_v.copy()
    current = rmse(problem.y_v, final.prediction_v)
    findings = []
    friction = np.array(final.friction_coefficients, dtype=float)
    for p in proposals:
        j = p.term.joint
        friction[columns[j]] += p.nuisance
        prediction_t[:, j] += p.prediction_t
        prediction_v[:, j] += p.prediction_v
        before = current.copy()
        before[j] = p.rmse_before
        after = before.copy()
        after[j] = p.rmse_after
        effect, explanation = p.term.interpret(p.coefficients)
        findings.append(
            Finding(
                effect=effect,
                label=p.term.label,
                joints=(j,),
                parameters=dict(zip(p.term.feature_names(), (float(c) for c in p.coefficients))),
                coefficients=tuple(float(c) for c in p.coefficients),
                feature_names=tuple(p.term.feature_names()),
                explanation=f"{explanation}; residual Ljung-Box p = {p.ljung_box_p:.2g}, largest correlation "
                f"with the joint's state {p.state_correlation:.2f}",
                signature=p.term.signature,
                rmse_before=tuple(float(x) for x in before),
                rmse_after=tuple(float(x) for x in after),
                delta_bic=p.delta_bic,
                validation_gain=p.validation_gain,
            )
        )
    final = replace(
        final,
        terms=final.terms + tuple(p.term for p in proposals),
        coefficients=final.coefficients + tuple(np.asarray(p.coefficients) for p in proposals),
        friction_coefficients=friction,
        prediction_t=prediction_t,
        prediction_v=prediction_v,
    )
    return final, tuple(findings)


def _replace_composite_shapes(problem, selection, final, nuisance, extra_nuisance, options) -> tuple:
    """``(selection, final, proposals)``: on each joint where the selection kept two or more ``SHAPE_KEYS`` terms, a
    sparse term fitted in their place; it replaces them (they leave the selection and the final fit, and
    ``selection.dropped`` says so) when it passes ``propose_sparse_terms``'s bar on the residual without them and
    predicts each of the joint's validation recordings as well as they do with fewer coefficients."""
    proposals = []
    extras = [(ctx, y, predict_recording(final, ctx, base)) for ctx, base, y in problem.extra_v]
    for j in range(problem.ctx_t.n_dof):
        n_steps = len(selection.steps)
        shapes = [
            k for k in range(n_steps) if final.terms[k].key in SHAPE_KEYS and tuple(final.terms[k].joints) == (j,)
        ]
        if len(shapes) < 2:
            continue
        parts_t = sum(final.terms[k].columns(problem.ctx_t)[:, j, :] @ final.coefficients[k] for k in shapes)
        parts_v = sum(final.terms[k].columns(problem.ctx_v)[:, j, :] @ final.coefficients[k] for k in shapes)
        without_t = problem.y_t[:, j] - final.prediction_t[:, j] + parts_t
        without_v = problem.y_v[:, j] - final.prediction_v[:, j] + parts_v
        more = [
            (ctx, y[:, j] - predicted[:, j] + sum(final.terms[k].columns(ctx)[:, j, :] @ final.coefficients[k]
                                                   for k in shapes), n[j])
            for (ctx, y, predicted), n in zip(extras, extra_nuisance)
        ]  # fmt: skip
        p = fit_sparse_term(problem.ctx_t, problem.ctx_v, j, without_t, without_v, *nuisance[j], more=more)
        n_library = sum(np.size(final.coefficients[k]) for k in shapes)
        library = [float(rms(problem.y_v[:, j] - final.prediction_v[:, j]))]
        library += [float(rms(y[:, j] - predicted[:, j])) for _, y, predicted in extras]
        floor = MIN_TORQUE_FRACTION * float(rms(problem.ctx_t.tau[:, j]))
        if (
            p is None
            or len(p.coefficients) >= n_library
            or any(a > (1.0 + VALIDATION_SLACK) * b for a, b in zip(p.each_after, library))
            or not p.holds(options.sparse_min_gain, floor)
        ):
            continue
        labels = ", ".join(final.terms[k].label for k in shapes)
        sentence = (
            f"{labels} replaced by {p.term.label}: one sparse term predicts joint {j + 1}'s validation recording "
            f"at least as well (validation RMSE {p.rmse_after:.4g} N m against {library[0]:.4g} N m with the named "
            f"terms) with {len(p.coefficients)} coefficient(s) instead of {n_library}: several named shapes stood in "
            "for one the library has no name for."
        )
        logger.info(f"diagnose: {sentence}")
        keep = [k for k in range(len(final.terms)) if k not in shapes]
        prediction_t, prediction_v = final.prediction_t.copy(), final.prediction_v.copy()
        prediction_t[:, j] -= parts_t
        prediction_v[:, j] -= parts_v
        final = replace(
            final,
            terms=tuple(final.terms[k] for k in keep),
            coefficients=tuple(final.coefficients[k] for k in keep),
            prediction_t=prediction_t,
            prediction_v=prediction_v,
        )
        steps = [k for k in keep if k < n_steps]
        selection = replace(
            selection,
            steps=tuple(selection.steps[k] for k in steps),
            coefficients=tuple(selection.coefficients[k] for k in steps),
            dropped=selection.dropped + (sentence,),
        )
        proposals.append(p)
    return selection, final, tuple(proposals)


def _friction_column_count(problem, options) -> int:
    """Number of nominal friction columns (the first columns of ``problem.base_t``; rigid-body ones follow)."""
    n = problem.ctx_t.n_dof
    dynamic = options.friction == "lugre" and problem.ctx_t.drives is not None
    return len(friction_feature_names(options.friction, n)) + (n if dynamic else 0)
