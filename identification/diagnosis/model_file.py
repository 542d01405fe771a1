"""Diagnose a calibrated model file (``psdm identify``'s JSON) as ``psdm diagnose MODEL.json`` does, from Python.

The nominal model is the file's: its robot, its identified inertia (``calibrated_robot``; the robot file's when identify
pushed links against their envelope for an absorbed effect, ``diagnosis_prior``, unless the diagnosis's model from
that rigid body, with the model's friction refitted and the findings added, predicts a joint of the validation
recording worse than the file as it is beyond the never-worse margin, ``robot_file_worse``: then the file's own, and
the report says why) and its friction per joint
(``file_friction``: the file's own columns, Coulomb + viscous or Stribeck with its vs, refitted; LuGre joints with
the diagnosis's LuGre columns at the file's values). The recordings are prepared as
the file says (``model_preparation``: its filter, cutoff and grid rate, and identify's samples with the file's edge
trim, one filter period in files of preparation version 1), so the report's "before" is the file's own validation
RMSE, the one ``psdm validate`` prints (``report_assembly.with_model_file_before``), and the report names the file
and the preparation it used. The friction identify held on joints that moved one way only in its training data
(``one_way_friction``) stays held at the file's values in every fit of the diagnosis
(``DiagnosisOptions.held_friction``), and so do the drive inertias the file fitted outside the base parameters
(its ``Ia<j>`` columns, ``file_held``): the diagnosis's nominal model predicts those joints as the file does, and its
refits (the rigid body recalibrated, freely or inside the envelope, the findings' joint fits) keep it, as ``diagnose
--apply``'s refit does (``recalibrate``); beside each such drive column a free one fits its value again with the
friction (``drive_columns``), as identify fits it: an effect the column absorbed (a torque ripple) is found with the
drive inertia it leaves, not beside the file's; and beside each torque offset identify chose from the data a free one
(``file_offsets``): an effect the offset absorbed is found without the offset's share, and a file's offset the data
move is reported as the file's value not holding (or moving between recordings), with its numbers. A rotor inertia
the diagnosis finds inside the file's base parameters is a change of them, not a finding (``base_change``). So does the
counterbalance identify took (``model_file_holds``): a column of the nominal model in every fit (``carried_terms``), its
coefficients fitted again, reported first among the findings as kept from identify, so that no rigid-body refit of the
diagnosis absorbs it into the links again; and the links identify held at the robot file's stay held in its rigid-body
recalibrations (``held_links``).
``psdm diagnose`` calls :func:`diagnose_model_prior`, so the Python API and the command give the same numbers.
"""

from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from identification.calibration.calibrated_model import LoadedModel, calibrated_robot, read_calibrated_model
from identification.calibration.coulomb_width import width_value
from identification.calibration.counterbalance_record import counterbalance_offsets
from identification.calibration.diagnosis_prior import carried_as, diagnosis_prior, with_file_rigid_body
from identification.calibration.finding_value import validation_rmse
from identification.calibration.findings import correct_recording
from identification.calibration.held_friction import HeldFriction, without_held_rotors
from identification.calibration.model_file_holds import model_file_holds
from identification.calibration.model_preparation import model_preparation
from identification.calibration.never_worse import JointComparison
from identification.calibration.refit_training import refit_training
from identification.data.filter_choice import AUTO
from identification.data.holdout import diagnose_parts, held_out_sentences, other_training_parts, training_part
from identification.data.layout import model_file_layout
from identification.data.robot_recordings import load_robot_recording
from identification.data.torque_constants import recording_kt
from identification.diagnosis.applied_after import with_applied_after
from identification.diagnosis.base_change import as_base_changes
from identification.diagnosis.candidates.base import SMOOTH_VELOCITY
from identification.diagnosis.carried_sizes import with_carried_sizes
from identification.diagnosis.carried_terms import KEPT_NOTE, carried_candidates
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.diagnosis.drive_columns import with_drive_columns, without_drive_columns
from identification.diagnosis.file_friction import FileFriction
from identification.diagnosis.file_offsets import with_file_offsets, with_offset_columns
from identification.diagnosis.motion_checks import training_recordings, validation_recordings
from identification.diagnosis.report import DiagnosisReport
from identification.diagnosis.report_assembly import with_model_file_before
from identification.paired_margin import paired_rmse_margin
from psdm_casadi.errors import ParameterError

__all__ = [
    "diagnose_model",
    "diagnose_model_prior",
    "file_corrected",
    "file_held",
    "file_refit",
    "file_prediction",
    "model_file_recordings",
    "model_file_options",
    "own_friction",
    "robot_file_worse",
]

logger = logging.getLogger(__name__)


def own_friction(calibrated) -> str:
    """The diagnosis' friction kind of a calibrated model's own shape (its drives carry vs or the LuGre values)."""
    shape = calibrated.document["drive"].get("friction_shape", "coulomb-viscous")
    return {"stribeck": "stribeck", "lugre": "lugre"}.get(shape, "coulomb_viscous")


def model_file_options(calibrated, options: DiagnosisOptions | None = None) -> DiagnosisOptions:
    """``options`` (default ``DiagnosisOptions()``) with what is left ``"auto"`` taken from the model file: its friction
    per joint (``DiagnosisOptions.file_friction``: the file's own columns on its steady-state joints), its cutoff and
    its grid rate (``model_preparation``); the samples are identify's unless stated, with the file's edge trim
    (``Preparation.edge_periods``); and the friction identify held (``one_way_friction``) and the file's torque offsets,
    which every fit of the diagnosis keeps at the file's values (``DiagnosisOptions.held_friction``, ``file_held``),
    unless ``options`` hold some; and the counterbalance identify took and the torque findings an earlier ``diagnose
    --apply`` wrote (``model_file_holds``), columns of the nominal model (``DiagnosisOptions.carried``,
    ``carried_terms``), unless ``options`` carry some; and the links identify held at the robot file's, held in every
    rigid-body recalibration of the diagnosis (``DiagnosisOptions.held_links``), unless ``options`` hold some; and the
    rotors identify took apart from the same actuator's (``DiagnosisOptions.rotors_apart``)."""
    options = DiagnosisOptions() if options is None else options
    if not isinstance(options, DiagnosisOptions):
        raise ParameterError(f"diagnose_model options must be a DiagnosisOptions; got {type(options).__name__}.")
    own = model_preparation(calibrated.document)
    cutoff = own.cutoff_hz if options.cutoff_hz == AUTO else options.cutoff_hz
    rate = options.rate_hz
    if rate == AUTO:
        rate = own.grid_rate_hz if options.cutoff_hz == AUTO else AUTO  # a stated cutoff: identify's grid for it
    own_shape = FileFriction.of_model(calibrated) if options.friction == AUTO else None  # the file's, per joint
    friction = own_shape.kind if own_shape is not None else options.friction
    held = options.held_friction if options.held_friction.values else file_held(calibrated.document)
    holds = model_file_holds(calibrated.document)
    carried = options.carried or carried_candidates(holds.torque_terms)
    smooth = options.coulomb_velocity
    shape = own_friction(calibrated) if own_shape is not None else friction  # a LuGre file's: as before
    if shape != "lugre" and smooth == SMOOTH_VELOCITY:  # the sign smoothed as the file predicts it
        smooth = width_value(calibrated.coulomb_widths)
    return replace(options, friction=friction, cutoff_hz=cutoff, rate_hz=rate, edge_periods=own.edge_periods,
                   held_friction=held, coulomb_velocity=smooth, carried=carried,
                   held_links=options.held_links or holds.held_links,
                   rotors_apart=options.rotors_apart or holds.rotors_apart, nominal="model file",
                   viscous_power=bool(calibrated.document["drive"].get("viscous_exponent")),
                   file_friction=options.file_friction or own_shape)  # fmt: skip


def file_held(document: dict) -> HeldFriction:
    """What the nominal model of ``diagnose MODEL`` holds at a model file's values (``HeldFriction.of_model_file``:
    with its drive columns ``Ia<j>``, which lie outside the base parameters, so that a rigid body the diagnosis
    recalibrates keeps them, ``held_friction.without_held_rotors``), but the torque offsets identify read as no
    sensor's and kept for want of a spring that held (``counterbalance_record``): the diagnosis judges and names that
    torque instead of carrying it silently."""
    return HeldFriction.of_model_file(document).without_offsets(counterbalance_offsets(document))


def diagnose_model(
    source,
    train,
    validation=None,
    options: DiagnosisOptions | None = None,
    derive=None,
    name: str | None = None,
    load=None,
) -> DiagnosisReport:
    """``diagnose`` with a calibrated model file as the nominal model (module docstring).

    Parameters
    ----------
    source : path or LoadedModel
        The calibrated-model file, or its ``read_calibrated_model`` (the file with its robot and PSDM model).
    train : Recording, path, or sequence of them
        The raw training recording(s), as for ``diagnose``; or its path: read with ``load`` and, when the model was
        identified with ``--holdout`` on it, cut where the model cut it (``data.holdout.diagnose_parts``, as ``psdm
        diagnose MODEL --train REC``), its held-out part a validation recording. Several paths (``psdm diagnose
        MODEL --train A B``): the diagnosis pools them (each cut as the first, ``holdout.training_part``;
        ``pooled_context``), and the refit with the findings (the report's "after") trains on them too
        (``refit_training``: the file's own recordings handed back, or new ones), with ``source`` a path.
    validation : Recording, sequence of Recording, or None
        Raw validation recordings. None (with ``train`` a path): the held-out parts the model file stores
        (``identification.holdout``), as ``psdm diagnose MODEL --train REC`` without ``--validate``.
    options : DiagnosisOptions, optional
        Fields left ``"auto"`` take the model file's values (``model_file_options``).
    derive : callable, optional
        ``derive(robot) -> PSDMModel`` for reading a path (the CLI's model cache).
    name : str, optional
        How the report names the file (default: the path, or the robot's name).
    load : callable, optional
        ``load(path) -> Recording`` for a ``train`` path and the stored parts (default: joint side, read as identify
        read the model's recordings, ``data.layout.model_file_layout``).

    Returns
    -------
    DiagnosisReport
        Whose ``nominal_model`` names the file, ``preparation`` its preparation, ``model_file_rmse`` the file's own
        validation RMSE on the first validation recording and, when the diagnosis judged the samples the file's
        preparation keeps, ``rmse_before`` that same RMSE (``before_is_model_file``); ``held_out`` the parts held
        out.

    Raises
    ------
    ParameterError
        No validation recording: ``validation`` None and no stored part (or ``train`` a recording, not its path);
        several ``train`` paths with ``source`` a ``LoadedModel`` (no file whose refit trains on them; several
        Recordings are pooled and the refit trains on them alone).
    """
    train, *more = train if isinstance(train, (list, tuple)) else (train,)
    if any(isinstance(p, (str, os.PathLike)) for p in more) and isinstance(source, LoadedModel):
        raise ParameterError(
            "diagnose_model: several train paths need source as the model file's path (its refit trains on them "
            "beside the file's own recordings); got a LoadedModel. Pass the path."
        )
    loaded = source if isinstance(source, LoadedModel) else read_calibrated_model(source, derive=derive)
    if name is None and not isinstance(source, LoadedModel):
        name = str(source)
    path, explicit = (str(train) if isinstance(train, (str, os.PathLike)) else None), validation is not None
    train, validation, held_out = model_file_recordings(loaded, train, validation, load, name or "the model file")
    refit, trains = None, [train] if path is not None else [train, *more]  # recordings given: pooled as given
    if path is not None and not isinstance(source, LoadedModel):  # on disk: the refit finds the file's own too
        reader, document = load or _reader(loaded), loaded.calibrated.document  # the others cut as the command cuts
        more, parts = other_training_parts([(str(p), reader(p)) for p in more], document, None, explicit,
                                           name or "the model file")  # fmt: skip
        validation = [*validation, *(part for _, part, _ in parts)]
        held_out = (*held_out, *(f"validation: {cut.describe()}" for _, _, cut in parts))
        trains += [training_part(entry, document, name or "the model file") for entry in more]  # pooled (diagnose)
        refit = file_refit(loaded, source, train, path, load, more)
    report = diagnose_model_prior(loaded, trains, validation, options, name, refit)[0]
    return replace(report, held_out=held_out) if held_out else report


def model_file_recordings(loaded: LoadedModel, train, validation, load=None, name: str = "the model file") -> tuple:
    """``(training recording, validation recordings, the report's sentences on the parts held out)`` of
    ``diagnose_model``: a ``train`` path read and cut as the model cut it, the stored parts after ``validation``
    (``data.holdout.diagnose_parts`` and ``held_out_sentences``, the command's own code); a ``train`` recording as
    given."""
    if not isinstance(train, (str, os.PathLike)):
        if validation is None:
            raise ParameterError(
                "diagnose_model: validation is missing and train is a Recording, so the held-out part the model file "
                "stores cannot be found (it is recognised by the recording file's content). Pass train as the path "
                "of the training recording (diagnose_model(MODEL, 'run.csv')), or validation=[recording, ...]."
            )
        return train, validation, ()
    load = load or _reader(loaded)
    given = [] if validation is None else validation_recordings(validation)
    path = str(train)
    train, held = diagnose_parts(path, load(path), loaded.calibrated.document, None, load, bool(given), name)
    validations = [*given, *(recording for _, recording, _ in held)]
    if not validations:
        raise ParameterError(
            f"diagnose_model: validation is missing and {name} stores no held-out part of {path} (identified without "
            "--holdout, or on another recording): the diagnosis keeps a finding only if it predicts a recording it "
            "was not fitted on. Pass validation=[recording, ...], or identify with --holdout 0.3."
        )
    return train, validations, held_out_sentences(path, held)


def _reader(loaded: LoadedModel):
    """``load(path)``: a recording read joint side as identify read the model's (``data.layout.model_file_layout``)."""
    robot = calibrated_robot(loaded.calibrated, loaded.robot)
    layout = model_file_layout(loaded.calibrated.document)
    return lambda path: load_robot_recording(path, robot, None, layout)


def file_refit(loaded: LoadedModel, model_path, train, train_path, load=None, more=()):
    """``refit()`` of ``applied_after.with_applied_after`` for the model file ``loaded`` read from ``model_path``: its
    own training recordings found again and read with ``load`` (default: as identify read them), their loads taken
    off, the raw ``train`` recording read from ``train_path`` and the other ``--train`` recordings ``more`` (``(path,
    raw recording)``), a recording the file does not list fitted beside the model where identify corrected a friction
    drift (``refit_training``); called only when a finding is to be applied."""
    calibrated = loaded.calibrated
    robot, cutoff = calibrated_robot(calibrated, loaded.robot), model_preparation(calibrated.document).cutoff_hz
    load = load or _reader(loaded)

    def predict(recording):
        kt = recording_kt(robot, recording)
        return calibrated.predict_recording(loaded.model, recording, kt)

    return lambda: refit_training(calibrated.document, model_path, train, train_path, load, robot, cutoff, more,
                                  predict)  # fmt: skip


def diagnose_model_prior(loaded: LoadedModel, train, validation, given=None, name=None, refit=None) -> tuple:
    """``(report, DiagnosisPrior)``: ``diagnose_model`` of the read file ``loaded`` with the rigid-body choice it made
    (the CLI prints its note). The robot file's rigid body (``diagnosis_prior``) is kept only if the diagnosis's
    model from it (the model's friction refitted, with the findings: the effect the file's rigid body absorbed is
    found again) predicts no joint of the first validation recording worse than the model file as it is beyond the
    never-worse margin (``robot_file_worse``); its findings would otherwise only repair a nominal worse than the model
    the user has. Then the diagnosis runs again from the model file's
    rigid body and the choice says why (``DiagnosisPrior.declining``): a finding's "before" is the nominal it used.
    ``train``: the training recording, or several, pooled (``diagnose``). ``refit``: the recordings the model with the
    findings trains on (``file_refit``; None: ``train`` alone)."""
    calibrated, robot_file, model = loaded.calibrated, loaded.robot, loaded.model
    train = training_recordings(train)
    options = model_file_options(calibrated, given)
    robot, prior = calibrated_robot(calibrated, robot_file), diagnosis_prior(calibrated.document, robot_file)
    held_out = validation_recordings(validation)
    first = held_out[0]
    raw, (train, validation) = train, (file_corrected(loaded, r) for r in (train, held_out))
    report = None
    if prior.robot_file:  # identify's rigid body absorbed an effect: try the robot file's (its rotors too)
        logger.info(f"diagnose: {prior.first_pass()}")
        kept = replace(options.held_friction, values=tuple((n, v) for n, v in options.held_friction.values
                                                           if not (n.startswith("Ia") and v >= 0.0)))  # fmt: skip
        own = with_offset_columns(replace(options, held_friction=kept, nominal="robot file"), calibrated.document)
        report = diagnose(with_file_rigid_body(robot, robot_file), train, validation, own, model=model)
        report = with_file_offsets(report, calibrated.document, options.min_improvement)
        worse = robot_file_worse(report, file_prediction(loaded, first))
        if worse:
            prior, report = prior.declining(worse), None
            logger.info(f"diagnose: {prior.second_pass()}")
        logger.debug(f"diagnose: {prior.note()}")  # the report says it (rigid_body_notes); the CLI prints it
    if report is None:  # the file's drive columns held, not rotors a recalibrated rigid body drops (file_held), and
        # fitted again beside the findings (``drive_columns``)
        own = with_offset_columns(with_drive_columns(options, calibrated.document), calibrated.document)
        report = diagnose(without_held_rotors(robot, options.held_friction), train, validation, own, model=model)
        report = without_drive_columns(report, calibrated.document)
        report = as_base_changes(with_file_offsets(report, calibrated.document, own.min_improvement), robot, model)
    report = with_carried_sizes(report, loaded, held_out)  # a carried finding's size read against the file's (raw)
    report = with_applied_after(report, loaded, raw, first, refit)  # the model --apply writes: its "after" (raw: the
    # refit corrects them as the file says)
    name = f"for {robot_file.name}" if name is None else name
    own = model_preparation(calibrated.document)
    preparation = own if (given is None or given.cutoff_hz == AUTO) else None
    return file_before(report, loaded, first, name, (preparation, prior)), prior


def file_corrected(loaded: LoadedModel, recordings) -> tuple:
    """``recordings`` with the model file's measurement corrections applied (its signal findings: a delay, an encoder
    before a compliance or a play; ``findings.correct_recording``), as ``psdm validate`` and ``--apply``'s refit apply
    them: the diagnosis's nominal model sees the recordings as the file does, and does not find them again (a
    correction of its size left is found as the same effect, beside the file's)."""
    corrections = loaded.calibrated.corrections
    if not corrections:
        return tuple(recordings)
    return tuple(correct_recording(r, corrections, recording_kt(loaded.robot, r)) for r in recordings)


def file_prediction(loaded: LoadedModel, validation) -> tuple:
    """``(RMSE per joint, prepared recording, prediction)`` of the model file as it is on the raw ``validation``
    recording, prepared as the file says (``finding_value.validation_rmse``, as ``psdm validate``)."""
    robot = loaded.robot
    kt = recording_kt(robot, validation)
    own, _, prepared, predicted = validation_rmse(loaded.calibrated, loaded.model, validation, kt)
    return own, prepared, predicted


def robot_file_worse(report, file_fit) -> str:
    """The joints (a sentence with their numbers; empty: none) on which the diagnosis's model of ``report`` (its
    nominal with the findings, before ``file_before``: ``validation_final``) predicts the validation samples worse
    than the model file as it is (``file_fit``, ``file_prediction``) by more than the never-worse margin:
    ``MARGIN_SIGMAS`` standard errors of the paired RMSE difference, at least ``MARGIN_FLOOR`` of the file's RMSE
    (``JointComparison.from_noise``).
    Empty as well when the two were not judged on the same samples (nothing to compare: the choice stays)."""
    _, prepared, predicted = file_fit
    t, tau, predicted = (np.asarray(x, dtype=float) for x in (prepared.t, prepared.tau, predicted))
    own_t, own_tau = np.asarray(report.validation_t), np.asarray(report.validation_tau)
    nominal = np.asarray(report.validation_final, dtype=float)
    if own_t.shape != t.shape or own_tau.shape != tau.shape or nominal.shape != tau.shape:
        return ""
    if not np.allclose(own_t, t, rtol=0.0, atol=1e-9):
        return ""
    measured = np.flatnonzero(np.all(np.isfinite(tau), axis=0) & np.all(np.isfinite(nominal), axis=0))
    file_residual, nominal_residual = tau[:, measured] - predicted[:, measured], tau[:, measured] - nominal[:, measured]
    before, after, se = paired_rmse_margin(file_residual, nominal_residual)
    comparison = JointComparison.from_noise(before, after, se)
    return "; ".join(f"joint {measured[j] + 1} {comparison.before[j]:.3g} -> {comparison.after[j]:.3g} N m, margin "
                     f"{comparison.margin[j]:.2g}" for j in comparison.worse)  # fmt: skip


def file_before(report, loaded: LoadedModel, validation, name: str, choices=(None, None)) -> DiagnosisReport:
    """The report naming the model file it started from (and, with ``choices`` = (its ``Preparation``, its
    ``DiagnosisPrior``), the preparation and why the rigid body came from the robot file), with the file's own
    validation RMSE as its "before" when the diagnosis judged the samples the file's preparation keeps (else beside
    it, ``model_file_rmse``), and the findings the file already holds named."""
    calibrated = loaded.calibrated
    preparation, prior = choices
    path = Path(name)
    digest = f"sha256 {hashlib.sha256(path.read_bytes()).hexdigest()[:12]}..., " if path.is_file() else ""
    created = calibrated.document.get("provenance", {}).get("created", "unknown")
    kept = (prior.sentence() if prior is not None else "") or "as identified in it"
    nominal = (f"the calibrated model file {name} ({digest}created {created}): rigid body "
               f"{kept if report.rigid_body == 'prior' else 'identified again on the training recording'}")  # fmt: skip
    notes = tuple(n for n in ((prior.note() if prior is not None else ""), _carried(report, calibrated)) if n)
    report = replace(report, rigid_body_notes=notes + tuple(report.rigid_body_notes))
    own, prepared, predicted = file_prediction(loaded, validation)
    text = report.preparation if preparation is None else preparation.text()
    report = replace(report, nominal_model=nominal, preparation=text,
                     model_file_rmse=tuple(float(v) for v in np.atleast_1d(own)))  # fmt: skip
    # one "before": the file as it is, when the diagnosis judged the samples the file's preparation keeps
    return with_model_file_before(report, prepared.t, prepared.tau, predicted) or report


def _carried(report, calibrated) -> str:
    """The sentences naming the findings the model file already holds: its torque findings (the counterbalance
    identify took, those an earlier ``diagnose --apply`` wrote), kept in the nominal model with their coefficients
    fitted again (``carried_terms``); the diagnosis's findings of the same torque as one of them on its joint (a
    spring found as a ripple), found beside it; its measurement corrections, applied to the recordings."""
    kept = {f.label: f for f in report.findings if f.shape_note == KEPT_NOTE}
    holds = model_file_holds(calibrated.document)
    entries = {e.get("label"): e for e in holds.torque_findings}
    pairs = [(x, held) for x, held in carried_as(report.findings, calibrated.document) if x not in kept]
    sentences = []
    if kept:
        sizes = "; ".join(_refit_size(label, kept[label], entries.get(label)) for label in kept)
        sentences.append(f"the model file's findings are kept from {holds.taken_by} ({sizes}): columns of the "
                         "diagnosis's nominal model in every fit, so none is found again and no rigid-body refit "
                         "absorbs it")  # fmt: skip
    if pairs:
        named = ", ".join(f"`{x}`" if x == held else f"`{held}` (found beside it as `{x}`)" for x, held in pairs)
        sentences.append(f"the model file already carries {named}, identified with it: a finding of the same torque "
                         "beside the file's may split it (--apply keeps the file's where it would)")  # fmt: skip
    if calibrated.corrections:
        named = ", ".join(f"`{label}`" for label in calibrated.corrections)
        sentences.append(f"the model file's measurement corrections ({named}) are applied to the recordings as the "
                         "file applies them (file_corrected), so they are not found again")  # fmt: skip
    return "; ".join(sentences)


def _refit_size(label: str, finding, entry) -> str:
    """ "`spring[j2]`: k = -3330 in the file, -3290 fitted again" (the first of the file's entry's parameters the
    diagnosis's refit states: a spring's mean stiffness, a ripple's amplitude, a coupling's viscous coefficient)."""
    stated = (entry or {}).get("parameters") or {}
    name = next((n for n in stated if n in finding.parameters), None)
    name = name or next((n for n in ("k", "amplitude", "viscous") if n in finding.parameters), None)
    if name is None:
        return f"`{label}`"
    value = float(finding.parameters[name])
    if name not in stated:
        return f"`{label}`: {name} = {value:.4g} fitted again"
    return f"`{label}`: {name} = {float(stated[name]):.4g} in the file, {value:.4g} fitted again"
