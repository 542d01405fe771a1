"""Identify takes the counterbalance it names: a spring column on the joint, kept only where it holds out of sample.

When identify's report names a counterbalance or spring on a joint (``counterbalance_sources``: a link or drive pushed
against its bounds, a gravity term the fit holds back, a torque offset no sensor has by its size that the data do not
say is an offset, or the fitted gravity torque of one joint alone off the robot file's), the route that finds it is
taken, not only suggested. A spring named by an offset takes that offset's place (the spring's constant); where the
data said balancer it must win beyond the noise like any spring, and one named by an offset the recorded swing cannot
tell from a balancer, or by the gravity departure, spans what it replaces: it is kept where no joint is worse than
the fit without it (``Judges.replacing``), the links or the offset then no longer holding a torque they cannot be.
A spring left out where its offset was is tried again with that offset back (the model keeps the offset).

Identify fits again with a spring on each named joint, linear and cubic (``findings.FindingTerm``, the term ``psdm
diagnose --apply`` adds; its constant left out where the joint's torque offset spans it), and the counterbalance's odd
law of order 5 about a fitted neutral angle where the training data support it beyond the cubic by BIC
(``counterbalance_laws``: the diagnosis's ``SpringTerm`` shape, ``candidates.counterbalance_law``; in a block
cross-validation its angle is fitted again on each fold's training blocks). A kept spring is a
``findings`` entry with ``source`` ``"identify"``, applied by ``psdm validate``, ``predict``, ``diagnose`` (which keeps
it in its nominal model, ``model_file_holds``) and the exported code alike; otherwise the model without it is written
and the report says why and suggests the route that fits it against the robot file (``psdm diagnose ROBOT ...``).

The spring is judged out of sample by the same rules as a diagnosis's finding (``diagnosis.second_opinion``): the
held-out recordings (``--validate A [B ...]``) and, with at most one of them, a block cross-validation over the
training recordings (``counterbalance_folds``: each block held out once, the models without and with the spring
identified on the rest; without held-out recordings it is the only judge). It is kept only if

- its joint's RMSE drops on **every** held-out part: each held-out recording and each block (``Opinion.lowers``; a
  spring that helps on most of the motion and not on a stretch of it does not hold there. While the TX40's links
  absorbed its rotors of joints 1-2, its envelope named a counterbalance on joint 2; a cubic spring there lowered
  three blocks by 24-34 % and raised the first by 6 %, within that block's noise, and the blocks taken together kept
  it, though it raised the held-out end's joint 2 from 3.80 to 4.22 N m; now the first block's rise refuses it);
- the blocks taken together lower its joint **beyond their noise margin**, not only lower it
  (``counterbalance_opinion``: a gain one block carries while the others stay within their noise is a stretch of
  the motion fitted, which an unseen recording of the same arm refuses);
- no joint's RMSE is worse than without it beyond the noise margin, on the held-out recordings together and on the
  blocks together (``never_worse``; the blocks' margin at least the spread of their changes). A joint over its margin
  on the held-out recordings is worse only if the blocks' models (without and with the spring) confirm it there
  (``BlockFolds.refits``): the Denso's cam as a cubic spring raises joint 4, at its noise floor, from 0.01309 to
  0.01353 N m (margin 0.00036), which the refits lower (mean -0.0009): the training fit's noise
  (``CounterbalanceChoice.cleared``);
- nothing is left pushed for a counterbalance on its joints.

``CounterbalanceChoice.route`` says what judged it, ``parts`` gives each recording's and block's numbers.
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field, replace

import numpy as np

from identification.calibration.counterbalance_folds import BlockFolds, FoldFailure, block_folds
from identification.calibration.counterbalance_opinion import HELD_OUT_ROUTE, Opinion, Trial
from identification.calibration.counterbalance_sources import (
    BY_DEPARTURE,
    BY_ENVELOPE,
    BY_HELD_BACK,
    BY_OFFSET,
    counterbalance_joints,
    named_counterbalances,
    named_joints,
)
from identification.calibration.envelope_report import DIAGNOSE_ROUTE
from identification.calibration.findings import FindingColumns, FindingTerm, filled_entries
from identification.calibration.lugre_recordings import split_findings
from identification.calibration.never_worse import compare_each, pooled_comparison
from identification.calibration.spring_rest import rest_angle_text, with_rest_angles
from identification.calibration.trial_fits import trial_fit
from identification.data.torque_constants import recording_kt
from psdm_casadi.errors import InsufficientExcitationError

__all__ = [
    "BY_DEPARTURE",
    "BY_ENVELOPE",
    "BY_HELD_BACK",
    "BY_OFFSET",
    "COUNTERBALANCE_SOURCE",
    "CounterbalanceChoice",
    "Judges",
    "counterbalance_joints",
    "named_joints",
    "spring_model",
    "take_counterbalance",
    "try_counterbalance",
    "trying_line",
]

logger = logging.getLogger(__name__)

#: ``findings[].source`` of a counterbalance identify took.
COUNTERBALANCE_SOURCE = "identify"
#: The spring shapes tried (``SpringTerm`` orders): linear, and a cubic for a cam's or gas spring's torque.
ORDERS = (1, 3)


@dataclass(frozen=True)
class CounterbalanceChoice:
    """What identify decided about the counterbalance its report named.

    Attributes
    ----------
    joints : tuple of int
        0-based joints named (empty: none named, nothing tried).
    named_by : dict
        0-based joint -> where the report named it (``named_joints``: the envelope report, or a parameter the fit
        holds back).
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
        What judged it: ``"held-out recordings"``, the block cross-validation (``counterbalance_folds``), or both.
    parts : tuple of dict
        Per held-out recording and per block, the RMSE of the springs' joints without and with them (each must
        drop).
    cleared : dict
        Joint (1-based) -> the mean held-out RMSE change [N m] of the refits without each training block, for the
        joints over their margin on the held-out recordings whose rise those refits do not reproduce (``never_worse``:
        the training fit's noise, not worse).
    """

    joints: tuple = ()
    named_by: dict = field(default_factory=dict)
    kept: bool = False
    reason: str = ""
    fit: object = field(default=None, repr=False)
    document: dict | None = field(default=None, repr=False)
    rmse_without: np.ndarray | None = None
    rmse_with: np.ndarray | None = None
    margin: np.ndarray | None = None
    route: str = ""
    parts: tuple = ()
    cleared: dict = field(default_factory=dict)

    @property
    def replaced_offsets(self) -> tuple:
        """0-based joints whose data-chosen torque offset a kept spring replaced (held at 0 in the model written)."""
        return tuple(j for j in self.joints if self.kept and self.named_by.get(j) == BY_OFFSET)

    def to_dict(self) -> dict:
        pairs = (("rmse_without", self.rmse_without), ("rmse_with", self.rmse_with), ("margin", self.margin))
        rmse = {k: None if v is None else [float(x) for x in v] for k, v in pairs}
        return {"joints": [j + 1 for j in self.joints], "kept": self.kept, "reason": self.reason, **rmse,
                "named_by": {str(j + 1): v for j, v in self.named_by.items()},
                "route": self.route, "parts": list(self.parts),
                "cleared_by_refits": {str(j): float(v) for j, v in self.cleared.items()}}  # fmt: skip


@dataclass(frozen=True)
class Judges:
    """What judges a spring out of sample: the raw held-out recordings (each), and the block cross-validation of the
    training recordings (each block; None: not used, ``note`` says why when there are held-out recordings).
    ``replacing``: joints whose spring takes the place of an offset no sensor has by size that the data cannot tell
    from a balancer (``counterbalance_sources``) or of a gravity torque the links' first moments took
    (``gravity_departure``): judged against the fit with them
    (``baseline``, its options), such a spring must leave every joint no worse, not lower its own (the two span the
    same torque over the recorded range; the spring keeps the links and the sensor physical)."""

    held: tuple = ()
    folds: BlockFolds | None = None
    note: str = ""
    replacing: tuple = ()
    baseline: object = None

    def holds(self, opinion, joint: int, before=None) -> bool:
        """Whether ``opinion`` keeps the spring on ``joint``: lowered on every part, or, in place of an offset, no
        worse taken together."""
        if joint in self.replacing:
            return joint not in opinion.together.worse
        return opinion.lowers(joint, before)


def _columns(joints, options, recordings, shape) -> FindingColumns:
    """A spring per joint of ``shape``: an order (``[q_j, 1]``, or ``[x, .., x^order, 1]`` with ``x = q_j`` less the
    middle of the training range), or per joint the ``SpringTerm`` to take (a counterbalance's odd law); the constant
    out where the fit has the joint's torque offset."""
    from identification.diagnosis.candidates import SpringTerm

    offsets = options.offset_joints if "offset" in options.friction else ()
    terms, keep = [], []
    for j in joints:
        q = np.concatenate([np.asarray(r.q, dtype=float)[:, j] for r in recordings])
        lo, hi = float(np.min(q)), float(np.max(q))
        if isinstance(shape, dict):
            term = shape.get(j)  # None: the linear spring
        else:
            term = None if shape == 1 else SpringTerm(joint=j, order=shape, centre=0.5 * (lo + hi), q_range=(lo, hi))
        terms.append(FindingTerm("spring", j, spec=None if term is None else term.spec()))
        keep += [True] * (len(terms[-1].feature_names()) - 1) + [not _offset(offsets, j)]
    return FindingColumns(tuple(terms), keep=tuple(keep))


def _with_springs(robot, model, options, build, columns, data, configurations) -> tuple:
    """(the fit without the springs' coefficients, its model file with the spring entries) on ``data``."""
    plain, extra = split_findings(trial_fit(robot, model, data, options, columns, configurations),
                                  len(columns.names))  # fmt: skip
    document = copy.deepcopy(build(plain).document)
    document["findings"] = with_rest_angles([*(document.get("findings") or []), *_entries(columns, extra)],
                                            document.get("drive"))  # fmt: skip
    return plain, document


def spring_model(robot, model, options, build, entries, data):
    """The ``CalibratedModel`` fitted on ``data`` with the springs of ``entries`` (identify's own findings, their terms
    as stored), or ``build`` of the fit without columns where there are none: a judge's refit of a model identify
    chose (``payload_route``)."""
    from identification.calibration.calibrated_model import CalibratedModel

    terms = [FindingTerm.from_dict(entry["term"]) for entry in entries]
    if not terms:
        return build(trial_fit(robot, model, list(data), options))
    offsets = options.offset_joints if "offset" in options.friction else ()
    keep = [k for t in terms for k in [True] * (len(t.feature_names()) - 1) + [not _offset(offsets, t.joint)]]
    columns = FindingColumns(tuple(terms), keep=tuple(keep))
    return CalibratedModel(_with_springs(robot, model, options, build, columns, list(data), None)[1])


def counterbalance_laws(
    robot, model, recordings, options, build, configurations=None, kt=None, joints=(), like=None
) -> dict:
    """Per joint of ``joints``, the counterbalance's odd law the training recordings support (``candidates.
    counterbalance_law``: the lowest BIC against the linear spring and the cubic, the neutral angle fitted), or None;
    with ``like`` (``{joint: law or None}``), its laws with their neutral angles refitted on ``recordings``.

    The torque each law must explain is the training residual of the fit with a cubic spring of every power on each
    joint (the springs' own torque given back): what the spring is to take once the links no longer absorb it. The
    independent samples are those of the low-pass filtered signal (``2 x cut-off x duration``, as the diagnosis's
    BIC)."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.finding_value import validation_rmse
    from identification.diagnosis.candidates import counterbalance_law

    columns = _columns(joints, options, recordings, 3)
    plain, document = _with_springs(robot, model, options, build, columns, recordings, configurations)
    document["findings"] = [f for f in document["findings"] if f.get("source") != COUNTERBALANCE_SOURCE]
    without = CalibratedModel(document)
    q, torque, n_eff = [], [], 0.0
    cutoff = min([c for c in plain.cutoff_hz if c] or [np.inf])
    for recording in recordings:
        _, _, ready, predicted = validation_rmse(without, model, recording, kt)
        q.append(ready.q)
        torque.append(ready.tau - predicted)
        n_eff += 2.0 * cutoff * float(ready.t[-1] - ready.t[0]) if np.isfinite(cutoff) else ready.t.size
    q, torque = np.concatenate(q), np.concatenate(torque)
    if like is not None:
        return {j: like.get(j) and counterbalance_law(j, q[:, j], torque[:, j], n_eff, order=like[j].order)
                for j in joints}  # fmt: skip
    return {j: counterbalance_law(j, q[:, j], torque[:, j], max(n_eff, 2.0)) for j in joints}


def _offset(offsets, joint: int) -> bool:
    """Whether the fit identifies ``joint``'s torque offset (``offsets`` None: every joint's)."""
    return offsets is None or joint in offsets


def _entries(columns: FindingColumns, extra) -> list:
    entries = [{"effect": "spring", "label": t.label, "kind": "torque", "joints": [t.joint + 1], "term": t.to_dict(),
                "source": COUNTERBALANCE_SOURCE, "cause": "counterbalance or spring named by identify's report (a link "
                "pushed against its envelope, or a parameter the fit holds back), kept on the held-out recordings or a "
                "block cross-validation of the training recordings"}
               for t in columns.terms]  # fmt: skip
    return filled_entries(entries, list(columns.terms), columns, extra)


def trying_line(named, held_out: bool) -> str:
    """The progress line of the trial of the counterbalances named on the 0-based joints ``named``, numbered from 1 as
    every other line numbers them (it said ``on [3]`` of the spring it then called joint 4's)."""
    how = "on each held-out recording" if held_out else "by block cross-validation over the training data"
    joints = ("joints " if len(named) > 1 else "joint ") + ", ".join(str(int(j) + 1) for j in named)
    return f"identify: trying the counterbalance the report names on {joints} ({how}) ..."


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
        The held-out recordings (raw); with one, the block cross-validation of ``recordings`` is the second opinion,
        with none the only one (``counterbalance_folds``).
    build : callable
        ``build(fit) -> CalibratedModel`` of a fit (the command line's ``CalibratedModel.from_fit``).
    kt : array, optional
        Torque constants for held-out recordings of currents.
    """
    naming = named_counterbalances(robot, model, recordings, options, fit, calibrated, validation, kt, configurations)
    named, said, readings = naming.named, naming.said, naming.readings
    if not named:
        return CounterbalanceChoice(reason=said)
    logger.info(trying_line(named, bool(validation)))
    judges, offsets = Judges(replacing=naming.lenient, baseline=options), options.offset_joints
    options = replace(options, offset_joints=tuple(j for j in offsets if j not in readings)) if readings else options
    problem = (robot, model, recordings, options, fit, calibrated, validation, build, configurations, kt)
    choice = _tried(problem, named, judges)
    lost = [j for j in readings if choice.kept and j not in choice.joints]
    if lost:  # a spring left out where its offset was: tried again with that offset back
        options = replace(options, offset_joints=tuple(j for j in offsets if j not in readings or j in lost))
        problem = (robot, model, recordings, options, *problem[4:])
        choice = _tried(problem, {j: v for j, v in named.items() if j not in lost}, judges)
    return replace(choice, reason=f"{said}: {choice.reason}") if said else choice


def _tried(problem, named, judges):
    """The ``CounterbalanceChoice`` of the springs on the ``named`` joints (``try_counterbalance``'s ``problem``;
    ``judges``: the offsets the springs replace)."""
    robot, model, recordings, options, fit, calibrated, validation, build, configurations, kt = problem
    joints = tuple(named)
    labels = ", ".join(f"joint {j + 1}" for j in joints)
    cutoffs = [c for c in fit.cutoff_hz if c]
    held = tuple(validation)
    folds = block_folds(recordings, configurations, min(cutoffs) if cutoffs else None) if len(held) < 2 else None
    not_tried = (f"a counterbalance named on {labels}: not tried without held-out recordings: {{}} (pass "
                 f"--validate); {SUGGESTED}")  # fmt: skip
    if isinstance(folds, str) and not held:
        return CounterbalanceChoice(joints, named, reason=not_tried.format(folds))
    judges = replace(judges, held=held, **({"note": folds} if isinstance(folds, str) else {"folds": folds}))
    problem = (robot, model, recordings, options, calibrated, judges, build, configurations, kt)
    shapes = list(ORDERS)
    try:
        laws = counterbalance_laws(robot, model, recordings, options, build, configurations, kt, joints)
    except InsufficientExcitationError as error:  # a spring these data cannot tell from the joint's friction
        return CounterbalanceChoice(joints, named, reason=f"not tried on {labels}: {error}; {SUGGESTED}")
    if any(law is not None for law in laws.values()):
        shapes.append(laws)
        logger.info("identify: the counterbalance's odd law the training data support (BIC): %s", ", ".join(
            f"{law.label} about {law.centre:.4g} rad" for law in laws.values() if law is not None))  # fmt: skip
    try:
        trials = [_pruned(problem, joints, shape) for shape in shapes]
    except FoldFailure as failure:
        if not held:
            return CounterbalanceChoice(joints, named, reason=not_tried.format(failure))
        judges = replace(judges, folds=None, note=str(failure))  # the held-out recordings alone judge
        trials = [_pruned((*problem[:5], judges, *problem[6:]), joints, shape) for shape in shapes]
    return _choice(named, trials, judges)


#: The route a counterbalance not kept is left to (the report's suggestion; the command line fills in its files).
SUGGESTED = DIAGNOSE_ROUTE.format(what="a spring or counterbalance")


def _choice(named, trials, judges) -> CounterbalanceChoice:
    """The ``CounterbalanceChoice`` of the best trial (one per spring order), with its numbers and why."""
    joints = tuple(named)
    passing = [t for t in trials if t[0]]
    ok, chosen, trial = min(passing or trials, key=lambda t: _score(t[2].opinions[0].together))
    comparison = trial.opinions[0].together
    route = " and ".join(opinion.route for opinion in trial.opinions)  # the judges that gave their opinion
    route += f" (no block cross-validation: {judges.note})" if judges.note else ""
    shown = sorted(set(chosen or joints) | set(comparison.worse) | set(comparison.cleared))
    cleared = {j + 1: float(comparison.refit_change[j]) for j in comparison.cleared}
    noise = "".join(f"; joint {j} over its margin, not in the refits without each training block (mean change "
                    f"{v:+.2g} N m: the training fit's noise)" for j, v in cleared.items())  # fmt: skip
    pair = "; ".join(f"joint {j + 1}: {comparison.before[j]:.4g} -> {comparison.after[j]:.4g} N m" for j in shown)
    labels = ", ".join(f"joint {j + 1}" for j in chosen)
    numbers = (comparison.before, comparison.after, comparison.margin, route)
    parts = tuple(part for opinion in trial.opinions for part in opinion.part_dicts(chosen or joints))
    if not ok:
        worse = sorted({j for opinion in trial.opinions for j in opinion.together.worse})
        lead = "none lowers its own joint's error on every held-out part (the blocks together beyond their noise): "
        why = [] if chosen else [lead + trial.failures(joints)]
        if worse:
            why.append("it makes " + ", ".join(f"joint {j + 1}" for j in worse) + " worse beyond the noise margin")
        why = "; ".join(why) or "it leaves them pushed against their bounds"
        return CounterbalanceChoice(joints, named, False, f"a spring on {labels or 'the named joints'} tried and not "
                                    f"kept: {why} ({pair}){noise}; {SUGGESTED}", None, None, *numbers, parts,
                                    cleared)  # fmt: skip
    springs = ", ".join(f["label"] + rest_angle_text(f) for f in trial.document["findings"]
                        if f.get("source") == COUNTERBALANCE_SOURCE)  # fmt: skip
    by = " and ".join(dict.fromkeys(named[j] for j in chosen))
    replaced = ", ".join(f"joint {j + 1}" for j in chosen if j in judges.replacing)
    verdict = (f"in place of what the offset or the links held on {replaced}, no joint worse" if replaced else
               "lower on every held-out part, no joint worse")  # fmt: skip
    reason = (f"a spring on {labels} ({springs}) identified with the model (the counterbalance named by {by}): RMSE on "
              f"the {route} {pair}, {verdict}{noise}")  # fmt: skip
    return CounterbalanceChoice(chosen, named, True, reason, trial.plain, trial.document, *numbers, parts, cleared)


def _score(comparison) -> float:
    """Mean relative held-out RMSE after over before (lower is better)."""
    return float(np.mean(comparison.after / np.maximum(comparison.before, 1e-12)))


def _pruned(problem, joints, order) -> tuple:
    """(passes, joints kept, ``Trial``) of springs of ``order``: each spring that does not lower its own joint's
    held-out error on every held-out part (``Opinion.lowers``; on held-out recordings judged against the fit without
    that spring, the others kept) is left out, then the rest is judged (module docstring)."""
    trial = _attempt(*problem, joints, order)
    kept = []
    for j in joints:
        without = None
        if len(joints) > 1 and problem[5].held:  # on held-out recordings: against the fit with the others kept
            without = _attempt(*problem, tuple(k for k in joints if k != j), order, second=False)
        before = None if without is None else without.opinions[0].together.after[j]
        if all(problem[5].holds(opinion, j, before if k == 0 else None) for k, opinion in enumerate(trial.opinions)):
            kept.append(j)
    if kept and tuple(kept) != tuple(joints):
        trial = _attempt(*problem, tuple(kept), order)
    worse = any(opinion.together.worse for opinion in trial.opinions)
    ok = bool(kept) and trial.complete and not worse and not set(counterbalance_joints(trial.plain)) & set(kept)
    ok = ok and all(problem[5].holds(opinion, j) for opinion in trial.opinions for j in kept)
    return ok, tuple(kept), trial


def _attempt(robot, model, recordings, options, calibrated, judges, build, configurations, kt, joints, order,
             second=True) -> Trial:  # fmt: skip
    """The ``Trial`` of the fit with a spring of ``order`` on ``joints``: judged on the held-out recordings (each, and
    together), then by the block cross-validation (each block, and together) unless the held-out recordings already
    refuse it (a joint worse, or no spring lowering its joint) or ``second`` is False."""
    columns = _columns(joints, options, recordings, order)
    fitted = {}

    def springs_on(pieces):  # a law's neutral angle is fitted again on each fold's training blocks
        fold = columns
        if isinstance(order, dict):
            laws = counterbalance_laws(robot, model, pieces, options, build, None, kt, joints, like=order)
            fold = _columns(joints, options, pieces, laws)
        return type(calibrated)(_with_springs(robot, model, options, build, fold, pieces, None)[1])

    def with_on(pieces):  # a block's model with the springs, once (the held-out second opinion, the block judge)
        if id(pieces) not in fitted:
            fitted[id(pieces)] = springs_on(list(pieces))
        return fitted[id(pieces)]

    def without(pieces):  # the model the springs are judged against: with the offsets they replace
        return build(trial_fit(robot, model, list(pieces), judges.baseline or options))

    plain, document = _with_springs(robot, model, options, build, columns, recordings, configurations)
    opinions = []
    if judges.held:
        each = compare_each(calibrated, type(calibrated)(document), model, list(judges.held), kt)
        together = pooled_comparison(each)
        if judges.folds is not None:  # a joint over its margin is worse only if the blocks' refits confirm it
            together = judges.folds.refits(without, with_on).confirm(together, (), model, list(judges.held), kt)
        opinions.append(Opinion(HELD_OUT_ROUTE, together, each))
    refused = opinions and (opinions[0].together.worse or not any(judges.holds(opinions[0], j) for j in joints))
    if judges.folds is not None and second and not refused:
        together, folds = judges.folds.compare(without, with_on, model, kt)
        opinions.append(Opinion(judges.folds.route, together, folds, beyond_margin=True))
    complete = len(opinions) == bool(judges.held) + (judges.folds is not None)
    return Trial(plain, document, tuple(opinions), complete)


def take_counterbalance(problem, fit, validation, saved: tuple, skip: bool = False) -> tuple:
    """(fit, CalibratedModel, ``CounterbalanceChoice``) of ``psdm identify``: ``problem`` = (robot, model, recordings,
    options, configurations), ``fit`` its consistent fit, ``validation`` the raw held-out recordings, ``saved`` =
    (keywords of ``CalibratedModel.from_fit``: robot_source, lugre, configurations; the recordings' paths); the fit
    without the springs' coefficients and the model file with them when they are kept, the choice in the file's
    ``identification.counterbalance``. ``skip``: a route that takes no extra columns (LuGre, a drive loss), as a fit
    without consistency."""
    from identification.calibration.calibrated_model import CalibratedModel
    from identification.calibration.recording_provenance import recording_provenance

    robot, model, recordings, options, configurations = problem
    keywords, paths = saved
    provenance = [recording_provenance(r, p) for r, p in zip(recordings, paths)]

    def build(result):
        return CalibratedModel.from_fit(robot, model, result, recordings=provenance, **keywords)

    choice, calibrated = CounterbalanceChoice(), build(fit)
    if not skip and fit.checked:
        kt = recording_kt(robot, *validation, *recordings)  # blocks: training
        choice = try_counterbalance(robot, model, recordings, options, fit, calibrated, validation, build,
                                    configurations, kt)  # fmt: skip
        if choice.reason:
            logger.info("identify: %s", choice.reason)
    if choice.kept:
        fit, calibrated = choice.fit, CalibratedModel(choice.document)
    calibrated.document["identification"]["counterbalance"] = choice.to_dict()
    return fit, calibrated, choice
