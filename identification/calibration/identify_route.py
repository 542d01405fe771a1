"""``psdm identify``'s route as one library call: the data's choices, the fit, the counterbalance, the model file.

raw training recordings (and held-out ones, if any) -> ``column_choice.choose_columns`` (the recordings prepared once:
the Coulomb column's smoothing velocity from the joints' reversals, ``coulomb_smoothing``; the friction shape, torque
offsets, drive inertias and drive losses per joint) -> the fit (``trajectory_fit.identify_trajectories``; with a drive
loss ``drive_loss.identify_with_drive_loss``; with LuGre friction ``lugre_identify``) -> the counterbalance the
envelope report names, tried and kept only where it holds out of sample (``counterbalance_column``), and the payload
(``payload_route``) -> one ``CalibratedModel``, checked against the robot file on the held-out recordings
(``robot_file_check``). The holds of the joints the data do not determine (``one_way_friction``) or the check names
worse (``worse_joint_hold``) judge the model that would be written, each fit they try carried through the counterbalance
and payload steps first (``written_model``): those steps take torque the fit's links absorbed, and a joint worse before
them may not be worse after. Where the held-out residual of that model lags the velocity at the reversals as
pre-sliding friction does, the LuGre route is tried and written instead if it is better there and worse on no joint
(``lugre_trial``). The coupling terms of a coupled transmission the robot file states are fitted before the
worse-joint holds, on the model the route would write, and kept where the held-out recordings, else a block
cross-validation of the training recordings, judge them (``coupled_drives``); the holds' fits carry the kept terms.

Python users, the benchmarks and the command line get the same model from the same data: defaults are decided from the
data here, not in the command line. Its options are overrides (``ColumnRequest``, ``counterbalance=False``), and
``IdentifyResult.describe`` states every choice with its reason.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.column_check import check_departures, offset_sizes, written_model_judge
from identification.calibration.column_choice import ColumnChoice, ColumnRequest, choose_columns
from identification.calibration.consistent_fit import lifted_links
from identification.calibration.counterbalance_column import CounterbalanceChoice
from identification.calibration.coupled_drives import CoupledDrives, carrying, coupled_on_route, not_on_route
from identification.calibration.drift_choice import FrictionDrift, check_drift_mode, judge_friction_drift
from identification.calibration.file_judged import file_judged, file_training
from identification.calibration.held_back import stored_held_back
from identification.calibration.lugre_trial import LuGreTrial, try_lugre
from identification.calibration.never_worse import JointComparison, compare_each
from identification.calibration.one_way_friction import (
    OneWayFriction,
    check_one_way_mode,
    file_friction_values,
    held_options,
    hold_one_way_friction,
)
from identification.calibration.payload_route import PayloadChoice
from identification.calibration.prior_pull import PriorPull
from identification.calibration.robot_file_check import FileCheck
from identification.calibration.rotors_apart import RotorsApart, judge_rotors_apart, unjudged_rotors
from identification.calibration.temperature_friction import temperature_block
from identification.calibration.trajectory_fit import (
    TrajectoryFit,
    TrajectoryOptions,
    identify_trajectories,
    torque_constants,
)
from identification.calibration.unstated_load import UnstatedLoads, take_unstated_loads
from identification.calibration.worse_joint_hold import (
    WorseJointHold,
    check_worse_joint_mode,
    hold_worse_joints,
)
from identification.calibration.written_model import ModelWriter
from identification.data.missing_torque import find_missing_torque
from psdm_casadi.state_cache import remembering

__all__ = ["IdentifyResult", "identify_recordings"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class IdentifyResult:
    """What :func:`identify_recordings` decided and found.

    Attributes
    ----------
    fit : TrajectoryFit
        The fit written (with a kept counterbalance: without its spring coefficients, which are findings of
        ``calibrated``; with LuGre friction: the Stribeck fit the LuGre block replaces).
    start : TrajectoryFit
        The fit before the counterbalance was tried (with LuGre friction, the Stribeck fit).
    calibrated : CalibratedModel
        The model file's document: ``identification.column_choice`` and ``identification.counterbalance`` say what
        was chosen and why.
    choice : ColumnChoice
        The drive columns and the Coulomb smoothing (``choice.smoothing``).
    options : TrajectoryOptions
        The options the fit used (the choice applied).
    counterbalance : CounterbalanceChoice
        What was decided about the counterbalance the envelope report named (empty: none named or not tried).
    lugre : object or None
        The LuGre fit (``lugre_recordings.LuGreFit``) with ``ColumnRequest(friction="lugre")``.
    file_check : FileCheck
        The model written against the robot file (its rigid body, friction fitted) on the held-out recordings, per
        joint with the never-worse margin (``robot_file_check``); not checked without held-out recordings.
    one_way : OneWayFriction
        The friction of the joints that move one way only in training: fitted, or held to the robot file's fit where
        the data do not determine it (``one_way_friction``).
    worse_joints : WorseJointHold
        What was done about the joints the robot-file check named worse: the links they carry held at the robot
        file's where that mends them (``worse_joint_hold``).
    payload : PayloadChoice
        What was decided about the payload the report named (``payload_route``: preferred to a spring explaining
        the same torque unless the spring is clearly better out of sample).
    drift : FrictionDrift
        Friction that changed between the training recordings (``drift_choice``): the joints named, the friction the
        model keeps, whether the fit saw each recording's own friction.
    rotors_apart : RotorsApart
        The rotors the training data want apart from their same actuator's: taken where the held-out data confirm it
        (``rotors_apart``), else held.
    unstated : UnstatedLoads
        The training recordings whose load no file states but the data show, identified as unknown payloads of their
        own (``unstated_load``).
    lugre_trial : LuGreTrial
        LuGre friction on default settings: the joints whose held-out residual lags at the velocity reversals, and
        whether the LuGre model tried there replaced the default one (``lugre_trial``).
    coupled : CoupledDrives
        The coupling terms of the robot file's coupled transmission: fitted before the worse-joint holds, and kept
        where out of sample they help, on the held-out recordings or the training blocks (``coupled_drives``).
    """

    fit: TrajectoryFit
    start: TrajectoryFit
    calibrated: CalibratedModel
    choice: ColumnChoice
    options: TrajectoryOptions
    counterbalance: CounterbalanceChoice = field(default_factory=CounterbalanceChoice)
    lugre: object = None
    file_check: FileCheck = field(default_factory=FileCheck)
    one_way: OneWayFriction = field(default_factory=OneWayFriction)
    worse_joints: WorseJointHold = field(default_factory=WorseJointHold)
    payload: PayloadChoice = field(default_factory=PayloadChoice)
    drift: FrictionDrift = field(default_factory=FrictionDrift)
    rotors_apart: RotorsApart = field(default_factory=RotorsApart)
    unstated: UnstatedLoads = field(default_factory=UnstatedLoads)
    lugre_trial: LuGreTrial = field(default_factory=LuGreTrial)
    coupled: CoupledDrives = field(default_factory=CoupledDrives)

    @property
    def pull(self) -> PriorPull | None:
        """The fit's pull towards the robot file (``prior_pull``; None without an envelope's note of it)."""
        note = dict(self.fit.envelope_bounds).get("prior")
        return None if note is None else PriorPull.from_note(note)

    @property
    def held_back(self) -> tuple:
        """The parameters the fit keeps away from the data's own estimate (``held_back.HeldBack``; empty: none)."""
        return stored_held_back(self.fit.envelope_bounds)

    @property
    def columns(self) -> list:
        """The drive columns chosen (``ColumnChoice.describe``) and the rotors the training data wanted apart from
        their same actuator's (``RotorsApart.describe``), one sentence each."""
        return [*self.choice.describe(), *self.rotors_apart.describe()]

    def describe(self) -> list:
        """One sentence per choice: the drive columns, the Coulomb smoothing, the counterbalance, the pull towards
        the robot file (stated here once, not by each consistent fit the choices ran), what the pull or the envelope
        holds back from the data (``held_back``), and whether the model is worse than the robot file on any joint of
        the held-out recordings."""
        lines = [f"unstated load: {self.unstated.describe()}"] if self.unstated.found else []
        lines += list(self.columns)
        if self.lugre_trial.describe():
            lines.append(self.lugre_trial.describe())
        if self.coupled.describe():
            lines.append(self.coupled.describe())
        if self.pull is not None:
            lines.append(self.pull.describe())
        lines.extend(f"held back from the data: {item.message}" for item in self.held_back)
        if self.counterbalance.reason:
            lines.append(f"counterbalance: {self.counterbalance.reason}")
        if self.payload.line:
            lines.append(self.payload.line)
        if self.drift.describe():
            lines.append(self.drift.describe())
        if self.one_way.describe():
            lines.append(self.one_way.describe())
        if self.worse_joints.describe():
            lines.append(self.worse_joints.describe())
        if self.file_check.comparison is not None or self.file_check.reason:
            lines.append(self.file_check.describe())
        return lines

    @property
    def warnings(self) -> tuple:
        """The warnings of the fit written, each once (and of the Stribeck fit a LuGre fit started from); a kept
        counterbalance's fit does not repeat what the fit without it warned about (the link it pushed)."""
        first = self.fit if self.counterbalance.kept else self.start
        return tuple(dict.fromkeys((*first.warnings, *self.fit.warnings)))


@remembering()  # the recordings' regressors evaluated once (state_cache)
def identify_recordings(
    robot,
    model,
    recordings,
    options: TrajectoryOptions | None = None,
    request: ColumnRequest | None = None,
    validation=(),
    configurations=None,
    *,
    counterbalance: bool = True,
    robot_source: str | None = None,
    paths=None,
    one_way: str = "auto",
    worse_joint: str = "hold",
    friction_drift: str = "auto",
    temperatures=None,
    held_configurations=None,
) -> IdentifyResult:
    """Identify a calibrated model from exciting recordings as ``psdm identify`` does (module docstring).

    Parameters
    ----------
    robot, model : RobotDescription, PSDMModel
    recordings : sequence of Recording
        The raw training recordings.
    options : TrajectoryOptions, optional
        Cutoff, consistency, envelope bounds; its drive columns are replaced by the choice, and its
        ``coulomb_velocity`` is the largest smoothing velocity the choice may take.
    request : ColumnRequest, optional
        ``"auto"`` (the data decide) for every column and the smoothing by default; explicit values are kept.
    validation : sequence of Recording
        Held-out raw recordings: they check the column choice and judge the counterbalance (without them, block
        cross-validations of the training recordings do).
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each training recording carries.
    counterbalance : bool
        Try the counterbalance the envelope report names (default); False only names it.
    robot_source : str, optional
        The robot file or built-in name the model file records (default ``robot.source``).
    paths : sequence of path, optional
        The training recordings' files, for the model file's provenance (their SHA-256).
    one_way : str
        The friction of joints that move one way only in training (``one_way_friction.ONE_WAY_MODES``): ``"auto"``
        holds it to the robot file's fit where the data do not determine it, ``"hold"`` wherever, ``"fit"`` nowhere.
    worse_joint : str
        The joints the robot-file check names worse (``worse_joint_hold.WORSE_JOINT_MODES``): ``"hold"`` the links
        they carry at the robot file's where that mends them, ``"report"`` name them only.
    friction_drift : str
        Friction that changed between the training recordings (``drift_choice.DRIFT_MODES``): ``"auto"`` names it and
        fits the rigid body beside each recording's own friction, keeping the friction the data choose; ``"report"``
        names it only; ``"off"`` does not check.
    temperatures : tuple, optional
        ``(per training recording, per held-out recording)`` the joints' mean temperatures [°C] the recordings log
        (``data.temperature.logged_temperatures``; None for one that logs none): a drift the temperature explains
        is read along it.
    held_configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each held-out recording states (``held_out_arm.held_out_configurations``): one that carries the
        training recordings' unknown payload, taken off as the fit estimates it, does not judge the robot file
        (``file_judged``).
    """
    check_one_way_mode(one_way)
    check_drift_mode(friction_drift)
    check_worse_joint_mode(worse_joint)
    options = TrajectoryOptions() if options is None else options
    request = ColumnRequest() if request is None else request
    recordings, validation = [find_missing_torque(r) for r in recordings], list(validation)  # marked for every fit
    configurations, unstated = _unstated_loads(robot, model, recordings, options, configurations)
    judged = file_judged(validation, held_configurations, configurations)  # what the robot file is judged on
    logger.info("identify: choosing the drive columns and the Coulomb smoothing from the data ...")
    choice = choose_columns(robot, model, recordings, options, request, validation, configurations)
    if request.friction != "lugre":  # each recording's own friction (``drift_choice``); the columns chosen again
        drifted = (robot, model, recordings, options, request, validation, configurations)
        recordings, drift, choice = _friction_drift(drifted, choice, friction_drift, temperatures)
    else:
        drift = FrictionDrift(mode=friction_drift)
    chosen = choice.options(options)
    lugre, held, mended, rotors = None, OneWayFriction(mode=one_way), WorseJointHold(mode=worse_joint), RotorsApart()
    source = robot.source if robot_source is None else robot_source

    def writer(lugre_fit=None, columns=None, drive_loss=()):  # a fit carried to its model file (``written_model``)
        saved = ({"robot_source": source, "lugre": lugre_fit, "configurations": configurations},
                 list(paths) if paths is not None else [None] * len(recordings))  # fmt: skip
        skip = lugre_fit is not None or bool(drive_loss) or not counterbalance  # routes that take no extra columns
        return ModelWriter((robot, model, recordings, configurations), validation, judged, saved, skip, drive_loss,
                           columns)  # fmt: skip

    given, trial, default = options, LuGreTrial(), None

    if request.friction == "lugre":
        from identification.calibration.lugre_identify import identify_lugre_trajectories

        found = identify_lugre_trajectories(robot, model, recordings, chosen, configurations=configurations)
        fit, lugre, start = found.fit, found.lugre, found.stribeck
        rotors, coupled = unjudged_rotors(fit, "LuGre"), not_on_route(robot, "on the LuGre route")
        written = writer(lugre, start)(chosen, fit)  # the file judged with the Stribeck columns LuGre starts from
    elif choice.loss_joints:  # currents with a gear loss (``drive_loss``)
        from identification.calibration.drive_loss import identify_with_drive_loss

        logger.info("identify: fitting the drive loss (gear efficiency by power-flow direction) ...")
        fit, *loss = identify_with_drive_loss(robot, model, recordings, chosen, choice.loss_joints, configurations)
        start, rotors = fit, unjudged_rotors(fit, "drive-loss")
        coupled = not_on_route(robot, "on the drive-loss route")
        written = writer(drive_loss=loss)(chosen, fit)
    else:
        choice, fit = _checked_fit(robot, model, recordings, options, choice, validation, configurations)
        fit, rotors = judge_rotors_apart((robot, model, recordings, choice.options(options), configurations), fit,
                                         validation)  # fmt: skip
        apart = tuple(sorted({*options.rotors_apart, *rotors.joints}))
        options = replace(options, rotors_apart=apart)  # every later fit takes them apart too
        problem, write = (robot, model, recordings, choice.options(options), configurations), writer()
        fit, held = _one_way(problem, fit, judged, one_way, write)
        chosen = held_options(problem[3], held.held, robot.n_dof) if held.held else problem[3]
        first, coupled = coupled_on_route(problem, write(chosen, fit), judged, source)  # before the holds
        carried = carrying(write, coupled, problem, judged, source)  # the holds' fits with the kept terms
        written, mended = _worse_joints(problem, first, judged, worse_joint, carried)
        held = held.replaced_by(mended.held_friction)  # one value per held column: the one in effect
        start = written.start
        if request.friction == "auto" and not drift.corrected and judged.recordings and robot.links is not None:
            trial, kept = try_lugre((robot, model, recordings, given, validation, configurations), written, judged,
                                    writer, request)  # fmt: skip
            if kept is not None:  # the LuGre model replaces the default one, and the default route's holds
                default, (found, written, choice) = written, kept
                lugre, start, rotors = found.lugre, found.stribeck, unjudged_rotors(found.fit, "LuGre")
                held, mended = OneWayFriction(mode=one_way), WorseJointHold(mode=worse_joint)
                coupled = not_on_route(robot, "on the LuGre route the trial chose")
    chosen, final, calibrated = written.options, written.fit, written.calibrated
    taken, payload = written.counterbalance, written.payload
    choice = replace(choice, replaced_offsets=taken.replaced_offsets)  # the model holds the spring there
    shapes = {"friction_shapes": list(calibrated.document["drive"]["friction_shapes"])} if lugre is not None else {}
    calibrated.document["identification"]["column_choice"] = {**choice.to_dict(), **shapes}  # LuGre: as written
    if rotors.verdicts:  # stated with the other column choices
        calibrated.document["identification"]["column_choice"]["rotors_apart"] = rotors.to_dict()
    check = _file_check(replace(written.check, held=held.held_joints, held_links=mended.held_links), trial, default)
    records = {"robot_file_check": check, "one_way_friction": held, "worse_joints": mended, "friction_drift": drift,
               "unstated_loads": unstated, "lugre_trial": trial, "coupled_drives": coupled}  # fmt: skip
    calibrated.document["identification"].update({key: value.to_dict() for key, value in records.items()})
    if (laws := temperature_block(drift, calibrated.document["drive"]["names"])) is not None:
        calibrated.document["drive"]["temperature"] = laws  # the kept friction's slopes in temperature
    return IdentifyResult(final, start, calibrated, choice, chosen, taken, lugre, check, held, mended, payload, drift,
                          rotors, unstated, trial, coupled)  # fmt: skip


def _file_check(check: FileCheck, trial: LuGreTrial, default) -> FileCheck:
    """The written model's ``check`` against the robot file; where the LuGre trial's model replaced the ``default``
    one (``written_model.WrittenModel``), each joint it does not predict better beyond their paired margin keeps the
    default model's verdict (``lugre_trial``'s rule, ``FileCheck.keeping_verdicts``)."""
    if not trial.kept:
        return check
    pooled = JointComparison(np.array(trial.before), np.array(trial.after), np.array(trial.margin))
    n_dof = len(trial.before)
    return check.keeping_verdicts(default.check, pooled, [j for j in range(n_dof) if j not in trial.better])


def _unstated_loads(robot, model, recordings, options, configurations) -> tuple:
    """``(configurations, UnstatedLoads)``: a training recording whose load no file states but the data show taken
    as an unknown payload of its own (``unstated_load``), found by one unconstrained fit of the options given."""

    def fit_of(trial):
        return identify_trajectories(robot, model, recordings, replace(options, consistency=False),
                                     configurations=trial)  # fmt: skip

    configurations, unstated = take_unstated_loads(fit_of, recordings, configurations)
    if unstated.found:
        logger.info("identify: %s", unstated.describe())
    return configurations, unstated


def _friction_drift(problem, choice, mode, temperatures) -> tuple:
    """``(training recordings, FrictionDrift, choice)``: the friction of each training recording with the shape
    ``choice`` takes (its least squares: only the shape is needed), compared (``drift_choice``); where a drift is
    named and fitted beside, the recordings with the drifting joints' torques moved to the kept friction and the
    columns chosen again on them (a drift mimics other columns: a load-dependent loss, an offset)."""
    robot, model, recordings, options, request, validation, configurations = problem
    if mode == "off" or len(recordings) < 2:
        return recordings, FrictionDrift(mode=mode), choice
    shaped = replace(choice.options(options), consistency=False)
    fit = identify_trajectories(robot, model, recordings, shaped, configurations=configurations)
    kt = torque_constants(robot, shaped, recordings)
    moved, drift = judge_friction_drift(robot, model, recordings, fit, validation, configurations, mode, kt,
                                        temperatures)  # fmt: skip
    if not drift.corrected:
        return recordings, drift, choice
    logger.info("identify: friction drift on joint(s) %s: the columns chosen again and fitted beside each recording's "
                "own friction ...", ", ".join(str(f.joint + 1) for f in drift.check.drifting))  # fmt: skip
    return moved, drift, choose_columns(robot, model, moved, options, request, validation, configurations)


def _refit(problem):
    """``refit(options) -> TrajectoryFit`` on the training recordings of ``problem`` (``(robot, model, recordings,
    options, configurations)``)."""
    robot, model, recordings, _, configurations = problem

    def refit(trial_options):
        return identify_trajectories(robot, model, recordings, trial_options, configurations=configurations)

    return refit


def _one_way(problem, fit, judged, mode, write) -> tuple:
    """``(fit, OneWayFriction)``: the undetermined friction of the joints that move one way only held to the robot
    file's fit where the held-out recordings (else none) say the data's own is worse (``one_way_friction``), judged on
    the model ``write(options, fit)`` makes of the fit (``written_model``). Beside payloads the file's friction is
    fitted on the training recordings without them (``file_judged.file_training``; where every training recording
    carries an unknown one there is none to fit it on, and the data's friction stays)."""
    from identification.calibration.column_candidates import prepare_training

    robot, _, recordings, options, configurations = problem
    beside = file_training(robot, recordings, options, configurations)  # the file's friction fitted without loads
    prepared = prepare_training(robot, recordings, options).prepared  # which joints move one way: every recording

    def judge(candidate):
        return write(options, candidate).check

    judge = judge if judged.recordings else None
    fit, record = hold_one_way_friction((*problem, _refit(problem)), fit, prepared, mode, judge, beside)
    if judged.reason and record.held and not record.decided_by_held_out:
        record = replace(record, reason=f"{record.reason} (the held-out recordings cannot judge it: {judged.reason})")
    return fit, record


def _worse_joints(problem, written, judged, mode, write) -> tuple:
    """``(WrittenModel, WorseJointHold)``: the links of the joints the robot-file check of the model identify writes
    (``written``, ``written_model``) names worse held to what the robot file predicts there where that mends them
    (``worse_joint_hold``), each fit tried carried to its model by ``write(options, fit)`` and judged there; not
    tried where the robot file cannot be judged (no held-out recording it is judged on, no links in it, every training
    recording with an unknown payload: ``file_judged``)."""
    robot, model, recordings, _, configurations = problem
    if not judged.recordings or robot.links is None:
        return written, WorseJointHold(mode=mode)
    prepared = file_training(robot, recordings, written.options, configurations)  # the file's friction without loads
    if not prepared:
        return written, WorseJointHold(mode=mode)
    refit = _refit(problem)

    def carried(trial_options):
        return write(trial_options, refit(trial_options))

    def friction_of(candidate, joints):
        return file_friction_values(robot, candidate.start, prepared, joints)

    kts = [torque_constants(robot, written.options, [r]) for r in judged.recordings]

    def compare(before, after):  # a step's model against the model before it, on each held-out recording
        return [compare_each(before.calibrated, after.calibrated, model, [r], kt)[0]
                for r, kt in zip(judged.recordings, kts)]  # fmt: skip

    lifted = lifted_links(robot, model=model)  # semi-definite in the file and free: held lifted, named
    problem = (carried, written.options, robot.n_dof)
    written, _, record = hold_worse_joints(problem, written, (_judge, compare), friction_of, mode, semidefinite=lifted)
    return written, record


def _judge(written) -> FileCheck:
    return written.check


def _checked_fit(robot, model, recordings, options, choice, validation, configurations) -> tuple:
    """(choice, fit): the consistent fit of ``choice``, each column the held-out data alone decided checked on it
    (``column_check``: on the held-out recordings, else by block cross-validation of the training recordings)."""

    def fit_of(columns):
        return identify_trajectories(robot, model, recordings, columns.options(options), configurations=configurations)

    fit = fit_of(choice)
    if not choice.departures:
        return choice, fit
    cutoffs = [c for c in fit.cutoff_hz if c]
    problem = (robot, model, recordings, options, configurations)
    judge = written_model_judge(problem, validation, min(cutoffs) if cutoffs else None)
    if isinstance(judge, str):
        logger.info("identify: the columns the held-out data alone decided are not checked on the model it writes: "
                    "%s", judge)  # fmt: skip
        return choice, fit
    logger.info("identify: checking the %d column(s) the held-out data alone decided on the model it writes ...",
                len(choice.departures))  # fmt: skip
    return check_departures(choice, fit, fit_of, judge, offset_sizes(problem))
