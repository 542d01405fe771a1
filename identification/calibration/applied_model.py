"""The model with a diagnosis's findings: the one builder of the diagnosis's "after" and of ``diagnose --apply``.

calibrated model + findings of a ``DiagnosisReport`` + training and validation recordings -> ``AppliedModel`` (the
calibrated model with the findings, its fit, the findings it holds, the ones it dropped).

``diagnose MODEL`` reports as its "after" the validation RMSE of this model, as ``psdm validate`` computes it
(``diagnosis.applied_after``), and ``diagnose MODEL --apply`` hands this same model to the never-worse gate
(``recalibrate``), which writes it or a refit of it without the findings it drops: a report's "after" is the model a
file holds, never a second fit of the findings built another way (the diagnosis's own linear fit holds the rigid body,
refits the friction without bounds and adds terms no model file can hold, such as a pre-sliding friction).

A missing effect corrupts the identification it hides in: a spring on a joint is absorbed into the gravity parameters
and the friction, a missing drive inertia into the link inertias. Adding the finding afterwards, with the corrupted
parameters kept, leaves them wrong. So the recordings-route fit (``trajectory_fit.identify_trajectories``) is run again
on the training recordings (the model file's own, found again, and the diagnosis's: ``refit_training``; trained on
the diagnosis's alone, the refit forgot what the others taught) with one more linear column per feature of every
torque-type finding (``findings.FindingColumns``), all fitted jointly and with their standard deviations from the
same covariance, with the file's own options (``refit_options``: its friction terms and Stribeck joints, offsets,
drive-inertia columns, held friction and held links, preparation); the ``signal`` findings correct the recordings
first (``findings.correct_recording``); a payload (``rigid_body``) is taken up by the rigid body, held to the robot file
carrying it (``carried_payload``). A feature the other columns span (a spring's constant beside a drive offset, a rotor
inertia the fit identifies: ``absorbed_features``) is left out and reported as absorbed. Load-dependent friction is
linear in its coefficient for a fixed torque: the model's own, then the new one's.

A model with LuGre friction (file version 3) is identified again as ``psdm identify --friction lugre`` does
(``lugre_identify.identify_lugre_trajectories``) with the finding columns in every linear fit; load-dependent friction
is refused for it (``psdm_inverse_dynamics`` does not hold the LuGre part).

A finding is kept only if it lowers the validation RMSE of every joint it names: one whose removal (no refit) does not
raise them is dropped, listed with its RMSE pair (``AppliedModel.dropped``), and the model is refitted without it; a
new finding that splits the torque of one the file carries (``split_torque``), or of the counterbalance it carries as
its torque offset (``offset_split``: the balancer's shape, found beside that offset), is dropped likewise (or replaces
the carried one, where it alone describes the torque better; or, a shape with which the offset predicts its joint
better, is written with the offset as one counterbalance finding, ``counterbalance_finding``), and so is a finding of
zero size (``zero_size``: a torque offset the file's own offset on its joint absorbed), which the file would hold as
0 N m beside the offset that carries its torque.

The refit keeps the file's friction shape: its Stribeck velocities are held (``TrajectoryOptions.stribeck_held``), not
searched again beside the findings, as the diagnosis judged them against that shape (and a smooth Coulomb finding and a
Stribeck hump searched together trade against each other). Friction stays bounded below by 0, as identify fits it:
where the diagnosis's own fit (unbounded) let a Coulomb friction go negative beside a smooth Coulomb finding, the model
with the finding is the bounded one, and the report's "after" says what that model predicts.
"""

from __future__ import annotations

import copy
import dataclasses
import logging

import numpy as np

from identification.calibration.absorbed_features import absorbed_mask
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.carried_payload import carrying_payloads
from identification.calibration.coulomb_width import joint_width, width_value
from identification.calibration.counterbalance_finding import combined_findings, versioned
from identification.calibration.envelope_report import with_concrete_route
from identification.calibration.finding_value import implausibility, unhelpful_findings
from identification.calibration.findings import (
    SPEC_EFFECTS,
    FindingColumns,
    FindingTerm,
    correct_recording,
    filled_entries,
    finding_kind,
    held_findings,
    offsets_left_to_findings,
)
from identification.calibration.held_friction import HeldFriction
from identification.calibration.lugre_identify import identify_lugre_trajectories
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.mixed_friction import file_viscous_exponents, mixed_options, steady_columns
from identification.calibration.model_file_holds import model_file_holds
from identification.calibration.model_preparation import model_preparation
from identification.calibration.offset_split import offset_splits, replaced_offsets, without_offset
from identification.calibration.recording_provenance import recording_provenance
from identification.calibration.resized_findings import held_entries, resized_model
from identification.calibration.split_torque import splitting_findings
from identification.calibration.spring_rest import with_rest_angles
from identification.calibration.trajectory_data import stribeck_joints
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.torque_constants import recording_kt
from psdm_casadi.errors import ParameterError, SolverError

__all__ = ["AppliedModel", "applied_model", "check_lugre_findings", "finding_terms", "joint_fit", "new_labels",
           "offset_left_out", "refit_options", "refit_without", "zero_size"]  # fmt: skip

logger = logging.getLogger(__name__)

#: Rounds of dropping the findings that do not help and refitting (a refit can make another one useless).
MAX_DROP_ROUNDS = 3


@dataclasses.dataclass(frozen=True, eq=False)
class AppliedModel:
    """The calibrated model with a diagnosis's findings (module docstring).

    Attributes
    ----------
    after : CalibratedModel
        The model with the findings it kept.
    fit : TrajectoryFit
        Its joint fit on the training recordings.
    findings : tuple
        (torque ``FindingTerm``s, corrections, entries) of the findings ``after`` holds.
    dropped : tuple of dict
        The findings dropped (a carried finding's torque split, no help on validation), each with its reason.
    train : tuple of Recording
        The raw recordings it was fitted on (``refit_training``: the model file's own and the diagnosis's), which the
        never-worse gate's refits train on too.
    resized : CalibratedModel or None
        With carried findings held at a new size (``applied_model``'s ``held``): the model file with those sizes in
        place and nothing refitted (``resized_findings.resized_model``), the model written where the gates leave no
        new finding (``recalibrate``); None otherwise.
    """

    after: CalibratedModel
    fit: object
    findings: tuple
    dropped: tuple = ()
    train: tuple = ()
    resized: CalibratedModel | None = None


def applied_model(calibrated: CalibratedModel, robot, model, report, train, validation, robot_source=None,
                  held=None):  # fmt: skip
    """The ``AppliedModel`` of ``report``'s findings on ``calibrated`` (module docstring).

    ``robot`` and ``model`` are ``calibrated.load_robot()`` and its derived model; ``train`` and ``validation`` raw
    recordings (or sequences of them) as given to the diagnosis; ``robot_source`` the robot file written into the new
    model (default: the file's own copy). ``held``: ``{label: (coefficients, record)}`` of carried findings whose size
    the diagnosis read as changed (``carried_sizes``), held at it in every refit rather than fitted on the file's
    recordings too (``resized_findings.held_entries``); where no new finding is left after the drops, the model is
    the file with those sizes alone (``AppliedModel.resized``, nothing refitted).

    Raises
    ------
    ParameterError
        When the report has no finding, or findings a LuGre model cannot hold.
    """
    if not report.findings:
        raise ParameterError(
            "recalibrate report.findings is empty: the diagnosis found nothing to apply. "
            "Use the calibrated model as it is."
        )
    train = [train] if not isinstance(train, (list, tuple)) else list(train)
    validation = [validation] if not isinstance(validation, (list, tuple)) else list(validation)
    terms, corrections, entries = finding_terms(calibrated, report)
    terms, entries = held_entries(terms, entries, held)
    check_lugre_findings(calibrated, terms)
    kt = recording_kt(robot, *validation)
    after, fit, terms, entries = _robust_fit(
        calibrated, robot, model, train, (terms, corrections, entries), robot_source
    )
    dropped = []
    for _ in range(MAX_DROP_ROUNDS):  # kept only with a torque of its own, lowering the validation RMSE where it acts
        refit = refit_without(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
        alone = offset_left_out(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
        recordings, constants = (train, validation), (recording_kt(robot, *train), kt)
        unhelpful = splitting_findings(calibrated, after, refit, model, recordings, constants)
        unhelpful = unhelpful or offset_splits(calibrated, after, refit, alone, model, recordings, constants)
        unhelpful = unhelpful or zero_size(after) or unhelpful_findings(after, model, validation, kt)
        if not unhelpful:
            break
        if any(d.get("combined") for d in unhelpful):  # an offset and its shape written as one counterbalance
            (terms, corrections, entries), held = combined_findings((terms, corrections, entries), unhelpful)
            dropped += held  # a torque-offset finding on its joint: the counterbalance's constant holds it
            after, fit = joint_fit(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
            continue
        dropped += unhelpful
        calibrated = replaced_offsets(calibrated, unhelpful)  # an offset a shape replaced: its column left out
        labels = {d["label"] for d in unhelpful}
        logger.info("recalibrate: dropped findings (a carried finding's torque split, or no help on validation): %s; "
                    "refitting", sorted(labels))  # fmt: skip
        terms = [t for t in terms if t.label not in labels]
        corrections = {k: v for k, v in corrections.items() if k not in labels}
        entries = [e for e in entries if e["label"] not in labels]
        after, fit = joint_fit(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
    resized = resized_model(calibrated, held) if held else None
    if resized is not None and not new_labels(calibrated, entries):  # the gates left the resize alone: nothing refitted
        findings = ([t for t, _ in resized.torque_findings], resized.corrections, resized.document["findings"])
        return AppliedModel(resized, None, findings, tuple(dropped), tuple(train), resized)
    return AppliedModel(after, fit, (terms, corrections, entries), tuple(dropped), tuple(train), resized)


def new_labels(calibrated: CalibratedModel, entries) -> set:
    """The labels of the findings ``entries`` (a refit's) that the model file ``calibrated`` does not hold."""
    return {e["label"] for e in entries} - {e.get("label") for e in calibrated.document.get("findings") or []}


def _pairs(report):
    """(Finding, candidate term or None, coefficients) of a diagnosis report, matched by label, in report order."""
    augmented = report.augmented
    terms = {} if augmented is None else {t.label: (t, c) for t, c in zip(augmented.terms, augmented.coefficients)}
    return [(f, *terms.get(f.label, (None, tuple(f.coefficients)))) for f in report.findings]


def zero_size(after: CalibratedModel) -> list:
    """The torque offsets among ``after``'s findings whose one feature the model's own offset on that joint absorbed
    (``absorbed_features``): a finding of zero size, which the file would hold as ``torque_offset[jJ]`` = 0 N m beside
    the offset that carries its torque; dropped with the reason, never written."""
    return [
        {"label": e["label"], "effect": e["effect"], "joints": list(e["joints"] or []),
         "reason": "a finding of zero size: the model's own torque offset on its joint holds its torque (absorbed)"}
        for e in after.document["findings"]
        if e.get("kind") == "torque" and (e.get("term") or {}).get("effect") == "torque_offset"
        and e.get("coefficients") and all(c is None for c in e["coefficients"])
    ]  # fmt: skip


def finding_terms(calibrated: CalibratedModel, report) -> tuple:
    """(torque FindingTerms, corrections, entries of every finding) from the report, merged with the file's own."""
    widths = calibrated.coulomb_widths
    existing = [entry for entry in calibrated.document.get("findings") or []]
    terms = [term for term, _ in calibrated.torque_findings]
    corrections = calibrated.corrections
    entries = [copy.deepcopy(entry) for entry in existing]
    labels = {entry["label"] for entry in existing}
    for finding, candidate, coefficients in _pairs(report):
        if finding.label in labels:
            continue
        kind = finding_kind(candidate.key) if candidate is not None else "reported"  # a counterbalance: its term's
        entry = {
            "effect": finding.effect,
            "label": finding.label,
            "kind": kind,
            "joints": [j + 1 for j in finding.joints],
            "diagnosis": {
                "feature_names": list(finding.feature_names),
                "coefficients": [float(c) for c in coefficients],
                "parameters": {k: float(v) for k, v in finding.parameters.items()},
                "rmse_before": list(finding.rmse_before),
                "rmse_after": list(finding.rmse_after),
            },
        }
        if kind == "torque":
            term = FindingTerm(
                effect=candidate.key,
                joint=int(candidate.joint),
                source=getattr(candidate, "source", None),
                harmonic=getattr(candidate, "harmonic", None),
                velocity=joint_width(widths, int(candidate.joint)),
                spec=candidate.spec() if candidate.key in SPEC_EFFECTS else None,
            )
            entry["term"] = term.to_dict()
            terms.append(term)
        elif kind == "signal":
            corrections[finding.label] = _correction(finding, candidate)
        entries.append(entry)
    return terms, corrections, entries


def _correction(finding, candidate) -> dict:
    """The ``corrections`` entry of a signal finding (``findings.correct_recording``)."""
    entry = {"effect": finding.effect, **{k: float(v) for k, v in finding.parameters.items()}}
    if candidate.joint is not None:
        entry["joint"] = int(candidate.joint) + 1
    if finding.effect == "joint_elasticity" and "compliance_rad_per_Nm" not in entry:
        entry["compliance_rad_per_Nm"] = 1.0 / entry["stiffness_Nm_per_rad"]
    if finding.effect == "backlash" and "torque_scale_Nm" not in entry:
        raise ParameterError(
            f"recalibrate: the backlash finding {finding.label} has no flank torque scale (torque_scale_Nm); run the "
            "diagnosis with its refinement on (DiagnosisOptions.refine=True)."
        )
    return entry


def check_lugre_findings(calibrated: CalibratedModel, terms) -> None:
    """Refuse the findings a LuGre model cannot hold (module docstring), naming them and the way out."""
    if calibrated.lugre_parameters is None:
        return
    refused = sorted(t.label for t in terms if t.load_dependent)
    if refused:
        raise ParameterError(
            f"recalibrate: a model with LuGre friction (drive.lugre) does not take the findings {refused}: "
            "load-dependent friction (a multiple of the model's own torque, whose LuGre part the exported "
            "psdm_inverse_dynamics does not hold) is not supported for LuGre models. Identify the robot with "
            "--friction stribeck and apply the findings to that model, or use this diagnosis without --apply."
        )


def refit_options(calibrated: CalibratedModel) -> TrajectoryOptions:
    """The recordings-route options the file was identified with (for LuGre: of the Stribeck fit it starts from)."""
    document, own = calibrated.document, model_preparation(calibrated.document)  # a refit keeps its file's preparation
    drive, identification = document["drive"], document["identification"]
    friction, lugre = tuple(drive["friction_terms"]), calibrated.lugre_parameters
    if lugre is not None and not steady_columns(drive):  # LuGre on every joint
        friction = ("fc", "fs", "fv", *(term for term in friction if term == "offset"))
    options = TrajectoryOptions(
        friction=friction,
        coulomb_velocity=width_value(calibrated.coulomb_widths),
        drive_inertia=bool(identification.get("drive_inertia", True)),
        consistency=bool(document["standard"].get("checked", True)),
        cutoff_hz=own.cutoff_hz,
        edge_periods=own.edge_periods,
        offset_joints=_offset_joints(identification),
        inertia_joints=tuple(j - 1 for j in drive.get("inertia_joints", [])),
        stribeck_joints=stribeck_joints(friction, drive.get("stribeck_velocity")),  # none stored for LuGre: None
        viscous_exponent=file_viscous_exponents(drive, lugre),  # the file's viscous power law, its LuGre joints' too
        held_friction=HeldFriction.of_document(document).values,  # as identified
        held_links=model_file_holds(document).held_links,  # as identified (``worse_joint_hold``)
        rotors_apart=model_file_holds(document).rotors_apart,  # as identified (``rotors_apart``)
        stribeck_held=_held_stribeck(calibrated, friction),  # the file's shape, as the diagnosis judged against it
    )
    if lugre is None or not steady_columns(drive):
        return options
    joints = [j for j, p in enumerate(lugre) if p is not None]  # a mixed model: its refits' options (mixed_friction)
    return mixed_options(options, joints, drive.get("stribeck_velocity") or [0.0] * len(lugre))


def _held_stribeck(calibrated: CalibratedModel, friction) -> tuple | None:
    """The file's Stribeck velocities (``TrajectoryOptions.stribeck_held``): a refit with findings keeps the shape the
    diagnosis judged them against, the file's (``DiagnosisOptions.friction`` ``"stribeck"``: its vs), rather than
    searching it again beside them (a smooth Coulomb finding and a Stribeck hump trade against each other). None for a
    LuGre file (its own route) or a file without them."""
    stored, drive = calibrated.document["drive"].get("stribeck_velocity"), calibrated.document["drive"]
    if (calibrated.lugre_parameters is not None and not steady_columns(drive)) or "fs" not in friction or not stored:
        return None
    return tuple(float(v) for v in stored)


def _offset_joints(identification):
    """The joints (0-based) of the file's chosen offsets (``column_choice``); None (every joint) in older files."""
    choice = identification.get("column_choice") or {}
    on = choice.get("request", {}).get("offset", "on") == "on"
    return None if on else tuple(j - 1 for j in choice["offset_joints"])


def _fit(robot, model, recordings, options, terms, reference, stribeck=None, lugre=None, held=()):
    """One joint fit with the finding columns, of the LuGre identification with ``lugre`` (the file's LuGre parameters
    per joint: a mixed model's refit fits LuGre on its LuGre joints, ``mixed_friction``); returns (fit, columns,
    ``lugre_recordings.LuGreFit`` or None). A feature is left out when it is absorbed beside the Stribeck shape; the
    findings ``held`` at their coefficients (``FindingColumns.held``) are no columns, their torque taken off."""
    columns = FindingColumns(tuple(terms), reference, held=tuple(held))
    if terms:
        keep = absorbed_mask(robot, model, recordings, options, columns, stribeck, recording_kt(robot, *recordings))
        columns = dataclasses.replace(columns, keep=keep)
    extra = columns if terms or held else None
    if lugre is not None:
        joints = tuple(j for j, p in enumerate(lugre) if p is not None)
        mixed = {"joints": joints} if None in lugre else {}  # started as the first fit was (``lugre_identify``)
        result = identify_lugre_trajectories(robot, model, recordings, options, extra=extra, **mixed)
        return result.fit, columns, result.lugre
    return identify_trajectories(robot, model, recordings, options, extra), columns, None


def refit_without(calibrated, robot, model, train, findings, robot_source):
    """``refit(labels)`` of ``never_worse.keep_not_worse``: the joint fit without the findings labelled ``labels``."""
    terms, corrections, entries = findings

    def refit(labels):
        labels, bad = set(labels), {None}
        while bad:  # dropping findings can push another's coefficients out of their bounds (implausibility): drop it
            kept = ([t for t in terms if t.label not in labels], {k: v for k, v in corrections.items()
                    if k not in labels}, [e for e in entries if e["label"] not in labels])  # fmt: skip
            after, fit = joint_fit(calibrated, robot, model, train, kept, robot_source)
            labels |= (bad := {e["label"] for e in after.document["findings"] if implausibility(e)} - labels)
        return after, fit

    return refit


def offset_left_out(calibrated, robot, model, train, findings, robot_source):
    """``alone(joint)`` of ``offset_split.offset_splits``: the joint fit with ``findings`` and without the torque offset
    on the 0-based ``joint`` (``offset_split.without_offset``), nor a torque-offset finding there (the same column)."""
    terms, corrections, entries = findings

    def alone(joint):
        offsets = {t.label for t in terms if t.effect == "torque_offset" and t.joint == joint}
        kept = ([t for t in terms if t.label not in offsets], corrections,
                [e for e in entries if e["label"] not in offsets])  # fmt: skip
        return joint_fit(without_offset(calibrated, joint), robot, model, train, kept, robot_source)

    return alone


def joint_fit(calibrated, robot, model, train, findings, robot_source) -> tuple:
    """(new CalibratedModel, fit) of the recordings-route fit on ``train`` with ``findings`` = (torque terms,
    corrections, entries): the signal findings correct the recordings, the torque ones add columns."""
    terms, corrections, entries = findings
    options = offsets_left_to_findings(refit_options(calibrated), terms)  # a spring's constant, not an offset
    corrected = [correct_recording(r, corrections, recording_kt(robot, *train)) for r in train]
    own = calibrated.lugre_parameters
    stribeck = calibrated.document["drive"].get("stribeck_velocity") or None
    stribeck = [p.vs for p in own] if own is not None and None not in own else stribeck  # LuGre: its own
    stribeck = None if stribeck is None or "fs" not in options.friction else np.asarray(stribeck, dtype=float)
    common = (carrying_payloads(robot, model, entries), model, corrected, options, terms)  # the prior holds the load
    held = held_findings(entries)  # carried findings at the size the diagnosis read (``resized_findings``)
    fit, columns, lugre = _fit(*common, _reference(calibrated, model), stribeck, own, held)
    if any(term.load_dependent for term in terms):  # second pass: the load of the new model itself
        interim = _document(calibrated, robot, model, fit, columns, terms, entries, corrections, robot_source, lugre)
        fit, columns, lugre = _fit(*common, _reference(interim, model), stribeck, own, held)
    after = _document(calibrated, robot, model, fit, columns, terms, entries, corrections, robot_source, lugre)
    after.document["provenance"]["recalibrated_on"] = [recording_provenance(r) for r in train]
    return after, fit


def _robust_fit(calibrated, robot, model, train, findings, robot_source) -> tuple:
    """``_joint_fit``, and when the consistent fit does not converge with unnamed (sparse) terms among the
    findings, the fit without them, which are then reported only (with the reason): (after, fit, terms, entries)."""
    terms, corrections, entries = findings
    unnamed = {term.label for term in terms if term.effect == "unnamed_effect"}
    try:
        after, fit = joint_fit(calibrated, robot, model, train, findings, robot_source)
        if not unnamed or fit.solver_status != "Maximum_Iterations_Exceeded":
            return after, fit, terms, entries
        reason = fit.solver_status
    except SolverError as exc:
        if not unnamed:
            raise
        reason = str(exc)
    logger.info("recalibrate: the joint fit with %s did not converge (%s); reported only", sorted(unnamed), reason)
    terms = [term for term in terms if term.label not in unnamed]
    entries = [copy.deepcopy(e) for e in entries]
    for entry in entries:
        if entry["label"] in unnamed:
            entry.pop("term", None)
            entry["kind"] = "reported"
            entry["applied"] = "reported only: the consistent joint fit did not converge with its columns"
    after, fit = joint_fit(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
    return after, fit, terms, entries


def _reference(calibrated: CalibratedModel, model):
    """The torque a load-dependent friction multiplies: the model's own, without load-dependent terms."""

    def torque(q, qd, qdd):
        document = copy.deepcopy(calibrated.document)
        document["findings"] = [
            e for e in document.get("findings") or [] if e.get("term", {}).get("effect") != "load_dependent_friction"
        ]
        return CalibratedModel(document).predict(model, q, qd, qdd)

    return torque


def _document(
    calibrated, robot, model, fit, columns, terms, entries, corrections, robot_source, lugre=None
) -> CalibratedModel:
    """The new calibrated model of a joint fit (findings filled, corrections, provenance kept; with ``lugre``, a
    ``lugre_recordings.LuGreFit``, a version 3 file with that friction)."""
    plain, extra = split_findings(fit, len(columns.names) if terms else 0)
    source = robot_source or calibrated.robot_file()  # the file's robot text, written to the robot cache
    recordings = calibrated.document.get("provenance", {}).get("recordings", [])
    new = CalibratedModel.from_fit(robot, model, plain, robot_source=source, recordings=recordings, lugre=lugre)
    document = new.document
    document["robot"] = copy.deepcopy(calibrated.document["robot"])
    document["identification"]["drive_inertia"] = refit_options(calibrated).drive_inertia
    kept = ("column_choice", "one_way_friction", "worse_joints", "torque_scale")  # as the refit kept them (_options)
    document["identification"].update({k: copy.deepcopy(v) for k, v in calibrated.document["identification"].items()
                                       if k in kept and v is not None})  # fmt: skip
    document["findings"] = with_rest_angles(filled_entries(entries, terms, columns, extra), document.get("drive"))
    versioned(document)  # a counterbalance written as one finding: a version older readers refuse
    document["corrections"] = corrections
    said = calibrated.document.get("warnings", [])  # identify's: its suggested command names the files
    document["warnings"] = with_concrete_route(dict.fromkeys(fit.warnings), said)  # the refit's own (flags stay)
    laws = calibrated.document["drive"].get("temperature")  # the friction's law in temperature (refit_training
    if laws and all(n in document["drive"]["names"] for j in laws["joints"] for n in j["slopes_per_c"]):  # repeats
        document["drive"]["temperature"] = copy.deepcopy(laws)  # the drift correction to its reference)
    return CalibratedModel(document)
