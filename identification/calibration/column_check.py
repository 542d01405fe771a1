"""A column the held-out data alone decided is checked on the model identify writes: no joint made worse.

The column choice (``column_choice``) judges its candidates on the free least squares of every candidate column. Where
the training BIC decides and the held-out error agrees, that is the verdict. Where the held-out data alone decide
(``Evidence.departs``: a BIC inside the indifferent band, kept for a clear held-out gain or refused for too small a
one; or a column one validation recording contradicts), the verdict rests on two free least-squares fits of the
training data, and those can be far from the model identify writes: the consistent fit, pulled towards the robot
file. On the Kinova Gen3's CLI defaults (one 4.7-s recording, opti_traj_testing1 -> 2) the free fit predicts the
held-out recording at 5.6/11.6/3.2/1.5/2.5/1.4/0.27 N m, the written model at 1.2/2.8/0.64/0.95/0.30/0.51/0.17. Its
joint-7 drive inertia (BIC -1.1) lowers the free fit's joint 7 by 56 % (0.60 -> 0.27 N m) and raises the written model's
(0.170 -> 0.268): the free fit's joint 7 wants what the pull holds back in link 7 (a tool). Kept, it also says the
torque signal holds rotors (``merged_rotors``: any kept ``Ia<j>``), so the rotors the base parameters hold on joints
1-2 are taken from the training data and held only >= 0, the pull no longer holds the inertia about joint 2 (0.93 ->
3.38, data 4.67, file 0.82), and joint 2 goes from 2.77 to 6.85 N m.

So each such column is decided on the written model, one at a time (in the choice's order): the model is fitted with
the choice as it stands and with that column as the plain rule would have it (its BIC's sign and the pooled held-out
error), and the choice stands unless it is worse than the plain one beyond the never-worse margin on some joint of
the held-out data. A refusal is a model change as much as a keep: it is judged the same way. The held-out data are the
validation recordings (``never_worse.compare_models``; one more consistent fit per departure), else, as for identify's
counterbalance, a block cross-validation of the training recordings with each fold's two models identified on its
other blocks (``counterbalance_folds``; 2 x 4 more fits per departure, a fold's model of columns an earlier departure
fitted reused, and the plain rule's fit of all the training data made only where it wins). Training recordings too
short to cut into blocks, or carrying payloads, leave the choice as the held-out verdict made it, and its reason
says so.

An offset the plain rule keeps is checked the same way when validation recordings are given (``Evidence.written``,
``column_choice``: a friction error the joint shows at other speeds one way than the other takes a constant column),
its plain rival the model without it: it stays if it lowers its own joint's held-out error there (the plain rule
kept it; the other joints' margins are not asked of it). Not an offset the size rule reads on the fit as no sensor's
(``offset_reading``: a share of its joint's gravity torque and recorded peak no zero error and no friction mean
reaches): that is a torque of the position the constant takes, the evidence identify's counterbalance naming reads
(``counterbalance_sources``), and it stands as the plain rule kept it (the heavy virtual arm's shoulder balancer,
dropped here as an offset its joint was no better with, left the counterbalance unnamed and a payload taking its
torque).

A judge must be a converged fit: a fit the judge compares that stopped at Ipopt's iteration cap
(``Maximum_Iterations_Exceeded``; a consistent fit that did not converge otherwise raises, and a fold that raises
cannot be judged) is not judged on (``UnconvergedFit``), and the column goes as the training BIC decides, the reason
naming the fit. On the Panda's defaults one fold fit of joint 5's Stribeck check once stopped at the barrier path's
cap and was finished by the chart (``barrier_path``: where a pass's path starts); all eight now converge on the path.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from functools import cache, partial

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.counterbalance_folds import FoldFailure, block_folds
from identification.calibration.never_worse import compare_models
from identification.calibration.offset_reading import fit_offsets
from identification.calibration.shared_barrier import shared_solvers
from identification.calibration.trajectory_fit import identify_trajectories, torque_constants
from identification.data.torque_constants import recording_kt

__all__ = ["UnconvergedFit", "check_departures", "converged", "offset_sizes", "written_model_judge"]

logger = logging.getLogger(__name__)

#: The ``TrajectoryOptions`` fields a ``ColumnChoice`` sets (``ColumnChoice.options``): a fold's model is the same for
#: the same values on the same pieces (the other fields are identify's options, the same for every choice).
COLUMN_FIELDS = ("friction", "offset_joints", "drive_inertia", "inertia_joints", "stribeck_joints", "coulomb_velocity")


class UnconvergedFit(FoldFailure):
    """A fit the judge would compare stopped at Ipopt's iteration cap: the column is not judged on it."""


def converged(fit, what: str):
    """``fit`` (a ``TrajectoryFit``), or ``UnconvergedFit`` naming ``what`` when its consistent fit stopped at
    Ipopt's iteration cap."""
    if fit.solver_status == "Maximum_Iterations_Exceeded":
        raise UnconvergedFit(f"the consistent fit {what} stopped at Ipopt's iteration cap ({fit.solver_status})")
    return fit


def check_departures(choice, fit, fit_of, compare, sized=None) -> tuple:
    """(choice, its fit) after each of ``choice.departures`` was checked on the written model (module docstring).

    ``fit``: the fit of ``choice``; ``fit_of(choice)``: the fit of a ``ColumnChoice``; ``compare(before, after)``: the
    ``never_worse.JointComparison`` of two ``(choice, fit())`` pairs on held-out data (``before``: the plain rule's,
    ``after``: the choice's; :func:`written_model_judge`), raising ``FoldFailure`` when it cannot judge. The fit is a
    call: the plain rule's consistent fit is made only when the judge uses it (the held-out recordings; the block
    folds identify their own models) or the plain rule wins, one fit fewer per departure the folds confirm.
    ``sized(fit, joint)``: the ``offset_reading.OffsetReading`` of the fit's offset on a joint where no sensor has it
    (:func:`offset_sizes`), else None; such a written offset is not judged (module docstring).
    """
    for evidence in choice.departures:
        current = next(e for e in choice.evidence if (e.term, e.joint) == (evidence.term, evidence.joint))
        plain = choice.decided(current, not current.kept, current.reason)
        rules = ("without it", "with it") if current.written else ("as the training BIC decides", "as the held-out "
                                                                    "data decide")  # fmt: skip
        outcome = "so it is left out" if current.written else "so the training BIC decides"
        plain_fit = cache(partial(fit_of, plain))  # fitted only if the judge or a flip needs it
        what = "keeping" if current.kept else "refusing"
        reading = sized(fit, current.joint) if current.written and sized is not None else None
        if reading is not None:  # a torque of the position, not a friction mean: the counterbalance naming reads it
            reason = (f"{current.reason}; not checked on the model identify writes: {reading.offset:+.4g} N m is "
                      f"{reading.gravity_share:.0%} of joint {current.joint + 1}'s gravity torque in the robot file "
                      f"and {reading.peak_share:.0%} of its recorded peak, no sensor's zero error and no friction "
                      "mean (a torque of the position the constant takes), so it stays as the plain rule kept "
                      "it")  # fmt: skip
            choice = choice.decided(current, current.kept, reason)
            logger.info("identify: %s on joint %d: %s", current.term, current.joint + 1, reason)
            continue
        try:
            comparison = compare((plain, plain_fit), (choice, partial(_same, fit)))
        except UnconvergedFit as failure:  # no verdict from a fit that did not converge: the training BIC decides
            reason = (
                f"{current.reason}; not checked on the model identify writes ({failure}), so the training BIC decides"
            )
            if current.written:  # the plain rule kept it: it stands as the training BIC decided it
                choice = choice.decided(current, current.kept, reason)
            else:
                choice, fit = choice.decided(current, not current.kept, reason), plain_fit()
            logger.info("identify: %s on joint %d: %s", current.term, current.joint + 1, reason)
            continue
        except FoldFailure as failure:
            reason = f"{current.reason}; not checked on the model identify writes ({failure})"
            choice = choice.decided(current, current.kept, reason)
            logger.info("identify: %s on joint %d: %s", current.term, current.joint + 1, reason)
            continue
        j = current.joint
        if current.written and comparison.after[j] >= comparison.before[j]:  # its own joint decides a written one
            reason = (f"{current.reason}; but the model identify writes predicts joint {j + 1} no better with it "
                      f"({comparison.text([j])}, {rules[0]} -> {rules[1]}), so it is left out")  # fmt: skip
            choice, fit = choice.decided(current, False, reason), plain_fit()
        elif comparison.worse and not current.written:
            reason = (f"{current.reason}; but {what} it makes the model identify writes worse on the held-out "
                      f"data: {comparison.text()} ({rules[0]} -> {rules[1]}), {outcome}")  # fmt: skip
            choice, fit = choice.decided(current, not current.kept, reason), plain_fit()
        elif current.written:
            reason = (f"{current.reason}; the model identify writes predicts joint {j + 1} better with it "
                      f"({comparison.text([j])}, {rules[0]} -> {rules[1]})")  # fmt: skip
            choice = choice.decided(current, current.kept, reason)
        else:
            reason = (f"{current.reason}; the model identify writes is no worse on any held-out joint for {what} it "
                      f"({comparison.text([current.joint])}, {rules[0]} -> {rules[1]})")  # fmt: skip
            choice = choice.decided(current, current.kept, reason)
        logger.info("identify: %s on joint %d: %s", current.term, current.joint + 1, reason)
    return choice, fit


def offset_sizes(problem):
    """The ``sized`` of :func:`check_departures` for ``problem`` = (robot, model, raw training recordings, identify's
    ``TrajectoryOptions``, ...): the size rule identify's counterbalance naming reads a fit's offset by
    (``offset_reading.fit_offsets``), on recordings of currents through the torque constants the fit reads them with
    (``trajectory_fit.torque_constants``)."""
    robot, model, recordings, options = problem[:4]
    kt = torque_constants(robot, options, recordings)

    def sized(fit, joint):
        return fit_offsets(robot, model, recordings, fit, (joint,), kt).get(joint)

    return sized


def _same(fit):
    return fit


def written_model_judge(problem, validation, cutoff_hz):
    """The ``compare`` of :func:`check_departures` for ``problem`` = (robot, model, training recordings, options,
    configurations): on the ``validation`` recordings when given (``never_worse.compare_models``), else by block
    cross-validation of the training recordings, each fold's two models identified on its other blocks
    (``counterbalance_folds.BlockFolds.compare``, as identify's counterbalance is judged); or a sentence saying why
    there is none (recordings too short to cut, payloads)."""
    robot, model, recordings, options, configurations = problem
    kt = recording_kt(robot, *validation, *recordings)

    def build(fit):
        return CalibratedModel.from_fit(robot, model, fit, robot_source=robot.source)

    if validation:

        def on_validation(before, after):
            models = [build(converged(fit(), f"of {what}")) for (_, fit), what in
                      ((before, "the training BIC's columns"), (after, "the held-out data's columns"))]  # fmt: skip
            return compare_models(*models, model, list(validation), kt)

        return on_validation
    folds = block_folds(recordings, configurations, cutoff_hz)
    if isinstance(folds, str):
        return folds

    fitted = {}  # a fold's model of the same columns on the same pieces, once over the departures

    def refit(choice):
        chosen = choice.options(options)

        def identify(pieces):
            key = (*(getattr(chosen, name) for name in COLUMN_FIELDS), *map(id, pieces))
            if key not in fitted:
                fold = identify_trajectories(robot, model, list(pieces), chosen)
                fitted[key] = build(converged(fold, f"on the training data without a block ({fold.n_samples} samples)"))
            return fitted[key]

        return identify

    def by_folds(before, after):
        with shared_solvers():  # eight fits of two structures: two solvers (``shared_barrier``)
            return replace(folds, baselines={}).compare(refit(before[0]), refit(after[0]), model, kt)[0]

    return by_folds
