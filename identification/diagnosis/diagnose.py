"""diagnose(): identify the nominal model on a training recording, find the missing physics, re-identify, validate.

RobotDescription + training/validation Recordings -> DiagnosisReport (with the augmented model). The
diagnoser sees only the robot file (kinematics, nominal inertia, drive friction shapes) and the
recordings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ParameterError

from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis.augmented import AugmentedModel
from identification.diagnosis.candidates import CandidateLibrary, default_library
from identification.diagnosis.context import build_context
from identification.diagnosis.nominal import FRICTION_MODELS, RIGID_BODY_CHOICES, filtered_friction_columns, friction_feature_names, friction_shapes
from identification.diagnosis.report import DiagnosisReport, Finding
from identification.diagnosis.residual_tests import analyse_residuals
from identification.diagnosis.refine import refine_fit
from identification.diagnosis.selection import forward_select


@dataclass(frozen=True)
class DiagnosisOptions:
    """Options of ``diagnose``.

    Parameters
    ----------
    friction : {"lugre", "coulomb_viscous"}
        Nominal friction (see ``nominal``).
    rigid_body : {"prior", "identified"}
        Keep the robot file's inertia (default) or identify the base parameters too.
    cutoff_hz : float or None
        Zero-phase low-pass cut-off of the preprocessing [Hz].
    rate_hz : float
        Rate of the decimated grid the fit works on [Hz].
    min_improvement : float
        Validation RMSE reduction (fraction) one joint must show for a term to be kept.
    max_effects : int
        Most terms kept.
    joint_threshold : float
        Relative reduction above which a joint is named for a robot-wide term.
    library : CandidateLibrary or None
        Candidate terms (default: every term).
    preprocess : bool
        Filter and differentiate the recordings (off when they already hold filtered qd and qdd).
    torque_constants : tuple or None
        Kt [N m/A] per joint for recordings with currents only (default: the robot file's drives).
    refine : bool
        Refit the kept terms with their nonlinear parameters after the linearised selection: delay,
        backlash (width and flank smoothing) and joint elasticity exactly by variable projection
        (``signal_fit``), then the drift time constant by Ipopt (``refine.refine_fit``).
    """

    friction: str = "lugre"
    rigid_body: str = "prior"
    cutoff_hz: float | None = 15.0
    rate_hz: float = 200.0
    min_improvement: float = 0.2
    max_effects: int = 4
    joint_threshold: float = 0.1
    library: CandidateLibrary | None = None
    preprocess: bool = True
    torque_constants: tuple | None = None
    refine: bool = True

    def __post_init__(self):
        if self.friction not in FRICTION_MODELS:
            raise ParameterError(f"DiagnosisOptions.friction must be one of {FRICTION_MODELS}; got {self.friction!r}.")
        if self.rigid_body not in RIGID_BODY_CHOICES:
            raise ParameterError(f"DiagnosisOptions.rigid_body must be one of {RIGID_BODY_CHOICES}; got {self.rigid_body!r}.")
        if not 0.0 < self.min_improvement < 1.0:
            raise ParameterError(f"DiagnosisOptions.min_improvement must be in (0, 1); got {self.min_improvement!r}. Use 0.2.")
        if not (isinstance(self.max_effects, (int, np.integer)) and self.max_effects >= 0):
            raise ParameterError(f"DiagnosisOptions.max_effects must be an integer >= 0; got {self.max_effects!r}.")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ParameterError(f"DiagnosisOptions.rate_hz must be positive [Hz]; got {self.rate_hz!r}.")
        if self.cutoff_hz is not None and not (np.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise ParameterError(f"DiagnosisOptions.cutoff_hz must be positive [Hz] or None; got {self.cutoff_hz!r}.")
        if self.library is not None and not isinstance(self.library, CandidateLibrary):
            raise ParameterError(f"DiagnosisOptions.library must be a CandidateLibrary; got {type(self.library).__name__}. "
                                 "Combine terms with +, e.g. SpringTerm() + TorqueOffsetTerm().")


def _r2(measured, predicted):
    ss = np.sum((measured - measured.mean(axis=0)) ** 2, axis=0)
    return 1.0 - np.sum((measured - predicted) ** 2, axis=0) / np.maximum(ss, 1e-300)


def diagnose(robot, train, validation, options: DiagnosisOptions | None = None, model=None,
             progress=None) -> DiagnosisReport:
    """Find the physics a nominal model leaves out of the recordings, and show the fit with it.

    Parameters
    ----------
    robot : RobotDescription
        The robot file (kinematics, nominal inertia = the prior, drives).
    train, validation : Recording
        Raw (or, with ``options.preprocess=False``, preprocessed) recordings; the model is fitted on
        ``train`` and judged on ``validation``.
    options : DiagnosisOptions, optional
    model : PSDMModel, optional
        ``derive_psdm(robot)``, derived when omitted.
    progress : callable, optional
        Called with progress messages.

    Returns
    -------
    DiagnosisReport

    Raises
    ------
    ShapeError, RecordingError
        When a recording does not match the robot or is too short.
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
    say = progress or (lambda message: None)
    train.check_robot(robot.n_dof, robot.name)
    validation.check_robot(robot.n_dof, robot.name)
    if model is None:
        from psdm_casadi.derive import derive_psdm
        say("diagnose: deriving the PSDM model ...")
        model = derive_psdm(robot)
    kt = options.torque_constants
    if kt is None and robot.drives is not None:
        kt = tuple(d.kt for d in robot.drives)
    raw_train, raw_validation = train, validation
    if options.preprocess:
        pre = PreprocessOptions(cutoff_hz=options.cutoff_hz)
        train, validation = preprocess(train, pre), preprocess(validation, pre)
    else:
        raw_train = raw_validation = None
    say("diagnose: evaluating the nominal model ...")
    kt_arr = None if kt is None else np.asarray(kt, dtype=float)
    need_y = options.rigid_body == "identified"
    ctx_t = build_context(robot, model, train, options.rate_hz, options.cutoff_hz, kt_arr, with_regressor=need_y,
                          raw=raw_train)
    ctx_v = build_context(robot, model, validation, options.rate_hz, options.cutoff_hz, kt_arr, with_regressor=need_y,
                          raw=raw_validation)
    vs, dv = friction_shapes(robot)
    base_t = filtered_friction_columns(robot, options.friction, ctx_t)
    base_v = filtered_friction_columns(robot, options.friction, ctx_v)
    if options.rigid_body == "prior":
        y_t, y_v = ctx_t.tau - ctx_t.tau_rigid, ctx_v.tau - ctx_v.tau_rigid
    else:
        base_t = np.concatenate([base_t, ctx_t.regressor], axis=2)
        base_v = np.concatenate([base_v, ctx_v.regressor], axis=2)
        y_t, y_v = ctx_t.tau, ctx_v.tau
    library = options.library if options.library is not None else default_library()
    instances = library.expand(robot.n_dof)
    n_eff = None
    if options.cutoff_hz is not None:
        n_eff = min(float(ctx_t.n_samples), 2.0 * options.cutoff_hz * float(ctx_t.t[-1] - ctx_t.t[0]))
    say(f"diagnose: selecting among {len(instances)} candidate terms ...")
    result = forward_select(instances, ctx_t, ctx_v, base_t, base_v, y_t, y_v,
                            min_improvement=options.min_improvement, max_effects=options.max_effects,
                            effective_samples=n_eff, joint_threshold=options.joint_threshold, progress=progress)
    terms = tuple(step.term for step in result.steps)
    coefficients_kept, friction_all = result.coefficients, result.friction_coefficients
    prediction_t, prediction_v = result.prediction_train, result.prediction_validation
    nonlinear = {}
    if options.refine and terms:
        refined = refine_fit(terms, coefficients_kept, friction_all, ctx_t, ctx_v, base_t, base_v, y_t, y_v)
        if refined is not None and refined.improved:
            say(f"diagnose: Ipopt refinement of the nonlinear terms: {refined.status} in {refined.iterations} iterations")
            terms, coefficients_kept, friction_all = refined.terms, refined.coefficients, refined.friction_coefficients
            prediction_t, prediction_v = refined.prediction_train, refined.prediction_validation
            nonlinear = refined.nonlinear
        elif refined is not None:
            say(f"diagnose: Ipopt refinement not used ({refined.status}); keeping the linearised fit")
    fixed_t = ctx_t.tau - y_t
    fixed_v = ctx_v.tau - y_v
    model_nominal_v = fixed_v + result.nominal_validation
    model_final_v = fixed_v + prediction_v
    model_nominal_t = fixed_t + result.nominal_train
    model_final_t = fixed_t + prediction_t
    n_friction = len(friction_feature_names(options.friction, robot.n_dof))
    n_dynamic = robot.n_dof if (options.friction == "lugre" and robot.drives is not None) else 0
    friction = friction_all[:n_friction]
    theta = (model.base_parameters(robot.nominal_dynamic_parameters()) if options.rigid_body == "prior"
             else friction_all[n_friction + n_dynamic:])
    findings = []
    for step, term, coefficients in zip(result.steps, terms, coefficients_kept):
        effect, explanation = term.interpret(coefficients)
        parameters = dict(term.physical_parameters(coefficients))
        parameters.update(nonlinear.get(term.label, {}))
        findings.append(Finding(
            effect=effect, label=term.label, joints=tuple(int(j) for j in step.joints),
            parameters=parameters, coefficients=tuple(float(c) for c in coefficients),
            feature_names=tuple(term.feature_names()), explanation=explanation, signature=term.signature,
            rmse_before=tuple(float(x) for x in step.rmse_before), rmse_after=tuple(float(x) for x in step.rmse_after),
            delta_bic=step.delta_bic, validation_gain=step.validation_gain))
    augmented = AugmentedModel(model=model, theta=np.asarray(theta, dtype=float), friction_kind=options.friction,
                               friction_coefficients=np.asarray(friction, dtype=float), friction_vs=vs, friction_dv=dv,
                               terms=terms, coefficients=coefficients_kept)
    residual_v = ctx_v.tau - model_nominal_v
    return DiagnosisReport(
        robot_name=robot.name, n_dof=robot.n_dof, friction=options.friction, rigid_body=options.rigid_body,
        findings=tuple(findings),
        rmse_before=tuple(np.sqrt(np.mean(residual_v**2, axis=0)).tolist()),
        rmse_after=tuple(np.sqrt(np.mean((ctx_v.tau - model_final_v) ** 2, axis=0)).tolist()),
        r2_before=tuple(_r2(ctx_v.tau, model_nominal_v).tolist()), r2_after=tuple(_r2(ctx_v.tau, model_final_v).tolist()),
        rmse_train_before=tuple(np.sqrt(np.mean((ctx_t.tau - model_nominal_t) ** 2, axis=0)).tolist()),
        rmse_train_after=tuple(np.sqrt(np.mean((ctx_t.tau - model_final_t) ** 2, axis=0)).tolist()),
        residual_findings=analyse_residuals(ctx_v, residual_v),
        candidates_tried=result.candidates_tried, augmented=augmented,
        validation_t=ctx_v.t, validation_q=ctx_v.q, validation_qd=ctx_v.qd, validation_tau=ctx_v.tau,
        validation_nominal=model_nominal_v, validation_final=model_final_v)
