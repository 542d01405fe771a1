"""The drive terms of the coupled transmission a robot file states: identify fits them, kept where they help.

robot file ``[transmission] coupling`` + the model identify would write + held-out recordings, else block
cross-validation of the training recordings -> the coupling terms fitted jointly with it (``applied_model.joint_fit``)
-> kept where no joint is worse out of sample and a coupled joint is better -> ``CoupledDrives`` (what was tried, kept,
on which evidence, and why).

identify's drive columns are per joint: a rotor inertia ``Ia_j qdd_j`` and the friction of joint j. With a coupled
transmission (``psdm_casadi.transmission.Transmission``: ``theta_m = N_q q`` with an entry off the diagonal) motor m
turns with joint k too, so its inertia and viscous friction act on both joints (``tau = N_q^T tau_m``, the motor's
velocity ``(N_q qd)_m``): on joint k a torque in ``qdd_m`` and ``qd_m`` (joint m's own motion), on joint m one in
``qdd_k`` and ``qd_k``. Those are the diagnosis's coupling terms (``findings.FindingTerm`` ``coupling``: columns
``[qd_source, qdd_source]`` on ``joint``), both directions of each coupled pair. Without them the coupled joint's
model can be worse than the robot file's own (its rigid body), a torque the per-joint columns cannot hold.

They are written as findings of the model file with ``source`` :data:`COUPLING_SOURCE` (the robot file states them),
so ``psdm diagnose`` carries them as the file's (``diagnosis_prior.carried_as``: by label) and does not find them
again. The terms are kept only where the out-of-sample evidence keeps them, by one rule whatever the evidence: no joint
worse beyond the paired margin, and a coupled joint better beyond it on each part (``never_worse.better_on_each``);
else the pair's single directions are tried, and the best of those that pass (``never_worse.improvement``) is kept.
The evidence is the held-out recordings when there are any (``never_worse.compare_each``, a part per recording; a
joint is worse on a recording beyond its margin plus what estimating the rigid body again costs there,
``robot_file_check.FileCheck.allowance``), else a block cross-validation of the training recordings as identify's
column check takes it (``counterbalance_folds``: each block predicted by the model without and with the terms, both
identified on the other blocks; a part per block, worse judged over the blocks taken together with the folds' spread,
as ``column_check`` judges a column). Without either (training recordings too short to cut, a fold that does
not converge), a training payload (``joint_fit`` refits without it) or another route (LuGre, a drive loss), they are
not kept, and the reason is stated.

They are decided on the model before identify's worse-joint holds (``worse_joint_hold``): a joint the coupling mends is
not worse than the robot file, and nothing is held for it. The holds' fits carry the kept terms (:func:`carrying`),
so they are judged against the coupled model alike.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.column_check import converged
from identification.calibration.counterbalance_folds import FoldFailure, block_folds
from identification.calibration.findings import FindingTerm
from identification.calibration.model_preparation import model_preparation
from identification.calibration.never_worse import better_on_each, compare_each, improvement, pooled_comparison

__all__ = [
    "COUPLING_SOURCE",
    "HELD_OUT",
    "CoupledDrives",
    "carried_over",
    "carrying",
    "choose_coupling",
    "coupled_on_route",
    "coupling_terms",
    "holding",
    "not_on_route",
    "take_coupled_drives",
]

logger = logging.getLogger(__name__)

#: The ``source`` of a coupling finding the robot file's transmission states (not a diagnosis's).
COUPLING_SOURCE = "robot file transmission"
#: The evidence with held-out recordings (``--validate``, ``--holdout``); without, the folds' route names itself.
HELD_OUT = "the held-out recordings"


@dataclass(frozen=True)
class CoupledDrives:
    """What identify did about the robot file's coupled transmission (module docstring).

    ``tried``: the coupling terms' labels; ``kept``: those the model holds; ``reason``: why (or why not tried);
    ``route``: the evidence that judged them (:data:`HELD_OUT` or the block cross-validation's, empty: not judged);
    ``comparison``: the comparison of the kept set against the model without it on that evidence
    (``JointComparison``); ``parts``: per held-out recording or block, its comparison (each must find a coupled joint
    better).
    """

    tried: tuple = ()
    kept: tuple = ()
    reason: str = ""
    route: str = ""
    comparison: object = None
    parts: tuple = ()

    def describe(self) -> str:
        """One sentence (empty: the robot file states no coupling)."""
        if not self.tried and not self.reason:
            return ""
        what = ", ".join(self.tried)
        if self.kept:
            return (
                f"coupled transmission: {', '.join(self.kept)} fitted (of {what}; beside the per-joint drive "
                f"columns, before the worse-joint holds), judged by {self.route}: {self.reason}"
            )
        by = f", judged by {self.route}" if self.route else ""
        return f"coupled transmission: {what or 'its coupling terms'} not added{by}: {self.reason}"

    def to_dict(self) -> dict:
        parts = [{"before": c.before.tolist(), "after": c.after.tolist(), "margin": c.margin.tolist()}
                 for c in self.parts]  # fmt: skip
        return {"tried": list(self.tried), "kept": list(self.kept), "reason": self.reason, "route": self.route,
                "comparison": None if self.comparison is None else self.comparison.to_dict(),
                "parts": parts}  # fmt: skip


def coupling_terms(robot) -> list:
    """The coupling ``FindingTerm``s of ``robot``'s transmission: for each motor m coupled to a joint k (an entry
    ``N_q[m, k]`` off the diagonal), ``coupling[jm->jk]`` and ``coupling[jk->jm]`` (module docstring; their columns
    are the source's velocity and acceleration, no smoothing)."""
    transmission = getattr(robot, "transmission", None)
    if transmission is None or not transmission.is_coupled:
        return []
    matrix, out = np.asarray(transmission.coupling), []
    for m, k in zip(*np.nonzero(matrix - np.diag(np.diag(matrix)))):
        for joint, source in ((int(k), int(m)), (int(m), int(k))):
            term = FindingTerm("coupling", joint=joint, source=source)
            if term not in out:
                out.append(term)
    return out


def _entry(term: FindingTerm) -> dict:
    return {"effect": "coupling", "label": term.label, "kind": "torque", "joints": [term.joint + 1],
            "source": COUPLING_SOURCE, "cause": "the robot file's coupled transmission: the coupled motor's inertia "
            "and viscous friction act on both joints", "term": term.to_dict()}  # fmt: skip


def _fitter(robot, model, calibrated: CalibratedModel, robot_source):
    """``fitted(recordings, subset) -> (CalibratedModel, fit)``: ``calibrated`` fitted again on ``recordings`` with its
    own torque findings and the coupling terms ``subset`` (``applied_model.joint_fit``)."""
    from identification.calibration.applied_model import joint_fit

    own = [t for t, _ in calibrated.torque_findings]
    entries = list(calibrated.document.get("findings") or [])

    def fitted(recordings, subset):
        findings = (own + list(subset), dict(calibrated.corrections), entries + [_entry(t) for t in subset])
        return joint_fit(calibrated, robot, model, list(recordings), findings, robot_source)

    return fitted


def _held_out_judge(calibrated, model, validation, kt, allowance, full):
    """``judge(subset) -> (pooled, parts, worse)`` on the held-out recordings: the model with ``subset`` fitted on the
    training recordings (``full(subset)``) against ``calibrated``, a part per recording, a joint worse on one beyond its
    paired margin plus ``allowance``."""

    def judge(subset):
        each = compare_each(calibrated, full(subset)[0], model, validation, kt)
        worse = sorted({int(j) for c in each for j in np.flatnonzero(c.after - c.before - c.margin > allowance)})
        return pooled_comparison(each), each, worse

    return judge


def _fold_judge(folds, fitted, model, kt):
    """``judge(subset) -> (pooled, parts, worse)`` by the block cross-validation ``folds`` (``BlockFolds``): each
    block predicted by the models without and with ``subset``, both fitted on the other blocks; a part per block, the
    joints worse over the blocks together (with the folds' spread); ``FoldFailure`` where a fold cannot judge."""

    def identify(subset):
        def on(pieces):
            after, fit = fitted(pieces, subset)
            converged(fit, f"on the training data without a block ({fit.n_samples} samples)")
            return after

        return on

    def judge(subset):
        together, parts = folds.compare(identify(()), identify(subset), model, kt)
        return together, parts, list(together.worse)

    return judge


def choose_coupling(terms, judge) -> tuple:
    """``(subset, pooled, parts, better)`` of the coupling ``terms`` kept by ``judge(subset) -> (pooled, parts,
    worse)``: the pair where it passes, else the best passing single direction (module docstring), ``better`` the
    coupled joints better on each part; ``(None, None, (), ())`` where none passes."""
    subsets = [terms] + ([[t] for t in terms] if len(terms) > 1 else [])
    best = None
    for subset in subsets:
        pooled, parts, worse = judge(subset)
        better = better_on_each(parts, sorted({t.joint for t in subset}))
        logger.info("identify: coupled transmission: with %s: worse on joint(s) %s, better on %s (%s)",
                    [t.label for t in subset], [j + 1 for j in worse], [j + 1 for j in better],
                    pooled.text(range(len(pooled.before))))  # fmt: skip
        if not worse and better and (best is None or improvement(pooled) > improvement(best[1])):
            best = (subset, pooled, parts, better)
        if best is not None and subset is terms:
            break  # the pair passing: kept; else the single directions compared
    return (None, None, (), ()) if best is None else best


def take_coupled_drives(problem, calibrated: CalibratedModel, validation, kt, robot_source=None, allowance=None):
    """``(CalibratedModel, fit or None, CoupledDrives)``: ``calibrated`` with the robot file's coupling terms fitted
    jointly where the evidence keeps them (module docstring); ``(calibrated, None, record)`` where none is kept.
    ``problem = (robot, model, training recordings, configurations)``; ``validation``: the held-out recordings (empty:
    block cross-validation of the training recordings); ``kt``: the torque constants their residuals are read with
    (held-out: one per recording, or None); ``allowance`` [N m] per joint: what estimating the rigid body again costs on
    the held-out motion (``robot_file_check.FileCheck.allowance``), allowed beyond the paired margin there (the refit
    moves the rigid body by its estimation noise; in the folds both models are estimated alike)."""
    robot, model, train, configurations = problem
    terms = coupling_terms(robot)
    if not terms:
        return calibrated, None, CoupledDrives()
    labels = tuple(t.label for t in terms)
    fitted, full = _fitter(robot, model, calibrated, robot_source), {}

    def fit_all(subset):  # on every training recording: the model kept (held out: the one judged too)
        key = tuple(t.label for t in subset)
        if key not in full:
            full[key] = fitted(train, subset)
        return full[key]

    if validation:
        allowance = np.zeros(robot.n_dof) if allowance is None else np.nan_to_num(np.asarray(allowance, dtype=float))
        route, judge = HELD_OUT, _held_out_judge(calibrated, model, validation, kt, allowance, fit_all)
    else:
        folds = block_folds(train, configurations, model_preparation(calibrated.document).cutoff_hz)
        if isinstance(folds, str):
            reason = f"no held-out recording to judge them (--holdout), and no block cross-validation: {folds}"
            return calibrated, None, CoupledDrives(labels, reason=reason)
        route, judge = folds.route, _fold_judge(folds, fitted, model, kt)
    try:
        subset, pooled, parts, better = choose_coupling(terms, judge)
    except FoldFailure as failure:
        return calibrated, None, CoupledDrives(labels, reason=f"not judged ({failure})", route=route)
    if subset is None:
        where = "held-out recording" if validation else "block"
        reason = f"no coupled joint predicted better on each {where} without another worse beyond the paired margin"
        return calibrated, None, CoupledDrives(labels, reason=reason, route=route)
    after, fit = fit_all(subset)
    return after, fit, CoupledDrives(labels, tuple(t.label for t in subset), reason=pooled.text(better), route=route,
                                     comparison=pooled, parts=tuple(parts))  # fmt: skip


def carried_over(before: dict, after: dict) -> None:
    """Copy into ``after``'s ``identification`` block what identify stated there in ``before`` and the joint fit did
    not keep (the column choice's record, the robot-file check, the holds), in place."""
    for key, value in before["identification"].items():
        after["identification"].setdefault(key, value)
    after.get("provenance", {}).pop("recalibrated_on", None)  # identified, not recalibrated


def holding(calibrated: CalibratedModel, options) -> CalibratedModel:
    """``calibrated`` stating what of the ``options`` (``TrajectoryOptions``) its fit was made with a model file
    states in its ``identification`` block: the held friction and links (``one_way_friction.held``,
    ``worse_joints.held_links``) and the offsets' joints (``column_choice``). The joint fit refits with the file's
    options (``applied_model.refit_options``), and identify writes those records only after its holds are decided
    (without the column choice's, an offset on every joint)."""
    identification = dict(calibrated.document["identification"])
    identification["one_way_friction"] = {"held": dict(options.held_friction)}
    identification["worse_joints"] = {"held_links": [i + 1 for i in options.held_links]}
    if "column_choice" not in identification:
        joints = options.offset_joints
        identification["column_choice"] = {"request": {"offset": "on" if joints is None else "auto"},
                                           "offset_joints": [j + 1 for j in joints or ()]}  # fmt: skip
    return CalibratedModel({**calibrated.document, "identification": identification})


def not_on_route(robot, why: str) -> CoupledDrives:
    """The record where the coupling terms are not tried (``why``: the route, a payload); empty without a coupling."""
    terms = coupling_terms(robot)
    return CoupledDrives(tuple(t.label for t in terms), reason=f"not tried {why}") if terms else CoupledDrives()


def coupled_on_route(problem, written, judged, robot_source) -> tuple:
    """``(WrittenModel, CoupledDrives)``: ``written`` (``written_model.WrittenModel``, the model identify would write
    before its worse-joint holds) with the coupling terms of the robot file's transmission where the held-out
    recordings, else the training blocks, keep them (``take_coupled_drives``), checked against the robot file again
    on the ``judged`` held-out recordings (``file_judged``; its friction with the per-joint drive columns);
    ``problem = (robot, model, training recordings, options, configurations)``. Not tried beside a training payload
    (``joint_fit`` refits without it), the reason stated."""
    from identification.calibration.file_judged import file_check
    from identification.calibration.trajectory_fit import torque_constants

    robot, model, recordings, _, configurations = problem
    terms = coupling_terms(robot)
    if not terms:
        return written, CoupledDrives()
    if any(getattr(c, "payload", None) is not None or getattr(c, "unknown", False) for c in configurations or ()):
        return written, not_on_route(robot, "beside a training payload")
    logger.info("identify: the robot file's coupled transmission: fitting its coupling terms %s ...",
                ", ".join(t.label for t in terms))  # fmt: skip
    base, validation = holding(written.calibrated, written.options), judged.recordings
    kt = torque_constants(robot, written.options, validation or recordings)
    after, fit, record = take_coupled_drives((robot, model, recordings, configurations), base, validation, kt,
                                             robot_source, written.check.allowance)  # fmt: skip
    logger.info("identify: %s", record.describe())
    if fit is None:
        return written, record
    carried_over(base.document, after.document)
    steps = (robot, model, recordings, written.options, configurations)
    check = file_check(steps, judged, fit, after, written.fit)
    return replace(written, fit=fit, calibrated=after, check=check), record


def carrying(write, record: CoupledDrives, problem, judged, robot_source):
    """``write(options, fit) -> WrittenModel`` (``written_model.ModelWriter``) with the coupling terms ``record`` kept
    fitted on every model it writes, without judging them again: the fits the worse-joint holds try are compared with
    the coupled model as it is (module docstring). ``write`` itself where none is kept."""
    from identification.calibration.file_judged import file_check

    if not record.kept:
        return write
    robot, model, recordings, _, configurations = problem
    subset = [t for t in coupling_terms(robot) if t.label in record.kept]
    known = []  # (options, fit, WrittenModel): each carried once, by identity (as ``ModelWriter``)

    def carried(options, fit):
        for known_options, known_fit, written in known:
            if known_options is options and known_fit is fit:
                return written
        written = write(options, fit)
        base = holding(written.calibrated, options)
        after, joint = _fitter(robot, model, base, robot_source)(recordings, subset)
        carried_over(base.document, after.document)
        check = file_check((robot, model, recordings, options, configurations), judged, joint, after, written.fit)
        out = replace(written, fit=joint, calibrated=after, check=check)
        known.append((options, fit, out))
        return out

    return carried
