"""DiagnosisOptions: what ``diagnose`` is asked to do, validated before any fit (friction, rigid body, preparation,
selection gates, second opinion, what a model file holds fixed).

Options -> ``diagnose.diagnose`` (and ``model_file.model_file_options``, which fills the fields left ``"auto"`` from a
calibrated model file).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.coulomb_width import positive_widths
from identification.calibration.held_friction import HeldFriction
from identification.data.excitation_check import ExcitationThresholds
from identification.data.filter_choice import AUTO, EDGE_PERIODS, resolve_auto
from identification.diagnosis.candidates import CandidateLibrary
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY, CandidateTerm
from identification.diagnosis.file_friction import FileFriction
from identification.diagnosis.nominal import FRICTION_MODELS, RIGID_BODY_CHOICES, nominal_friction
from psdm_casadi.errors import ParameterError

__all__ = ["DiagnosisOptions"]


@dataclass(frozen=True)
class DiagnosisOptions:
    """Options of ``diagnose``.

    Parameters
    ----------
    friction : {"auto", "lugre", "coulomb_viscous", "stribeck"}
        Nominal friction (see ``nominal``); ``"auto"`` (default): the steady-state LuGre with the robot file's shape,
        or Coulomb + viscous when its drives state torque constants but no friction (``nominal_friction``); a
        calibrated model's own shape in ``model_file.diagnose_model``.
    rigid_body : {"auto", "prior", "identified"}
        Keep the robot file's inertia, identify the base parameters too, or (default) decide from the data: a
        payload- or inertia-type finding of the prior model must beat a full rigid-body recalibration on the
        validation recording, otherwise the rigid body is identified and the report says the robot file's
        inertial parameters are off (``rigid_body_choice``).
    cutoff_hz, rate_hz : float or "auto"
        Zero-phase low-pass cut-off of the preprocessing [Hz] (None: unfiltered) and rate of the grid the fit works on
        [Hz]; ``"auto"`` (default): as ``psdm identify`` chooses them for the training recording (``filter_choice``:
        ``min(10 Hz, rate / 10)``, samples at ten times the cutoff), or a calibrated model file's own preparation
        (``model_file.diagnose_model``), so ``diagnose`` in Python and ``psdm diagnose`` give the same numbers.
        A cutoff of 15 Hz on a 200 Hz grid keeps more of a narrow Stribeck hump than identify's 10 Hz.
    samples : {"identify", "diagnosis"}
        The grid's samples: identify's (default; ``filter_choice.kept_samples``: ``edge_periods`` trimmed, identify's
        step), so a model is judged on the samples ``psdm validate`` judges it on; or without 5 % (at most 0.2 s) of
        the grid at each end.
    edge_periods : float
        Filter periods trimmed at each end (``filter_choice.EDGE_PERIODS``; a model file's own: ``model_file``).
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
    excitation : ExcitationThresholds or None
        Thresholds of the excitation checks run before any fit (default ``ExcitationThresholds()``): every
        joint must move in both recordings (range and speed, :func:`check_joint_motion`), and the columns
        of the nominal model's free parameters must be well conditioned on the training recording
        (:func:`check_regressor`). A still or dithering joint otherwise gives noise-fitted "findings".
    max_samples : int
        Most samples of a recording's decimated grid: a recording longer than ``max_samples / rate_hz``
        (41.7 minutes on a 100 Hz grid) gets a coarser grid, so the memory and time of the fit are bounded by
        this rather than by the recording's length (about 1.5 kB per sample for 6 joints). A grid with fewer
        than 4 samples per cut-off period is reported as a warning. Recordings up to the bound keep the
        ``rate_hz`` grid.
    sparse : bool
        Look beyond the library: propose a sparse symbolic term (``sparse_terms``) for a joint whose residual
        stays structured after the library's terms, reported as an unnamed effect with its formula.
    sparse_min_gain : float
        Validation RMSE reduction (fraction) of its joint a sparse term must show to be kept.
    envelope : bool
        With ``rigid_body="auto"``: a finding the free rigid-body recalibration makes unnecessary still stands where a
        rigid body recalibrated inside its physical envelope, as ``psdm identify`` fits it, needs it
        (``envelope_check``: a counterbalance that only a link twice as heavy with its centre of mass outside the link
        absorbs); False judges against the free recalibration alone.
    cv_folds : int
        With one validation recording, the second opinion on each finding (``second_opinion``): the training recording
        is cut into this many contiguous blocks, each held out once, and a finding must hold on every block; 0 turns
        it off (with several validation recordings a finding must hold on each of them instead).
    friction_shapes : bool
        Offer the friction shapes the nominal model lacks (``lacking_friction_shapes``): beside a Coulomb-viscous or
        Stribeck one as candidates and in place of a lag they explain, beside the robot file's LuGre friction a Stribeck
        peak at another velocity than the drive's; the fleet's day diagnosis, which asks what changed, turns it off.
    held_friction : HeldFriction
        Friction the nominal model holds at a model file's values (identify's ``one_way_friction``; a model file's, from
        ``model_file.model_file_options``): no fit of the diagnosis estimates those joints' friction columns, every one
        explains the torque the held friction leaves (``DiagnosisContext.tau_fit``), so the nominal model predicts
        those joints as ``psdm validate`` predicts the file.
    coulomb_velocity : float or tuple of float
        The smoothing [rad/s] of the nominal friction's sign without drives, one width or one per joint (a model file's:
        ``model_file_options``).
    carried : tuple of CandidateTerm
        Terms the nominal model holds as columns (``carried_terms``): a model file's counterbalance identify took or
        torque finding an earlier ``diagnose --apply`` wrote (``model_file_options``), its coefficients fitted again in
        every fit of the diagnosis, reported as kept from the file, never selected, dropped or rejected; no other
        spring is offered on a counterbalance's joint. Or a model file's drive column (``drive_columns``: a rotor
        inertia fitted again beside the file's value, no finding); the library never offers a carried term again.
    held_links : tuple of int
        Links (0-based) every rigid-body recalibration of the diagnosis holds at the nominal robot's inertia
        (``held_links``): a model file's, which identify held (``worse_joint_hold``, ``model_file_options``).
    rotors_apart : tuple of int
        Joints (0-based) whose merged drive inertia every enveloped recalibration takes from the data rather than the
        same actuator's (``TrajectoryOptions.rotors_apart``): a model file's, which identify took apart where the
        held-out data confirmed it (``calibration.rotors_apart``, ``model_file_options``).
    nominal : str
        What the nominal model's inertia is, as the report names it: ``"robot file"`` (default) or ``"model file"``
        (``model_file_options``: identify's rigid body).
    viscous_power : bool
        The Coulomb-viscous nominal keeps the drives' viscous exponents ``dv`` (a model file's viscous power law,
        ``viscous_power``; set by ``model_file_options``). Otherwise ``"coulomb_viscous"`` is linear in the velocity,
        whatever a robot file's drives state.
    file_friction : FileFriction or None
        A model file's friction per joint (``file_friction``; set by ``model_file_options`` when ``friction`` is left
        ``"auto"``): the nominal model's friction columns on its steady-state joints are the file's own (its Coulomb
        smoothing, Stribeck velocities and viscous exponents per joint), and the friction shapes the file holds on a
        joint are not offered there. None: the columns of ``friction``.
    """

    friction: str = AUTO
    rigid_body: str = "auto"
    cutoff_hz: float | None | str = AUTO
    rate_hz: float | str = AUTO
    samples: str = "identify"
    edge_periods: float = EDGE_PERIODS
    min_improvement: float = 0.2
    max_effects: int = 4
    joint_threshold: float = 0.1
    library: CandidateLibrary | None = None
    friction_shapes: bool = True
    preprocess: bool = True
    torque_constants: tuple | None = None
    refine: bool = True
    excitation: ExcitationThresholds | None = None
    max_samples: int = 250_000
    sparse: bool = True
    sparse_min_gain: float = 0.3
    cv_folds: int = 4
    envelope: bool = True
    held_friction: HeldFriction = HeldFriction()
    coulomb_velocity: float | tuple = SMOOTH_VELOCITY
    carried: tuple = ()
    held_links: tuple = ()
    viscous_power: bool = False
    rotors_apart: tuple = ()
    nominal: str = "robot file"
    file_friction: FileFriction | None = None

    def __post_init__(self):
        if isinstance(self.cv_folds, bool) or not (
            isinstance(self.cv_folds, (int, np.integer)) and (self.cv_folds == 0 or 2 <= self.cv_folds <= 20)
        ):
            raise ParameterError(
                f"DiagnosisOptions.cv_folds must be 0 (off) or an integer 2..20; got {self.cv_folds!r}. Use 4."
            )
        if not 0.0 < self.sparse_min_gain < 1.0:
            raise ParameterError(
                f"DiagnosisOptions.sparse_min_gain must be in (0, 1); got {self.sparse_min_gain!r}. Use 0.3."
            )
        if self.friction not in (AUTO, *FRICTION_MODELS):
            raise ParameterError(
                f"DiagnosisOptions.friction must be {AUTO!r} or one of {FRICTION_MODELS}; got {self.friction!r}."
            )
        if self.rigid_body not in RIGID_BODY_CHOICES:
            raise ParameterError(
                f"DiagnosisOptions.rigid_body must be one of {RIGID_BODY_CHOICES}; got {self.rigid_body!r}."
            )
        if not 0.0 < self.min_improvement < 1.0:
            raise ParameterError(
                f"DiagnosisOptions.min_improvement must be in (0, 1); got {self.min_improvement!r}. Use 0.2."
            )
        if not (isinstance(self.max_effects, (int, np.integer)) and self.max_effects >= 0):
            raise ParameterError(f"DiagnosisOptions.max_effects must be an integer >= 0; got {self.max_effects!r}.")
        if self.rate_hz != AUTO and not (_number(self.rate_hz) and self.rate_hz > 0):
            raise ParameterError(
                f"DiagnosisOptions.rate_hz must be positive [Hz] or {AUTO!r}; got {self.rate_hz!r}. Leave it {AUTO!r}."
            )
        if isinstance(self.max_samples, bool) or not (
            isinstance(self.max_samples, (int, np.integer)) and self.max_samples >= 1000
        ):
            raise ParameterError(
                f"DiagnosisOptions.max_samples must be an integer >= 1000; got {self.max_samples!r}. Use 250000."
            )
        if not (_number(self.edge_periods) and self.edge_periods >= 0):
            raise ParameterError(f"DiagnosisOptions.edge_periods must be a number >= 0; got {self.edge_periods!r}.")
        if self.samples not in ("diagnosis", "identify"):
            raise ParameterError(f"DiagnosisOptions.samples must be 'diagnosis' or 'identify'; got {self.samples!r}.")
        if self.cutoff_hz not in (None, AUTO) and not (_number(self.cutoff_hz) and self.cutoff_hz > 0):
            raise ParameterError(
                f"DiagnosisOptions.cutoff_hz must be positive [Hz], None (unfiltered) or {AUTO!r}; got "
                f"{self.cutoff_hz!r}. Leave it {AUTO!r} (identify's preparation)."
            )
        if self.excitation is not None and not isinstance(self.excitation, ExcitationThresholds):
            raise ParameterError(
                f"DiagnosisOptions.excitation must be an ExcitationThresholds or None; got "
                f"{type(self.excitation).__name__}. Pass ExcitationThresholds(...)."
            )
        if self.file_friction is not None and not isinstance(self.file_friction, FileFriction):
            raise ParameterError(f"DiagnosisOptions.file_friction must be a FileFriction or None; got "
                                 f"{type(self.file_friction).__name__}.")  # fmt: skip
        if not isinstance(self.held_friction, HeldFriction):
            raise ParameterError(f"DiagnosisOptions.held_friction must be a HeldFriction; got "
                                 f"{type(self.held_friction).__name__}.")  # fmt: skip
        width = positive_widths(self.coulomb_velocity, "DiagnosisOptions.coulomb_velocity")  # one, or per joint
        object.__setattr__(self, "coulomb_velocity", width)
        if not all(isinstance(t, CandidateTerm) and t.joints for t in self.carried):
            raise ParameterError(f"DiagnosisOptions.carried must hold candidate terms with their joints (a model "
                                 f"file's counterbalance or finding); got {self.carried!r}.")  # fmt: skip
        for name in ("held_links", "rotors_apart"):
            if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and i >= 0
                       for i in getattr(self, name)):  # fmt: skip
                raise ParameterError(f"DiagnosisOptions.{name} must be 0-based indices; got {getattr(self, name)!r}.")
        if self.library is not None and not isinstance(self.library, CandidateLibrary):
            raise ParameterError(
                f"DiagnosisOptions.library must be a CandidateLibrary; got {type(self.library).__name__}. "
                "Combine terms with +, e.g. SpringTerm() + TorqueOffsetTerm()."
            )

    def for_recording(self, train, robot=None) -> DiagnosisOptions:
        """These options with ``"auto"`` cutoff and grid rate resolved for the training recording ``train`` as
        ``psdm identify`` resolves them (``filter_choice.resolve_auto``), and an ``"auto"`` friction for ``robot``
        (``nominal_friction``)."""
        cutoff, rate = resolve_auto(self.cutoff_hz, self.rate_hz, 1.0 / float(train.dt))
        friction = nominal_friction(robot) if self.friction == AUTO and robot is not None else self.friction
        return replace(self, cutoff_hz=cutoff, rate_hz=rate, friction=friction)


def _number(value) -> bool:
    return isinstance(value, (int, float, np.number)) and not isinstance(value, bool) and bool(np.isfinite(value))
