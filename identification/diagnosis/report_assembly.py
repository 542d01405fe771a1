"""The ``DiagnosisReport`` of a diagnosis fit: the findings of the kept terms, the augmented model, the errors.

``diagnose`` hands over its ``DiagnosisProblem``, the selection, the final fit (``diagnose.FinalFit``) and the
unnamed findings of the beyond-library stage; ``build_report`` turns them into the report that the C export and
the model file reproduce (the augmented model holds exactly the terms and coefficients the findings show).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identification.calibration.carried_payload import flange_parameter_map
from identification.calibration.held_friction import CONSTANT_FEATURE, HeldFriction
from identification.calibration.merged_rotors import merged_rotor_map, robot_file_theta
from identification.calibration.model_preparation import Preparation, edge_text
from identification.data.filter_choice import AUTO
from identification.diagnosis.augmented import AugmentedModel
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from identification.diagnosis.carried_terms import CarriedColumns, carried_labels
from identification.diagnosis.confounding import confounding_of
from identification.diagnosis.counterbalance_naming import name_counterbalances, offset_verdicts
from identification.diagnosis.design import left_out
from identification.diagnosis.elasticity_evidence import with_elasticity_evidence
from identification.diagnosis.held_links import held_links
from identification.diagnosis.joint_changes import explain_joint_changes, rise_margin, rise_sentence
from identification.diagnosis.nominal import friction_feature_names, friction_shapes
from identification.diagnosis.recording_checks import check_recordings
from identification.diagnosis.report import DiagnosisReport, Finding
from identification.diagnosis.residual_tests import analyse_residuals
from identification.metrics import r2, rmse

RISE_NOTED = 0.01  # a joint's rise above the model file named as worse: beyond 1 %, the never-worse margin's floor


def build_report(
    robot,
    model,
    problem,
    selection,
    final,
    options,
    unnamed: tuple = (),
) -> DiagnosisReport:
    """The findings, the augmented model and the per-joint errors of the nominal and the final model (a spring fitted
    beside a carried offset given the combined constant, ``CarriedColumns.with_constants``)."""
    final = CarriedColumns(options.carried).with_constants(final)
    ctx_t, ctx_v = problem.ctx_t, problem.ctx_v
    fixed_t = ctx_t.tau - problem.y_t
    fixed_v = ctx_v.tau - problem.y_v
    model_nominal_v = fixed_v + selection.nominal_validation
    model_final_v = fixed_v + final.prediction_v
    model_nominal_t = fixed_t + selection.nominal_train
    model_final_t = fixed_t + final.prediction_t
    residual_v = ctx_v.tau - model_nominal_v
    found = findings_of(selection, final, options.held_friction)
    held = (ctx_v, ctx_v.tau - model_final_v)  # the data's verdict on an offset no sensor has by size
    verdicts = offset_verdicts(found, ctx_t, ctx_t.tau - model_final_t, held, options.rigid_body != "prior")
    offsets = carried_labels(options, "torque_offset")  # a carried offset fits how far the file's is off
    findings = name_counterbalances(found, ctx_t, verdicts, offsets) + tuple(unnamed)
    findings = with_elasticity_evidence(findings, final, ctx_t, model_nominal_t)
    if options.rigid_body == "prior":
        findings = tuple(with_rotor_note(f, robot, model) for f in findings)
    rmse_before, rmse_after = rmse(ctx_v.tau, model_nominal_v), rmse(ctx_v.tau, model_final_v)
    r2_before, r2_after = r2(ctx_v.tau, model_nominal_v), r2(ctx_v.tau, model_final_v)
    for values in (rmse_before, rmse_after, r2_before, r2_after):  # a joint without a torque measurement: no number
        values[list(left_out(ctx_v))] = np.nan
    margin = rise_margin(ctx_v.tau - model_nominal_v, ctx_v.tau - model_final_v)  # the never-worse gate's
    return DiagnosisReport(
        robot_name=robot.name,
        n_dof=robot.n_dof,
        friction=options.friction if options.file_friction is None else options.file_friction.describe(),
        rigid_body=options.rigid_body,
        findings=findings,
        rmse_before=tuple(rmse_before.tolist()),
        rmse_after=tuple(rmse_after.tolist()),
        r2_before=tuple(r2_before.tolist()),
        r2_after=tuple(r2_after.tolist()),
        rmse_train_before=tuple(rmse(ctx_t.tau, model_nominal_t).tolist()),
        rmse_train_after=tuple(rmse(ctx_t.tau, model_final_t).tolist()),
        residual_findings=analyse_residuals(ctx_v, residual_v),
        candidates_tried=selection.candidates_tried,
        augmented=augmented_model_of(robot, model, final, options, ctx_t.torque_constants),
        validation_t=ctx_v.t,
        validation_q=ctx_v.q,
        validation_qd=ctx_v.qd,
        validation_tau=ctx_v.tau,
        validation_nominal=model_nominal_v,
        validation_final=model_final_v,
        joint_notes=explain_joint_changes(
            rmse_before, rmse_after, findings, options.rigid_body, bool(final.nonlinear), margin
        ),
        confounding=confounding_of(robot, model, problem, final, len(selection.steps), options),
        dropped=selection.dropped,
        unstable=held_offset_unstable(selection.unstable, options.held_friction),
        rejected=selection.rejected,
        opinion_route=selection.opinion_route,
        recordings=check_recordings(problem, final, findings),
        left_out=problem.left_out,
        held_friction=options.held_friction.values,
    )


def with_rotor_note(finding, robot, model):
    """``finding`` with the note a ``rotor_inertia`` finding gets where it is what the robot file lacks, as ``psdm
    identify`` states it: a drive inertia the base parameters merge with the links' and the file does not state.
    Identify fits such a rotor from the data beside the file's links and keeps it in the model it writes
    (``merged_rotors.with_merged_rotors``), so the file needs it and identify's model does not (the TX40's motor-side
    torques: joints 1-2, 0.60 and 0.51 kg m^2 here, 0.60 and 0.49 identify's on its own training part)."""
    if finding.effect != "rotor_inertia" or len(finding.joints) != 1:
        return finding
    j = finding.joints[0]
    if np.asarray(robot.rotor_inertia, dtype=float)[j] > 0 or not merged_rotor_map(model, robot, [j]):
        return finding
    note = (f"joint {j + 1}'s drive inertia lies inside the base parameters and the robot file states none: this is "
            "what the robot file lacks, not an effect beyond the model. 'psdm identify' fits it from the data beside "
            "the file's links and keeps it in the model it writes (a diagnosis of that model file does not list it); "
            "state it as rotor_inertia in the robot file's [[link]] table to use it with the file.")  # fmt: skip
    return replace(finding, notes=finding.notes + (note,))


def findings_of(selection, final, held: HeldFriction | None = None) -> tuple:
    """One ``Finding`` per kept term, in the order the selection kept them; a term's constant is stated with the
    torque offset the nominal model holds on its joint (``with_held_offset``), and a torque offset on such a joint is
    that held offset found not to hold, not a missing effect (``held_offset_correction``)."""
    findings = []
    for step, term, coefficients in zip(selection.steps, final.terms, final.coefficients):
        effect, explanation = term.interpret(coefficients)
        stated, note = with_held_offset(term, coefficients, held or HeldFriction())
        stated, correction = held_offset_correction(term, stated, held or HeldFriction())
        parameters = dict(term.physical_parameters(stated))
        parameters.update(final.nonlinear.get(term.label, {}))
        findings.append(
            Finding(
                effect=effect,
                label=term.label,
                joints=tuple(int(j) for j in step.joints),
                parameters=parameters,
                coefficients=tuple(float(c) for c in coefficients),
                feature_names=tuple(term.feature_names()),
                explanation=explanation,
                signature=term.signature,
                rmse_before=tuple(float(x) for x in step.rmse_before),
                rmse_after=tuple(float(x) for x in step.rmse_after),
                delta_bic=step.delta_bic,
                validation_gain=step.validation_gain,
                notes=(note,) if note else (),
                shape_note=step.shape_note,
                correction=correction,
            )
        )
    return tuple(findings)


def held_offset_correction(term, coefficients, held: HeldFriction) -> tuple:
    """``(coefficients, correction)`` of a ``torque_offset`` term on a joint whose torque offset the nominal model
    holds (a model file's, ``HeldFriction.of_model_file``): the term's column is that offset's, so what it fits is how
    far the file's offset is off on these recordings, not an effect the model lacks. Its offset is stated as the data's
    (the file's plus the fit's part: what ``diagnose --apply``, whose refit fits the file's offset again, writes), and
    the sentence says the file's offset does not hold, with both values. Any other term: unchanged and ""."""
    joint = getattr(term, "joint", None)
    offset = held.offset_of(int(joint)) if getattr(term, "key", "") == "torque_offset" and joint is not None else 0.0
    if offset == 0.0:
        return coefficients, ""
    change = float(coefficients[0])
    correction = (f"the model file's torque offset on joint {int(joint) + 1} does not hold on these recordings: the "
                  f"file holds {offset:+.4g} N m, the data's is {offset + change:+.4g} N m ({change:+.4g}); a "
                  "correction of the file's value, not a missing effect ('diagnose --apply' fits the file's offset "
                  "again)")  # fmt: skip
    return np.array([offset + change, *np.asarray(coefficients, dtype=float)[1:]]), correction


def held_offset_unstable(unstable, held: HeldFriction) -> tuple:
    """The unstable findings (``second_opinion.UnstableFinding``) with a ``torque_offset`` on a joint whose offset the
    nominal model holds (a model file's) stated as the joint's whole offset on each recording or block: its fit there
    is the part the data add to the file's (the two are one column), which alone reads as an offset the joint does not
    have. Each opinion's ``offset`` is then the file's part plus the data's, both stated (``file_part``,
    ``data_part``), and the finding says so; any other unstable finding is unchanged."""
    out = []
    for u in unstable:
        offset = held.offset_of(int(u.joints[0])) if u.effect == "torque_offset" and len(u.joints) == 1 else 0.0
        if offset == 0.0:
            out.append(u)
            continue
        opinions = tuple(
            replace(o, parameters={"offset": offset + o.parameters["offset"], "file_part": offset,
                                   "data_part": o.parameters["offset"]}) if "offset" in o.parameters else o
            for o in u.opinions
        )  # fmt: skip
        note = (f"the model file holds a torque offset of {offset:+.4g} N m on joint {int(u.joints[0]) + 1}: each "
                "offset below is the joint's whole, the file's part plus the part the data add")  # fmt: skip
        out.append(replace(u, opinions=opinions, note=note))
    return tuple(out)


def with_held_offset(term, coefficients, held: HeldFriction) -> tuple:
    """``(coefficients, note)``: ``coefficients`` with the term's constant (``CONSTANT_FEATURE``: a spring's, which
    holds its rest angle ``q0 = -c / k``) plus the torque offset the nominal model holds on its joint (a model file's,
    ``HeldFriction.of_model_file``), and the sentence that says so; the coefficients and "" otherwise.

    The held offset and the constant are one column: the fit sees the torque the offset leaves, so its constant is
    what the spring adds to the offset, and its rest angle without the offset is not the spring's. ``diagnose --apply``
    leaves the offset to the spring's constant (``findings.offsets_left_to_findings``), so the rest angle stated with
    the offset is the one the file it writes holds."""
    joint = getattr(term, "joint", None)
    names = list(term.feature_names()) if joint is not None else []
    constant = [k for k, name in enumerate(names) if CONSTANT_FEATURE.fullmatch(name)]
    offset = held.offset_of(int(joint)) if constant else 0.0
    if offset == 0.0:
        return coefficients, ""
    stated = np.array(coefficients, dtype=float)
    stated[constant[0]] += offset
    note = (f"its constant {names[constant[0]]} = {stated[constant[0]]:.4g} N m includes the torque offset the "
            f"model file holds on joint {int(joint) + 1} ({offset:.4g} N m; the fit's own part "
            f"{float(coefficients[constant[0]]):.4g}): the two are one column, and 'diagnose --apply' gives an "
            "offset chosen from the data to this term, so its parameters are stated as the file it writes holds "
            "them")  # fmt: skip
    return stated, note


def augmented_model_of(robot, model, final, options, kt=None) -> AugmentedModel:
    """The nominal model (the robot file's or the identified base parameters, fitted friction) plus the kept terms;
    the robot file's in identify's map (``merged_rotors.robot_file_theta``: on motor currents, ``kt``, with the rotors
    the base parameters merge)."""
    n_friction = len(friction_feature_names(options.friction, robot.n_dof))
    n_dynamic = robot.n_dof if (options.friction == "lugre" and robot.drives is not None) else 0
    friction_all = final.friction_coefficients
    theta = (
        robot_file_theta(robot, model, kt) if options.rigid_body == "prior" else friction_all[n_friction + n_dynamic :]
    )
    held = held_links(model, robot, options.held_links) if options.rigid_body != "prior" else None
    theta = theta if held is None else held.theta(theta)  # the free links' coefficients (``held_links``)
    vs, dv = friction_shapes(robot)
    return AugmentedModel(
        model=model,
        theta=np.asarray(theta, dtype=float),
        friction_kind=options.friction,
        friction_coefficients=np.asarray(friction_all[:n_friction], dtype=float),
        friction_vs=vs,
        friction_dv=dv,
        terms=final.terms,
        coefficients=final.coefficients,
        parameter_map=flange_parameter_map(robot, model),
        held_friction=options.held_friction,
        coulomb_velocity=options.coulomb_velocity if robot.drives is None else SMOOTH_VELOCITY,  # as its columns
    )


def with_model_file_before(report: DiagnosisReport, t, tau, predicted, rtol: float = 1e-9) -> DiagnosisReport | None:
    """The report whose "before" is a calibrated model file as it is, or None when the diagnosis did not judge the
    same samples.

    ``t``, ``tau`` and ``predicted`` are the validation recording as the model file prepares it and the file's
    prediction there (``CalibratedModel.predict_recording``, as ``psdm validate``). The diagnosis prepares its
    recordings as the file says (``DiagnosisOptions`` cutoff and grid rate, identify's trims), so its validation
    samples are those same instants with the same torque, to ``rtol``; then one "before" is shown per joint: the RMSE,
    R^2 and prediction of the file, and a joint whose final RMSE is above it gets its sentence (``joint_notes``). Not
    the same samples (a file with measurement corrections, a grid made coarser by ``max_samples``): None. Without a
    finding the diagnosis adds nothing to the file, so its "after" is the file as it is too: its own refit of the
    nominal friction on the one training recording is no model anyone writes (``diagnose --apply`` writes none); so
    is it when every finding is the file's own at the file's size (``DiagnosisReport.nothing_applied``).
    """
    t, tau, predicted = (np.asarray(x, dtype=float) for x in (t, tau, predicted))
    own_t, own_tau = np.asarray(report.validation_t), np.asarray(report.validation_tau)
    if own_t.shape != t.shape or own_tau.shape != tau.shape or predicted.shape != tau.shape:
        return None
    measured = np.all(np.isfinite(tau), axis=0)  # a joint without a torque measurement is not compared
    own_tau, tau_measured = own_tau[:, measured], tau[:, measured]
    scale = max(float(np.max(np.abs(tau_measured), initial=0.0)), 1e-300)
    if not (
        np.allclose(own_t, t, rtol=0.0, atol=1e-9) and np.allclose(own_tau, tau_measured, rtol=rtol, atol=rtol * scale)
    ):
        return None
    before, after = rmse(tau, predicted), np.asarray(report.rmse_after, dtype=float)
    if not report.findings or report.nothing_applied:  # nothing to add: the model it stands by is the file as it is
        fit = r2(tau, predicted).tolist()
        source = f"the model file as it is: {report.nothing_applied}" if report.nothing_applied else report.after_source
        return replace(report, rmse_before=tuple(before.tolist()), r2_before=tuple(fit), validation_nominal=predicted,
                       rmse_after=tuple(before.tolist()), r2_after=tuple(fit), validation_final=predicted,
                       joint_notes=(), model_file_rmse=tuple(before.tolist()), before_is_model_file=True,
                       after_source=source)  # fmt: skip
    cause = (
        "the diagnosis refits the nominal friction on the training recording before it adds the findings; the model "
        "file as it is predicts this joint better ('diagnose --apply' refits the file itself, never worse)"
    )
    if report.applied is not None:  # the "after" is the model --apply writes (``applied_after``)
        cause = ("the model file identified again with the findings predicts this joint worse than the file as it is; "
                 "'diagnose --apply' writes it only if no joint is worse beyond the never-worse margin")  # fmt: skip
    risen = [j for j in range(before.size) if after[j] > before[j] * (1.0 + RISE_NOTED)]  # not a rise within noise
    notes = tuple(rise_sentence(j, before[j], after[j], cause) for j in risen)
    return replace(report, rmse_before=tuple(before.tolist()), r2_before=tuple(r2(tau, predicted).tolist()),
                   validation_nominal=predicted, joint_notes=notes, model_file_rmse=tuple(before.tolist()),
                   before_is_model_file=True)  # fmt: skip


def preparation_text(given, options) -> str:
    """How the diagnosis prepared its recordings (``DiagnosisReport.preparation``): ``options`` as resolved from the
    ``given`` ones, identify's default for the training recording when the cutoff was left ``"auto"``."""
    if options.cutoff_hz is None or not options.preprocess:
        return "the recordings as given (not filtered by the diagnosis)"
    source = "identify's default for the training recording" if given.cutoff_hz == AUTO else "DiagnosisOptions"
    text = Preparation(float(options.cutoff_hz), float(options.rate_hz), source, "", options.edge_periods).text()
    other = "5 % of the grid (at most 0.2 s) trimmed at each end"
    return text if options.samples == "identify" else text.replace(edge_text(options.edge_periods), other)
