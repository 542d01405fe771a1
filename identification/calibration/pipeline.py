"""IdentificationPipeline: the paper's four calibration steps, then a joint Ipopt refinement, into an IdentifiedModel.

Input is :class:`identification.data.dataset.CalibrationData` (or a data directory, see ``dataset``).
Each experiment is filtered as in the paper (4 Hz motor and gravity, 15 Hz inertial; zero-phase
8th-order Butterworth, central differences), out-and-back experiments are folded
(forward/backward averaged), everything is split 85/15 into training and validation (a joint's
second friction experiment, when recorded, validates its friction instead), and the steps run in
order, each on the previous steps' estimates:

1. :class:`MotorIdentifier` -> Kt;  2. :class:`GravityIdentifier` -> theta_grav;
3. :class:`FrictionIdentifier` -> LuGre per joint, then 2 again on the jog without that friction;
4. :class:`InertialIdentifier` -> theta;
   (with ``gravity_inertia="identified"``: 2 again with the jog's inertial torques of step 4
   removed, then 4 again);
5. :func:`refine_parameters` (optional) -> all together; then the consistency check and the
   validation report (Table 3, "all" on the excitation validation part).

Friction data (documented choice): used unfiltered at the recorded rate (1 kHz), with central
differences, by default (``friction_cutoff_hz=None``). The paper's 40 Hz filter leaves 10 Hz
pre-sliding loops intact (the squared 8th-order response is 1 - 2e-10 at 10 Hz) but smears the
friction reversal at the end of each sliding stroke, where the friction flips by 2 Fc within a few
milliseconds; on the virtual Denso that biased vs by about 20 % on joint 1, against 0.4 % without
the filter. The shooting fit is least squares, so white current noise needs no filter.

Friction fit (documented choices): the shooting NLP models what the friction data measures
(``ShootingOptions(measurement="central-difference")``, see ``identification.friction.models.measurement``):
held current set-points and the central second difference of q average the friction over two
sample periods, which matters on heavy joints that ring on their bristles after every stick (about
80 Hz on the Denso's base joints). The torques the held joints' accelerations couple into the
moving joint are removed with the nominal inertias (``friction_coupling``). Together with the
virtual robot's leapfrog integration of the friction experiments they took sigma1 of the Denso's
joints 1-3 from 86-115 % off to 16-19 % (joints 4-6 within 6 %) at 1 kHz.

Gravity (documented choice, ``gravity_inertia``): eq. 18 neglects the inertial and Coriolis
torques ``(Y(q, qd, qdd) - Y_grav(q)) theta`` of the jog; at 0.25 rad/s they are about 0.05 N m, as
large as the torques of the smallest gravity parameters of the Denso (0.006-0.013 kg m), which
came out 10-160 % off. By default they are removed with the robot's nominal (CAD) inertias,
``model.base_parameters(robot.nominal_dynamic_parameters())``: the correction is small, so a 20 %
error of the CAD inertias should leave about 0.01 N m (an estimate; the benchmark's nominal
inertias are the truth). The step-4 estimate ("identified", a second gravity
pass) is no substitute: its wrist inertias are poorly excited and moved the small gravity
parameters by up to 30 %. On the virtual Denso (where the nominal inertias are the truth) the
120 s jog at 0.15 rad/s then gives eight of the nine within 0.5 % and the smallest
(theta4 = -0.013 kg m, 0.1 N m of torque) within 3 %; removing the identified friction before
folding (``gravity_friction``) and the dynamic load of the motor step (``MotorIdentifier.load``)
bring theta4 within 1.1 % (benchmarks/calibration.py). The gravity rows are weighted per joint
by their mean square (``GravityIdentifier.joint_weighting``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from psdm_casadi.cli import progress
from psdm_casadi.errors import ParameterError
from psdm_casadi.model import PSDMModel
from psdm_casadi.robot import RobotDescription

from identification.calibration.consistency import check_consistency
from identification.data.dataset import CalibrationData, load_calibration_data
from identification.calibration.payload import payload_torque
from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.data.recording import Recording
from identification.calibration.refinement import RefinementBlock, RefinementOptions, refine_parameters
from identification.calibration.report import StepScore, ValidationReport, plot_observed_predicted
from identification.calibration.result import IdentifiedModel
from identification.calibration.steps import (FrictionExperiment, FrictionIdentifier, GravityIdentifier, InertialIdentifier, MotorExperiment,
                    MotorIdentifier, fold_out_and_back, friction_torque, regressor_chunked)

__all__ = ["PipelineOptions", "IdentificationPipeline"]


@dataclass(frozen=True)
class PipelineOptions:
    """Options of :class:`IdentificationPipeline`.

    Parameters
    ----------
    motor_cutoff_hz, gravity_cutoff_hz, inertial_cutoff_hz : float
        Butterworth cutoffs [Hz] (paper: 4, 4, 15).
    friction_cutoff_hz : float or None
        Cutoff of the friction data [Hz] (paper 40); None (default) uses them unfiltered (module docstring).
    split_fraction : float
        Training share (paper 0.85).
    n_blocks : int
        Contiguous blocks of the split of the folded motor and gravity sweeps (``Recording.split``),
        so their validation part covers the whole sweep rather than its end.
    gravity_rate_hz, inertial_rate_hz, friction_rate_hz, refinement_rate_hz : float
        Rates [Hz] the filtered data is decimated to before the regression (the regressor
        evaluation and the shooting NLP grow with the samples; the filters remove what decimation
        would alias). ``friction_rate_hz`` defaults to 1 kHz: the pre-sliding loops need every sample.
    gravity_inertia : {"nominal", "identified", "none"}
        Which model removes the jog's inertial and Coriolis torques before eq. 18 (module docstring):
        the robot's nominal inertias (default; "none" when the robot has no links), the step-4
        estimate in a second pass, or none (the paper).
    gravity_friction : {"identified", "folded"}
        ``"identified"`` (default): after step 3, step 2 runs again on the jog with the identified
        LuGre friction (simulated along its measured velocity) removed before folding; ``"folded"``:
        folding alone cancels friction (the paper). Folding cancels only the part of the friction that
        is odd in the velocity at mirrored samples; on the virtual Denso the rest (the bristle state
        and the joints' speed changes along the jog) moved the smallest gravity parameter (theta4,
        -0.013 kg m) by 1.6 % without noise.
    friction_coupling : {"nominal", "none"}
        ``"nominal"`` (default; "none" when the robot has no links): the robot's nominal inertias
        remove the torques the held joints' accelerations couple into the moving joint of a friction
        experiment (``FrictionIdentifier.coupling_theta``; they ring with it after every stick).
    refine : bool
        Run the joint Ipopt refinement after the four steps.
    refinement : RefinementOptions
    shooting_options : identification.friction.shooting.ShootingOptions or None
        Default ``ShootingOptions(measurement="central-difference")`` (``"sample"`` when the friction
        data is decimated or ``held_torque`` is False): the fit compares the friction model with
        what the measurement averages (``identification.friction.models.measurement``), which took sigma1
        of the Denso's base joints from 50-170 % off to within about 10 %.
    held_torque : bool
        Currents are set-points held over the next sample period (``FrictionIdentifier.held_torque``).
    consistency_samples : int
        Random configurations of the mass-matrix check.
    seed : int
        Seed of the consistency configurations.
    quiet : bool
        No progress lines.
    """

    motor_cutoff_hz: float = 4.0
    gravity_cutoff_hz: float = 4.0
    friction_cutoff_hz: float | None = None
    inertial_cutoff_hz: float = 15.0
    split_fraction: float = 0.85
    n_blocks: int = 4
    gravity_rate_hz: float = 50.0
    inertial_rate_hz: float = 200.0
    friction_rate_hz: float = 1000.0
    refinement_rate_hz: float = 50.0
    gravity_inertia: str = "nominal"
    gravity_friction: str = "identified"
    friction_coupling: str = "nominal"
    refine: bool = True
    refinement: RefinementOptions = RefinementOptions()
    shooting_options: object = None
    held_torque: bool = True
    consistency_samples: int = 200
    seed: int = 0
    quiet: bool = False

    def __post_init__(self):
        for name in ("motor_cutoff_hz", "gravity_cutoff_hz", "friction_cutoff_hz", "inertial_cutoff_hz",
                     "gravity_rate_hz", "inertial_rate_hz", "friction_rate_hz", "refinement_rate_hz"):
            value = getattr(self, name)
            if value is None and name == "friction_cutoff_hz":
                continue
            if not (np.isfinite(value) and value > 0):
                raise ParameterError(f"PipelineOptions.{name} must be positive [Hz]; got {value!r}.")
        if not 0.0 < self.split_fraction < 1.0:
            raise ParameterError(f"PipelineOptions.split_fraction must be in (0, 1); got {self.split_fraction!r}.")
        if self.gravity_friction not in ("identified", "folded"):
            raise ParameterError(f"PipelineOptions.gravity_friction must be 'identified' or 'folded'; got "
                                 f"{self.gravity_friction!r}.")
        if self.friction_coupling not in ("nominal", "none"):
            raise ParameterError(f"PipelineOptions.friction_coupling must be 'nominal' or 'none'; got "
                                 f"{self.friction_coupling!r}.")
        if self.gravity_inertia not in ("nominal", "identified", "none"):
            raise ParameterError(f"PipelineOptions.gravity_inertia must be 'nominal', 'identified' or 'none'; got "
                                 f"{self.gravity_inertia!r}.")


def _without_torque(rec: Recording, torque, kt) -> Recording:
    """``rec`` with ``torque`` [N m], shape (n_samples, n_dof), removed from its torques or currents."""
    if rec.tau is not None:
        return rec.with_signals(tau=rec.tau - torque)
    return rec.with_signals(current=rec.current - torque / np.asarray(kt, dtype=float))


def _decimate(rec: Recording, rate_hz: float) -> Recording:
    step = max(1, int(round(1.0 / (rec.dt * rate_hz))))
    return rec if step == 1 else rec._take(slice(None, None, step))


class IdentificationPipeline:
    """The four calibration steps of the paper, a joint refinement, a consistency check and Table 3.

    Parameters
    ----------
    robot : RobotDescription
        Kinematics, joint ranges and gravity (inertia and drives are not used).
    model : PSDMModel
        The derived model (``derive_psdm(robot)``).
    options : PipelineOptions, optional

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

    def __init__(self, robot=None, model=None, options=None):
        self.robot = robot
        self.model = model
        self.options = options

    def _validate(self):
        if not isinstance(self.robot, RobotDescription):
            raise ParameterError(f"IdentificationPipeline.robot must be a RobotDescription; got {type(self.robot).__name__}.")
        if not isinstance(self.model, PSDMModel):
            raise ParameterError(f"IdentificationPipeline.model must be a PSDMModel; got {type(self.model).__name__}. "
                                 "Use derive_psdm(robot).")
        if self.model.n_dof != self.robot.n_dof:
            raise ParameterError(f"IdentificationPipeline.model has n_dof={self.model.n_dof} but the robot has "
                                 f"{self.robot.n_dof}. Derive the model from this robot.")
        options = PipelineOptions() if self.options is None else self.options
        if not isinstance(options, PipelineOptions):
            raise ParameterError(f"IdentificationPipeline.options must be a PipelineOptions; got {type(options).__name__}.")
        return options

    def fit(self, data):
        """Run the calibration on a data directory or :class:`CalibrationData`; return ``self``."""
        o = self._validate()
        say = (lambda msg: progress(msg, quiet=o.quiet))
        if isinstance(data, (str, Path)):
            data = load_calibration_data(data, self.robot.n_dof)
        if not isinstance(data, CalibrationData):
            raise ParameterError(f"IdentificationPipeline.fit data must be a directory or CalibrationData; got "
                                 f"{type(data).__name__}.")
        robot, model, n = self.robot, self.model, self.robot.n_dof
        timings, total = {}, time.perf_counter()
        tool = data.tool

        def prep(rec, cutoff):
            return preprocess(rec, PreprocessOptions(cutoff_hz=cutoff, split_fraction=o.split_fraction))

        # step 1: motor
        start = time.perf_counter()
        say("identify: step 1/4 motor constants (eqs. 16-17) ...")
        train, valid = [], []
        for joint, nominal, loaded in data.motor:
            a = fold_out_and_back(prep(nominal, o.motor_cutoff_hz))
            b = fold_out_and_back(prep(loaded, o.motor_cutoff_hz))
            (a_t, a_v), (b_t, b_v) = a.split(o.split_fraction, o.n_blocks), b.split(o.split_fraction, o.n_blocks)
            train.append(MotorExperiment(joint, a_t, b_t))
            valid.append(MotorExperiment(joint, a_v, b_v))
        motor = MotorIdentifier(robot=robot, payload=data.payload).fit(train)
        kt = motor.kt_
        if np.any(~np.isfinite(kt)):
            missing = [j + 1 for j in range(n) if not np.isfinite(kt[j])]
            raise ParameterError(f"CalibrationData.motor has no sweep of joints {missing}; record motor_j<k> sweeps "
                                 "for every joint.")
        timings["motor"] = time.perf_counter() - start
        say(f"identify: Kt = {np.array2string(kt, precision=3)} N m/A ({timings['motor']:.1f} s)")

        # step 2: gravity
        start = time.perf_counter()
        say("identify: step 2/4 gravity parameters (eq. 18) ...")
        g_train, g_valid = [], []
        for rec in data.gravity:
            folded = _decimate(fold_out_and_back(prep(rec, o.gravity_cutoff_hz)), o.gravity_rate_hz)
            tr, va = folded.split(o.split_fraction, o.n_blocks)
            g_train.append(tr)
            g_valid.append(va)
        nominal = None
        if o.gravity_inertia == "nominal" and robot.links is not None:
            nominal = model.base_parameters(robot.nominal_dynamic_parameters())
        gravity = GravityIdentifier(model=model, kt=kt, robot=robot, tool=tool, theta=nominal).fit(g_train)
        timings["gravity"] = time.perf_counter() - start
        say(f"identify: {int(model.gravity_mask.sum())} gravity parameters ({timings['gravity']:.1f} s)")

        # step 3: friction
        start = time.perf_counter()
        f_train, f_valid = [], []
        second = dict(data.friction_validation)
        for joint, rec in data.friction:
            clean = prep(rec, o.friction_cutoff_hz)
            if joint in second:
                tr, va = clean, prep(second[joint], o.friction_cutoff_hz)
            else:
                tr, va = clean.split(o.split_fraction)
            f_train.append(FrictionExperiment(joint, tr))
            f_valid.append(FrictionExperiment(joint, va))
        decimation = max(1, int(round(1.0 / (data.friction[0][1].dt * o.friction_rate_hz))))
        shooting_options = o.shooting_options
        if shooting_options is None:
            from identification.friction.shooting import ShootingOptions

            # the exact model of the measured friction needs every sample and the held-command average
            exact = decimation == 1 and o.held_torque
            shooting_options = ShootingOptions(measurement="central-difference" if exact else "sample")
        coupling = None
        if o.friction_coupling == "nominal" and robot.links is not None:
            coupling = model.base_parameters(robot.nominal_dynamic_parameters())
        friction = FrictionIdentifier(model=model, kt=kt, theta=gravity.theta_, robot=robot, tool=tool,
                                      decimation=decimation, shooting_options=shooting_options,
                                      held_torque=o.held_torque, coupling_theta=coupling)
        lugre = [None] * n
        friction_fits = []
        for k, experiment in enumerate(f_train):
            say(f"identify: step 3/4 friction joint {experiment.joint + 1} ({k + 1}/{len(f_train)}): eq. 20 + "
                "LuGre multiple shooting (Ipopt) ...")
            fit = FrictionIdentifier(**friction.get_params()).fit([experiment])
            lugre[experiment.joint] = fit.lugre_[experiment.joint]
            friction_fits.append(fit)
        if any(p is None for p in lugre):
            missing = [j + 1 for j in range(n) if lugre[j] is None]
            raise ParameterError(f"CalibrationData.friction has no experiment of joints {missing}; record friction_j<k>.")
        friction.lugre_ = tuple(lugre)
        friction.inertia_ = np.nanmax(np.array([f.inertia_ for f in friction_fits]), axis=0)
        friction.coef_, friction.n_dof_ = np.zeros(0), n
        friction.shooting_ = tuple(next((f.shooting_[j] for f in friction_fits if f.shooting_[j] is not None), None)
                                   for j in range(n))
        friction.seconds_ = np.nansum(np.array([f.seconds_ for f in friction_fits]), axis=0)
        timings["friction"] = time.perf_counter() - start
        say(f"identify: friction done ({timings['friction']:.1f} s)")
        if o.gravity_friction == "identified":
            start = time.perf_counter()
            say("identify: step 2 again, the jog without the identified friction ...")
            first = gravity.theta_gravity_
            g_train, g_valid = [], []
            for rec in data.gravity:
                raw = prep(rec, None)  # friction along the unfiltered velocity, removed before the filter
                raw = _without_torque(raw, friction_torque(tuple(lugre), raw.t, raw.qd), kt)
                folded = _decimate(fold_out_and_back(prep(raw, o.gravity_cutoff_hz)), o.gravity_rate_hz)
                tr, va = folded.split(o.split_fraction, o.n_blocks)
                g_train.append(tr)
                g_valid.append(va)
            gravity = GravityIdentifier(**gravity.get_params()).fit(g_train)
            timings["gravity_friction"] = time.perf_counter() - start
            change = np.abs(gravity.theta_gravity_ - first).max()
            say(f"identify: gravity parameters moved by up to {change:.3g} ({timings['gravity_friction']:.1f} s)")

        # step 4: inertial
        start = time.perf_counter()
        say("identify: step 4/4 inertial parameters (eq. 21) ...")
        e_train, e_valid = [], []
        for rec in data.excitation:
            clean = prep(rec, o.inertial_cutoff_hz)
            tr, va = clean.split(o.split_fraction)
            e_train.append(tr)
            e_valid.append(va)
        decimation = max(1, int(round(1.0 / (data.excitation[0].dt * o.inertial_rate_hz))))
        inertial = InertialIdentifier(model=model, kt=kt, theta=gravity.theta_, lugre=tuple(lugre), robot=robot,
                                      tool=tool, decimation=decimation).fit(e_train)
        theta = inertial.theta_
        timings["inertial"] = time.perf_counter() - start
        say(f"identify: {model.n_base} base parameters ({timings['inertial']:.1f} s)")
        if o.gravity_inertia == "identified":
            start = time.perf_counter()
            say("identify: gravity again without the jog's inertial torques, then inertial again ...")
            first = gravity.theta_gravity_
            gravity = GravityIdentifier(**dict(gravity.get_params(), theta=theta)).fit(g_train)
            inertial = InertialIdentifier(**dict(inertial.get_params(), theta=gravity.theta_)).fit(e_train)
            theta = inertial.theta_
            timings["second_pass"] = time.perf_counter() - start
            change = np.abs(gravity.theta_gravity_ - first).max()
            say(f"identify: gravity parameters moved by up to {change:.3g} ({timings['second_pass']:.1f} s)")
        self.step_theta_, self.step_kt_, self.step_lugre_ = theta.copy(), kt.copy(), tuple(lugre)

        # step 5: joint refinement
        metadata = {}
        final_theta, final_kt, final_lugre = theta, kt, tuple(lugre)
        if o.refine:
            start = time.perf_counter()
            say("identify: refinement of all parameters together (Ipopt) ...")
            blocks = self._refinement_blocks(data, o, prep)
            refined = refine_parameters(model, blocks, theta, kt, lugre, o.refinement, robot.q_min, robot.q_max,
                                        np.random.default_rng(o.seed))
            final_theta, final_kt, final_lugre = refined.theta, refined.kt, refined.lugre
            timings["refinement"] = time.perf_counter() - start
            metadata["refinement"] = {"status": refined.status, "iterations": refined.iterations,
                                      "objective_initial": refined.objective_initial,
                                      "objective_final": refined.objective_final}
            say(f"identify: refinement {refined.status} in {refined.iterations} iterations, cost "
                f"{refined.objective_initial:.3g} -> {refined.objective_final:.3g} ({timings['refinement']:.1f} s)")

        # consistency and report
        consistency = check_consistency(model, final_theta, robot.q_min, robot.q_max, o.consistency_samples,
                                        np.random.default_rng(o.seed))
        say(f"identify: mass matrix min eigenvalue {consistency.min_eigenvalue:.3g} over {consistency.n_samples} "
            f"configurations ({'consistent' if consistency.consistent else 'NOT positive definite'})")
        scores = [StepScore("motor", *motor.evaluate(valid)), StepScore("gravity", *gravity.evaluate(g_valid)),
                  StepScore("friction", *friction.evaluate(f_valid)), StepScore("inertial", *inertial.evaluate(e_valid))]
        all_rmse, all_r2, plot_data = self._score_all(e_valid, final_theta, final_kt, final_lugre, tool)
        scores.append(StepScore("all", all_rmse, all_r2))
        report = ValidationReport(tuple(scores), tuple(robot.joint_names))
        timings["total"] = time.perf_counter() - total
        metadata["timings"] = timings
        metadata["friction_seconds"] = friction.seconds_.tolist()
        self.friction_train_ = {e.joint: e.recording for e in f_train}
        self.friction_valid_ = {e.joint: e.recording for e in f_valid}
        self.steps_ = {"motor": motor, "gravity": gravity, "friction": friction, "inertial": inertial}
        self.timings_ = timings
        self.plot_data_ = plot_data
        self.result_ = IdentifiedModel(robot_name=robot.name, model=model, theta=final_theta, kt=final_kt,
                                       lugre=tuple(final_lugre), report=report, consistency=consistency,
                                       metadata=metadata)
        say(f"identify: done in {timings['total']:.1f} s")
        return self

    def _refinement_blocks(self, data, o, prep):
        robot, blocks = self.robot, []

        def add(rec, cutoff, payload=None):
            clean = _decimate(prep(rec, cutoff).split(o.split_fraction)[0], o.refinement_rate_hz)
            tool = np.zeros_like(clean.q)
            for load in (payload, data.tool):
                if load is not None:
                    tool = tool + payload_torque(robot, load, clean.q, clean.qd, clean.qdd)
            blocks.append(RefinementBlock(clean, tool))

        for _, nominal, loaded in data.motor:
            add(nominal, o.motor_cutoff_hz)
            add(loaded, o.motor_cutoff_hz, data.payload)
        for rec in data.gravity:
            add(rec, o.gravity_cutoff_hz)
        for _, rec in data.friction:
            add(rec, o.friction_cutoff_hz)
        for rec in data.excitation:
            add(rec, o.inertial_cutoff_hz)
        return blocks

    def _score_all(self, recordings, theta, kt, lugre, tool):
        """RMSE and R^2 of the full model on the fast validation path (Table 3 "All")."""
        obs, pred, plot = [], [], None
        for rec in recordings:
            observed = rec.joint_torque(kt)
            predicted = regressor_chunked(self.model, rec.q, rec.qd, rec.qdd) @ theta + \
                friction_torque(lugre, rec.t, rec.qd)
            if tool is not None:
                predicted = predicted + payload_torque(self.robot, tool, rec.q, rec.qd, rec.qdd)
            obs.append(observed)
            pred.append(predicted)
            if plot is None:
                plot = (rec.t, observed, predicted)
        obs, pred = np.vstack(obs), np.vstack(pred)
        from identification.calibration.estimator import r2, rmse

        n = obs.shape[1]
        return (np.array([rmse(obs[:, j], pred[:, j]) for j in range(n)]),
                np.array([r2(obs[:, j], pred[:, j]) for j in range(n)]), plot)

    def plot(self, directory) -> list:
        """Write observed-vs-predicted plots (the "all" validation path) into ``directory``; return the paths."""
        from identification.calibration.estimator import check_is_fitted

        check_is_fitted(self, "result_")
        t, observed, predicted = self.plot_data_
        path = plot_observed_predicted(t, observed, predicted, Path(directory) / "validation_all.png",
                                       title="Full model on the excitation validation path",
                                       joint_names=list(self.robot.joint_names))
        return [path]
