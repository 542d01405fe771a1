"""LuGre friction by default where the data show the bristles' lag: a trial of ``--friction lugre``, kept if better.

A steady-state friction model (Coulomb-viscous or Stribeck, its sign smoothed by ``tanh(qd / v)``) is an odd function of
the velocity: around a velocity reversal its error is odd in time about the zero crossing (a sharper or smoother truth
is above the model on one side and below it on the other). LuGre friction with pre-sliding is not: after a reversal the
bristles hold the old direction's friction until the joint has moved some ``fc / sigma0``, so the friction lags the
velocity, and the residual of a steady-state model has the old direction's sign on *both* sides of the crossing, and
only there. That even part, less the same mean over the sliding flanks of the reversal (where an error of the position,
a spring's, shows alike), averaged over the reversals (:func:`reversal_lags`), is the symptom; a symmetric window around
zero velocity (what a smoothed Coulomb step's error also fills) is not. The rigid body cannot take it: it runs against
the acceleration at the reversals only, and a fit that lowers the inertia to absorb it there is wrong elsewhere (the
belt cobot of ``benchmarks/unseen_belt_cobot``: its joint-1 inertia came out low).

The lag is read on the held-out recordings the robot file is judged on (``file_judged``), on the residual of the model
identify would write. Where the arm shows it beyond noise and in size (its joints' readings pooled, ``ArmLag``:
``LAG_SIGMAS`` standard errors of their sum and ``LAG_SHARE`` of their RMSE; a joint of three to six reversals reads
a lag the LuGre model then removes at only one or two standard errors, where the steady-state truths' readings pool to
about zero), the LuGre route (``lugre_identify``) is fitted beside, carried to its model file
(``written_model``), and kept only where it predicts each held-out recording better on a lagging joint and worse on none
(``never_worse``'s paired margins), and pushes no link against its physical envelope (``envelope_report``) that the
default model leaves inside it: a rigid body bent to fit the friction at the reversals is not a better model.

The trial's model is judged against the default model (:func:`_refused_joints`), and the default model against the
robot file (``robot_file_check``, with the holds that check calls for): a joint the trial predicts within the paired
margin of the default keeps the default model's verdict against the file, and a joint beyond it is worse already. The
trial's own check against the file (written and reported with its model) is no judge of the trial: it compares the two
models through a third, with the noise of both comparisons and, on a LuGre joint, a baseline of its own (the file with
the Stribeck friction the LuGre fit starts from); as a judge it flipped the friction chosen by which held-out recording
was used, on a joint the trial predicted as the default model does.

Where LuGre on every joint is refused, the joints it predicts better on each held-out recording and worse on none
(:func:`keep_joints`) keep it and the others the default model's steady-state shape (``mixed_friction``): the
alternation goes on from the trial's LuGre fit on those joints alone (:func:`mixed_trial`), and the mixed model is
judged by the same rules. A joint whose LuGre fit is worse (a wrist of few or fast reversals, a steady-state shape the
LuGre fit cannot take) then no longer costs the joints that lag their gain; it is tried only where a lagging joint
gains beyond its margin. The result names the LuGre joints and why each other joint kept the steady-state shape
(:func:`steady_reasons`). The trial's own log lines are not identify's (silenced: the result states it once).

The trial's fit takes the default model's viscous power law (``viscous_power``: the exponent ``dv`` each joint's data
chose, 1 where linear): its Stribeck start is fitted with it, and each joint's LuGre friction holds it (the paper's
eq. 14 carries ``fv |qd|^dv``), as does the robot file's friction the trial's model is judged against there
(``robot_file_check``: the start's columns). Fitted with ``dv = 1`` instead, a LuGre joint lost the law its default
model had found: the virtual Denso's wrist (a power law in its truth, and no Stribeck hump) predicted its held-out
motion worse than the file's linear Stribeck start, whose static friction below the Coulomb level takes some of the
filter's smearing, and was reported worse than the file by a hair, at the edge of that comparison's noise.
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from dataclasses import dataclass

import numpy as np

from identification.calibration.coulomb_width import joint_width
from identification.calibration.never_worse import better_on_each
from psdm_casadi.log_context import held_back
from psdm_casadi.state_cache import BlockMemory

__all__ = ["JOINT_SIGMAS", "LAG_SHARE", "LAG_SIGMAS", "MIN_REVERSALS", "RULE", "SETTLE_SD", "ArmLag", "LuGreTrial",
           "ReversalLag", "judge_trial", "keep_joints", "lag_joints", "mixed_trial", "quiet_trial", "recording_lags",
           "reversal_lags", "steady_reasons", "try_lugre"]  # fmt: skip

logger = logging.getLogger(__name__)

#: The arm's lag counts when its joints' readings (each the even part of the residual over its reversals in standard
#: errors of its mean, ``ReversalLag.sigmas``) sum to this many standard errors of the sum (``ArmLag``) ...
LAG_SIGMAS = 2.5
#: ... and their mean share of the joints' held-out RMSE is at least this; a joint lags where its own reading is this
#: share and ``JOINT_SIGMAS`` standard errors.
LAG_SHARE = 0.5
JOINT_SIGMAS = 1.0
#: Fewer reversals than this in a recording say nothing about a joint.
MIN_REVERSALS = 3
#: The window of a reversal: the samples around the crossing slower than this multiple of the Coulomb smoothing.
WINDOW_SMOOTHINGS = 2.0
#: The trial's LuGre fits and rigid-body refits alternate until every LuGre parameter moves by less than this many of
#: its standard deviations between two fits (or by less than 1 %; ``lugre_identify.round_change``): a step inside
#: the parameter's uncertainty changes neither the friction's prediction nor the rigid body beyond it, and each
#: round costs a LuGre fit of every joint (``--friction lugre`` keeps the finer ``ROUND_TOLERANCE_SD``).
SETTLE_SD = 0.5


@dataclass(frozen=True)
class ReversalLag:
    """One joint's residual at its velocity reversals on one recording: ``lag`` [N m] the mean over the reversals of
    the even part (the old direction's sign on both sides of the crossing), its ``standard_error``, ``reversals``
    counted and the joint's ``rmse`` over the recording."""

    joint: int
    reversals: int
    lag: float
    standard_error: float
    rmse: float

    @property
    def sigmas(self) -> float:
        return self.lag / self.standard_error if self.standard_error > 0 else 0.0

    @property
    def share(self) -> float:
        return self.lag / self.rmse if self.rmse > 0 else 0.0

    @property
    def shows(self) -> bool:
        """Whether the joint lags where the arm does (``ArmLag``): enough reversals, a reading of ``JOINT_SIGMAS``
        standard errors and ``LAG_SHARE`` of its RMSE."""
        return self.reversals >= MIN_REVERSALS and self.sigmas >= JOINT_SIGMAS and self.share >= LAG_SHARE

    def text(self) -> str:
        """The lag in words; its size against the joint's RMSE as a share up to the whole, as a ratio beyond (the lag
        is the mean at the reversals, the RMSE over the whole recording, so it may exceed it: it was printed as a share
        above 100 %)."""
        size = (
            f"{self.share:.0%} of its RMSE"
            if self.share <= 1.0
            else (f"{self.share:.2g} x its RMSE over the recording, which the lag at the reversals exceeds")
        )
        return (f"joint {self.joint + 1}: {self.lag:.3g} N m over {self.reversals} reversals ({self.sigmas:.1f} "
                f"standard errors, {size})")  # fmt: skip


def _events(qd, residual, velocity) -> list:
    """Per reversal (a run of samples slower than ``velocity`` entered in one direction and left in the other): the
    mean of ``-s * residual`` before and after the crossing, ``s`` the new direction, less its mean over the flanks
    (as many samples as the run on each side, sliding): an error of the position (an unmodelled spring or gravity)
    has the old direction's sign at both ends of a stroke too, but it is there before and after the run as well,
    where the bristles have let go."""
    slow = np.abs(qd) < velocity
    edges = np.flatnonzero(np.diff(slow.astype(int)) != 0) + 1
    bounds = np.concatenate([[0], edges, [len(qd)]])
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if not slow[a] or a == 0 or b == len(qd) or b - a < 3:
            continue
        before, after = np.sign(qd[a - 1]), np.sign(qd[b])
        if before == after or before == 0:
            continue
        cross = a + int(np.argmax(np.sign(qd[a:b]) == after))
        pre, post = -after * residual[a:cross], -after * residual[cross:b]
        flanks = -after * np.concatenate([residual[max(0, 2 * a - b) : a], residual[b : 2 * b - a]])
        if pre.size and post.size and np.all(np.isfinite(np.concatenate([pre, post, flanks]))):
            out.append(0.5 * (pre.mean() + post.mean()) - flanks.mean())
    return out


def reversal_lags(qd, residual, velocity) -> tuple:
    """One :class:`ReversalLag` per joint of a prepared recording's velocity ``qd`` and a model's ``residual`` (both
    ``(samples, joints)``), the reversals' windows slower than ``velocity`` [rad/s] (one, or one per joint).

    The standard error of the mean lag is the reversals' spread over the root of their number, never below the joint's
    RMSE over it: a model error is correlated across a reversal's window, so one window's mean is not known better
    than the residual's own size, and the spread of three or four reversals can be small by chance (on a
    Coulomb-viscous truth's short held-out recording, the spread alone made a joint's odd-shaped error a "lag" of many
    standard errors)."""
    out = []
    for j in range(residual.shape[1]):
        even = np.asarray(_events(qd[:, j], residual[:, j], joint_width(velocity, j)))
        finite = residual[np.isfinite(residual[:, j]), j]
        rmse = float(np.sqrt(np.mean(finite**2))) if finite.size else 0.0
        spread = float(even.std(ddof=1)) if even.size > 1 else 0.0
        se = max(spread, rmse) / np.sqrt(max(even.size, 1))  # a reversal's mean is not known better than the RMSE
        out.append(ReversalLag(j, int(even.size), float(even.mean()) if even.size else 0.0, se, rmse))
    return tuple(out)


def recording_lags(calibrated, model, recordings, kts, velocity) -> tuple:
    """Per raw held-out recording, the :func:`reversal_lags` of ``calibrated``'s residual (``kts``: each recording's
    torque constants, as the robot-file check reads them)."""
    out = []
    for recording, kt in zip(recordings, kts):
        ready, predicted = calibrated.predict_recording(model, recording, kt)
        out.append(
            reversal_lags(ready.qd, ready.tau - predicted, WINDOW_SMOOTHINGS * np.asarray(velocity, dtype=float))
        )
    return tuple(out)


@dataclass(frozen=True)
class ArmLag:
    """The arm's lag on one recording: its joints' readings (those with ``MIN_REVERSALS``) pooled, ``sigmas`` their sum
    over the root of their number (a standard normal where no joint lags), ``share`` their mean share of the joints'
    RMSE, ``joints`` how many were read.

    Pooled because a drive's bristles are the arm's make, not one joint's: a joint of a few reversals reads its lag
    at one or two standard errors (each a reversal window's mean, not known better than the joint's RMSE), and the
    arm's joints together read it beyond noise where each alone does not."""

    sigmas: float
    share: float
    joints: int

    @classmethod
    def of(cls, per) -> ArmLag:
        read = [item for item in per if item.reversals >= MIN_REVERSALS]
        if not read:
            return cls(0.0, 0.0, 0)
        total = sum(item.sigmas for item in read) / np.sqrt(len(read))
        return cls(float(total), float(np.mean([item.share for item in read])), len(read))

    @property
    def shows(self) -> bool:
        return self.joints > 0 and self.sigmas >= LAG_SIGMAS and self.share >= LAG_SHARE

    def text(self) -> str:
        return (f"the arm's {self.joints} joints {self.sigmas:.1f} standard errors together, {self.share:.0%} of their "
                "RMSE")  # fmt: skip


def lag_joints(lags) -> tuple:
    """The joints (0-based) that lag (``ReversalLag.shows``) on a recording where the arm does (``ArmLag``), and
    against it on none."""
    shows = {item.joint for per in lags if ArmLag.of(per).shows for item in per if item.shows}
    against = {item.joint for per in lags for item in per if item.reversals >= MIN_REVERSALS
               and item.sigmas <= -LAG_SIGMAS}  # fmt: skip
    return tuple(sorted(shows - against))


@dataclass(frozen=True)
class LuGreTrial:
    """What identify decided about LuGre friction on default settings (module docstring).

    ``lags``: per held-out recording the :class:`ReversalLag` of each joint on the default model; ``joints``: the
    joints (0-based) that showed it (empty: LuGre not tried); ``kept``: the LuGre model written; ``before``/``after``
    /``margin``: the held-out RMSE per joint of the default and the LuGre model with the paired margin (pooled over
    the recordings); ``reason``: why kept or not; ``better``: the joints (0-based) it predicts better than the default
    model beyond the margin on each held-out recording (the others keep the default model's verdict against the robot
    file where it is kept: ``robot_file_check.FileCheck.keeping_verdicts``)."""

    lags: tuple = ()
    joints: tuple = ()
    kept: bool = False
    before: tuple = ()
    after: tuple = ()
    margin: tuple = ()
    reason: str = ""
    lugre_joints: tuple = ()
    every_joint: str = ""
    steady: str = ""
    better: tuple = ()

    def describe(self) -> str:
        """``friction: LuGre on every joint, chosen because ...``, ``friction: LuGre on joint(s) 1, 2 (the others keep
        the steady-state shape: ...), chosen because ...`` or why the steady-state shape stays ("" where no joint
        showed the lag)."""
        if not self.joints:
            return ""
        arm = "; ".join(ArmLag.of(per).text() for per in self.lags if ArmLag.of(per).shows)
        shown = "; ".join([arm, *(item.text() for per in self.lags for item in per if item.joint in self.joints)])
        head = f"the residual at the velocity reversals lags the velocity as pre-sliding friction does ({shown})"
        n = len(self.lags[0]) if self.lags else 0
        mixed = self.every_joint and 0 < len(self.lugre_joints) < n
        named = ", ".join(str(j + 1) for j in self.lugre_joints)
        rest = ", ".join(str(j + 1) for j in range(n) if j not in self.lugre_joints)
        where = (f"LuGre on joint(s) {named} (joint(s) {rest} keep the steady-state shape: {self.steady})" if mixed
                 else "LuGre on every joint")  # fmt: skip
        if self.kept:
            return f"friction: {where}, chosen because {head}, and {self.reason}"
        tried = f"the LuGre fit tried on every joint {self.every_joint}, and with {where}," if mixed else (
            "the LuGre fit tried")  # fmt: skip
        return f"friction: the steady-state shape kept: {head}, but {tried} {self.reason}"

    def to_dict(self) -> dict:
        lags = [[{"joint": i.joint + 1, "reversals": i.reversals, "lag": float(i.lag), "rmse": float(i.rmse),
                  "standard_error": float(i.standard_error), "shows": bool(i.shows)} for i in per]
                for per in self.lags]  # fmt: skip
        arms = [ArmLag.of(per) for per in self.lags]
        return {
            "tried": bool(self.joints),
            "kept": self.kept,
            "lag_joints": [j + 1 for j in self.joints],
            "lugre_joints": [j + 1 for j in self.lugre_joints],  # of the model tried last (kept where "kept")
            "every_joint_reason": self.every_joint,  # why LuGre on every joint was refused ("" where it was not)
            "steady_joints_reason": self.steady,  # why each joint outside lugre_joints kept the steady-state shape
            "lags": lags,
            "arm": [{"sigmas": a.sigmas, "share": a.share, "joints": a.joints, "shows": a.shows} for a in arms],
            "rule": RULE,
            "validation_rmse_default": list(self.before),
            "validation_rmse_lugre": list(self.after),
            "margin": list(self.margin),
            "better_joints": [j + 1 for j in self.better],  # the others keep the default model's verdict if kept
            "reason": self.reason,
        }


RULE = (
    f"the arm shows the bristles' lag when the even part of its joints' held-out residual over their velocity "
    f"reversals (>= {MIN_REVERSALS} each), in standard errors, sums to >= {LAG_SIGMAS:g} standard errors of the sum "
    f"and is >= {LAG_SHARE:.0%} of their RMSE on average; a joint lags there at >= {JOINT_SIGMAS:g} standard error "
    f"and >= {LAG_SHARE:.0%} of its RMSE; then LuGre "
    "friction is fitted and kept only if it predicts each held-out recording better on a lagging joint, worse on "
    "none (paired margins; a joint within them keeps the default model's verdict against the robot file), and "
    "pushes no link against its physical envelope the default model leaves inside it; where LuGre on every joint is "
    "refused, LuGre is fitted on the joints it predicts better on each held-out recording and worse on none (the "
    "others keeping the default model's steady-state shape), and that model is judged by the same rules"
)


def _refused_joints(comparisons) -> tuple:
    """The joints (0-based, sorted) a trial's model is refused on: those it predicts a held-out recording worse on than
    the default model beyond the paired margin (``comparisons``). The one reading of the rules :func:`judge_trial`,
    :func:`keep_joints` and :func:`steady_reasons` share.

    A joint within the margin on every recording keeps the default model's verdict against the robot file: the two
    models predict it alike to the noise, and the default one is the model judged against the file (module
    docstring). The trial's own check against the file adds no joint beyond these: where it names a joint the default
    model's does not and the joint is within the margin, it judges the noise of two comparisons (or, on a LuGre joint,
    a baseline of its own: the file with the Stribeck friction the LuGre fit starts from), not the trial's model."""
    return sorted({j for c in comparisons for j in c.worse})


def keep_joints(comparisons, joints) -> tuple:
    """The joints (0-based) on which a mixed model keeps LuGre friction (``mixed_friction``) where the LuGre model of
    every joint is refused: those it predicts better than the default model on each held-out recording
    (``comparisons``, as :func:`judge_trial`'s) and worse on none beyond the margin; empty unless one of the lagging
    ``joints`` is among them better beyond the margin and a joint is left to the steady-state shape (else the mixed
    model is the one refused, or cannot pass)."""
    n, off = len(comparisons[0].before), set(_refused_joints(comparisons))
    keep = tuple(j for j in range(n) if j not in off and all(c.after[j] < c.before[j] for c in comparisons))
    gain = [j for j in keep if j in better_on_each(comparisons, joints)]
    return keep if gain and len(keep) < n else ()


def steady_reasons(comparisons, keep) -> str:
    """Why each joint outside ``keep`` keeps the steady-state shape (:func:`keep_joints`'s rule, its numbers from the
    first held-out recording): worse beyond its margin, or not better on each."""
    n, first = len(comparisons[0].before), comparisons[0]
    worse = _refused_joints(comparisons)
    rest = [j for j in range(n) if j not in keep and j not in worse]
    parts = [f"joint {j + 1} worse ({first.before[j]:.4g} -> {first.after[j]:.4g} N m, margin {first.margin[j]:.2g})"
             for j in worse]  # fmt: skip
    if rest:
        parts.append(f"joint(s) {', '.join(str(j + 1) for j in rest)} not better on each held-out recording")
    return "; ".join(parts)


def judge_trial(default, lugre, comparisons, joints) -> tuple:
    """``(kept, reason)``: whether the LuGre ``lugre`` written model (``written_model.WrittenModel``) replaces the
    ``default`` one, ``comparisons`` the ``never_worse.JointComparison`` of the two on each held-out recording
    (default before, LuGre after), ``joints`` the lagging ones."""
    worse = _refused_joints(comparisons)
    if worse:
        return False, f"is worse on joint(s) {', '.join(str(j + 1) for j in worse)} ({comparisons[0].text(worse)})"
    better = better_on_each(comparisons, joints)
    if not better:
        return False, "does not predict a lagging joint better beyond the margin on each held-out recording"
    pushed = sorted({f.link for f in lugre.fit.envelope} - {f.link for f in default.fit.envelope})
    if pushed:  # a rigid body made implausible to fit the friction's reversals is no better model
        links = ", ".join(str(i + 1) for i in pushed)
        return False, f"pushes link(s) {links} against their physical envelope, which the default model does not"
    text = "; ".join(f"joint {j + 1}: {comparisons[0].before[j]:.4g} -> {comparisons[0].after[j]:.4g} N m"
                     for j in better)  # fmt: skip
    return True, f"it predicts the held-out recording(s) better there ({text}) and worse on no joint"


#: The trial's LuGre fits, kept while a ``state_cache.remembering`` block is open (``psdm identify``'s run): by
#: ``trial_fits.fit_key``, the LuGre joints and the start, with the model fitted and the fit's warnings.
_FITS = BlockMemory()


def _lugre_fit(problem, caught, joints=None, start=None):
    """The trial's ``LuGreIdentification`` of ``problem = (robot, model, recordings, options, configurations)`` (LuGre
    on ``joints``, None: every joint, from ``start``; :func:`mixed_trial`'s): made once in a ``remembering`` block
    (``_FITS``; ``psdm identify`` runs its route again where it took a held-out load off, on the same training
    recordings), its warnings added to ``caught`` as the fit issued them."""
    from identification.calibration.lugre_identify import identify_lugre_trajectories
    from identification.calibration.trial_fits import fit_key

    robot, model, recordings, chosen, configurations = problem
    first, made, held = len(caught), [], () if start is None else tuple(start)

    def fit() -> tuple:
        found = identify_lugre_trajectories(robot, model, recordings, chosen, configurations=configurations,
                                            settle_sd=SETTLE_SD, joints=joints, start=start)  # fmt: skip
        made.append(found)
        return held, found, tuple(caught[first:])  # the fit's warnings: the result's if it is kept

    # the start by identity: the entry holds it, so an id in a remembered key is the very start it was made from
    key = (fit_key(robot, recordings, chosen, configurations), joints, tuple(map(id, held)))
    _, found, said = _FITS.get_with(key, model, fit)  # a --model file's derivation: fitted again
    if not made:
        caught.extend(said)
    return found


@contextlib.contextmanager
def quiet_trial():
    """The trial's log lines and Python warnings held back: identify's log is the default route's, and the result
    states the trial once. Its progress lines (of ``identification`` and ``psdm_casadi``, below WARNING) are held back
    in this context only (``log_context.held_back``: a fleet run's other threads log on); its warnings are recorded
    and yielded (re-issued by the caller if the trial's model is kept)."""
    with held_back("identification", "psdm_casadi"), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield caught


def try_lugre(problem, written, judged, writer, request) -> tuple:
    """``(LuGreTrial, kept)``: the lag of the default model ``written`` (``written_model.WrittenModel``) on the
    ``judged`` held-out recordings (``file_judged.FileJudged``), and where a joint shows it the LuGre route fitted and
    judged (module docstring): on every joint, and where that is refused, on the joints it helps (:func:`keep_joints`,
    :func:`mixed_trial`); ``kept`` is ``(LuGreIdentification, WrittenModel, ColumnChoice)`` of the LuGre model where it
    replaces the default, else None. ``problem = (robot, model, recordings, options, validation, configurations)``
    with the options identify was given; ``writer(lugre_fit, columns) -> written_model.ModelWriter``; ``request`` the
    column request (its friction becomes ``"lugre"``). The LuGre fit of every joint is made once in a
    ``state_cache.remembering`` block (``_lugre_fit``)."""
    from dataclasses import replace

    from identification.calibration.column_choice import choose_columns
    from identification.calibration.never_worse import compare_each
    from identification.calibration.trajectory_fit import torque_constants
    from psdm_casadi.errors import ParameterError, SolverError

    robot, model, recordings, options, validation, configurations = problem
    kts = [torque_constants(robot, written.options, [r]) for r in judged.recordings]
    lags = recording_lags(written.calibrated, model, judged.recordings, kts, written.fit.coulomb_velocity)
    joints = lag_joints(lags)
    if not joints:
        return LuGreTrial(lags=lags), None
    if written.check.one_way:  # the LuGre route fits every joint along its reversals
        one_way = ", ".join(str(j + 1) for j in written.check.one_way)
        return LuGreTrial(lags, joints, reason=f"was not made: joint(s) {one_way} never reverse in training"), None
    logger.info("identify: joint(s) %s lag at their velocity reversals as pre-sliding friction does: trying LuGre "
                "friction beside ...", ", ".join(str(j + 1) for j in joints))  # fmt: skip
    try:
        with quiet_trial() as caught:
            choice = choose_columns(robot, model, recordings, options, replace(request, friction="lugre"), validation,
                                    configurations)  # fmt: skip
            chosen = replace(choice.options(options), viscous_exponent=written.options.viscous_exponent)  # as chosen
            found = _lugre_fit((robot, model, recordings, chosen, configurations), caught)
            lugre = writer(found.lugre, found.stribeck)(chosen, found.fit)
            comparisons = [compare_each(written.calibrated, lugre.calibrated, model, [r], kt)[0]
                           for r, kt in zip(judged.recordings, kts)]  # fmt: skip
    except (ParameterError, SolverError) as error:  # the default model stands, and the record says why
        return LuGreTrial(lags, joints, reason=f"could not be made ({error})"), None
    kept, reason = judge_trial(written, lugre, comparisons, joints)
    trial = _trial(lags, joints, kept, reason, comparisons, tuple(range(robot.n_dof)))
    if not kept and (keep := keep_joints(comparisons, joints)):
        steady = steady_reasons(comparisons, keep)
        outcome = mixed_trial(problem, written, (judged, kts), writer, found, keep)
        if outcome[0] is not None:
            caught, (found, lugre, comparisons) = outcome[0], outcome[1:]
            kept, mixed = judge_trial(written, lugre, comparisons, joints)
            trial = replace(_trial(lags, joints, kept, mixed, comparisons, keep), every_joint=reason, steady=steady)
        else:
            trial = replace(trial, lugre_joints=keep, every_joint=reason, steady=steady, reason=outcome[1])
    logger.info("identify: %s", trial.describe())
    if not trial.kept:
        return trial, None
    for warning in caught:  # the LuGre model's warnings are the result's
        warnings.warn(warning.message, warning.category, stacklevel=2)
    return trial, (found, lugre, choice)


def _trial(lags, joints, kept, reason, comparisons, lugre_joints) -> LuGreTrial:
    """The :class:`LuGreTrial` of a judged LuGre model (on ``lugre_joints``), its RMSE pooled over the recordings."""
    from identification.calibration.never_worse import pooled_comparison

    pooled = pooled_comparison(comparisons)
    better = better_on_each(comparisons, range(len(pooled.before)))
    return LuGreTrial(lags, joints, kept, tuple(map(float, pooled.before)), tuple(map(float, pooled.after)),
                      tuple(map(float, pooled.margin)), reason, tuple(lugre_joints), better=better)  # fmt: skip


def mixed_trial(problem, written, judged, writer, found, keep) -> tuple:
    """``(caught warnings, LuGreIdentification, WrittenModel, comparisons)`` of the mixed model (``mixed_friction``):
    LuGre on the joints ``keep`` (0-based), continued from the LuGre model of every joint ``found``, the default model
    ``written``'s steady-state shape on the others; or ``(None, why not)`` where it cannot be made. ``judged`` =
    ``(file_judged.FileJudged, torque constants per recording)``. Its check against the robot file gives each joint
    the file's friction in that joint's shape (``robot_file_check.joint_fits``): the Stribeck start on a LuGre joint,
    the model's own columns on a steady-state one."""
    from identification.calibration.mixed_friction import mixed_options
    from identification.calibration.never_worse import compare_each
    from psdm_casadi.errors import ParameterError, SolverError

    robot, model, recordings, _, _, configurations = problem
    (judged, kts), named = judged, ", ".join(str(j + 1) for j in keep)
    logger.info("identify: LuGre on every joint refused; trying it on joint(s) %s only ...", named)
    try:
        with quiet_trial() as caught:
            options = mixed_options(written.options, keep, written.fit.stribeck_velocity or [0.0] * robot.n_dof)
            mixed = _lugre_fit((robot, model, recordings, options, configurations), caught, tuple(keep),
                               (found.stribeck, found.lugre))  # fmt: skip
            columns = tuple(found.stribeck if j in keep else None for j in range(robot.n_dof))  # shapes as given
            lugre = writer(mixed.lugre, columns)(options, mixed.fit)
            comparisons = [compare_each(written.calibrated, lugre.calibrated, model, [r], kt)[0]
                           for r, kt in zip(judged.recordings, kts)]  # fmt: skip
    except (ParameterError, SolverError) as error:
        return None, f"could not be made ({error})"
    return list(caught), mixed, lugre, comparisons
