"""The drive terms of the coupled transmission a robot file states: identify fits them, kept where held out they help.

robot file ``[transmission] coupling`` + the model identify would write + held-out recordings -> the coupling terms
fitted jointly with it (``applied_model.joint_fit``) -> kept where no joint of the held-out recordings is worse and a
coupled joint is better -> ``CoupledDrives`` (what was tried, kept, and why).

identify's drive columns are per joint: a rotor inertia ``Ia_j qdd_j`` and the friction of joint j. With a coupled
transmission (``psdm_casadi.transmission.Transmission``: ``theta_m = N_q q`` with an entry off the diagonal) motor m
turns with joint k too, so its inertia and viscous friction act on both joints (``tau = N_q^T tau_m``, the motor's
velocity ``(N_q qd)_m``): on joint k a torque in ``qdd_m`` and ``qd_m`` (joint m's own motion), on joint m one in
``qdd_k`` and ``qd_k``. Those are the diagnosis's coupling terms (``findings.FindingTerm`` ``coupling``: columns
``[qd_source, qdd_source]`` on ``joint``), both directions of each coupled pair. Without them the coupled joint's
model can be worse than the robot file's own (its rigid body), a torque the per-joint columns cannot hold.

They are written as findings of the model file with ``source`` :data:`COUPLING_SOURCE` (the robot file states them),
so ``psdm diagnose`` carries them as the file's (``diagnosis_prior.carried_as``: by label) and does not find them
again. The terms are kept only where the held-out recordings judge them (``never_worse.compare_each``): no joint worse
beyond the paired margin on any held-out recording, and a coupled joint better beyond it on each (``better_on_each``);
else the pair's single directions are tried, and the best of those that pass (``never_worse.improvement``) is kept.
Without held-out recordings, a training payload (``joint_fit`` refits without it) or another route (LuGre, a drive
loss), they are not tried, and the reason is stated.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.coulomb_width import joint_width
from identification.calibration.findings import FindingTerm
from identification.calibration.never_worse import better_on_each, compare_each, improvement, pooled_comparison

__all__ = [
    "COUPLING_SOURCE",
    "CoupledDrives",
    "carried_over",
    "coupled_on_route",
    "coupling_terms",
    "take_coupled_drives",
]

logger = logging.getLogger(__name__)

#: The ``source`` of a coupling finding the robot file's transmission states (not a diagnosis's).
COUPLING_SOURCE = "robot file transmission"


@dataclass(frozen=True)
class CoupledDrives:
    """What identify did about the robot file's coupled transmission (module docstring).

    ``tried``: the coupling terms' labels; ``kept``: those the model holds; ``reason``: why (or why not tried);
    ``comparison``: the held-out comparison of the kept set against the model without it (``JointComparison``).
    """

    tried: tuple = ()
    kept: tuple = ()
    reason: str = ""
    comparison: object = None

    def describe(self) -> str:
        """One sentence (empty: the robot file states no coupling)."""
        if not self.tried and not self.reason:
            return ""
        what = ", ".join(self.tried)
        if self.kept:
            return (
                f"coupled transmission: {', '.join(self.kept)} fitted (of {what}; beside the per-joint drive "
                f"columns, on the model the holds above chose): {self.reason}"
            )
        return f"coupled transmission: {what or 'its coupling terms'} not added: {self.reason}"

    def to_dict(self) -> dict:
        return {"tried": list(self.tried), "kept": list(self.kept), "reason": self.reason,
                "comparison": None if self.comparison is None else self.comparison.to_dict()}  # fmt: skip


def coupling_terms(robot, widths=None) -> list:
    """The coupling ``FindingTerm``s of ``robot``'s transmission: for each motor m coupled to a joint k (an entry
    ``N_q[m, k]`` off the diagonal), ``coupling[jm->jk]`` and ``coupling[jk->jm]`` (module docstring)."""
    transmission = getattr(robot, "transmission", None)
    if transmission is None or not transmission.is_coupled:
        return []
    matrix, out = np.asarray(transmission.coupling), []
    for m, k in zip(*np.nonzero(matrix - np.diag(np.diag(matrix)))):
        for joint, source in ((int(k), int(m)), (int(m), int(k))):
            width = {} if widths is None else {"velocity": joint_width(widths, joint)}  # unused by its columns
            term = FindingTerm("coupling", joint=joint, source=source, **width)
            if term not in out:
                out.append(term)
    return out


def _entry(term: FindingTerm) -> dict:
    return {"effect": "coupling", "label": term.label, "kind": "torque", "joints": [term.joint + 1],
            "source": COUPLING_SOURCE, "cause": "the robot file's coupled transmission: the coupled motor's inertia "
            "and viscous friction act on both joints", "term": term.to_dict()}  # fmt: skip


def take_coupled_drives(
    robot, model, calibrated: CalibratedModel, train, validation, kt, robot_source=None, allowance=None
) -> tuple:
    """``(CalibratedModel, fit or None, CoupledDrives)``: ``calibrated`` with the robot file's coupling terms fitted
    jointly where the held-out ``validation`` recordings keep them (module docstring); ``(calibrated, None, record)``
    where none is kept. ``kt``: the held-out recordings' torque constants (one per recording, or None);
    ``allowance`` [N m] per joint: what estimating the rigid body again costs on the held-out motion
    (``robot_file_check.FileCheck.allowance``), allowed beyond the paired margin (the refit moves the rigid body by
    its estimation noise)."""
    allowance = np.zeros(robot.n_dof) if allowance is None else np.nan_to_num(np.asarray(allowance, dtype=float))
    from identification.calibration.applied_model import joint_fit

    terms = coupling_terms(robot, calibrated.coulomb_widths)
    if not terms:
        return calibrated, None, CoupledDrives()
    labels = tuple(t.label for t in terms)
    if not validation:
        return calibrated, None, CoupledDrives(labels, reason="no held-out recording to judge them (--holdout)")
    own = [t for t, _ in calibrated.torque_findings]
    entries = list(calibrated.document.get("findings") or [])
    subsets = [terms] + ([[t] for t in terms] if len(terms) > 1 else [])
    best = None
    for subset in subsets:
        findings = (own + subset, dict(calibrated.corrections), entries + [_entry(t) for t in subset])
        after, fit = joint_fit(calibrated, robot, model, list(train), findings, robot_source)
        each = compare_each(calibrated, after, model, validation, kt)
        pooled = pooled_comparison(each)
        coupled = sorted({t.joint for t in subset})
        better = better_on_each(each, coupled)
        worse = sorted({int(j) for c in each for j in np.flatnonzero(c.after - c.before - c.margin > allowance)})
        logger.info("identify: coupled transmission: with %s: worse on joint(s) %s, better on %s (%s)",
                    [t.label for t in subset], [j + 1 for j in worse], [j + 1 for j in better],
                    pooled.text(range(len(pooled.before))))  # fmt: skip
        if not worse and better and (best is None or improvement(pooled) > improvement(best[3])):
            best = (subset, after, fit, pooled, better)
        if best is not None and subset is terms:
            break  # the pair passing: kept; else the single directions compared
    if best is None:
        return calibrated, None, CoupledDrives(labels, reason="no coupled joint predicted better on each held-out "
                                               "recording without another worse beyond the paired margin")  # fmt: skip
    subset, after, fit, pooled, better = best
    said = pooled.text(better)
    return after, fit, CoupledDrives(labels, tuple(t.label for t in subset), reason=f"held out: {said}",
                                     comparison=pooled)  # fmt: skip


def carried_over(before: dict, after: dict) -> None:
    """Copy into ``after``'s ``identification`` block what identify stated there in ``before`` and the joint fit did
    not keep (the column choice's record, the robot-file check, the holds), in place."""
    for key, value in before["identification"].items():
        after["identification"].setdefault(key, value)
    after.get("provenance", {}).pop("recalibrated_on", None)  # identified, not recalibrated


def coupled_on_route(problem, calibrated: CalibratedModel, validation, robot_source, route: bool, allowance) -> tuple:
    """``take_coupled_drives`` on the model identify writes, ``problem = (robot, model, training recordings, options,
    configurations)``: ``(calibrated, fit or None, CoupledDrives)``; not tried on the LuGre and drive-loss routes
    (``route`` False) or beside a training payload (``joint_fit`` refits without it), the reason stated."""
    from identification.calibration.trajectory_fit import torque_constants

    robot, model, recordings, options, configurations = problem
    terms = coupling_terms(robot)
    if not terms:
        return calibrated, None, CoupledDrives()
    loaded = any(getattr(c, "payload", None) is not None or getattr(c, "unknown", False) for c in configurations or ())
    if not route or loaded:
        reason = "not tried on the LuGre or drive-loss route or beside a training payload"
        return calibrated, None, CoupledDrives(tuple(t.label for t in terms), reason=reason)
    logger.info("identify: the robot file's coupled transmission: fitting its coupling terms %s ...",
                ", ".join(t.label for t in terms))  # fmt: skip
    kt = torque_constants(robot, options, validation) if validation else None
    after, fit, record = take_coupled_drives(robot, model, calibrated, recordings, validation, kt, robot_source,
                                             allowance)  # fmt: skip
    if fit is not None:
        carried_over(calibrated.document, after.document)
    logger.info("identify: %s", record.describe())
    return after, fit, record
