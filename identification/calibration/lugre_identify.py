"""identify_lugre_trajectories(): rigid body and LuGre friction from exciting recordings, fitted in turn.

The recordings route with ``--friction lugre`` (``lugre_recordings`` fits the friction itself):

1. the linear fit with the Stribeck shape (``trajectory_fit.identify_trajectories``, friction ``fc, fs, fv``):
   rigid body, drive inertias, offsets and the steady state the LuGre fit starts from;
2. the LuGre fit of every joint on the friction left by step 1's other terms (``fit_lugre_recordings``);
3. the linear fit again, without friction columns, on the recordings with that LuGre friction taken out of
   their torque: a friction model that is wrong near zero speed (the tanh-rounded Stribeck shape against
   the bristles' hysteresis) biases the rigid body it is fitted with, and this removes the bias;
4. the LuGre fit again from step 2's parameters on the friction step 3 leaves.

With payload ``configurations`` (``trajectory_fit.identify_trajectories(configurations=)``) every linear fit shares
the arm across them, subtracts the known loads and identifies the unknown ones as flange bodies; every LuGre fit
sees the friction left once the known loads and the unknown ones as that linear fit identified them are taken out
too (``payload_fit.subtract_loads``): the loads' torque never passes for friction.

Steps 3 and 4 are repeated until the LuGre parameters settle (``round_change``: each moves by less than 1 % or a
tenth of its standard deviation between two LuGre fits), at most ``MAX_ROUNDS`` LuGre fits in all, or ``rounds - 1``
times when ``rounds`` is given. The alternation converges slowly because the rigid body and the friction compete for
the same torque at the reversals (the inertia torque peaks where the bristles flip): on the virtual Denso of
``tests/identification/lugre_recordings_data`` two LuGre fits left sigma0 8 % low on joints 1, 3 and 4, five settle
it within 5 % (the alternation's fixed point: the rigid body refitted with the true friction taken out leaves the
friction residual of the true rigid body, to 1e-4 N m RMS).

The friction step 3 takes out starts each recording where the LuGre fit found the bristles at its first prepared
sample (``LuGreFit.start_force``, carried back to the raw start, ``raw_start_force``), not relaxed: a robot starts a
recording holding what its last motion left, and pre-sliding keeps it until the joint slides. The virtual Denso's
joint 2 starts holding its static friction (4.5 N m) for 0.6 s; a relaxed start put that into its gravity parameters.

With ``extra`` columns (the torque findings of a diagnosis, ``recalibrate``) every linear fit holds them beside the
rigid body, and every LuGre fit sees the friction they leave: a spring the first identification put into gravity and
friction is taken out of both.

The LuGre fits take their series with ``FRICTION_EDGE_PERIODS`` filter periods trimmed at each end, fewer than the
linear fits' ``filter_choice.EDGE_PERIODS``: the bristles show only at velocity reversals, and a reversal in the
recording's first or last periods is one of a dozen in a training recording. The wider trim keeps the rigid body
from the filter's start-up transient in qdd; the friction residual of a wrist joint hardly feels it. On the virtual
Denso of ``tests/identification/lugre_recordings_data`` (12 s at 500 Hz, 50 Hz cutoff) the three-period trim drops
one of joint 4's 14 reversals and its sigma0 error grows from 8 % to 18 % (7 of its sigma); with one period the
worst sigma0 error over the six joints was 8 % (two LuGre fits, relaxed start), now 5 %.

The LuGre friction taken out of a raw recording is evaluated at its full rate on the velocity of its positions
filtered as the identification filters them (``trajectory_data.prepare_recording``), so the filter then sees it
as it sees the recorded torque.

The filter is not what biases sigma0: fitted on the filtered true friction of that recording along the filtered
velocity, with its noise, sigma0 comes out within 3 % on every joint (the bias was the rigid body's, above).

Whether the model explains a joint's torque at all (``trajectory_checks.fit_quality_warnings``: a torque of another
joint, a swapped column) is judged on the whole torque, by the Stribeck fit of step 1 (:func:`whole_torque_warnings`),
not by the R^2 of step 3's refit: that is the R^2 of the torque left once the friction is taken out, near 0 by
construction on a joint whose torque is mostly friction (a belt-driven wrist), where a warning of a swapped column
would be false.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings

import numpy as np

from identification.calibration.lugre_recordings import fit_lugre_recordings, lugre_friction
from identification.calibration.mixed_friction import stribeck_start
from identification.calibration.payload_fit import subtract_loads
from identification.calibration.trajectory_checks import fit_quality_warnings
from identification.calibration.trajectory_data import choose_filter, prepare_recordings
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, torque_constants
from identification.data.preprocessing import central_difference, resample_uniform, zero_phase_filter
from identification.data.recording import Recording
from identification.friction.simulation import simulate_lugre
from psdm_casadi.errors import ParameterError, SolverError

__all__ = ["FRICTION_EDGE_PERIODS", "MAX_ROUNDS", "ROUND_TOLERANCE", "ROUND_TOLERANCE_SD", "LuGreIdentification",
           "identify_lugre_trajectories", "raw_start_force", "restricted", "round_change", "whole_torque_warnings",
           "without_lugre_friction"]  # fmt: skip

logger = logging.getLogger(__name__)

#: The LuGre fit and the rigid-body refit alternate until every LuGre parameter moves by less than this (relative)
#: or less than ``ROUND_TOLERANCE_SD`` of its standard deviation between two LuGre fits (module docstring) ...
ROUND_TOLERANCE = 0.01
ROUND_TOLERANCE_SD = 0.1
#: ... and at most this many LuGre fits in all.
MAX_ROUNDS = 5
#: A later LuGre fit whose friction RMSE rises on a joint beyond this factor (or that does not converge) ends the
#: alternation at the round before it: the alternation refines, it never trades a fit for a worse one.
RMSE_RISE = 1.5
#: Filter periods trimmed at each end of the series the LuGre fits see (module docstring): the one period identify
#: trimmed before ``filter_choice.EDGE_PERIODS``, or the options' own trim when that is shorter.
FRICTION_EDGE_PERIODS = 1.0


@dataclasses.dataclass(frozen=True)
class LuGreIdentification:
    """What :func:`identify_lugre_trajectories` found.

    Attributes
    ----------
    fit : TrajectoryFit
        The last linear fit: rigid body, drive inertias and offsets (no friction columns), then the coefficients
        of the ``extra`` columns when there are any. Its warnings of a joint the model does not explain are those of
        the whole torque, ``stribeck``'s (:func:`whole_torque_warnings`).
    lugre : lugre_recordings.LuGreFit
        The LuGre friction of every joint, fitted on the friction ``fit`` leaves.
    stribeck : TrajectoryFit
        The first linear fit, with the Stribeck shape (the start; reported beside the result).
    rounds : int
        The LuGre fits made (each after the first follows a rigid-body refit).
    """

    fit: object
    lugre: object
    stribeck: object
    rounds: int = 1


def raw_start_force(parameters, t, qd, index: int, force: float) -> float:
    """[N m] The bristle force at ``t[0]`` from which the LuGre state carried along ``qd`` has ``force`` at ``index``.

    The exponential integrator's state is affine in its start (``simulate_lugre`` composes linear maps), so two
    simulations give it exactly. Where the joint has slid before ``index`` the start is forgotten: the answer is then
    held within the steady state's reach (``+- fs``), where it changes nothing that follows.
    """
    if index <= 0:
        return float(force)
    free = parameters.sigma0 * simulate_lugre(parameters, t[: index + 1], qd[: index + 1])[1][-1]
    gain = (
        parameters.sigma0
        * simulate_lugre(parameters, t[: index + 1], qd[: index + 1], z0=1.0 / parameters.sigma0)[1][-1]
    )
    gain -= free
    bound = max(parameters.fs, parameters.fc)
    return float(np.clip((force - free) / gain, -bound, bound)) if gain > 1e-12 else 0.0


def without_lugre_friction(recordings, lugre, prepared, kt, cutoff_hz) -> list:
    """Raw recordings with the LuGre friction of their filtered velocity taken out of their joint torque.

    The bristles start each recording in the state the LuGre fit found at its first prepared sample
    (``LuGreFit.start_force``, carried back to the raw start by :func:`raw_start_force`), not relaxed: on the virtual
    Denso the arm starts holding joint 2 at its static friction (4.5 N m), and a relaxed start put 3 N m of friction
    error into the first 0.6 s of the rigid-body refit (joint 2's sigma0 6 % high, vs 14 % low).
    """
    out = []
    for k, recording in enumerate(recordings):
        rec = recording if recording.is_uniform(1e-6) else resample_uniform(recording)
        rate = 1.0 / rec.dt
        cutoff, _ = choose_filter(rate, cutoff_hz)
        qd, _ = central_difference(rec.t, zero_phase_filter(rec.q, rate, cutoff))
        first = int(np.searchsorted(rec.t, prepared[k].t[0] - 1e-9 * rec.dt))
        s0 = [0.0 if p is None else raw_start_force(p, rec.t, qd[:, j], first, lugre.start_force[k, j])
              for j, p in enumerate(lugre.parameters)]  # fmt: skip
        tau = rec.joint_torque(kt) - lugre_friction(lugre.parameters, rec.t, qd, s0)
        out.append(Recording(t=rec.t, q=rec.q, tau=tau, name=rec.name))
    return out


def round_change(previous, current, tolerance_sd: float = ROUND_TOLERANCE_SD) -> tuple:
    """(score, largest relative change) of the LuGre parameters between two fits (``LuGreFit``).

    A parameter has settled when it moved by less than :data:`ROUND_TOLERANCE` of its value or less than
    ``tolerance_sd`` of its standard deviation (a parameter the data hardly determine wanders by more than
    1 % from round to round without meaning anything); the score is the largest over the parameters of the smaller
    of the two ratios, below 1 when all have settled.
    """
    joints = list(current.joints)  # a joint of a steady-state shape has no LuGre parameters
    before, after, sd = previous.table()[joints], current.table()[joints], current.std[joints]
    relative = np.abs(np.log(after / before))
    with np.errstate(divide="ignore", invalid="ignore"):  # a held parameter (sd 0) settles by value alone
        in_sd = np.where(sd > 0, np.abs(after - before) / sd, np.inf)
    return float(np.max(np.minimum(relative / ROUND_TOLERANCE, in_sd / tolerance_sd))), float(relative.max())


def identify_lugre_trajectories(
    robot, model, recordings, options: TrajectoryOptions, rounds=None, extra=None, configurations=None, settle_sd=None,
    joints=None, start=None,
):  # fmt: skip
    """Rigid body, drive terms and LuGre friction of exciting recordings (module docstring).

    Parameters
    ----------
    robot : RobotDescription
    model : PSDMModel
    recordings : sequence of Recording
        Raw recordings with ``tau``, or ``current`` and torque constants.
    options : TrajectoryOptions
        Its ``friction`` holds ``fc``, ``fs``, ``fv`` (optionally ``offset``); with ``joints``, the options of the
        mixed model's refits instead (``mixed_options``: the other joints' steady-state shape, the LuGre joints'
        friction columns held at 0).
    rounds : int, optional
        Passes of the LuGre fit, >= 1 (each after the first follows a linear refit without friction columns);
        default: until the parameters settle (``round_change``), at most :data:`MAX_ROUNDS`.
    extra : findings.FindingColumns, optional
        Extra linear columns fitted jointly in every linear fit (module docstring); their coefficients follow the
        drive parameters in ``fit.drive``, as in ``trajectory_fit.identify_trajectories``.
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each recording carries at the flange (module docstring); the unknown ones are in ``fit.payloads``.
    settle_sd : float, optional
        A parameter has settled when it moved by less than this many of its standard deviations (``round_change``);
        default :data:`ROUND_TOLERANCE_SD`. Identify's LuGre trial (``lugre_trial.SETTLE_SD``) stops at a coarser step.
    joints : sequence of int, optional
        A mixed model: LuGre friction on these joints (0-based) only, the others keep the steady-state shape of
        ``options`` (identify's trial of the joints LuGre helps, ``lugre_trial``; the refit of such a model file).
        Its rigid-body refits take the LuGre joints' friction out of the torque and hold their columns at 0, its
        LuGre fits are of ``joints`` alone.
    start : tuple, optional
        With ``joints``: ``(stribeck, lugre)``, the Stribeck fit of the whole torque the model starts from (None: one
        of every joint, ``mixed_friction.stribeck_start``) and the ``lugre_recordings.LuGreFit`` (of every joint, as
        identify's trial fitted it) whose parameters and bristle forces of ``joints`` the first refit takes out (None:
        fitted on the friction ``stribeck`` leaves, as step 2). A start's bristle forces matter: relaxed at each
        recording's start instead, the first refit's rigid body took the break-away torque the bristles held.

    Returns
    -------
    LuGreIdentification

    Raises
    ------
    ParameterError
        For options without the Stribeck shape, or ``rounds < 1``.
    SolverError, InsufficientExcitationError
        From the linear or the LuGre fits.
    """
    mixed, counted = joints is not None, rounds is None or (isinstance(rounds, int) and rounds >= 1)
    if (not mixed and "fs" not in options.friction) or not counted:
        raise ParameterError(
            f"identify_lugre_trajectories needs options.friction with 'fs' (or joints) and rounds >= 1 "
            f"(or None); got {options.friction!r}, joints {joints!r} and {rounds!r}. Pass "
            "TrajectoryOptions(friction=('fc', 'fs', 'fv'))."
        )
    recordings = list(recordings)
    kt = torque_constants(robot, options, recordings)
    if mixed:  # the start's Stribeck fit, or one of every joint (``mixed_friction.stribeck_start``)
        (stribeck, lugre), plain = start or (None, None), dataclasses.replace(options, kt=None)
        stribeck = stribeck or identify_trajectories(robot, model, recordings, stribeck_start(options), extra,
                                                     configurations)  # fmt: skip
    else:
        stribeck = identify_trajectories(robot, model, recordings, options, extra, configurations)
        plain = dataclasses.replace(options, friction=tuple(t for t in options.friction if t == "offset"), kt=None)
    edge = min(FRICTION_EDGE_PERIODS, options.edge_periods)  # the reversals at the ends kept (module docstring)
    _, _, prepared = prepare_recordings(robot, recordings, kt, options.cutoff_hz, edge)
    if mixed and lugre is not None:
        lugre = restricted(lugre, joints)
    else:  # step 2: the LuGre fit on the friction the Stribeck fit leaves
        arm = subtract_loads(robot, prepared, configurations, stribeck.payloads)
        lugre = fit_lugre_recordings(model, stribeck, arm, warn=rounds == 1, extra=extra, joints=joints)
    problem = (robot, model, recordings, configurations, extra, prepared, kt, plain)
    fit, lugre, taken = _alternate(problem, stribeck, lugre, rounds, settle_sd, mixed)
    return LuGreIdentification(fit=whole_torque_warnings(robot, fit, stribeck or fit), lugre=lugre,
                               stribeck=stribeck or fit, rounds=taken)  # fmt: skip


def restricted(lugre, joints):
    """``lugre`` (a ``lugre_recordings.LuGreFit``) with the joints outside ``joints`` (0-based) of no LuGre friction:
    a mixed model's start (``identify_lugre_trajectories(joints=)``)."""
    keep = set(joints)
    off = [j for j in range(len(lugre.parameters)) if j not in keep]
    std, rmse, force = np.array(lugre.std, dtype=float), np.array(lugre.rmse, dtype=float), lugre.start_force
    std[off], rmse[off] = np.nan, np.nan
    if force is not None:
        force = np.array(force, dtype=float)
        force[:, off] = 0.0
    return dataclasses.replace(
        lugre, parameters=tuple(p if j in keep else None for j, p in enumerate(lugre.parameters)), std=std, rmse=rmse,
        identifiable=tuple(bool(v) and j in keep for j, v in enumerate(lugre.identifiable)), start_force=force,
        status=tuple(s if j in keep else "" for j, s in enumerate(lugre.status)),
    )  # fmt: skip


def _alternate(problem, stribeck, lugre, rounds, settle_sd, mixed) -> tuple:
    """``(fit, lugre, LuGre fits taken)``: steps 3 and 4 of the module docstring repeated from ``lugre`` (module
    docstring; ``identify_lugre_trajectories``). A mixed model's first refit is its fit even where the LuGre fit after
    it fails: the start's fit holds the LuGre joints' steady-state friction, which the mixed model does not."""
    robot, model, recordings, configurations, extra, prepared, kt, plain = problem
    joints = lugre.joints
    fit, caught, taken, ended = stribeck, [], 1, f"stopped at the limit of {MAX_ROUNDS}"
    for taken in range(2, max(rounds or MAX_ROUNDS, 2 if mixed else 1) + 1):  # a mixed model: one refit at least
        corrected = without_lugre_friction(recordings, lugre, prepared, kt, plain.cutoff_hz)
        refit = identify_trajectories(robot, model, corrected, plain, extra, configurations)
        arm = subtract_loads(robot, prepared, configurations, refit.payloads)
        previous, fit = lugre, refit if mixed and taken == 2 else fit
        try:
            with warnings.catch_warnings(record=True) as recorded:  # only the last fit's warnings are the result's
                warnings.simplefilter("always")
                lugre = fit_lugre_recordings(model, refit, arm, initial=lugre.parameters, extra=extra, joints=joints)
        except SolverError:
            if rounds is not None:
                raise
            lugre = None
        if rounds is None and (lugre is None or np.any(lugre.rmse > RMSE_RISE * previous.rmse)):
            logger.info("identify: LuGre round %d did not converge or raised a joint's friction RMSE; round %d kept",
                        taken, taken - 1)  # fmt: skip
            lugre, taken, ended = previous, taken - 1, f"round {taken} not kept"
            break
        fit, caught = refit, recorded
        score, relative = round_change(previous, lugre, settle_sd or ROUND_TOLERANCE_SD)
        logger.info("identify: LuGre round %d: friction RMSE %s N m; the parameters moved up to %.2g %%",
                    taken, np.round(lugre.rmse, 4), 100 * relative)  # fmt: skip
        if rounds is None and score < 1.0:
            ended = "converged"
            break
    for warning in caught:
        warnings.warn(warning.message, warning.category, stacklevel=3)
    if rounds is None and taken > 1:
        logger.info("identify: LuGre fits alternated with rigid-body refits: %d LuGre fits kept (%s)", taken, ended)
    return fit, lugre, taken


def whole_torque_warnings(robot, fit, stribeck):
    """``fit`` (a refit on the torque with the LuGre friction taken out) with its warnings of a joint the model does
    not explain (``trajectory_checks.fit_quality_warnings``, the only ones that read its R^2) replaced by those of
    ``stribeck``, the fit of the whole torque it started from.

    The refit's R^2 is of the torque left once the friction is taken out: on a joint whose torque is mostly friction
    (a belt-driven wrist) it is near 0 by construction, and a warning that the torque does not look like the joint's
    (columns swapped) would be false. A torque the Stribeck fit does not explain either (a swapped column) is still
    warned about, in ``stribeck``'s words. The refit's other warnings (envelope, masses, drive inertias) stay."""
    if fit is stribeck:
        return fit
    own = set(fit_quality_warnings(robot, fit, fit.loaded))
    whole = fit_quality_warnings(robot, stribeck, stribeck.loaded)
    return dataclasses.replace(fit, warnings=(*whole, *(w for w in fit.warnings if w not in own)))
