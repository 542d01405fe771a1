"""recalibrate(): a diagnosis' findings added to a calibrated model, identified jointly with it.

calibrated model + DiagnosisReport + recordings -> calibrated model with findings (version 2).

A missing effect corrupts the identification it hides in: a spring on a joint is absorbed into the gravity parameters
and the friction, a missing drive inertia into the link inertias. Adding the finding afterwards, with the corrupted
parameters kept, leaves them wrong. So the recordings-route fit (``trajectory_fit.identify_trajectories``) is run again
on the training recording with one more linear column per feature of every torque-type finding
(``findings.FindingColumns``), all fitted jointly and with their standard deviations from the same covariance; the
``signal`` findings correct the recordings first (``findings.correct_recording``); a payload (``rigid_body``) is taken
up by the rigid body, held to the robot file carrying it (``carried_payload``). A feature the other columns span (a
spring's constant beside a drive offset, a rotor inertia the fit identifies: ``absorbed_features``) is left out and
reported as absorbed.
Load-dependent friction is linear in its coefficient for a fixed torque: the model's own, then the new one's.

A model with LuGre friction (file version 3) is identified again as ``psdm identify --friction lugre`` does
(``lugre_identify.identify_lugre_trajectories``: the Stribeck fit, the LuGre fit of the friction it leaves, the rigid
body again with that friction taken out, the LuGre fit again) with the finding columns in every linear fit, so the new
file holds the LuGre friction and the findings. Its signal findings correct the recordings the LuGre friction is fitted
on and judged on alike (``CalibratedModel.predict_recording``: the bristle state carried along the corrected
recording). Load-dependent friction is refused for it (``psdm_inverse_dynamics`` does not hold the LuGre part).

The result is judged on the validation recording as ``psdm validate`` judges it (the same corrections and preparation,
``CalibratedModel.predict_recording``), before and after, so the file's numbers are what its exported code gives. A
finding is kept only if it lowers the validation RMSE of every joint it names: one whose removal (no refit) does not
raise them is dropped, listed with its RMSE pair in the ``recalibration`` block (``dropped_findings``), and the model
is refitted without it (a finding whose every feature the fit's other columns already span contributes nothing by
construction; it is kept and reported as absorbed). First, a new finding that splits the torque of one the file
carries (``split_torque``: the two one shape, the carried one moved beyond its uncertainty) is dropped likewise.

Then the never-worse gate (``never_worse.keep_not_worse``, its record in ``recalibration.never_worse``): no joint's
validation RMSE may rise beyond a noise margin (``never_worse.MARGIN_RULE``) where the refits without each training
block (``refit_folds``) reproduce the rise; otherwise findings are dropped and the model refitted, or
``Recalibration.refused`` names the joints and findings and nothing may be written.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import logging

import numpy as np

from identification.calibration.absorbed_features import absorbed_mask
from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.carried_payload import carrying_payloads
from identification.calibration.consistency import MASS_CHECK_CONFIGURATIONS, consistency_failure, min_mass_eigenvalue
from identification.calibration.finding_value import implausibility, unhelpful_findings, validation_rmse, without_entry
from identification.calibration.findings import (
    SPEC_EFFECTS,
    FindingColumns,
    FindingTerm,
    correct_recording,
    filled_entries,
    finding_kind,
    offsets_left_to_findings,
)
from identification.calibration.held_friction import HeldFriction
from identification.calibration.lugre_identify import identify_lugre_trajectories
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.model_file_holds import model_file_holds
from identification.calibration.model_preparation import model_preparation
from identification.calibration.never_worse import keep_not_worse
from identification.calibration.payload_fit import carried_configurations
from identification.calibration.recording_provenance import recording_provenance
from identification.calibration.refit_folds import training_refits
from identification.calibration.split_torque import splitting_findings
from identification.calibration.trajectory_data import (
    stribeck_joints,
)
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.friction.models import LUGRE_PARAMETER_NAMES
from psdm_casadi.errors import ParameterError, SolverError

__all__ = ["MASS_CHECK_CONFIGURATIONS", "Recalibration", "consistency_failure", "min_mass_eigenvalue", "recalibrate",
           "validation_rmse"]  # fmt: skip

logger = logging.getLogger(__name__)

#: Rounds of dropping the findings that do not help and refitting (a refit can make another one useless).
MAX_DROP_ROUNDS = 3


@dataclasses.dataclass(frozen=True, eq=False)
class Recalibration:
    """The calibrated model before and after the findings, with what changed.

    Attributes
    ----------
    before, after : CalibratedModel
    rmse_before, rmse_after : array (n_dof,)
        Validation RMSE [N m] of each model as ``psdm validate`` computes it.
    moved : list of dict
        The base and drive parameters that moved by more than 3 standard deviations (of the new fit).
    min_mass_eigenvalue : float
        Smallest mass-matrix eigenvalue of the new standard parameters over random configurations.
    refused : str or None
        Why no subset of the findings keeps every joint within its noise margin (``never_worse``); the caller
        writes nothing then. None when ``after`` may be written.
    """

    before: CalibratedModel
    after: CalibratedModel
    rmse_before: np.ndarray
    rmse_after: np.ndarray
    moved: list
    min_mass_eigenvalue: float
    refused: str | None = None


def _pairs(report):
    """(Finding, candidate term or None, coefficients) of a diagnosis report, matched by label, in report order."""
    augmented = report.augmented
    terms = {} if augmented is None else {t.label: (t, c) for t, c in zip(augmented.terms, augmented.coefficients)}
    return [(f, *terms.get(f.label, (None, tuple(f.coefficients)))) for f in report.findings]


def _finding_terms(calibrated: CalibratedModel, report) -> tuple:
    """(torque FindingTerms, corrections, entries of every finding) from the report, merged with the file's own."""
    velocity = float(calibrated.document["drive"].get("coulomb_velocity") or 0.05)
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
                velocity=velocity,
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


def _check_lugre_findings(calibrated: CalibratedModel, terms) -> None:
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


def _kt(robot, recordings):
    if all(r.tau is not None for r in recordings) or robot.drives is None:
        return None
    return np.array([d.kt for d in robot.drives], dtype=float)


def _options(calibrated: CalibratedModel) -> TrajectoryOptions:
    """The recordings-route options the file was identified with (for LuGre: of the Stribeck fit it starts from)."""
    document, own = calibrated.document, model_preparation(calibrated.document)  # a refit keeps its file's preparation
    drive, identification = document["drive"], document["identification"]
    friction = tuple(drive["friction_terms"])
    if calibrated.lugre_parameters is not None:
        friction = ("fc", "fs", "fv", *(term for term in friction if term == "offset"))
    return TrajectoryOptions(
        friction=friction,
        coulomb_velocity=float(drive["coulomb_velocity"]),
        drive_inertia=bool(identification.get("drive_inertia", True)),
        consistency=bool(document["standard"].get("checked", True)),
        cutoff_hz=own.cutoff_hz,
        edge_periods=own.edge_periods,
        offset_joints=_offset_joints(identification),
        inertia_joints=tuple(j - 1 for j in drive.get("inertia_joints", [])),
        stribeck_joints=stribeck_joints(friction, drive.get("stribeck_velocity")),  # none stored for LuGre: None
        viscous_exponent=tuple(drive.get("viscous_exponent") or ()) or None,  # the file's viscous power law
        held_friction=HeldFriction.of_document(document).values,  # as identified
        held_links=model_file_holds(document).held_links,  # as identified (``worse_joint_hold``)
    )


def _offset_joints(identification):
    """The joints (0-based) of the file's chosen offsets (``column_choice``); None (every joint) in older files."""
    choice = identification.get("column_choice") or {}
    on = choice.get("request", {}).get("offset", "on") == "on"
    return None if on else tuple(j - 1 for j in choice["offset_joints"])


def _fit(robot, model, recordings, options, terms, reference, stribeck=None, lugre=False):
    """One joint fit with the finding columns, of the LuGre identification with ``lugre``; returns (fit, columns,
    ``lugre_recordings.LuGreFit`` or None). A feature is left out when it is absorbed beside the Stribeck shape."""
    columns = FindingColumns(tuple(terms), reference)
    if terms:
        keep = absorbed_mask(robot, model, recordings, options, columns, stribeck, _kt(robot, recordings))
        columns = dataclasses.replace(columns, keep=keep)
    extra = columns if terms else None
    if lugre:
        result = identify_lugre_trajectories(robot, model, recordings, options, extra=extra)
        return result.fit, columns, result.lugre
    return identify_trajectories(robot, model, recordings, options, extra), columns, None


def recalibrate(
    calibrated: CalibratedModel, robot, model, report, train, validation, *, robot_source=None, configurations=None
) -> Recalibration:
    """Identify ``calibrated`` again from ``train`` with the findings of ``report``; judge it on ``validation``.

    Parameters
    ----------
    calibrated : CalibratedModel
        The model the diagnosis started from.
    robot, model : RobotDescription, PSDMModel
        ``calibrated.load_robot()`` and its derived model.
    report : DiagnosisReport
        Of ``diagnose`` run with the calibrated model as the nominal one.
    train, validation : Recording or sequence of Recording
        Raw recordings (as given to the diagnosis).
    robot_source : path, optional
        Robot file written into the new model (default: the file's own copy).
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each ``train`` recording states, taken off its torque already (``payload_check.without_load``);
        listed in the new file's ``configurations``, which keeps the model's own (``carried_configurations``).

    Returns
    -------
    Recalibration

    Raises
    ------
    ParameterError
        When the report has no finding to apply.
    """
    if not report.findings:
        raise ParameterError(
            "recalibrate report.findings is empty: the diagnosis found nothing to apply. "
            "Use the calibrated model as it is."
        )
    train = [train] if not isinstance(train, (list, tuple)) else list(train)
    validation = [validation] if not isinstance(validation, (list, tuple)) else list(validation)
    terms, corrections, entries = _finding_terms(calibrated, report)
    _check_lugre_findings(calibrated, terms)
    kt = _kt(robot, validation)
    after, fit, terms, entries = _robust_fit(
        calibrated, robot, model, train, (terms, corrections, entries), robot_source
    )
    dropped = []
    for _ in range(MAX_DROP_ROUNDS):  # kept only with a torque of its own, lowering the validation RMSE where it acts
        refit = _refit_without(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
        unhelpful = splitting_findings(calibrated, after, refit, model, (train, validation), (_kt(robot, train), kt))
        unhelpful = unhelpful or unhelpful_findings(after, model, validation, kt)
        if not unhelpful:
            break
        dropped += unhelpful
        labels = {d["label"] for d in unhelpful}
        logger.info("recalibrate: dropped findings (a carried finding's torque split, or no help on validation): %s; "
                    "refitting", sorted(labels))  # fmt: skip
        terms = [t for t in terms if t.label not in labels]
        corrections = {k: v for k, v in corrections.items() if k not in labels}
        entries = [e for e in entries if e["label"] not in labels]
        after, fit = _joint_fit(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
    findings, droppable = (terms, corrections, entries), [t.label for t in terms] + list(corrections)
    refit_on = functools.partial(_refit_without, calibrated, robot, model, findings=findings, robot_source=robot_source)
    refits = training_refits(train, refit_on, droppable, _options(calibrated).cutoff_hz)
    gate = keep_not_worse(calibrated, (after, fit), refit_on(train), droppable, model, validation, kt, refits)
    after, fit = gate.after, gate.payload
    rmse_before, rmse_after = gate.comparison.before, gate.comparison.after
    scores = [validation_rmse(after, model, r, kt) for r in validation]
    mass = min_mass_eigenvalue(robot, fit.standard) if fit.checked else float("nan")
    moved = _moved(calibrated, after)
    document = after.document
    carried = carried_configurations(calibrated.configurations, configurations, [r.name for r in train])
    document.update({"configurations": carried} if carried else {})
    document["validation"] = {
        "recordings": [
            {"recording": r.name, "rmse": _list(s[0]), "r2": _list(s[1])} for r, s in zip(validation, scores)
        ],
        "min_mass_eigenvalue": None if not np.isfinite(mass) else mass,
    }
    document["recalibration"] = {
        "before": {
            "validation_rmse": _list(rmse_before),
            "consistent": calibrated.consistent,
            "min_pseudo_inertia_eigenvalue": calibrated.document["standard"]["min_pseudo_inertia_eigenvalue"],
        },
        "after": {
            "validation_rmse": _list(rmse_after),
            "consistent": after.consistent,
            "min_pseudo_inertia_eigenvalue": document["standard"]["min_pseudo_inertia_eigenvalue"],
        },
        "moved_parameters": moved,
        "dropped_findings": dropped,
        "never_worse": gate.to_dict(),
    }
    for entry in document["findings"]:
        entry["validation_rmse_before"], entry["validation_rmse_after"] = _list(rmse_before), _list(rmse_after)
        if entry["kind"] in ("torque", "signal"):
            without = without_entry(after, entry)
            entry["validation_rmse_without"] = _list(
                np.mean([validation_rmse(without, model, r, kt)[0] for r in validation], axis=0)
            )
    return Recalibration(before=calibrated, after=after, rmse_before=rmse_before, rmse_after=rmse_after, moved=moved,
                         min_mass_eigenvalue=mass, refused=gate.refused)  # fmt: skip


def _refit_without(calibrated, robot, model, train, findings, robot_source):
    """``refit(labels)`` of ``never_worse.keep_not_worse``: the joint fit without the findings labelled ``labels``."""
    terms, corrections, entries = findings

    def refit(labels):
        labels, bad = set(labels), {None}
        while bad:  # dropping findings can push another's coefficients out of their bounds (implausibility): drop it
            kept = ([t for t in terms if t.label not in labels], {k: v for k, v in corrections.items()
                    if k not in labels}, [e for e in entries if e["label"] not in labels])  # fmt: skip
            after, fit = _joint_fit(calibrated, robot, model, train, kept, robot_source)
            labels |= (bad := {e["label"] for e in after.document["findings"] if implausibility(e)} - labels)
        return after, fit

    return refit


def _joint_fit(calibrated, robot, model, train, findings, robot_source) -> tuple:
    """(new CalibratedModel, fit) of the recordings-route fit on ``train`` with ``findings`` = (torque terms,
    corrections, entries): the signal findings correct the recordings, the torque ones add columns."""
    terms, corrections, entries = findings
    options = offsets_left_to_findings(_options(calibrated), terms)  # a spring's constant, not an offset
    corrected = [correct_recording(r, corrections, _kt(robot, train)) for r in train]
    own = calibrated.lugre_parameters
    stribeck = calibrated.document["drive"].get("stribeck_velocity") or None
    stribeck = [p.vs for p in own] if own is not None else stribeck  # LuGre: its own Stribeck velocities
    stribeck = None if stribeck is None or "fs" not in options.friction else np.asarray(stribeck, dtype=float)
    common = (carrying_payloads(robot, model, entries), model, corrected, options, terms)  # the prior holds the load
    fit, columns, lugre = _fit(*common, _reference(calibrated, model), stribeck, own is not None)
    if any(term.load_dependent for term in terms):  # second pass: the load of the new model itself
        interim = _document(calibrated, robot, model, fit, columns, terms, entries, corrections, robot_source, lugre)
        fit, columns, lugre = _fit(*common, _reference(interim, model), stribeck, own is not None)
    after = _document(calibrated, robot, model, fit, columns, terms, entries, corrections, robot_source, lugre)
    after.document["provenance"]["recalibrated_on"] = [recording_provenance(r) for r in train]
    return after, fit


def _robust_fit(calibrated, robot, model, train, findings, robot_source) -> tuple:
    """``_joint_fit``, and when the consistent fit does not converge with unnamed (sparse) terms among the
    findings, the fit without them, which are then reported only (with the reason): (after, fit, terms, entries)."""
    terms, corrections, entries = findings
    unnamed = {term.label for term in terms if term.effect == "unnamed_effect"}
    try:
        after, fit = _joint_fit(calibrated, robot, model, train, findings, robot_source)
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
    after, fit = _joint_fit(calibrated, robot, model, train, (terms, corrections, entries), robot_source)
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
    document["identification"]["drive_inertia"] = _options(calibrated).drive_inertia
    kept = ("column_choice", "one_way_friction", "worse_joints", "torque_scale")  # as the refit kept them (_options)
    document["identification"].update({k: copy.deepcopy(v) for k, v in calibrated.document["identification"].items()
                                       if k in kept and v is not None})  # fmt: skip
    document["findings"] = filled_entries(entries, terms, columns, extra)
    document["corrections"] = corrections
    document["warnings"] = list(dict.fromkeys(fit.warnings))  # the refit's own (a wrong recording stays flagged)
    return CalibratedModel(document)


def _moved(before: CalibratedModel, after: CalibratedModel) -> list:
    """Base, drive (and LuGre) parameters whose change exceeds 3 standard deviations of the new estimate."""
    out = []
    blocks = [before.document[b] for b in ("base", "drive")], [after.document[b] for b in ("base", "drive")]
    if before.lugre_parameters is not None and after.lugre_parameters is not None:  # LuGre: p1, p2, ... per joint
        for document, listed in zip((before.document, after.document), blocks):
            lugre = document["drive"]["lugre"]
            names = [f"{n}{j + 1}" for n in LUGRE_PARAMETER_NAMES for j in range(before.n_dof)]
            values, std = ([v for n in LUGRE_PARAMETER_NAMES for v in part[n]] for part in (lugre, lugre["std"]))
            listed.append({"names": names, "values": values, "std": std})
    for old, new in zip(*blocks):
        for name, a, b, s in zip(new["names"], _values(old, new["names"]), new["values"], new["std"]):
            if a is None or b is None:
                continue
            sigma = s if s is not None and s > 0 else float("inf")
            if abs(b - a) > 3.0 * sigma:
                out.append({"name": name, "before": a, "after": b, "std": s, "sigmas": abs(b - a) / sigma})
    return out


def _values(block: dict, names: list) -> list:
    lookup = dict(zip(block["names"], block["values"]))
    return [lookup.get(name) for name in names]


def _list(values) -> list:
    return [float(v) for v in np.atleast_1d(values)]
