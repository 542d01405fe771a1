"""A rotor taken apart from its same-actuator siblings: a finding that must hold on data the fit did not see.

training recordings + the fit that held every same-actuator rotor + held-out recordings (or none) -> the fit with the
confirmed rotors taken apart, and ``RotorsApart`` (per proposal: taken or held, and why, with its numbers).

On motor currents a rotor the robot file does not state, inside the base parameters, is held to the drive inertias of
the joints with the same torque constant (``merged_rotors.sibling_rotors``). Where the training BIC is strongly against
that hold (``merged_rotors.siblings_apart``: the rotor fitted freely beside the robot file's links), the fit records a
proposal and still holds it. A training BIC alone is no finding: beside the file's links the free rotor also takes up
what the file's link inertias miss (a URDF whose link 2 carries a quarter of its inertia: BIC over +1000 on the
virtual Denso with the siblings truly equal), and the hold it is compared with is fitted on the same samples. So
identify judges each proposal as ``diagnose --apply`` judges a finding (``no_gain.GAIN_RULE``): the model identified
with the rotor apart must predict the joint better than the model with the hold in at least ``GAIN_SHARE`` of the
circular block bootstrap draws of their paired RMSE difference (``paired_margin.share_lower``) on each validation
recording, and no joint may be worse beyond the never-worse margin (``never_worse``). Without a held-out recording the
training recordings are cut into blocks, each predicted by both models identified on the others (``counterbalance_
folds``, as identify's counterbalance is judged), and the blocks' residuals are judged taken together, the margin at
least the folds' spread. Recordings that cannot be cut (too short, carrying payloads) leave the hold, and say why.

A confirmed rotor is listed in ``TrajectoryOptions.rotors_apart``: every later fit of the route (the counterbalance,
the payload, the robot-file check) and a model file's refit (``model_file_holds``) take it apart too.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.column_check import converged
from identification.calibration.counterbalance_folds import FoldFailure, block_folds, fold_comparison
from identification.calibration.never_worse import compare_models
from identification.calibration.no_gain import GAIN_RULE, GAIN_SHARE, finding_gain
from identification.calibration.shared_barrier import shared_solvers
from identification.calibration.trajectory_fit import identify_trajectories
from identification.data.torque_constants import recording_kt
from identification.paired_margin import share_lower
from psdm_casadi.errors import PSDMError

__all__ = ["RotorVerdict", "RotorsApart", "judge_rotors_apart", "proposed_rotors", "unjudged_rotors"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class RotorVerdict:
    """One proposal: joint ``joint`` (0-based) apart from ``siblings`` (their reference ``reference`` [kg m^2]), its
    training BIC change ``delta_bic``, whether it was ``taken``, why, and (when judged) the smallest share of draws in
    which the model with it apart is lower on the joint and the joint's held-out RMSE [N m] with the hold and apart."""

    joint: int
    siblings: tuple
    reference: float
    delta_bic: float
    taken: bool
    reason: str
    share: float | None = None
    rmse_held: float | None = None
    rmse_apart: float | None = None

    def sentence(self) -> str:
        """``drive inertia of joint 2 apart from joint 3's 0.55 kg m^2 (same torque constant): taken (...)``."""
        siblings = ", ".join(str(s + 1) for s in self.siblings)
        verdict = "taken" if self.taken else "refused, held to theirs"
        return (f"drive inertia of joint {self.joint + 1} apart from joint(s) {siblings}'s {self.reference:.3g} kg m^2 "
                f"(same torque constant): {verdict} ({self.reason})")  # fmt: skip

    def to_dict(self) -> dict:
        return {"joint": self.joint + 1, "siblings": [s + 1 for s in self.siblings], "reference_kg_m2": self.reference,
                "delta_bic": self.delta_bic, "taken": self.taken, "reason": self.reason, "share_lower": self.share,
                "held_out_rmse_held": self.rmse_held, "held_out_rmse_apart": self.rmse_apart}  # fmt: skip


@dataclass(frozen=True)
class RotorsApart:
    """The proposals identify judged (``verdicts``: ``RotorVerdict``) and on what (``route``); empty: none."""

    verdicts: tuple = ()
    route: str = ""

    @property
    def joints(self) -> tuple:
        """The joints (0-based) taken apart: ``TrajectoryOptions.rotors_apart``."""
        return tuple(v.joint for v in self.verdicts if v.taken)

    def describe(self) -> list:
        """One sentence per proposal (none: no line)."""
        return [v.sentence() for v in self.verdicts]

    def to_dict(self) -> dict:
        return {"route": self.route, "rule": GAIN_RULE, "verdicts": [v.to_dict() for v in self.verdicts]}


def proposed_rotors(fit) -> dict:
    """{joint (0-based): (reference, sibling joints (0-based), training BIC change)} of the rotors ``fit`` (a
    ``TrajectoryFit``) held to their siblings though the training BIC wants them apart (``merged_rotors``)."""
    entries = dict(getattr(fit, "envelope_bounds", ()) or ()).get("drive_inertia_reference") or ()
    out = {}
    for entry in entries:
        same = entry.get("same_actuator")
        if same and not same.get("taken", True):
            out[int(entry["joint"]) - 1] = (float(same["kg_m2"]), tuple(s - 1 for s in same["joints"]),
                                            float(same["delta_bic"]))  # fmt: skip
    return out


def judge_rotors_apart(problem, fit, validation=()) -> tuple:
    """``(fit, RotorsApart)``: ``fit`` (identified with ``problem`` = (robot, model, training recordings, options,
    configurations)) again with the proposals the held-out data confirm taken apart (module docstring); ``fit`` itself
    when none is."""
    proposals = proposed_rotors(fit)
    if not proposals:
        return fit, RotorsApart()
    robot, model, recordings, options, configurations = problem
    joints = tuple(sorted(proposals))
    kt = recording_kt(robot, *validation, *recordings)

    def fitted(apart, pieces=None):  # pieces: a fold's (no payloads there: ``block_folds`` refuses them)
        trial = replace(options, rotors_apart=tuple(sorted({*options.rotors_apart, *apart})))
        given = (recordings, configurations) if pieces is None else (list(pieces), None)
        found = identify_trajectories(robot, model, given[0], trial, configurations=given[1])
        return converged(found, "with the rotors apart" if apart else "with the rotors held")

    logger.info("identify: the training data want the drive inertia of joint(s) %s apart from the same actuator's; "
                "checking on held-out data ...", ", ".join(str(j + 1) for j in joints))  # fmt: skip
    try:
        if validation:
            route = f"{len(validation)} validation recording(s)"
            apart = fitted(joints)
            judged = _on_validation(_calibrated(robot, model, fit), _calibrated(robot, model, apart), model,
                                    list(validation), kt, joints)  # fmt: skip
        else:
            cutoffs = [c for c in fit.cutoff_hz if c]
            folds = block_folds(recordings, configurations, min(cutoffs) if cutoffs else None)
            if isinstance(folds, str):
                return fit, _held(proposals, f"not checked on held-out data ({folds}): the same-actuator hold stays")
            route, apart = folds.route, None
            models = [lambda pieces, a=a: _calibrated(robot, model, fitted(a, pieces)) for a in ((), joints)]
            judged = _by_folds(folds, *models, model, kt, joints)
    except (FoldFailure, PSDMError) as failure:  # a fold or a fit that cannot be judged: no finding, the hold stays
        return fit, _held(proposals, f"not checked on held-out data ({failure}): the same-actuator hold stays")
    verdicts = tuple(_verdict(j, proposals[j], *judged[j], route) for j in joints)
    result = RotorsApart(verdicts, route)
    for verdict in verdicts:
        logger.info("identify: %s", verdict.sentence())
    taken = result.joints
    if not taken:
        return fit, result
    if taken == joints and apart is not None:
        return apart, result
    return fitted(taken), result


def unjudged_rotors(fit, route: str) -> RotorsApart:
    """The proposals of ``fit`` held on a ``route`` of identify that does not judge them (a drive loss, LuGre
    friction: their refits are routes of their own), stated as such (empty: none)."""
    proposals = proposed_rotors(fit)
    if not proposals:
        return RotorsApart()
    return _held(proposals, f"not judged on the {route} route: the same-actuator hold stays")


def _calibrated(robot, model, fit) -> CalibratedModel:
    return CalibratedModel.from_fit(robot, model, fit, robot_source=robot.source)


def _on_validation(held, apart, model, validation, kt, joints) -> dict:
    """{joint: (share, RMSE held, RMSE apart, worse joints)}: ``no_gain.finding_gain`` of each rotor apart against the
    hold on each validation recording, and the joints worse beyond the never-worse margin (``compare_models``)."""
    worse = compare_models(held, apart, model, validation, kt).worse
    out = {}
    for j in joints:
        entry = {"label": f"rotor_apart[j{j + 1}]", "effect": "rotor_inertia", "kind": "rotor", "joints": [j + 1]}
        gain = finding_gain(entry, apart, held, model, validation, kt)
        out[j] = (float(gain.share[0]), float(gain.rmse_without[0]), float(gain.rmse_with[0]), worse)
    return out


def _by_folds(folds, identify_held, identify_apart, model, kt, joints) -> dict:
    """``_on_validation``'s numbers from the training blocks held out in turn, their residuals taken together (the
    margin at least the folds' spread: ``counterbalance_folds.fold_comparison``)."""
    with shared_solvers():  # eight fits of two structures: two solvers (``shared_barrier``)
        residuals = replace(folds, baselines={}).residuals(identify_held, identify_apart, model, kt)
    comparison = fold_comparison(residuals)[0]
    held, apart = (np.concatenate([fold[i] for fold in residuals]) for i in (0, 1))
    out = {}
    for j in joints:
        pair = np.column_stack([held[:, j], apart[:, j]])
        pair = pair[np.all(np.isfinite(pair), axis=1)]
        share = float(share_lower(pair[:, :1], pair[:, 1:])[0]) if len(pair) else float("nan")
        out[j] = (share, float(comparison.before[j]), float(comparison.after[j]), comparison.worse)
    return out


def _verdict(j, proposal, share, rmse_held, rmse_apart, worse, route) -> RotorVerdict:
    """Taken when lower in ``GAIN_SHARE`` of the draws on its joint and no joint worse (module docstring)."""
    reference, siblings, delta = proposal
    gained = bool(np.isfinite(share) and share >= GAIN_SHARE)
    numbers = (f"training BIC {delta:+.3g}; on {route} joint {j + 1}'s RMSE {rmse_held:.4g} N m held, "
               f"{rmse_apart:.4g} apart, lower in {share:.0%} of draws")  # fmt: skip
    if gained and not worse:
        reason = f"{numbers}: the held-out data confirm it"
    elif gained:
        reason = f"{numbers}, but joint(s) {', '.join(str(k + 1) for k in worse)} worse beyond the never-worse margin"
    else:
        reason = f"{numbers}, less than the {GAIN_SHARE:.0%} asked of a finding: the held-out data do not confirm it"
    return RotorVerdict(j, siblings, reference, delta, gained and not worse, reason, share, rmse_held, rmse_apart)


def _held(proposals, why) -> RotorsApart:
    """Every proposal held, unjudged, for the reason ``why``."""
    verdicts = tuple(RotorVerdict(j, sib, reference, delta, False, f"training BIC {delta:+.3g}; {why}")
                     for j, (reference, sib, delta) in sorted(proposals.items()))  # fmt: skip
    for verdict in verdicts:
        logger.info("identify: %s", verdict.sentence())
    return RotorsApart(verdicts, why)
