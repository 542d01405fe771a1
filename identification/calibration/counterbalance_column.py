"""Identify takes the counterbalance it names: a spring column on the joint, kept only where it earns its place.

When the plausible fit pushes a link (or one joint's drive inertia) against its bounds and the report names a
counterbalance or spring on a joint (``envelope_report``), the route that finds it is taken, not only suggested:
identify fits again with a spring on each named joint, linear and cubic (``findings.FindingTerm``, the term ``psdm
diagnose --apply`` adds; its constant left out where the joint's torque offset spans it). The spring is kept only if,
on the held-out recordings, no joint's RMSE is worse than without it beyond the noise margin
(``never_worse.compare_models``), its joints' RMSE drops, and nothing is left pushed for a counterbalance on those
joints; otherwise the model without it is written and the report says why. A kept spring is a ``findings`` entry with
``source`` ``"identify"``, applied by ``psdm validate``, ``predict``, ``diagnose`` (which says the model already
carries it) and the exported code alike. Without held-out recordings (``psdm identify robot.toml rec.csv``) the same
rules are judged by a block cross-validation over the training recordings (``counterbalance_folds``: each block held
out once, the models without and with the spring identified on the rest), where the spring must also not raise its own
joint's error beyond the noise in any block; ``CounterbalanceChoice.route`` says which judged it.
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field

import numpy as np

from identification.calibration.counterbalance_folds import BlockFolds, FoldFailure, block_folds, holds_everywhere
from identification.calibration.findings import FindingColumns, FindingTerm, filled_entries
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.never_worse import compare_models
from identification.calibration.trajectory_fit import identify_trajectories

__all__ = [
    "COUNTERBALANCE_SOURCE",
    "CounterbalanceChoice",
    "counterbalance_joints",
    "take_counterbalance",
    "try_counterbalance",
]

logger = logging.getLogger(__name__)

#: ``findings[].source`` of a counterbalance identify took.
COUNTERBALANCE_SOURCE = "identify"
#: The spring shapes tried (``SpringTerm`` orders): linear, and a cubic for a cam's or gas spring's torque.
ORDERS = (1, 3)


@dataclass(frozen=True)
class CounterbalanceChoice:
    """What identify decided about the counterbalance its envelope report named.

    Attributes
    ----------
    joints : tuple of int
        0-based joints named (empty: none named, nothing tried).
    kept : bool
        Whether the spring columns are in the model written.
    reason : str
        The sentence for the report.
    fit, document : TrajectoryFit, dict or None
        With ``kept``: the fit without the spring columns' coefficients (``lugre_recordings.split_findings``) and the
        calibrated-model document with the spring entries.
    rmse_without, rmse_with, margin : array or None
        Per joint, the held-out RMSE [N m] of the models without and with the springs, and the noise margin a joint
        may be worse by (``never_worse``).
    route : str
        What judged it: ``"held-out recordings"`` or the block cross-validation (``counterbalance_folds``).
    """

    joints: tuple = ()
    kept: bool = False
    reason: str = ""
    fit: object = field(default=None, repr=False)
    document: dict | None = field(default=None, repr=False)
    rmse_without: np.ndarray | None = None
    rmse_with: np.ndarray | None = None
    margin: np.ndarray | None = None
    route: str = ""

    def to_dict(self) -> dict:
        pairs = (("rmse_without", self.rmse_without), ("rmse_with", self.rmse_with), ("margin", self.margin))
        rmse = {k: None if v is None else [float(x) for x in v] for k, v in pairs}
        return {"joints": [j + 1 for j in self.joints], "kept": self.kept, "reason": self.reason, **rmse,
                "route": self.route}  # fmt: skip


def counterbalance_joints(fit) -> tuple:
    """0-based joints the fit's envelope report names a counterbalance or spring on: through a link's bounds (its
    first moment absorbing a gravity-like torque) or one joint's drive inertia pressed down (a torque following the
    position looks like a negative inertia on a periodic motion)."""
    return tuple(sorted({f.joint for f in fit.envelope if f.absorbs == "counterbalance" and f.pressed}))


def _columns(joints, options, recordings, order: int) -> FindingColumns:
    """A spring of ``order`` per joint (``[q_j, 1]``, or ``[x, .., x^order, 1]`` with ``x = q_j`` less the middle of
    the training range: a cam's or gas spring's shape); the constant out where the fit has the joint's torque offset."""
    from identification.diagnosis.candidates import SpringTerm

    offsets = options.offset_joints if "offset" in options.friction else ()
    terms, keep = [], []
    for j in joints:
        q = np.concatenate([np.asarray(r.q, dtype=float)[:, j] for r in recordings])
        lo, hi = float(np.min(q)), float(np.max(q))
        spec = None if order == 1 else SpringTerm(joint=j, order=order, centre=0.5 * (lo + hi), q_range=(lo, hi)).spec()
        terms.append(FindingTerm("spring", j, spec=spec))
        keep += [True] * order + [not _offset(offsets, j)]
    return FindingColumns(tuple(terms), keep=tuple(keep))


def _offset(offsets, joint: int) -> bool:
    """Whether the fit identifies ``joint``'s torque offset (``offsets`` None: every joint's)."""
    return offsets is None or joint in offsets


def _entries(columns: FindingColumns, extra) -> list:
    entries = [{"effect": "spring", "label": t.label, "kind": "torque", "joints": [t.joint + 1], "term": t.to_dict(),
                "source": COUNTERBALANCE_SOURCE, "cause": "counterbalance or spring named by identify's envelope "
                "report (a link pushed against its envelope), kept on the held-out recordings or a block "
                "cross-validation of the training recordings"}
               for t in columns.terms]  # fmt: skip
    return filled_entries(entries, list(columns.terms), columns, extra)


def try_counterbalance(
    robot, model, recordings, options, fit, calibrated, validation, build, configurations=None, kt=None
):
    """The ``CounterbalanceChoice`` for ``fit`` (module docstring).

    Parameters
    ----------
    robot, model, recordings, options, configurations
        Of the fit (``configurations``: the recordings' payload configurations).
    fit, calibrated : TrajectoryFit, CalibratedModel
        The fit without springs and its model file.
    validation : list of Recording
        The held-out recordings (raw); empty: the block cross-validation of ``recordings`` (``counterbalance_folds``).
    build : callable
        ``build(fit) -> CalibratedModel`` of a fit (the command line's ``CalibratedModel.from_fit``).
    kt : array, optional
        Torque constants for held-out recordings of currents.
    """
    joints = counterbalance_joints(fit)
    if not joints:
        return CounterbalanceChoice()
    labels = ", ".join(f"joint {j + 1}" for j in joints)
    cutoffs = [c for c in fit.cutoff_hz if c]
    judge = list(validation) or block_folds(recordings, configurations, min(cutoffs) if cutoffs else None)
    route = judge.route if isinstance(judge, BlockFolds) else "held-out recordings"
    problem = (robot, model, recordings, options, calibrated, judge, build, configurations, kt)
    try:
        if isinstance(judge, str):
            raise FoldFailure(judge)
        trials = [_pruned(problem, joints, order) for order in ORDERS]
    except FoldFailure as failure:
        return CounterbalanceChoice(joints, reason=f"a counterbalance named on {labels}: not tried without held-out "
                                    f"recordings: {failure} (pass --validate)")  # fmt: skip
    passing = [t for t in trials if t[0]]
    ok, chosen, (plain, document, comparison, _) = min(passing or trials, key=lambda t: _score(t[2][2]))
    shown = sorted(set(chosen or joints) | set(comparison.worse))
    pair = "; ".join(f"joint {j + 1}: {comparison.before[j]:.4g} -> {comparison.after[j]:.4g} N m" for j in shown)
    labels = ", ".join(f"joint {j + 1}" for j in chosen)
    numbers = (comparison.before, comparison.after, comparison.margin, route)
    if not ok:
        why = ("it makes " + ", ".join(f"joint {j + 1}" for j in comparison.worse) + " worse beyond the noise margin"
               if comparison.worse else "it leaves them pushed against their bounds" if chosen
               else f"none lowers its own joint's error on the {route}")  # fmt: skip
        return CounterbalanceChoice(joints, False, f"a spring on {labels or 'the named joints'} tried and not kept: "
                                    f"{why} ({pair})", None, None, *numbers)  # fmt: skip
    return CounterbalanceChoice(chosen, True, f"a spring on {labels} identified with the model (the counterbalance "
                                f"the envelope report named): RMSE on the {route} {pair}, no joint worse", plain,
                                document, *numbers)  # fmt: skip


def _score(comparison) -> float:
    """Mean relative held-out RMSE after over before (lower is better)."""
    return float(np.mean(comparison.after / np.maximum(comparison.before, 1e-12)))


def _pruned(problem, joints, order) -> tuple:
    """(passes, joints kept, attempt) of springs of ``order``: each spring whose own joint's held-out error is not
    lower with it than without it (the others kept) is left out, then the rest is judged (module docstring)."""
    trial = _attempt(*problem, joints, order)
    kept = []
    for j in joints:  # judged against the fit without that spring; by the folds, against none (a fifth of the fits)
        alone = trial if len(joints) == 1 or trial[3] is not None else None
        without = _attempt(*problem, tuple(k for k in joints if k != j), order) if alone is None else None
        before = trial[2].before[j] if alone is not None else without[2].after[j]
        if trial[2].after[j] < before and (trial[3] is None or holds_everywhere(trial[3], j)):
            kept.append(j)
    if kept and tuple(kept) != tuple(joints):
        trial = _attempt(*problem, tuple(kept), order)
    plain, _, comparison, _ = trial
    ok = bool(kept) and not comparison.worse and not set(counterbalance_joints(plain)) & set(kept)
    return ok, tuple(kept), trial


def _attempt(robot, model, recordings, options, calibrated, validation, build, configurations, kt, joints, order):
    """(fit without the springs' coefficients, document with the spring entries, ``JointComparison`` against
    ``calibrated`` on the held-out recordings or pooled over the ``BlockFolds``, the folds' comparisons or None) of
    the fit with a spring on ``joints``."""
    columns = _columns(joints, options, recordings, order)

    def with_springs(data, configs):
        plain, extra = split_findings(identify_trajectories(robot, model, data, options, columns, configs),
                                      len(columns.names))  # fmt: skip
        document = copy.deepcopy(build(plain).document)
        document["findings"] = [*(document.get("findings") or []), *_entries(columns, extra)]
        return plain, document

    plain, document = with_springs(recordings, configurations)
    if not isinstance(validation, BlockFolds):
        return plain, document, compare_models(calibrated, type(calibrated)(document), model, validation, kt), None
    comparison, folds = validation.compare(
        lambda pieces: build(identify_trajectories(robot, model, list(pieces), options)),
        lambda pieces: type(calibrated)(with_springs(list(pieces), None)[1]),
        model,
        kt,
    )
    return plain, document, comparison, folds


def take_counterbalance(problem, fit, validation, saved: tuple, skip: bool = False) -> tuple:
    """(fit, CalibratedModel, ``CounterbalanceChoice``) of ``psdm identify``: ``problem`` = (robot, model, recordings,
    options, configurations), ``fit`` its consistent fit, ``validation`` the raw held-out recordings, ``saved`` =
    (keywords of ``CalibratedModel.from_fit``: robot_source, lugre, configurations; the recordings' paths); the fit
    without the springs' coefficients and the model file with them when they are kept, the choice in the file's
    ``identification.counterbalance``. ``skip``: a route that takes no extra columns (LuGre, a drive loss), as a fit
    without consistency."""
    from identification.calibration.calibrated_model import CalibratedModel, recording_provenance

    robot, model, recordings, options, configurations = problem
    keywords, paths = saved
    provenance = [recording_provenance(r, p) for r, p in zip(recordings, paths)]

    def build(result):
        return CalibratedModel.from_fit(robot, model, result, recordings=provenance, **keywords)

    choice, calibrated = CounterbalanceChoice(), build(fit)
    if not skip and fit.checked:
        kt = None
        if any(r.tau is None for r in (validation or recordings)) and robot.drives is not None:
            kt = np.array([d.kt for d in robot.drives], dtype=float)
        if counterbalance_joints(fit):
            how = "on the held-out recordings" if validation else "by block cross-validation over the training data"
            logger.info(f"identify: trying the counterbalance the envelope report names ({how}) ...")
        choice = try_counterbalance(robot, model, recordings, options, fit, calibrated, validation, build,
                                    configurations, kt)  # fmt: skip
        if choice.reason:
            logger.info("identify: %s", choice.reason)
    if choice.kept:
        fit, calibrated = choice.fit, CalibratedModel(choice.document)
    calibrated.document["identification"]["counterbalance"] = choice.to_dict()
    return fit, calibrated, choice
