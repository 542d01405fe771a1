"""IdentificationPipeline: the paper's four calibration steps, then a joint Ipopt refinement, into an IdentifiedModel.

Input is :class:`identification.data.dataset.CalibrationData` (or a data directory, see ``dataset``),
made ready per step by :mod:`identification.calibration.preparation` (paper: 4 Hz motor and
gravity, 15 Hz inertial, 85/15 training and validation). :meth:`IdentificationPipeline.fit` runs
named steps in order, each on the previous steps' estimates, passed explicitly:

1. motor: :class:`MotorIdentifier` -> Kt;
2. gravity: :class:`GravityIdentifier` -> theta_grav;
3. friction: :class:`FrictionIdentifier` -> LuGre per joint; then gravity again on the jog without
   that friction (``gravity_friction``);
4. inertial: :class:`InertialIdentifier` -> theta (with ``gravity_inertia="identified"``: gravity
   again with the jog's inertial torques of step 4 removed, then inertial again);
5. refinement: :func:`refine_parameters` (optional) -> all together; then the consistency check
   and the validation report (Table 3, "all" on the excitation validation part).

Known extra torques (``extra_terms``, e.g. the spring a diagnosis found; :mod:`identification.calibration.extra_terms`):
the gravity step fits their columns beside the gravity parameters, the friction step removes the
torque so fitted, the inertial step fits them again beside the inertial parameters; then the terms
and the gravity parameters are fitted jointly on the jog and the excitation (each experiment's rows
weighted by its own residual variance), and the inertial step runs on that gravity (its values are
the ones reported, with their sigma; ``extra_passes``); the refinement and Table 3 hold them. Without
terms the gravity parameters come from the jog alone. Step 1 needs no
column: a torque of the joint state is the same on the sweeps with and without the mass along the
same path and cancels in their difference, like gravity.

Before step 1 every raw recording is checked for motion (:mod:`identification.calibration.excitation`),
and each step checks its own data and regressor: a recording in which what is identified does not move
is refused with the joints to move and the experiment to record (``PipelineOptions.excitation``).

Friction data (documented choice): used unfiltered at the recorded rate (1 kHz), with central
differences, by default (``friction_cutoff_hz=None``). The paper's 40 Hz filter leaves 10 Hz
pre-sliding loops intact (the squared 8th-order response is 1 - 2e-10 at 10 Hz) but smears the
friction reversal at the end of each sliding stroke, where the friction flips by 2 Fc within a few
milliseconds, which biases the Stribeck velocity vs. The shooting fit is least squares, so white
current noise needs no filter.

Friction fit (documented choices): the shooting NLP models what the friction data measures
(``ShootingOptions(measurement="central-difference")``, see ``identification.friction.measurement``):
held current set-points and the central second difference of q average the friction over two
sample periods, which matters on heavy joints that ring on their bristles after every stick. The
torques the held joints' accelerations couple into the moving joint are removed with the nominal
inertias (``friction_coupling``). Together with the virtual robot's leapfrog integration of the
friction experiments they make the damping sigma1 of the heavy base joints identifiable.

Gravity (documented choice, ``gravity_inertia``): eq. 18 neglects the inertial and Coriolis
torques ``(Y(q, qd, qdd) - Y_grav(q)) theta`` of the jog; slow as the jog is, they are as large as
the torques of the smallest gravity parameters. By default they are removed with the robot's
nominal (CAD) inertias, ``model.base_parameters(robot.nominal_dynamic_parameters())``: the
correction itself is small, so an error of the CAD inertias leaves a much smaller error. The
step-4 estimate ("identified", a second gravity pass) is no substitute: its wrist inertias are
poorly excited and move the small gravity parameters. Removing the identified friction before
folding (``gravity_friction``) and the dynamic load of the motor step (``MotorIdentifier.load``)
bring the smallest gravity parameter closer still (``benchmarks/calibration.py`` measures it). The
gravity rows are weighted per joint by their mean square (``GravityIdentifier.joint_weighting``).
"""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from identification.calibration.consistency import check_consistency
from identification.calibration.estimator import check_is_fitted
from identification.calibration.excitation import check_calibration_data
from identification.calibration.extra_passes import refit_friction, settle_extra_terms
from identification.calibration.extra_terms import ExtraTerms, extra_torque
from identification.calibration.friction_step import FrictionIdentifier, friction_torque
from identification.calibration.payload import payload_torque
from identification.calibration.pipeline_options import PipelineOptions
from identification.calibration.preparation import (
    decimation_step,
    excitation_split,
    friction_split,
    gravity_split,
    motor_split,
    refinement_blocks,
)
from identification.calibration.refinement import refine_parameters
from identification.calibration.report import StepScore, ValidationReport, plot_observed_predicted
from identification.calibration.result import IdentifiedModel
from identification.calibration.steps import GravityIdentifier, InertialIdentifier, MotorIdentifier, regressor_chunked
from identification.data.dataset import CalibrationData, load_calibration_data
from identification.friction.shooting import ShootingOptions
from identification.metrics import r2, rmse
from psdm_casadi.errors import ParameterError
from psdm_casadi.model import PSDMModel
from psdm_casadi.robot import RobotDescription

__all__ = ["PipelineOptions", "IdentificationPipeline"]

logger = logging.getLogger(__name__)


class _Stages:
    """The progress lines (at INFO, none when quiet) and the wall time [s] per stage of one fit."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.timings = {}

    def say(self, message: str) -> None:
        if not self.quiet:
            logger.info(message)

    @contextmanager
    def stage(self, name: str, message: str | None = None):
        if message is not None:
            self.say(message)
        start = time.perf_counter()
        yield
        self.timings[name] = time.perf_counter() - start

    def took(self, name: str) -> str:
        return f"({self.timings[name]:.1f} s)"


class IdentificationPipeline:
    """The four calibration steps of the paper, a joint refinement, a consistency check and Table 3.

    Parameters
    ----------
    robot : RobotDescription
        Kinematics, joint ranges and gravity (inertia and drives are not used).
    model : PSDMModel
        The derived model (``derive_psdm(robot)``).
    options : PipelineOptions, optional
    extra_terms : ExtraTerms or sequence of CandidateTerm, optional
        Known additive torques fitted in every step (module docstring), e.g.
        ``ExtraTerms.from_diagnosis(report)`` or ``(SpringTerm(joint=3),)``.

    Attributes
    ----------
    result_ : IdentifiedModel
    steps_ : dict
        The fitted step estimators by name (``motor``, ``gravity``, ``friction``, ``inertial``).
    step_theta_ : array, shape (n_base,)
        Base parameters after step 4 (before refinement).
    step_kt_ : array, shape (n_dof,)
    step_lugre_ : tuple of LuGreParameters
    friction_train_, friction_valid_ : dict
        Preprocessed friction recordings by joint (training and validation parts).
    timings_ : dict
        Seconds per stage.

    Examples
    --------
    >>> pipeline = IdentificationPipeline(robot, derive_psdm(robot)).fit("data/")   # doctest: +SKIP
    >>> pipeline.result_.report.min_r2("all") > 0.9                                  # doctest: +SKIP
    True
    """

    def __init__(self, robot=None, model=None, options=None, extra_terms=None):
        self.robot = robot
        self.model = model
        self.options = options
        self.extra_terms = extra_terms

    def _extra_terms(self):
        """``extra_terms`` as an unfitted :class:`ExtraTerms` (None without terms), its joints checked."""
        if self.extra_terms is None:
            return None
        terms = self.extra_terms.terms if isinstance(self.extra_terms, ExtraTerms) else tuple(self.extra_terms)
        for term in terms:
            bad = [j + 1 for j in getattr(term, "joints", ()) if not 0 <= j < self.robot.n_dof]
            if bad:
                raise ParameterError(
                    f"IdentificationPipeline.extra_terms: {term.label} acts on joint {bad[0]}, but the robot has "
                    f"{self.robot.n_dof} joints. Pass terms of this robot."
                )
        return ExtraTerms(terms)

    def _validate(self):
        if not isinstance(self.robot, RobotDescription):
            raise ParameterError(
                f"IdentificationPipeline.robot must be a RobotDescription; got {type(self.robot).__name__}."
            )
        if not isinstance(self.model, PSDMModel):
            raise ParameterError(
                f"IdentificationPipeline.model must be a PSDMModel; got {type(self.model).__name__}. "
                "Use derive_psdm(robot)."
            )
        if self.model.n_dof != self.robot.n_dof:
            raise ParameterError(
                f"IdentificationPipeline.model has n_dof={self.model.n_dof} but the robot has "
                f"{self.robot.n_dof}. Derive the model from this robot."
            )
        options = PipelineOptions() if self.options is None else self.options
        if not isinstance(options, PipelineOptions):
            raise ParameterError(
                f"IdentificationPipeline.options must be a PipelineOptions; got {type(options).__name__}."
            )
        return options

    def _calibration_data(self, data) -> CalibrationData:
        if isinstance(data, (str, Path)):
            data = load_calibration_data(data, self.robot.n_dof, robot=self.robot)
        if not isinstance(data, CalibrationData):
            raise ParameterError(
                f"IdentificationPipeline.fit data must be a directory or CalibrationData; got {type(data).__name__}."
            )
        return data

    def _nominal_theta(self):
        """Base parameters of the robot's nominal (CAD) inertias; None when the robot has no links."""
        if self.robot.links is None:
            return None
        return self.model.base_parameters(self.robot.nominal_dynamic_parameters())

    def fit(self, data):
        """Run the calibration on a data directory or :class:`CalibrationData`; return ``self``."""
        options = self._validate()
        data = self._calibration_data(data)
        check_calibration_data(self.robot, self.model, data, options.excitation)
        extra = self._extra_terms()
        stages, total = _Stages(options.quiet), time.perf_counter()
        motor, motor_data = self._motor_step(data, options, stages)
        kt = motor.kt_
        gravity, gravity_data = self._gravity_step(data, options, kt, stages, extra)
        friction, friction_data = self._friction_step(data, options, kt, gravity, stages)
        lugre = friction.lugre_
        if options.gravity_friction == "identified":
            gravity, gravity_data = self._gravity_without_friction_step(data, options, gravity, kt, lugre, stages)
        inertial, excitation = self._inertial_step(data, options, kt, gravity.theta_, lugre, stages, extra)
        if options.gravity_inertia == "identified":
            gravity, inertial = self._second_pass_step(gravity, inertial, gravity_data.train, excitation.train, stages)
        if extra is not None:
            gravity, gravity_data, friction, inertial = self._extra_terms_step(
                data, options, (gravity, gravity_data), (friction, friction_data), (inertial, excitation), stages
            )
            lugre = friction.lugre_
        theta, extra = inertial.theta_, inertial.extra_terms_
        self.step_theta_, self.step_kt_, self.step_lugre_ = theta.copy(), kt.copy(), tuple(lugre)
        metadata = {}
        if options.refine:
            refined = self._refinement_step(data, options, theta, kt, lugre, stages, extra)
            theta, kt, lugre = refined.theta, refined.kt, refined.lugre
            metadata["refinement"] = {
                "status": refined.status,
                "iterations": refined.iterations,
                "objective_initial": refined.objective_initial,
                "objective_final": refined.objective_final,
            }
        consistency = self._consistency_step(options, theta, stages)
        fitted = (
            ("motor", motor, motor_data),
            ("gravity", gravity, gravity_data),
            ("friction", friction, friction_data),
            ("inertial", inertial, excitation),
        )
        report, self.plot_data_ = self._report_step(fitted, excitation.valid, theta, kt, lugre, data.tool, extra)
        stages.timings["total"] = time.perf_counter() - total
        metadata["timings"] = stages.timings
        metadata["friction_seconds"] = friction.seconds_.tolist()
        self.friction_train_ = {e.joint: e.recording for e in friction_data.train}
        self.friction_valid_ = {e.joint: e.recording for e in friction_data.valid}
        self.steps_ = {name: step for name, step, _ in fitted}
        self.timings_ = stages.timings
        self.result_ = IdentifiedModel(
            robot_name=self.robot.name,
            model=self.model,
            theta=theta,
            kt=kt,
            lugre=tuple(lugre),
            report=report,
            consistency=consistency,
            metadata=metadata,
            extra_terms=extra,
        )
        stages.say(f"identify: done in {stages.timings['total']:.1f} s")
        return self

    def _motor_step(self, data, options, stages):
        """Step 1 (eqs. 16-17): the torque constants from the sweeps without and with the calibration mass."""
        with stages.stage("motor", "identify: step 1/4 motor constants (eqs. 16-17) ..."):
            split = motor_split(data, options)
            motor = MotorIdentifier(robot=self.robot, payload=data.payload, excitation=options.excitation).fit(
                split.train
            )
        kt = motor.kt_
        if np.any(~np.isfinite(kt)):
            missing = [j + 1 for j in range(self.robot.n_dof) if not np.isfinite(kt[j])]
            raise ParameterError(
                f"CalibrationData.motor has no sweep of joints {missing}; record motor_j<k> sweeps for every joint."
            )
        stages.say(f"identify: Kt = {np.array2string(kt, precision=3)} N m/A {stages.took('motor')}")
        return motor, split

    def _gravity_step(self, data, options, kt, stages, extra):
        """Step 2 (eq. 18): the gravity parameters from the folded jogs, their inertial torques removed (options)."""
        with stages.stage("gravity", "identify: step 2/4 gravity parameters (eq. 18) ..."):
            split = gravity_split(data, options)
            theta = self._nominal_theta() if options.gravity_inertia == "nominal" else None
            gravity = GravityIdentifier(
                model=self.model,
                kt=kt,
                robot=self.robot,
                tool=data.tool,
                theta=theta,
                excitation=options.excitation,
                extra_terms=extra,
            ).fit(split.train)
        stages.say(f"identify: {int(self.model.gravity_mask.sum())} gravity parameters {stages.took('gravity')}")
        return gravity, split

    def _friction_step(self, data, options, kt, gravity, stages):
        """Step 3 (eqs. 19-20, LuGre by multiple shooting): friction per joint on its experiment."""
        with stages.stage(
            "friction", "identify: step 3/4 friction per joint: eq. 20 + LuGre multiple shooting (Ipopt) ..."
        ):
            split = friction_split(data, options)
            step = decimation_step(data.friction[0][1], options.friction_rate_hz)
            shooting_options = options.shooting_options
            if shooting_options is None:
                # the exact model of the measured friction needs every sample and the held-command average
                exact = step == 1 and options.held_torque
                shooting_options = ShootingOptions(measurement="central-difference" if exact else "sample")
            coupling = self._nominal_theta() if options.friction_coupling == "nominal" else None
            friction = FrictionIdentifier(
                model=self.model,
                kt=kt,
                theta=gravity.theta_,
                robot=self.robot,
                tool=data.tool,
                decimation=step,
                shooting_options=shooting_options,
                held_torque=options.held_torque,
                coupling_theta=coupling,
                verbose=not options.quiet,
                excitation=options.excitation,
                extra_terms=gravity.extra_terms_,
            ).fit(split.train)
        if any(p is None for p in friction.lugre_):
            missing = [j + 1 for j in range(self.robot.n_dof) if friction.lugre_[j] is None]
            raise ParameterError(
                f"CalibrationData.friction has no experiment of joints {missing}; record friction_j<k>."
            )
        stages.say(f"identify: friction done {stages.took('friction')}")
        return friction, split

    def _gravity_without_friction_step(self, data, options, gravity, kt, lugre, stages):
        """Step 2 again on the jog with the identified friction removed before folding."""
        with stages.stage("gravity_friction", "identify: step 2 again, the jog without the identified friction ..."):
            split = gravity_split(data, options, lugre=lugre, kt=kt)
            again = GravityIdentifier(**gravity.get_params()).fit(split.train)
        change = np.abs(again.theta_gravity_ - gravity.theta_gravity_).max()
        stages.say(f"identify: gravity parameters moved by up to {change:.3g} {stages.took('gravity_friction')}")
        return again, split

    def _inertial_step(self, data, options, kt, theta, lugre, stages, extra):
        """Step 4 (eq. 21): the remaining base parameters on the exciting trajectories."""
        with stages.stage("inertial", "identify: step 4/4 inertial parameters (eq. 21) ..."):
            split = excitation_split(data, options)
            step = decimation_step(data.excitation[0], options.inertial_rate_hz)
            inertial = InertialIdentifier(
                model=self.model,
                kt=kt,
                theta=theta,
                lugre=tuple(lugre),
                robot=self.robot,
                tool=data.tool,
                decimation=step,
                excitation=options.excitation,
                extra_terms=extra,
            ).fit(split.train)
        stages.say(f"identify: {self.model.n_base} base parameters {stages.took('inertial')}")
        return inertial, split

    def _second_pass_step(self, gravity, inertial, gravity_train, excitation_train, stages):
        """Gravity again without the jog's inertial torques of step 4, then inertial again."""
        with stages.stage(
            "second_pass", "identify: gravity again without the jog's inertial torques, then inertial again ..."
        ):
            again = GravityIdentifier(**dict(gravity.get_params(), theta=inertial.theta_)).fit(gravity_train)
            inertial = InertialIdentifier(**dict(inertial.get_params(), theta=again.theta_)).fit(excitation_train)
        change = np.abs(again.theta_gravity_ - gravity.theta_gravity_).max()
        stages.say(f"identify: gravity parameters moved by up to {change:.3g} {stages.took('second_pass')}")
        return again, inertial

    def _extra_terms_step(self, data, options, gravity_fit, friction_fit, inertial_fit, stages):
        """The extra terms settled between the steps: ``(gravity, gravity_split, friction, inertial)`` again.

        The slow jog moves the joints over a small range, where a spring ``k q + c`` is nearly collinear
        with the gravity torques; the excitation separates them. So the terms and the gravity parameters
        are fitted jointly on the jog and the excitation, then the inertial step runs on that gravity
        (``settle_extra_terms``); then the friction of the terms' joints is fitted again without their
        torque (the first friction fit removed the gravity step's estimate), and the terms are settled
        once more on that friction.
        """
        (gravity, gravity_data), (friction, friction_data), (inertial, excitation) = (
            gravity_fit,
            friction_fit,
            inertial_fit,
        )
        with stages.stage("extra_terms", "identify: gravity, friction and inertial again with the extra terms ..."):
            gravity, inertial = settle_extra_terms(gravity, inertial, gravity_data.train, excitation.train)
            friction = refit_friction(friction, friction_data.train, inertial.extra_terms_, gravity.theta_)
            if options.gravity_friction == "identified":
                gravity_data = gravity_split(data, options, lugre=friction.lugre_, kt=inertial.kt)
            inertial = InertialIdentifier(**dict(inertial.get_params(), lugre=tuple(friction.lugre_)))
            gravity, inertial = settle_extra_terms(gravity, inertial, gravity_data.train, excitation.train)
        extra = inertial.extra_terms_
        values = ", ".join(f"{name} = {value:.4g}" for name, value in zip(extra.feature_names, extra.coefficients))
        stages.say(f"identify: extra terms {values} {stages.took('extra_terms')}")
        return gravity, gravity_data, friction, inertial

    def _refinement_step(self, data, options, theta, kt, lugre, stages, extra):
        """All parameters together by Ipopt on the training parts of every experiment (extra terms held)."""
        with stages.stage("refinement", "identify: refinement of all parameters together (Ipopt) ..."):
            blocks = refinement_blocks(self.robot, data, options, extra)
            refined = refine_parameters(
                self.model,
                blocks,
                theta,
                kt,
                lugre,
                options.refinement,
                self.robot.q_min,
                self.robot.q_max,
                np.random.default_rng(options.seed),
                excitation=options.excitation,
            )
        stages.say(
            f"identify: refinement {refined.status} in {refined.iterations} iterations, cost "
            f"{refined.objective_initial:.3g} -> {refined.objective_final:.3g} {stages.took('refinement')}"
        )
        return refined

    def _consistency_step(self, options, theta, stages):
        """Is the mass matrix of ``theta`` positive definite over random configurations?"""
        consistency = check_consistency(
            self.model,
            theta,
            self.robot.q_min,
            self.robot.q_max,
            options.consistency_samples,
            np.random.default_rng(options.seed),
        )
        stages.say(
            f"identify: mass matrix min eigenvalue {consistency.min_eigenvalue:.3g} over "
            f"{consistency.n_samples} configurations "
            f"({'consistent' if consistency.consistent else 'NOT positive definite'})"
        )
        return consistency

    def _report_step(self, fitted, excitation, theta, kt, lugre, tool, extra):
        """Table 3: every step on its validation part, and the full model ("all") on the excitation's."""
        scores = [StepScore(name, *step.evaluate(split.valid)) for name, step, split in fitted]
        all_rmse, all_r2, plot_data = self._score_all(excitation, theta, kt, lugre, tool, extra)
        scores.append(StepScore("all", all_rmse, all_r2))
        return ValidationReport(tuple(scores), tuple(self.robot.joint_names)), plot_data

    def _score_all(self, recordings, theta, kt, lugre, tool, extra):
        """RMSE and R^2 per joint of the full model on the fast validation path (Table 3 "All"), and plot data."""
        obs, pred, plot = [], [], None
        for rec in recordings:
            observed = rec.joint_torque(kt)
            predicted = (
                regressor_chunked(self.model, rec.q, rec.qd, rec.qdd) @ theta
                + friction_torque(lugre, rec.t, rec.qd)
                + extra_torque(extra, rec)
            )
            if tool is not None:
                predicted = predicted + payload_torque(self.robot, tool, rec.q, rec.qd, rec.qdd)
            obs.append(observed)
            pred.append(predicted)
            if plot is None:
                plot = (rec.t, observed, predicted)
        obs, pred = np.vstack(obs), np.vstack(pred)
        return np.asarray(rmse(obs, pred)), np.asarray(r2(obs, pred)), plot

    def plot(self, directory) -> list:
        """Write observed-vs-predicted plots (the "all" validation path) into ``directory``; return the paths."""
        check_is_fitted(self, "result_")
        t, observed, predicted = self.plot_data_
        path = plot_observed_predicted(
            t,
            observed,
            predicted,
            Path(directory) / "validation_all.png",
            title="Full model on the excitation validation path",
            joint_names=list(self.robot.joint_names),
        )
        return [path]
