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

When the prior wins with an inertial finding, the robot file's inertia is in question, so its other findings
are judged against the recalibrated rigid body too (``stand_ins``): one that the diagnosis with the rigid body
identified does not need, on joints the recalibrated model predicts about as well, only stands in for the wrong
prior; it is not reported and the prior diagnosis is repeated without it (``drop_stand_ins``, with a note). The
unnamed sparse terms of the beyond-library stage obey the same rule (``standing_in``, judged there against the
``IdentifiedDiagnosis`` looked at beyond the library too). The free recalibration may take up an effect no
physical link can (a counterbalance on a shoulder, with a link twice as heavy): a finding that a rigid body
recalibrated inside its envelope still needs stands (``envelope_check``, passed to ``drop_stand_ins``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.merged_rotors import robot_file_theta
from identification.diagnosis.columns import BlockColumns, row_chunks
from identification.metrics import rmse

INERTIAL_TERMS = ("payload", "rotor_inertia")  # term keys (the payload term also reports last_link_mass_excess)
AUTO_TOLERANCE = 0.1  # the prior model with the finding may be this much (fraction) worse than the recalibration
MIN_SHARE = 0.95  # or its findings remove this share of the error the recalibration removes
N_MOVED = 5  # base parameters listed in the note
STAND_IN_MARGIN = 0.2  # a prior finding stands where the recalibration needs none if it predicts this much better
STAND_IN_PASSES = 2  # rounds of dropping stand-ins and selecting again


def with_regressor(context, model):
    """``context`` with its PSDM regressor (n_samples, n_dof, n_base), evaluated in chunks of rows."""
    if context.regressor is not None:
        return context
    q, qd, qdd = context.q, context.qd, context.qdd
    regressor = np.concatenate([model.regressor(q[r], qd[r], qdd[r]) for r in row_chunks(q.shape[0])])
    return replace(context, regressor=regressor)


def recalibration_parts(problem, model, held=None) -> dict:
    """The fields of the ``DiagnosisProblem`` with the identified rigid body, from a prior-mode ``problem``: the
    contexts with their regressor, the friction columns followed by the rigid body's, and the whole torque (less a
    model file's held friction, ``DiagnosisContext.tau_fit``); with ``held`` (``held_links.HeldLinks``), the rigid
    body's columns are those of its free links and the held links' torque is taken off."""
    ctx_t, ctx_v = with_regressor(problem.ctx_t, model), with_regressor(problem.ctx_v, model)
    base_t, y_t = rigid_body_part(ctx_t, problem.base_t, held)
    base_v, y_v = rigid_body_part(ctx_v, problem.base_v, held)
    extra = tuple((c, *rigid_body_part(c, base, held)) for c, base in
                  ((with_regressor(ctx, model), base) for ctx, base, _ in problem.extra_v))  # fmt: skip
    return {"ctx_t": ctx_t, "ctx_v": ctx_v, "base_t": base_t, "base_v": base_v, "y_t": y_t, "y_v": y_v,
            "extra_v": extra}  # fmt: skip


def rigid_body_part(ctx, base, held=None) -> tuple:
    """``(columns, torque)`` of a context with its regressor: ``base`` followed by the rigid body's columns, and the
    torque they are fitted to (``recalibration_parts``)."""
    if held is None:
        return base.concatenate(BlockColumns.from_dense(ctx.regressor)), ctx.tau_fit
    columns = BlockColumns.from_dense(held.columns(ctx.regressor))
    return base.concatenate(columns), ctx.tau_fit - held.torque(ctx.regressor)


def prior_wins(rmse_nominal, rmse_prior, rmse_recalibrated, weights, effects=(), recalibrated_effects=(),
               counted=None) -> bool:  # fmt: skip
    """Whether the prior model with its findings (``effects``) is as good as the recalibrated one with its own
    (``recalibrated_effects``) on the validation recording: per-joint RMSE summed with ``weights`` (1 / the joint's
    torque RMS, so that every joint counts alike).

    It is when its error is clearly lower (by ``AUTO_TOLERANCE``); or within ``AUTO_TOLERANCE`` of the
    recalibrated one's with no more findings (findings that only stand in for wrong inertia are extra ones; the
    findings ``counted``, by default ``effects``: an angle law the recalibration matches only by moving a link's
    gravity far from the file is not counted, ``angle_law_choice``);
    or when its findings remove at least ``MIN_SHARE`` of the error that the recalibration removes from the prior
    nominal model (``rmse_nominal``): a payload close to a point mass leaves a small residual of its inertia about
    the flange (its body fit, ``PayloadTerm(inertia=True)``, is inconsistent at the noise level, so the point-mass
    shape is kept), while wrong CAD inertia is only partly mimicked by findings. The
    share rule does not apply to a last link lighter than the file says (``last_link_mass_excess``): that is the
    file's inertia being off, not missing physics.

    A payload both diagnoses keep is a load at the flange, and the prior wins whatever the errors: the recalibrated
    rigid body still needs it, so it is no stand-in for wrong inertia (the links before the flange mimic the mass
    and the first moment of a body on the last joint's axis, never its part that turns with that joint), and only
    the prior's diagnosis weighs it. With the rigid body identified, the load's mass and its first moment along
    the last axis go into the arm's parameters and the payload term's coefficients take an arbitrary share of them
    (on the virtual Denso a 0.8 kg load was weighed 1.77 kg there, 0.85 kg by the prior's diagnosis)."""
    if "payload" in effects and "payload" in recalibrated_effects:
        return True
    nominal, prior, recalibrated = (
        float(np.sum(np.asarray(x) * weights)) for x in (rmse_nominal, rmse_prior, rmse_recalibrated)
    )
    if prior * (1.0 + AUTO_TOLERANCE) < recalibrated:
        return True
    counted = effects if counted is None else counted
    if prior <= (1.0 + AUTO_TOLERANCE) * recalibrated and len(counted) <= len(recalibrated_effects):
        return True
    if "last_link_mass_excess" in effects:
        return False
    return nominal > recalibrated and (nominal - prior) >= MIN_SHARE * (nominal - recalibrated)


@dataclass(frozen=True)
class Claim:
    """What a finding claims, for ``standing_in``: its effect ``key``, its ``joints`` (0-based) and whether it is a
    per-joint term (else robot-wide: a base tilt, a delay)."""

    key: str
    joints: tuple
    per_joint: bool = True

    @classmethod
    def of_step(cls, step) -> Claim:
        """The claim of a kept term (a ``SelectionStep``, or anything with ``term`` and ``joints``)."""
        named = tuple(int(j) for j in (step.term.joints or step.joints))
        return cls(key=step.term.key, joints=named, per_joint=bool(step.term.joints))


@dataclass(frozen=True, eq=False)
class IdentifiedDiagnosis:
    """The diagnosis with the rigid body identified that the prior's findings were judged against when the prior
    won (``DiagnosisProblem``, selection, final fit and options of that run): the beyond-library stage judges its
    unnamed terms against it too (``standing_in``)."""

    problem: object
    selection: object
    final: object
    options: object


def inertia_in_question(selection, carried=()) -> bool:
    """Whether the prior model kept an inertial finding (a payload, a rotor inertia): the robot file's inertia is
    then in question, and its other findings are judged against the recalibrated rigid body (``standing_in``). The
    terms labelled ``carried`` are the nominal model's (a model file's drive columns, ``drive_columns``), no finding."""
    return any(step.term.key in INERTIAL_TERMS and step.term.label not in carried for step in selection.steps)


def standing_in(claims, supporting, rmse_prior, rmse_recalibrated, needed=()) -> tuple:
    """The prior model's findings (``claims``, ``Claim`` values) that only stand in for its wrong inertia: ``(joints,
    keys)``, the joints of the per-joint ones and the effect keys of the robot-wide ones.

    A finding stands if the diagnosis with the rigid body identified also keeps a finding (``supporting``, its
    ``Claim`` values) on one of its joints, or if the prior model with its findings predicts one of its joints'
    validation recording better than the recalibrated one by ``STAND_IN_MARGIN`` (a robot-wide finding, such as a
    base tilt, needs the same effect kept with the rigid body identified); inertial findings always stand. Otherwise
    it only mimics the wrong prior (CAD inertia 10-20 % off leaves a torque that a spring, an offset, a base tilt or
    an unnamed sparse term fits in part). ``rmse_*`` are the per-joint validation RMSE of the two fits. A finding
    among the ``needed`` claims stands too: a rigid body recalibrated inside its physical envelope still needs it
    (``envelope_check``), so only a rigid body no arm has would do its work."""
    supported = {j for claim in supporting for j in claim.joints}
    supported_keys = {claim.key for claim in supporting}
    joints, keys = set(), set()
    for claim in claims:
        found = any(j in supported for j in claim.joints) if claim.per_joint else claim.key in supported_keys
        better = any(rmse_prior[j] <= (1.0 - STAND_IN_MARGIN) * rmse_recalibrated[j] for j in claim.joints)
        if claim.key in INERTIAL_TERMS or found or better or claim in needed:
            continue
        if claim.per_joint:
            joints.update(claim.joints)
        else:
            keys.add(claim.key)
    return tuple(sorted(joints)), tuple(sorted(keys))


def stand_ins(selection, selection_identified, rmse_prior, rmse_recalibrated, needed=(), carried=()) -> tuple:
    """The non-inertial findings of the prior model's ``selection`` that only stand in for its wrong inertia, when
    the prior wins: ``(joints, keys)`` of ``standing_in``, judged against ``selection_identified`` (the selection with
    the rigid body identified), and only when the prior model kept an inertial finding (``inertia_in_question``).
    ``rmse_*`` are the per-joint validation RMSE of the two fits (``prior_wins``); ``needed`` as in ``standing_in``;
    the terms labelled ``carried`` are the nominal model's (``carried_terms``), no finding to judge."""
    if not inertia_in_question(selection, carried):
        return (), ()
    claims = [Claim.of_step(step) for step in selection.steps if step.term.label not in carried]
    supporting = [Claim.of_step(step) for step in selection_identified.steps]
    return standing_in(claims, supporting, rmse_prior, rmse_recalibrated, needed)


def stand_in_note(labels, joints, rmse_prior, rmse_recalibrated, action: str, nominal: str = "robot file") -> str:
    """The report's sentence on findings (``labels``) on ``joints`` that stand in for the ``nominal`` file's inertia
    (``standing_in``); ``action`` says what was done about them."""
    pairs = "; ".join(f"joint {j + 1}: {rmse_prior[j]:.4g} with them, {rmse_recalibrated[j]:.4g}" for j in joints)
    return (
        f"{', '.join(f'`{x}`' for x in labels)} not reported as missing physics: the prior model needed an "
        f"inertial finding (the {nominal}'s inertia is in question), and with the rigid body identified the "
        f"diagnosis needs no finding there and predicts those joints about as well (validation RMSE {pairs} "
        f"recalibrated), so they stand in for the {nominal}'s inertia; {action}."
    )


def without_stand_ins(instances, joints, keys=()) -> tuple:
    """The candidate ``instances`` without the non-inertial per-joint ones on ``joints`` and the robot-wide ones of
    effect ``keys`` (``stand_ins``)."""
    return tuple(
        term
        for term in instances
        if term.key in INERTIAL_TERMS or not (set(term.joints) & set(joints) or (not term.joints and term.key in keys))
    )


def drop_stand_ins(reselect, instances, fit, selection_identified, y_validation, rmse_recalibrated, envelope=None,
                   carried=(), nominal="robot file"):  # fmt: skip
    """The prior fit without the findings that stand in for its wrong inertia (``stand_ins``): ``(selection, final,
    notes)``. ``reselect(instances)`` runs the prior diagnosis's selection and final fit on the candidate
    ``instances``; ``fit`` is its ``(selection, final)`` on all of them. Up to ``STAND_IN_PASSES`` rounds, since a
    new selection may take another stand-in. ``envelope(selection, joints)``, when given, is the
    ``envelope_check.EnvelopeCheck`` of the findings on ``joints`` that would be dropped: those it needs stand. The
    terms labelled ``carried`` (a model file's counterbalance, ``carried_terms``) are the nominal model's: never
    dropped. ``nominal`` names the prior's inertia in the notes (``DiagnosisOptions.nominal``)."""
    selection, final = fit
    notes = []
    for _ in range(STAND_IN_PASSES):
        rmse_prior = rmse(y_validation, final.prediction_v)
        joints, keys = stand_ins(selection, selection_identified, rmse_prior, rmse_recalibrated, carried=carried)
        check = envelope(selection, joints) if envelope is not None and joints else None
        if check is not None and check.needed:
            notes.extend(note for note in check.notes() if note not in notes)
            joints, keys = stand_ins(selection, selection_identified, rmse_prior, rmse_recalibrated, check.claims,
                                     carried)  # fmt: skip
        if not (joints or keys):
            break
        kept = set(without_stand_ins([step.term for step in selection.steps], joints, keys))
        kept |= {step.term for step in selection.steps if step.term.label in carried}
        labels = [step.term.label for step in selection.steps if step.term not in kept]
        named = sorted({j for step in selection.steps if step.term not in kept for j in step.joints})
        action = "the diagnosis was repeated without them"
        notes.append(stand_in_note(labels, named, rmse_prior, rmse_recalibrated, action, nominal))
        instances = without_stand_ins(instances, joints, keys)
        selection, final = reselect(instances)
    return selection, final, tuple(notes)


def moved_parameters(model, robot, theta_identified, count: int = N_MOVED, kt=None) -> list:
    """The base parameters that moved most from the robot file's values: ``(name, file, identified, relative)``,
    largest relative change first (relative to the larger of the file's value and 1 % of the largest one). The file's
    in identify's map (``merged_rotors.robot_file_theta``: on motor currents, ``kt``, with the merged rotors)."""
    prior = np.asarray(robot_file_theta(robot, model, kt), dtype=float)
    theta = np.asarray(theta_identified, dtype=float)
    floor = 0.01 * max(float(np.max(np.abs(prior))), 1e-12)
    relative = np.abs(theta - prior) / np.maximum(np.abs(prior), floor)
    order = np.argsort(-relative)[:count]
    return [(str(model.base_names[k]), float(prior[k]), float(theta[k]), float(relative[k])) for k in order]


def inertial_note(effects, error_prior: float, error_recalibrated: float, moved, nominal: str = "robot file") -> str:
    """The report's sentence when the recalibration beats the prior model's findings ``effects`` (effect names);
    the errors are the joint-weighted validation RMSE sums of ``prior_wins`` (fractions of the torque RMS);
    ``nominal`` names whose inertia the prior was (``DiagnosisOptions.nominal``)."""
    names = ", ".join(f"`{e}`" for e in effects) or "its findings"
    listed = "; ".join(f"{name} {a:.4g} -> {b:.4g} ({r:.0%})" for name, a, b, r in moved)
    return (
        f"the {nominal}'s inertial parameters are off: with them the model needs {names} and still predicts the "
        f"validation recording worse (mean relative RMSE {error_prior:.3g}) than a full rigid-body recalibration "
        f"({error_recalibrated:.3g}), so those findings are not reported as missing physics and the rigid body is "
        f"identified. Base parameters that moved most (file -> identified, relative change): {listed}."
    )
