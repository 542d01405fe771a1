"""Identification from a few exciting trajectories: weighted least squares, then a physically consistent fit.

The everyday route (FIGAROH's and BIRDy's): recordings of joint torques (or currents with known torque constants)
along exciting trajectories, in :func:`identify_trajectories`:

1. each recording is filtered, differentiated and decimated (``trajectory_data``), and its rows
   ``tau = Y(q, qd, qdd) theta + D(qd, qdd) f`` are summed into per-joint normal equations: the base parameters
   ``theta`` and the drive parameters ``f`` (Coulomb, viscous, optional offset, and the drive inertia of joints whose
   model has none; columns of ``TrajectoryOptions.held_friction`` held, ``held_friction``). With the Stribeck shape
   (``"fs"``) each joint's Stribeck velocity is found first (``stribeck``) and then held: ``f`` stays linear;
2. ordinary least squares with each joint's rows scaled by its torque RMS gives residual variances ``sigma_j^2``;
   weighted least squares with weights ``1 / sigma_j^2`` gives the unconstrained estimate, its covariance (standard
   deviations, relative sigma in percent) and the condition number of the weighted regressor (unit-norm columns);
3. unless ``consistency=False``, Ipopt minimises the same weighted residual over standard parameters in the
   log-Cholesky chart (``pseudo_inertia``), so every link has a positive-definite pseudo-inertia, with friction and
   drive inertias bounded below by zero, and a pull towards the robot file's parameters (a Gaussian prior against the
   data's independent samples, ``prior_pull``) that only settles what the data hardly fix. It is solved twice: the
   second time each joint's weight is ``1 / sigma_j^2`` of the first consistent fit's own residual (two-step feasible
   GLS: where the constraint keeps a joint from the least-squares fit, its residual, and so its noise estimate, is
   larger). The base parameters are computed from the standard ones.

The unconstrained estimate is kept beside the consistent one, so a report can show what the constraint cost on the data.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration import held_friction
from identification.calibration.angle_noise import effect_free_noise
from identification.calibration.configuration_check import accumulate, loaded_recordings, unstated_payload_warnings
from identification.calibration.consistent_covariance import consistent_covariance
from identification.calibration.consistent_fit import (
    IPOPT_OPTIONS,
    ROTOR,
    consistent_fit,
    drive_lower_bounds,
    link_is_free,
)
from identification.calibration.coulomb_width import positive_widths
from identification.calibration.envelope import check_ratio
from identification.calibration.envelope_report import bounds_note, envelope_findings
from identification.calibration.held_back import causes
from identification.calibration.inertia_floor import floor_note
from identification.calibration.merged_rotors import with_merged_rotors
from identification.calibration.payload_fit import (
    Estimable,
    FlangeBodies,
    identified_payloads,
    payload_prior,
    separable_in_place,
    subtract_known_payloads,
)
from identification.calibration.prior_pull import PRIOR_UNCERTAINTY, check_prior_options
from identification.calibration.pseudo_inertia import LINK_PARAMETER_COUNT, pseudo_inertia_eigenvalues
from identification.calibration.residual_correlation import correlation_time, sandwich_covariance
from identification.calibration.separate_inertia import drive_inertias, separate_inertia_joints
from identification.calibration.stribeck import StribeckColumns, stribeck_velocities, stribeck_velocity_std
from identification.calibration.trajectory_checks import (
    check_columns,
    check_offset_reversals,
    fit_warnings,
    torque_ratio,
)
from identification.calibration.trajectory_data import (
    FRICTION_TERMS,
    drive_column_names,
    drive_columns,
    fit_shape,
    prepare_recordings,
    samples_text,
)
from identification.calibration.weighted_solve import weighted_least_squares
from identification.data.filter_choice import EDGE_PERIODS
from identification.data.missing_torque import find_missing_torque, missing_torque_messages
from identification.data.robot_recordings import no_torque_constants
from identification.data.torque_constants import drive_kt
from psdm_casadi.errors import ParameterError
from psdm_casadi.log_context import ONCE
from psdm_casadi.state_cache import remembering

__all__ = ["IPOPT_OPTIONS", "TrajectoryFit", "TrajectoryOptions", "drive_inertia_joints", "identify_trajectories",
           "predict_torque", "torque_constants"]  # fmt: skip

logger = logging.getLogger(__name__)
JOINT_OPTIONS = ("offset_joints", "inertia_joints", "stribeck_joints", "held_links", "rotors_apart")


@dataclass(frozen=True)
class TrajectoryOptions:
    """Options of :func:`identify_trajectories`.

    Parameters
    ----------
    friction : tuple of str
        Drive terms per joint among ``("fc", "fs", "fv", "offset")``: Coulomb, static (with ``fc``), viscous, offset.
    coulomb_velocity : float or tuple of float
        [rad/s] The Coulomb term is ``fc tanh(qd / coulomb_velocity)``: a sign smoothed over the
        velocities where real joints pass from sticking to sliding (a few hundredths of a rad/s). One width for every
        joint, or one per joint (``coulomb_width``; held as one number when they are all the same).
    drive_inertia : bool
        Identify a drive (rotor, armature) inertia per joint, ``Ia qdd``: inside the base parameters for
        the joints whose model has one, as a column of its own for the others.
    consistency : bool
        Solve for physically consistent standard parameters (default); False keeps the weighted least
        squares estimate alone (reported as not checked for consistency).
    margin : float
        [kg m^2] by which every identified pseudo-inertia stays positive definite (its smallest
        eigenvalue is at least this).
    prior_uncertainty, prior_weight : float
        The pull towards the robot file, weighed against the data's independent samples: its parameters known to
        ``prior_uncertainty`` times their size (``prior_pull``); a ``prior_weight`` (per sample) overrides it.
    cutoff_hz : float or None
        Low-pass cutoff [Hz]; None chooses ``min(10 Hz, rate / 10)`` per recording.
    edge_periods : float
        Filter periods trimmed at each end of a recording (``filter_choice.EDGE_PERIODS``; a refit keeps its file's).
    kt : array or None
        Torque constants [N m/A] per joint for recordings of currents (default: the robot's drives).
    stribeck_velocity : float
        [rad/s] Where the Gauss-Newton search of each joint's Stribeck velocity starts when a grid
        (``stribeck.STRIBECK_GRID``) does not find a better start; used only with ``"fs"``.
    envelope : bool
        Keep each link of the consistent fit inside its physical envelope (``envelope``): its bounding
        ellipsoid, its mass within ``mass_ratio`` and its drive inertia within ``drive_inertia_ratio`` of the
        robot file's (default; needs the robot file's links).
    mass_ratio, drive_inertia_ratio : tuple of float
        ``(low, high)`` multiples of the robot file's link masses and drive inertias (default 0.5 and 2).
    offset_joints : tuple of int or None
        With ``"offset"``: the joints (0-based) whose torque offset is identified; the others' is held at 0
        (``column_choice`` decides it from the data). None: every joint.
    inertia_joints : tuple of int or None
        With ``drive_inertia``: the joints (0-based) whose drive-inertia column of its own is identified, among
        ``separate_inertia.separate_inertia_joints`` (``column_choice`` drops those the data want negative). None: all
        of them.
    stribeck_joints : tuple of int or None
        With ``"fs"``: the joints (0-based) of the Stribeck shape; the others are Coulomb-viscous (Stribeck velocity
        0, static friction held at 0: ``trajectory_data.friction_term``; ``column_choice`` decides it per joint from
        the data). None: every joint.
    viscous_exponent : tuple of float or None
        Per joint the exponent ``dv`` of the viscous power law (``trajectory_data.viscous_column``; 1: linear);
        ``column_choice`` decides it per joint from the data. None: every joint linear.
    held_friction : tuple of (str, float)
        Drive columns (``fc<j>``, ``fv<j>`` of Coulomb-viscous joints) held at these values, not fitted
        (``held_friction``; ``one_way_friction`` holds the friction of a joint the data do not determine it on).
    held_links : tuple of int
        Links (0-based) whose ten inertial parameters the consistent fit holds at the robot file's, and the drive
        inertia of each joint whose every carried link is among them (``consistent_fit.held_rotors``):
        ``worse_joint_hold`` holds the links a joint carries where the identified ones made it worse than the robot
        file on the held-out recordings.
    baseline_friction : tuple of str
        The names among ``held_friction`` that ``worse_joint_hold`` held at the robot file's baseline: a choice of the
        held-out recordings, not of the data, so free in the data's own least squares ``held_back`` compares with.
    stribeck_held : tuple of float or None
        With ``"fs"``: the Stribeck velocities [rad/s] per joint held, not searched (0: a Coulomb-viscous joint); a
        refit of a model file with a diagnosis's findings keeps the file's shape, as the diagnosis judged them against
        it (``applied_model``). None: searched (``stribeck``).
    rotors_apart : tuple of int
        Joints (0-based) whose drive inertia, merged into the base parameters and held to the same actuator's on other
        joints by default (``merged_rotors.sibling_rotors``), is taken from the training data instead
        (``merged_rotors.siblings_apart``). identify lists a joint here only where the training BIC wants it apart and
        held-out data confirm it (``rotors_apart``); a refit keeps its file's.
    """

    friction: tuple = ("fc", "fv")
    coulomb_velocity: float | tuple = 0.05
    drive_inertia: bool = True
    consistency: bool = True
    margin: float = 1e-6
    prior_uncertainty: float = PRIOR_UNCERTAINTY
    prior_weight: float | None = None
    cutoff_hz: float | None = None
    edge_periods: float = EDGE_PERIODS
    kt: tuple | None = None
    stribeck_velocity: float = 0.1
    envelope: bool = True
    mass_ratio: tuple = (0.5, 2.0)
    drive_inertia_ratio: tuple = (0.5, 2.0)
    offset_joints: tuple | None = None
    inertia_joints: tuple | None = None
    stribeck_joints: tuple | None = None
    viscous_exponent: tuple | None = None
    held_friction: tuple = ()
    held_links: tuple = ()
    baseline_friction: tuple = ()
    stribeck_held: tuple | None = None
    rotors_apart: tuple = ()

    def __post_init__(self):
        for name in JOINT_OPTIONS:
            joints = getattr(self, name)
            if joints is not None and not all(isinstance(j, (int, np.integer)) and j >= 0 for j in joints):
                raise ParameterError(f"TrajectoryOptions.{name} must be None or 0-based joint indices; got {joints!r}.")
        unknown = [t for t in self.friction if t not in FRICTION_TERMS]
        if unknown or len(set(self.friction)) != len(self.friction):
            raise ParameterError(
                f"TrajectoryOptions.friction must hold distinct terms of {FRICTION_TERMS}; got {self.friction!r}."
            )
        if "fs" in self.friction and "fc" not in self.friction:
            raise ParameterError(
                f"TrajectoryOptions.friction must hold 'fc' with 'fs' (the Stribeck shape); got {self.friction!r}."
            )
        if not (np.isfinite(self.stribeck_velocity) and self.stribeck_velocity > 0):
            raise ParameterError(
                f"TrajectoryOptions.stribeck_velocity must be > 0 [rad/s]; got {self.stribeck_velocity!r}."
            )
        width = positive_widths(self.coulomb_velocity, "TrajectoryOptions.coulomb_velocity")  # one, or per joint
        object.__setattr__(self, "coulomb_velocity", width)
        if not (np.isfinite(self.margin) and self.margin > 0):
            raise ParameterError(f"TrajectoryOptions.margin must be > 0 [kg m^2]; got {self.margin!r}.")
        check_prior_options(self)
        held_friction.check_held_friction(self)
        for key in ("mass_ratio", "drive_inertia_ratio"):
            check_ratio(f"TrajectoryOptions.{key}", getattr(self, key))


@dataclass(frozen=True)
class TrajectoryFit:
    """What :func:`identify_trajectories` found. Arrays are per joint (``n_dof``) unless said otherwise.

    Attributes
    ----------
    standard : array, shape (n_dof, 11)
        Standard parameters (10 per link, then the drive inertia ``Ia``), consistent when ``consistent``.
    theta : array, shape (n_base,)
        Base parameters of ``standard``.
    drive : array, shape (n_drive,)
        Drive parameters, labelled by ``drive_names`` (``fc1``, ``fv1``, ..., ``Ia<j>``).
    theta_ols, drive_ols, theta_std, drive_std : arrays
        The weighted least-squares estimate and its standard deviations.
    covariance : array, shape (n_base + n_drive, n_base + n_drive) or None
        Of the base then drive parameters as written: of the least-squares estimate (the sandwich covariance their
        standard deviations are the diagonal of), or of a consistent fit that with the pull's precision added
        (``consistent_covariance``: the fit is pulled towards the robot file, and more precise than the least
        squares where the data hardly fix it); None where not computed.
    sigma : array
        Residual standard deviation [N m] per joint of the least-squares fit (its weights are ``1 / sigma^2``).
    condition_number : float
        Of the weighted regressor with unit-norm columns.
    min_pseudo_inertia_eigenvalue : float
        Over the links of ``standard`` (positive when consistent).
    stribeck_velocity, stribeck_velocity_std : tuple
        [rad/s] Per joint, for the Stribeck shape (``"fs"`` in ``friction_terms``); empty otherwise.
    viscous_exponent : tuple
        As ``TrajectoryOptions``' (empty: every joint linear).
    training_r2, training_r2_ols : tuple
        Per joint, R^2 of the identified model (and of the least-squares estimate) on the recordings it was fitted to.
    torque_ratio : tuple
        Per joint, the RMS of the unconstrained fit's rigid-body torque over that of the robot file's on the same
        motion (about 1; about 1000 on every joint for torques in mN m); empty without the file's links.
    envelope_bounds : tuple
        ``(name, value)`` pairs of the bounds (``mass_ratio``, ``drive_inertia_ratio``, ``envelopes``: each ellipsoid's
        source; ``prior``: the pull, ``PriorPull``; ``held_back``: what it keeps from the data, ``held_back``).
    envelope : tuple of EnvelopeFinding
        The links and drives the data pushed against their physical envelope (``envelope_report``), each with what
        it most likely absorbs; empty when the fit stayed inside (or was not bounded).
    warnings : tuple of str
        What looks like a wrong recording (``trajectory_checks.fit_warnings``): a joint the model does not explain
        on its own data, a friction or drive inertia the data want negative by many sigma, link masses an order of
        magnitude from the robot file's.
    payloads : tuple of payload_fit.IdentifiedPayload
        The unknown payloads of the recordings' configurations (``identify_trajectories(configurations=)``),
        each a body fixed to the flange identified with the arm's parameters shared.
    edge_periods : float
        Filter periods trimmed at each end of every recording (``TrajectoryOptions.edge_periods``).
    loaded : tuple of configuration_check.LoadedRecording
        The recordings that look loaded (or lighter) at the flange against the others, said in ``warnings``.
    """

    standard: np.ndarray
    theta: np.ndarray
    drive: np.ndarray
    drive_names: tuple
    inertia_joints: tuple
    friction_terms: tuple
    coulomb_velocity: float | tuple
    theta_ols: np.ndarray
    drive_ols: np.ndarray
    theta_std: np.ndarray
    drive_std: np.ndarray
    sigma: np.ndarray
    condition_number: float
    consistent: bool
    checked: bool
    min_pseudo_inertia_eigenvalue: float
    cutoff_hz: tuple
    decimation: tuple
    n_samples: int  # the samples the fit used (the most any joint has); ``joint_samples``: per joint
    solver_status: str
    seconds: float
    stribeck_velocity: tuple = ()
    stribeck_velocity_std: tuple = ()
    viscous_exponent: tuple = ()
    training_r2: tuple = ()
    training_r2_ols: tuple = ()
    torque_ratio: tuple = ()
    envelope_bounds: tuple = ()
    envelope: tuple = ()
    warnings: tuple = ()
    payloads: tuple = ()
    edge_periods: float = EDGE_PERIODS
    covariance: np.ndarray | None = None
    loaded: tuple = ()
    joint_samples: tuple = ()

    @property
    def relative_sigma_percent(self) -> np.ndarray:
        """100 * sigma / |estimate| of the base then drive parameters of the least-squares estimate."""
        x = np.concatenate([self.theta_ols, self.drive_ols])
        s = np.concatenate([self.theta_std, self.drive_std])
        with np.errstate(divide="ignore", invalid="ignore"):  # 0 / 0: an offset held at 0 (``offset_joints``)
            return 100.0 * s / np.abs(x)


def predict_torque(model, fit: TrajectoryFit, q, qd, qdd, *, ols: bool = False) -> np.ndarray:
    """Joint torques [N m] of the identified model (or of its least-squares estimate), (n_samples, n_dof)."""
    theta, drive = (fit.theta_ols, fit.drive_ols) if ols else (fit.theta, fit.drive)
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    columns = drive_columns(qd, qdd, fit.friction_terms, fit.inertia_joints, fit.coulomb_velocity, *fit_shape(fit))
    return model.inverse_dynamics(q, qd, qdd, theta) + columns @ drive


@remembering()  # the recordings' regressors evaluated once (state_cache)
def identify_trajectories(
    robot, model, recordings, options: TrajectoryOptions | None = None, extra=None, configurations=None
) -> TrajectoryFit:
    """Identify base, standard and drive parameters from exciting recordings (module docstring).

    Parameters
    ----------
    robot : RobotDescription
        Kinematics, and the prior standard parameters when it has links.
    model : PSDMModel
        ``derive_psdm(robot)``.
    recordings : sequence of Recording
        Raw recordings with ``tau``, or ``current`` and torque constants.
    options : TrajectoryOptions, optional
    extra : findings.FindingColumns, optional
        Extra linear columns fitted jointly (the torque-type findings of a diagnosis, ``recalibrate``); their
        coefficients follow the drive parameters in ``TrajectoryFit.drive`` (labelled by ``extra.names``); the torque
        of the terms it holds at given coefficients (``extra.held``) is taken off the recordings first.
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each recording carries at the flange (default: none): known loads are subtracted, unknown
        ones identified with the arm's parameters shared (``payload_fit``; ``TrajectoryFit.payloads``).

    Returns
    -------
    TrajectoryFit

    Raises
    ------
    ParameterError, RecordingError
        For recordings that do not match the robot, in the wrong units (``plausibility``), or too short to filter.
    InsufficientExcitationError
        For recordings that do not excite the parameters (``trajectory_checks``), e.g. a torque offset on a joint
        that never reverses.
    SolverError
        When Ipopt does not converge on the consistent fit.
    """
    options, start = TrajectoryOptions() if options is None else options, time.perf_counter()
    recordings = [find_missing_torque(r) for r in recordings]  # a dead torque channel: only its joint's rows out
    if not recordings:
        raise ParameterError("identify_trajectories needs at least one recording; got none. Pass --data FILE.")
    bodies = FlangeBodies.of(configurations, len(recordings))
    kt, inertia_joints = torque_constants(robot, options, recordings), drive_inertia_joints(model, robot, options)
    lower = drive_lower_bounds(names := drive_column_names(robot.n_dof, options.friction, inertia_joints))
    if extra is not None:
        names, lower = names + list(extra.names), np.concatenate([lower, extra.lower])
    cutoffs, steps, prepared = _prepared(robot, recordings, kt, options, configurations, extra)
    check_offset_reversals(robot, prepared, options.friction, options.coulomb_velocity, options.offset_joints)
    vs, extras = None, (plain := bodies.extras(robot, extra))
    if "fs" in options.friction:  # Stribeck velocities first; their derivative columns stay for the covariance
        vs = stribeck_velocities(model, prepared, options, inertia_joints, plain)
        extras = [StribeckColumns(options.coulomb_velocity, vs, e, options.viscous_exponent) for e in plain]
    n_all = (n_fit := model.n_base + len(names)) + bodies.n_columns
    setup = (options.friction, inertia_joints, options.coulomb_velocity, vs, options.viscous_exponent)
    n_columns = n_all + (0 if vs is None else robot.n_dof)  # one pass; flange probes of configuration_check
    equations, own = accumulate(robot, model, prepared, extras, setup, n_columns, bodies.index)
    logger.info("identify: %s of %d recording(s), cutoff %s Hz", samples_text(equations.count), len(recordings),
                ", ".join(f"{c:g}" for c in cutoffs), extra=ONCE)  # fmt: skip
    held = _held_columns(names, options, model.n_base, vs, n_columns)  # held at 0: left out of both fits
    free = [k for k in range(equations.n_columns) if k not in held]
    check_columns(robot, model, equations.subset([k for k in free if k < n_fit]),
                  [n for k, n in enumerate(names) if model.n_base + k not in held], recordings)  # fmt: skip
    sigma, x_ols, inverse, condition = weighted_least_squares(equations, free, range(n_fit, n_all))
    noise = effect_free_noise(robot, model, prepared, extras, setup, n_columns, free, range(n_fit, n_all))  # lazy
    correlation = np.max([correlation_time(model, rec, x_ols, options, inertia_joints, columns, stribeck=vs)
                          for rec, columns in zip(prepared, extras)], axis=0)  # fmt: skip
    covariance = sandwich_covariance(equations, sigma, inverse, correlation)
    data_own = _data_own(equations, (names, held, n_fit, n_all), options, correlation, (x_ols, covariance))
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    vs_std = () if vs is None else stribeck_velocity_std(x_ols, std, model.n_base, names, vs)
    x_ols, std, equations = x_ols[:n_all], std[:n_all], equations.subset(range(n_all))
    loaded = [] if own is None else loaded_recordings(own, n_all, equations, sigma, correlation)
    mixed = [*missing_torque_messages(recordings, robot.joint_names, "fit"), *unstated_payload_warnings(loaded)]
    estimable = Estimable(equations.weighted(1.0 / sigma**2)[0])
    (keep, separable), prior = bodies.separable(estimable, n_fit), payload_prior(bodies, x_ols, n_fit, estimable)
    if options.consistency:
        model, robot, merged = with_merged_rotors(model, robot, options, kt, (equations, names), True, correlation)
        fitted = [k for k in range(len(names)) if model.n_base + k not in held]
        standard, drive_fitted, found, status, bounds = consistent_fit(
            robot, model, equations.subset([k for k in keep if k not in held]), sigma, [names[k] for k in fitted],
            options, lower[fitted], prior[separable], merged.fit_bounds(options), correlation=correlation)  # fmt: skip
        drive = np.zeros(len(names))
        drive[fitted] = drive_fitted
        found = separable_in_place(found, separable)
        standard[:, ROTOR] = drive_inertias(model, standard, drive, names)
        x_fit = np.concatenate([model.base_parameters(standard), drive, np.nan_to_num(np.ravel(found))])
        pushed = envelope_findings(robot, bounds, standard, equations, x_fit, data_own[0], sigma, kt is not None)
        pushed, kept = causes(robot, model, (x_fit, data_own[0], equations, sigma, prepared), data_own[1], names,
                              pushed, kt, options.held_links, noise)  # fmt: skip
        free = [i for i in range(robot.n_dof) if link_is_free(model, i)]
        eigen = float(pseudo_inertia_eigenvalues(standard[free]).min()) if free else float("inf")
        theta = model.base_parameters(standard)
        stated = consistent_covariance(covariance[:n_fit, :n_fit], model, robot, bounds.prior, options.held_links)
    else:  # base parameters only: no standard parameters are identified, none are made up
        standard = np.full((robot.n_dof, LINK_PARAMETER_COUNT + 1), np.nan)
        drive, status, eigen, theta = x_ols[model.n_base : n_fit], "not solved", float("nan"), x_ols[: model.n_base]
        found, (pushed, bounds, merged, kept, stated) = x_ols[n_fit:].reshape(-1, 10), ((), None, None, (), covariance)
    payloads = identified_payloads(bodies, [r.name for r in recordings], n_fit, estimable, covariance, found)
    fit = TrajectoryFit(
        standard=standard, theta=theta, drive=np.asarray(drive, dtype=float), drive_names=tuple(names),
        inertia_joints=tuple(inertia_joints), friction_terms=tuple(options.friction), envelope=tuple(pushed),
        coulomb_velocity=options.coulomb_velocity, viscous_exponent=tuple(options.viscous_exponent or ()),
        theta_ols=x_ols[: model.n_base], drive_ols=x_ols[model.n_base : n_fit], theta_std=std[: model.n_base],
        drive_std=std[model.n_base : n_fit], condition_number=condition, seconds=time.perf_counter() - start,
        consistent=bool(options.consistency and eigen > 0), checked=options.consistency, solver_status=status,
        min_pseudo_inertia_eigenvalue=eigen, cutoff_hz=tuple(cutoffs), decimation=tuple(steps),
        n_samples=int(equations.count.max()), joint_samples=tuple(equations.count.tolist()), sigma=sigma,
        stribeck_velocity=() if vs is None else tuple(float(v) for v in vs), stribeck_velocity_std=vs_std,
        training_r2=tuple(equations.r2(np.concatenate([theta, drive, np.nan_to_num(np.ravel(found))])).tolist()),
        training_r2_ols=tuple(equations.r2(x_ols).tolist()), payloads=payloads, edge_periods=options.edge_periods,
        envelope_bounds=bounds_note(options, bounds) + (merged.note() + bounds.prior.note() if merged else ()) + kept
        + floor_note(robot, standard, bounds),
        torque_ratio=torque_ratio(robot, model, equations, x_ols), covariance=stated[:n_fit, :n_fit], loaded=(*loaded,),
    )  # fmt: skip
    return held_friction.with_held_values(replace(fit, warnings=(*fit_warnings(robot, fit, loaded), *mixed)), options)


def _prepared(robot, recordings, kt, options, configurations, extra=None) -> tuple:
    """(cutoffs, decimation steps, prepared recordings) of the fit: known payloads, held friction and the findings
    ``extra`` holds (``FindingColumns.held``) taken off."""
    cutoffs, steps, prepared = prepare_recordings(robot, recordings, kt, options.cutoff_hz, options.edge_periods)
    prepared = held_friction.subtract_held_friction(subtract_known_payloads(robot, prepared, configurations), options)
    return cutoffs, steps, prepared if extra is None else extra.without_held(prepared)


def _data_own(equations, columns, options, correlation, ols) -> tuple:
    """``(x, covariance)`` of the data's own least squares over the first ``n_all`` columns: ``ols`` as fitted, or,
    with columns ``worse_joint_hold`` held by choice (``options.baseline_friction``), with those free: what the data
    want is not what the held-out recordings chose (``held_back``, ``envelope_findings``). ``columns`` = ``(names,
    held, n_fit, n_all)``; the fit's own weights and correlation stay those of ``ols``'s fit."""
    names, held, n_fit, n_all = columns
    chosen = held_friction.baseline_columns(names, options, n_fit - len(names))
    if not chosen:
        return ols[0][:n_all], ols[1]
    free = [k for k in range(equations.n_columns) if k not in held - chosen]
    sigma, x, inverse, _ = weighted_least_squares(equations, free, range(n_fit, n_all))
    return x[:n_all], sandwich_covariance(equations, sigma, inverse, correlation)


def _held_columns(names, options, n_base, vs, n_columns) -> set:
    """Column indices (after the ``n_base`` base parameters) held at 0: the offsets outside ``options.offset_joints``,
    those of ``options.held_friction`` (their torque is off the data), and on a Coulomb-viscous joint of a Stribeck
    model (Stribeck velocity ``vs`` 0) its static friction and velocity's derivative column (the last ``n_dof``)."""
    kept = options.offset_joints
    held = {n_base + k for k, n in enumerate(names) if n.startswith("offset") and kept is not None
            and int(n[6:]) - 1 not in kept} | held_friction.held_friction_columns(names, options, n_base)  # fmt: skip
    flat = [] if vs is None else [j for j in range(len(vs)) if vs[j] == 0]
    return held | {n_base + names.index(f"fs{j + 1}") for j in flat} | {n_columns - len(vs) + j for j in flat}


def torque_constants(robot, options, recordings):
    """Torque constants [N m/A] for recordings of currents; None when every recording holds joint torques."""
    if all(rec.tau is not None for rec in recordings):
        return None
    if options.kt is not None:
        return np.asarray(options.kt, dtype=float)
    if robot.drives is None:
        raise ParameterError(no_torque_constants(robot))
    return drive_kt(robot)


def drive_inertia_joints(model, robot, options: TrajectoryOptions) -> list:
    """The joints with an ``Ia<j>`` column in a fit with ``options`` (0-based): ``options.inertia_joints`` as given
    (``column_choice`` takes them among the separate ones), else every separate one."""
    if not options.drive_inertia:
        return []
    kept = options.inertia_joints
    return separate_inertia_joints(model, robot) if kept is None else sorted(int(j) for j in kept)
