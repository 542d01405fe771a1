"""diagnose(): identify the nominal model on the training recording(s), find the missing physics, re-identify, validate.

RobotDescription + training/validation Recordings -> DiagnosisReport (with the augmented model). The
diagnoser sees only the robot file (kinematics, nominal inertia, drive friction shapes) and the
recordings. The steps, each a function below: ``prepare_problem`` (preprocess, nominal signals, the
nominal model's columns), ``select_terms`` (``selection.forward_select``), ``refine_terms``
(``refine.refine_fit``), ``settle_rigid_body`` (``rigid_body_choice``), ``look_beyond_library``, and
``report_assembly.build_report``. Progress is logged at INFO (logger ``identification.diagnosis``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.data.missing_torque import measured_torque
from identification.data.plausibility import check_plausible_recording
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.data.torque_constants import drive_kt
from identification.diagnosis.angle_law_choice import gravity_backed_laws
from identification.diagnosis.beyond_library import look_beyond_library
from identification.diagnosis.candidates import CandidateLibrary, default_library
from identification.diagnosis.candidates.friction import lacking_friction_shapes
from identification.diagnosis.carried_terms import CarriedColumns, carried_labels
from identification.diagnosis.columns import BlockColumns
from identification.diagnosis.context import DiagnosisContext, build_context
from identification.diagnosis.design import left_out
from identification.diagnosis.envelope_check import EnvelopedRecalibration
from identification.diagnosis.friction_rival import FrictionRival
from identification.diagnosis.held_links import held_links
from identification.diagnosis.hidden_balancer import name_hidden_balancers
from identification.diagnosis.hidden_payload import name_hidden_payload
from identification.diagnosis.motion_checks import (
    check_motion,
    check_nominal_columns,
    training_recordings,
    validation_recordings,
)
from identification.diagnosis.nominal import (
    friction_blocks,
    friction_feature_names,
    linear_viscous_unless_stated,
    torque_constants_only,
)
from identification.diagnosis.options import DiagnosisOptions
from identification.diagnosis.plausible_fit import implausible_terms, plausible_diagnosis
from identification.diagnosis.pooled_context import pooled_context
from identification.diagnosis.refine import refine_fit
from identification.diagnosis.report import DiagnosisReport
from identification.diagnosis.report_assembly import build_report, findings_of, preparation_text
from identification.diagnosis.rigid_body_choice import (
    IdentifiedDiagnosis,
    drop_stand_ins,
    inertial_note,
    moved_parameters,
    prior_wins,
    recalibration_parts,
    rigid_body_part,
)
from identification.diagnosis.second_opinion import SecondOpinion
from identification.diagnosis.selection import SelectionResult, forward_select
from identification.metrics import rms, rmse
from psdm_casadi.errors import ParameterError

__all__ = ["DiagnosisOptions", "DiagnosisProblem", "FinalFit", "check_motion", "diagnose", "prepare_problem"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class DiagnosisProblem:
    """The least-squares problem the selection and the refinement share, on training (``_t``) and validation (``_v``).

    Attributes
    ----------
    ctx_t, ctx_v : DiagnosisContext
        The preprocessed recordings with the nominal model's signals.
    base_t, base_v : BlockColumns
        Columns (n_samples, n_dof, p) of the nominal model's free parameters (friction, and base parameters if
        identified), stored per joint.
    y_t, y_v : arrays (n_samples, n_dof)
        Measured torque minus the fixed part of the nominal model (the robot file's rigid body for
        ``rigid_body="prior"``, nothing otherwise).
    extra_v : tuple of (DiagnosisContext, BlockColumns, array)
        The further validation recordings, each as its ``ctx_v``, ``base_v`` and ``y_v`` (the second opinion of
        ``second_opinion``).
    """

    ctx_t: DiagnosisContext
    ctx_v: DiagnosisContext
    base_t: BlockColumns
    base_v: BlockColumns
    y_t: np.ndarray
    y_v: np.ndarray
    extra_v: tuple = ()
    left_out: tuple = ()  # why joints without a torque measurement are left out (``missing_torque.measured_torque``)


@dataclass(frozen=True, eq=False)
class FinalFit:
    """The kept terms with their final coefficients and predictions (refined, or the selection's linear fit)."""

    terms: tuple
    coefficients: tuple
    friction_coefficients: np.ndarray
    prediction_t: np.ndarray
    prediction_v: np.ndarray
    nonlinear: dict


def diagnose(
    robot, train, validation, options: DiagnosisOptions | None = None, model=None, derive=None
) -> DiagnosisReport:
    """Find the physics a nominal model leaves out of the recordings, and show the fit with it.

    Parameters
    ----------
    robot : RobotDescription
        The robot file (kinematics, nominal inertia = the prior, drives).
    train : Recording or sequence of Recording
        Raw (or, with ``options.preprocess=False``, preprocessed) recording(s) the model is fitted on. Several are
        pooled (``pooled_context``): every fit and the selection see all of them, as a refit with the findings does;
        the first sets the preparation ("auto" cutoff and grid rate) and is checked for motion.
    validation : Recording or sequence of Recording
        The recording(s) the model is judged on. With several, a finding is kept only if it passes the selection's
        gates on each (the first is the one the report's errors are computed on); with one, a block
        cross-validation of ``train`` gives the second opinion (``DiagnosisOptions.cv_folds``). A finding that does
        not hold is reported in ``DiagnosisReport.unstable``, not as missing physics.
    options : DiagnosisOptions, optional
    model : PSDMModel, optional
        ``derive_psdm(robot)``, derived when omitted (after the recordings are checked).
    derive : callable, optional
        ``derive(robot) -> PSDMModel`` used instead of ``derive_psdm`` when ``model`` is omitted (the CLI's model
        cache).

    Returns
    -------
    DiagnosisReport

    Raises
    ------
    ShapeError, RecordingError
        When a recording does not match the robot, is too short, or is in the wrong units (positions in degrees, a
        time column in milliseconds: ``plausibility.check_plausible_recording``, as ``psdm diagnose`` refuses them).
    InsufficientExcitationError
        When a joint does not move enough in a recording, or the nominal model's columns are not excited
        (before any candidate is tried).
    ParameterError
        For bad options.

    Examples
    --------
    >>> report = diagnose(robot, train, validation)          # doctest: +SKIP
    >>> print(report.to_markdown())                          # doctest: +SKIP
    """
    options = DiagnosisOptions() if options is None else options
    if not isinstance(options, DiagnosisOptions):
        raise ParameterError(f"diagnose options must be a DiagnosisOptions; got {type(options).__name__}.")
    trains = training_recordings(train)
    train = trains[0]
    given, options = options, options.for_recording(train, robot)
    robot, options = torque_constants_only(robot, options)
    robot = linear_viscous_unless_stated(robot, options)
    validations = validation_recordings(validation)
    for recording in (*trains, *validations):  # positions, speeds and time in the robot's units, before any fit
        recording.check_robot(robot.n_dof, robot.name)
        check_plausible_recording(recording, robot)
    for recording in validations:
        check_motion(robot, train, recording, options)
    if model is None:
        from psdm_casadi.derive import derive_psdm

        logger.info("diagnose: deriving the PSDM model ...")
        model = (derive or derive_psdm)(robot)
    prepared = prepare_problem(robot, model, trains, validations, options)

    def run(options):  # the findings: selection, refinement, rigid-body choice, beyond the library
        problem, selection = prepared, select_terms(robot, prepared, options)
        final, notes, identified = refine_terms(problem, selection, options), (), None
        if options.rigid_body == "auto":
            problem, selection, final, options, notes, identified = settle_rigid_body(
                robot, model, problem, selection, final, options
            )
        selection, final, unnamed, more = look_beyond_library(problem, selection, final, options, identified)
        return problem, selection, final, options, notes + more, unnamed

    (problem, selection, final, options, notes, unnamed), rejected = plausible_diagnosis(run, options, robot.n_dof)
    report = build_report(robot, model, problem, selection, final, options, unnamed)
    return replace(report, rigid_body_notes=notes, preparation=preparation_text(given, options),
                   rejected=report.rejected + rejected)  # fmt: skip


def settle_rigid_body(robot, model, problem: DiagnosisProblem, selection, final: FinalFit, options) -> tuple:
    """``rigid_body="auto"`` (``rigid_body_choice``): ``(problem, selection, final, options, notes, identified)`` of
    the prior fit, or of the identified rigid body when that diagnosis predicts the validation recording better;
    ``identified`` is the ``IdentifiedDiagnosis`` the prior's findings were judged against when the prior won."""
    prior = replace(options, rigid_body="prior")
    if not selection.steps:
        return problem, selection, final, prior, (), None
    logger.info(f"diagnose: findings with the {options.nominal}'s inertia; diagnosing with a recalibrated rigid body "
                "too ...")  # fmt: skip
    identified = replace(options, rigid_body="identified")
    held = held_links(model, robot, options.held_links)  # a model file's held links stay held (``held_links``)
    recal = DiagnosisProblem(**recalibration_parts(problem, model, held), left_out=problem.left_out)
    selection_i = select_terms(robot, recal, identified)
    final_i = refine_terms(recal, selection_i, identified)
    weights = 1.0 / np.maximum(rms(problem.ctx_v.tau), 1e-9)
    weights[list(left_out(problem.ctx_v))] = 0.0  # joints without a torque measurement are not judged
    rmse_prior, rmse_recal = rmse(problem.y_v, final.prediction_v), rmse(recal.y_v, final_i.prediction_v)
    rmse_nominal = rmse(problem.y_v, selection.nominal_validation)
    findings = findings_of(selection, final)
    found, found_i = tuple(f.effect for f in findings), tuple(f.effect for f in findings_of(selection_i, final_i))
    wins, backed = prior_wins(rmse_nominal, rmse_prior, rmse_recal, weights, found, found_i), ()
    if not wins:  # an angle law the recalibration matches only by moving a link's gravity is no extra finding
        theta = identified_theta(robot, final_i, options, held)
        backed = gravity_backed_laws(robot, model, problem.ctx_v, theta, final.terms, final.coefficients, findings,
                                     problem.ctx_t)  # fmt: skip
        counted = list(found)
        for law in backed:
            counted.remove(law.effect)
        errors = (rmse_nominal, rmse_prior, rmse_recal, weights)
        wins = bool(backed) and prior_wins(*errors, found, found_i, counted=tuple(counted))
    if wins:

        def reselect(instances):  # the prior diagnosis on fewer candidates (``drop_stand_ins``)
            again = replace(prior, library=CandidateLibrary(tuple(instances)))
            chosen = select_terms(robot, problem, again)
            return chosen, refine_terms(problem, chosen, again)

        library = (options.library or default_library()).expand(robot.n_dof)
        contexts, friction = (recal.ctx_t, recal.ctx_v), (problem.base_t, problem.base_v)
        enveloped = EnvelopedRecalibration(robot, model, contexts, friction, options.held_links, options.rotors_apart)
        envelope = enveloped.check if options.envelope else None
        fit = drop_stand_ins(reselect, library, (selection, final), selection_i, problem.y_v, rmse_recal, envelope,
                             carried=carried_labels(options), nominal=options.nominal)  # fmt: skip
        notes = tuple(law.note() for law in backed if law.label in {s.term.label for s in fit[0].steps}) + fit[2]
        for note in notes:
            logger.info(f"diagnose: {note}")
        return problem, fit[0], fit[1], prior, notes, IdentifiedDiagnosis(recal, selection_i, final_i, identified)
    effects = sorted(set(found) - set(found_i))
    named = None
    if options.envelope:  # a tool the free recalibration takes into the links (``hidden_payload``)
        enveloped = EnvelopedRecalibration(robot, model, (recal.ctx_t, recal.ctx_v), (problem.base_t, problem.base_v),
                                           options.held_links, options.rotors_apart)  # fmt: skip
        named = name_hidden_payload(robot, model, (problem, recal), (selection_i, final_i), identified, enveloped)
        if named is not None:
            selection_i, final_i, named = named
            logger.info(f"diagnose: {named}")
    theta = identified_theta(robot, final_i, options, held)  # after a hidden payload was taken out of the links
    balanced = ()
    if options.envelope:  # a counterbalance the free recalibration takes into the links (``hidden_balancer``)
        fits = name_hidden_balancers(robot, model, recal, (selection_i, final_i), (problem.base_t, problem.base_v),
                                     theta, final.terms, options.held_links)  # fmt: skip
        if fits is not None:
            selection_i, final_i, balanced = fits
            theta = identified_theta(robot, final_i, options, held)
            effects = [e for e in effects if e not in {f.effect for f in findings_of(selection_i, final_i)}]
            for line in balanced:
                logger.info(f"diagnose: {line}")
    moved = moved_parameters(model, robot, theta, kt=problem.ctx_t.torque_constants)
    n = robot.n_dof
    note = inertial_note(effects, float(rmse_prior @ weights) / n, float(rmse_recal @ weights) / n, moved,
                         options.nominal)  # fmt: skip
    notes = (note,) + ((named,) if named else ()) + balanced
    return recal, selection_i, final_i, identified, notes, None


def identified_theta(robot, final_i: FinalFit, options, held=None) -> np.ndarray:
    """The recalibrated rigid body's base parameters of the identified diagnosis's final fit (after the nominal
    friction's coefficients; a model file's ``held`` links put back)."""
    n_friction = len(friction_feature_names(options.friction, robot.n_dof))
    n_friction += robot.n_dof if (options.friction == "lugre" and robot.drives is not None) else 0
    theta = final_i.friction_coefficients[n_friction:]
    return theta if held is None else held.theta(theta)


def prepare_problem(robot, model, train, validation, options: DiagnosisOptions) -> DiagnosisProblem:
    """Preprocess the recordings, evaluate the nominal model's signals on them, and set up the least squares;
    ``train`` is a Recording or a sequence of them (pooled into ``ctx_t``, ``pooled_context``), ``validation`` too
    (the first is ``ctx_v``, the others ``extra_v``)."""
    trains = training_recordings(train)
    options = options.for_recording(trains[0], robot)
    given = options.torque_constants
    kt_arr = drive_kt(robot) if given is None else np.asarray(given, dtype=float)
    logger.info("diagnose: evaluating the nominal model ...")
    recordings, missing, left_out = measured_torque((*trains, *validation_recordings(validation)), robot.joint_names)
    held = held_links(model, robot, options.held_links) if options.rigid_body == "identified" else None
    contexts = [_context(robot, model, r, options, kt_arr).without_torque(missing) for r in recordings]
    ctx_t = pooled_context(contexts[: len(trains)])
    base_t, y_t = _least_squares(robot, options, ctx_t, held)
    validations = contexts[len(trains) :]
    parts = [(ctx, *_least_squares(robot, options, ctx, held)) for ctx in validations]
    (ctx_v, base_v, y_v), extra = parts[0], tuple(parts[1:])
    problem = DiagnosisProblem(ctx_t, ctx_v, base_t, base_v, y_t, y_v, extra_v=extra, left_out=left_out)
    check_nominal_columns(robot, model, problem, options)
    return problem


def _least_squares(robot, options: DiagnosisOptions, ctx, held=None) -> tuple:
    """``(base, y)`` of a recording's context: the nominal model's free columns and the torque they are fitted to
    (with the rigid body identified, its ``held`` links held: ``rigid_body_choice.rigid_body_part``)."""
    base = friction_blocks(robot, options.friction, ctx, held=options.held_friction.joints, own=options.file_friction)
    if options.rigid_body != "identified":
        return base, ctx.tau_fit - ctx.tau_rigid
    return rigid_body_part(ctx, base, held)


def _context(robot, model, recording, options: DiagnosisOptions, kt) -> DiagnosisContext:
    """The recording preprocessed (unless ``options.preprocess`` is off) and its ``DiagnosisContext``; the full-rate
    position and acceleration of the preprocessed recording are released on return (only the grid keeps them)."""
    raw = recording if options.preprocess else None
    if options.preprocess:
        recording = preprocess(recording, PreprocessOptions(cutoff_hz=options.cutoff_hz))
    ctx = build_context(robot, model, recording, options.rate_hz, options.cutoff_hz, kt,
                        with_regressor=options.rigid_body == "identified", raw=raw, max_samples=options.max_samples,
                        identify_samples=options.samples == "identify", edge_periods=options.edge_periods,
                        sign_from_raw=options.friction == "lugre",
                        filtered_friction=False if _file_signs(options) else None)  # fmt: skip
    held = options.held_friction.torque(ctx.qd, ctx.qdd) if options.held_friction.values else None
    offsets = tuple(options.held_friction.offset_of(j) for j in range(ctx.n_dof)) if held is not None else ()
    return replace(ctx, coulomb_velocity=options.coulomb_velocity, tau_held=held, held_offsets=offsets)


def _file_signs(options) -> bool:
    """Whether the friction-like columns take the sign as a model file holds them (``file_friction``: smoothed, on the
    grid's filtered velocity), so that a candidate's gain is what the file gains with it: a file without LuGre joints;
    with them the diagnosis keeps its own form (the exact sign at full rate, filtered like the recording)."""
    return options.file_friction is not None and not options.file_friction.lugre_joints


def select_terms(robot, problem: DiagnosisProblem, options: DiagnosisOptions) -> SelectionResult:
    """Forward selection of the library's terms, the BIC counted with the filter's effective sample count; the default
    library takes the friction shapes the nominal model lacks (``lacking_friction_shapes``: a model file's friction,
    whose Stribeck velocities are fixed and whose Coulomb friction is a step, but not a shape the file already holds
    on a joint, ``FileFriction.holds``; the robot file's LuGre friction, whose one Stribeck peak sits at the drive's
    velocity). The terms ``options.carried`` are columns of the nominal model,
    kept and reported first (``carried_terms``); a spring beside a carried offset is fitted without its constant
    (``CarriedColumns.shaped``)."""
    library = options.library if options.library is not None else default_library()
    lacking = options.friction_shapes and options.friction in ("coulomb_viscous", "stribeck")  # LuGre drives state them
    if options.library is None and options.friction_shapes:  # a LuGre nominal lacks a peak at another velocity
        library = library + CandidateLibrary(lacking_friction_shapes(options.friction))
    ctx_t, carried = problem.ctx_t, CarriedColumns(options.carried)
    held = None if options.file_friction is None else options.file_friction.holds  # a model file's own shapes
    instances = [carried.shaped(term) for term in library.expand(robot.n_dof)
                 if not set(term.joints) & set(left_out(ctx_t)) and not carried.covers(term)
                 and not (held is not None and held(term))]  # fmt: skip
    n_eff = None
    if options.cutoff_hz is not None:
        n_eff = min(float(ctx_t.n_samples), 2.0 * options.cutoff_hz * float(ctx_t.t[-1] - ctx_t.t[0]))
    setting = "recalibrated rigid body" if options.rigid_body == "identified" else "nominal rigid body"
    logger.info(f"diagnose: [{setting}] selecting among {len(instances)} candidate terms ...")
    base_t, base_v, extra_v = carried.bases(problem)
    validations = [(problem.ctx_v, base_v, problem.y_v), *extra_v]
    opinion = SecondOpinion(ctx_t, validations, folds=options.cv_folds or 2, offsets=carried.offset_columns(problem))
    result = forward_select(
        instances, ctx_t, problem.ctx_v, base_t, base_v, problem.y_t, problem.y_v,
        min_improvement=options.min_improvement, max_effects=options.max_effects, effective_samples=n_eff,
        joint_threshold=options.joint_threshold, opinion=opinion if problem.extra_v or options.cv_folds else None,
        rival=FrictionRival(ctx_t, validations, offer=lacking, held=held), setting=setting,
    )  # fmt: skip
    return carried.selection(result, problem, n_eff)


#: Terms whose nonlinear parameter judges the term itself: a friction drift settling within seconds is no warm-up
#: (``FrictionDriftTerm.implausibility``), whatever its linear screening column (``rate t``) suggested.
SHAPE_VERDICTS = ("friction_drift",)


def refine_terms(problem: DiagnosisProblem, selection: SelectionResult, options: DiagnosisOptions) -> FinalFit:
    """Refit the kept terms with their nonlinear parameters; the linear fit stays when that does not improve it, or
    when the refit alone moved a term out of its bounds, unless the term is in ``SHAPE_VERDICTS`` (then the refit
    stands and ``plausible_diagnosis`` rejects the term)."""
    linear = FinalFit(terms=tuple(step.term for step in selection.steps), coefficients=selection.coefficients,
                      friction_coefficients=selection.friction_coefficients, prediction_t=selection.prediction_train,
                      prediction_v=selection.prediction_validation, nonlinear={})  # fmt: skip
    if not (options.refine and linear.terms):
        return linear
    refined = refine_fit(linear.terms, linear.coefficients, linear.friction_coefficients, problem.ctx_t,
                         problem.ctx_v, problem.base_t, problem.base_v, problem.y_t, problem.y_v)  # fmt: skip
    if refined is None:
        return linear
    if not refined.improved:
        logger.info(f"diagnose: Ipopt refinement not used ({refined.status}); keeping the linearised fit")
        return linear
    moved = implausible_terms(refined.terms, refined.coefficients, problem.ctx_t)
    shape = [term.label for term, _ in moved if term.key in SHAPE_VERDICTS]  # the refit's verdict on the term itself
    if moved and not shape and not implausible_terms(linear.terms, linear.coefficients, problem.ctx_t):
        logger.info(f"diagnose: Ipopt refinement not used: {moved[0][0].label}: {moved[0][1]}; keeping the linear fit")
        return linear
    logger.info(
        f"diagnose: Ipopt refinement of the nonlinear terms: {refined.status} in {refined.iterations} iterations"
    )
    return FinalFit(terms=refined.terms, coefficients=refined.coefficients,
                    friction_coefficients=refined.friction_coefficients, prediction_t=refined.prediction_train,
                    prediction_v=refined.prediction_validation, nonlinear=refined.nonlinear)  # fmt: skip
