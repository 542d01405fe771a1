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

Steps 3 and 4 are repeated ``rounds - 1`` times in all. With ``extra`` columns (the torque findings of a
diagnosis, ``recalibrate``) every linear fit holds them beside the rigid body, and every LuGre fit sees the
friction they leave: a spring the first identification put into gravity and friction is taken out of both.

The LuGre fits take their series with ``FRICTION_EDGE_PERIODS`` filter periods trimmed at each end, fewer than the
linear fits' ``filter_choice.EDGE_PERIODS``: the bristles show only at velocity reversals, and a reversal in the
recording's first or last periods is one of a dozen in a training recording. The wider trim keeps the rigid body
from the filter's start-up transient in qdd; the friction residual of a wrist joint hardly feels it. On the virtual
Denso of ``tests/identification/lugre_recordings_data`` (12 s at 500 Hz, 50 Hz cutoff) the three-period trim drops
one of joint 4's 14 reversals and its sigma0 error grows from 8 % to 18 % (7 of its sigma); with one period the
worst sigma0 error over the six joints is 8 %.

The LuGre friction taken out of a raw recording is evaluated at its full rate on the velocity of its positions
filtered as the identification filters them (``trajectory_data.prepare_recording``), so the filter then sees it
as it sees the recorded torque.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from identification.calibration.lugre_recordings import fit_lugre_recordings, lugre_friction
from identification.calibration.payload_fit import subtract_loads
from identification.calibration.trajectory_data import choose_filter, prepare_recordings
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.preprocessing import central_difference, resample_uniform, zero_phase_filter
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError

__all__ = ["FRICTION_EDGE_PERIODS", "LuGreIdentification", "identify_lugre_trajectories"]

logger = logging.getLogger(__name__)

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
        of the ``extra`` columns when there are any.
    lugre : lugre_recordings.LuGreFit
        The LuGre friction of every joint, fitted on the friction ``fit`` leaves.
    stribeck : TrajectoryFit
        The first linear fit, with the Stribeck shape (the start; reported beside the result).
    """

    fit: object
    lugre: object
    stribeck: object


def _without_friction_torque(recordings, parameters, kt, cutoff_hz) -> list:
    """Raw recordings with the LuGre friction of their filtered velocity taken out of their joint torque."""
    out = []
    for recording in recordings:
        rec = recording if recording.is_uniform(1e-6) else resample_uniform(recording)
        rate = 1.0 / rec.dt
        cutoff, _ = choose_filter(rate, cutoff_hz)
        qd, _ = central_difference(rec.t, zero_phase_filter(rec.q, rate, cutoff))
        tau = rec.joint_torque(kt) - lugre_friction(parameters, rec.t, qd)  # relaxed at the start
        out.append(Recording(t=rec.t, q=rec.q, tau=tau, name=rec.name))
    return out


def identify_lugre_trajectories(
    robot, model, recordings, options: TrajectoryOptions, rounds: int = 2, extra=None, configurations=None
):
    """Rigid body, drive terms and LuGre friction of exciting recordings (module docstring).

    Parameters
    ----------
    robot : RobotDescription
    model : PSDMModel
    recordings : sequence of Recording
        Raw recordings with ``tau``, or ``current`` and torque constants.
    options : TrajectoryOptions
        Its ``friction`` holds ``fc``, ``fs``, ``fv`` (optionally ``offset``).
    rounds : int
        Passes of the LuGre fit, >= 1 (each after the first follows a linear refit without friction columns).
    extra : findings.FindingColumns, optional
        Extra linear columns fitted jointly in every linear fit (module docstring); their coefficients follow the
        drive parameters in ``fit.drive``, as in ``trajectory_fit.identify_trajectories``.
    configurations : sequence of data.configuration.PayloadConfiguration, optional
        The load each recording carries at the flange (module docstring); the unknown ones are in ``fit.payloads``.

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
    if "fs" not in options.friction or not (isinstance(rounds, int) and rounds >= 1):
        raise ParameterError(
            f"identify_lugre_trajectories needs options.friction with 'fs' and rounds >= 1; got "
            f"{options.friction!r} and {rounds!r}. Pass TrajectoryOptions(friction=('fc', 'fs', 'fv'))."
        )
    recordings = list(recordings)
    kt = None
    if not all(r.tau is not None for r in recordings):
        kt = np.asarray(options.kt if options.kt is not None else [d.kt for d in robot.drives], dtype=float)
    stribeck = identify_trajectories(robot, model, recordings, options, extra, configurations)
    edge = min(FRICTION_EDGE_PERIODS, options.edge_periods)  # the reversals at the ends kept (module docstring)
    _, _, prepared = prepare_recordings(robot, recordings, kt, options.cutoff_hz, edge)
    arm = subtract_loads(robot, prepared, configurations, stribeck.payloads)
    fit, lugre = stribeck, fit_lugre_recordings(model, stribeck, arm, warn=rounds == 1, extra=extra)
    plain = dataclasses.replace(options, friction=tuple(t for t in options.friction if t == "offset"), kt=None)
    for k in range(1, rounds):
        corrected = _without_friction_torque(recordings, lugre.parameters, kt, options.cutoff_hz)
        fit = identify_trajectories(robot, model, corrected, plain, extra, configurations)
        arm = subtract_loads(robot, prepared, configurations, fit.payloads)
        lugre = fit_lugre_recordings(model, fit, arm, initial=lugre.parameters, warn=k == rounds - 1, extra=extra)
        logger.info("identify: LuGre round %d: friction RMSE %s N m", k + 1, np.round(lugre.rmse, 4))
    return LuGreIdentification(fit=fit, lugre=lugre, stribeck=stribeck)
