"""What identify's robot-file check and its holds are judged on when recordings carry payloads the file does not.

The robot file is judged (``robot_file_check``) by its rigid body with a friction fitted on the training recordings,
on the held-out recordings' torque. A training recording with an unknown payload (a sidecar ``{"unknown": ...}``, or a
load nothing states, ``unstated_load``) cannot be in that friction fit: the file cannot hold its load. It does not
touch the held-out torque, though: a held-out recording with no load, a known one, or one ``held_out_arm`` finds on
its own is the arm's torque, and the file is judged there as without the training load. So the friction is fitted on
the other training recordings (``file_training``: known loads taken off, unknown ones left out), and the check and the
never-worse holds run (:func:`file_check`).

Two cases leave the file unjudgeable, and the reason is stated instead: every training recording carries an unknown
payload (no recording for the file's friction), or every held-out recording carries the training recordings' unknown
payload, taken off as the training fit estimates it (``held_out_arm``): judged on that torque, the file would carry
the identified model's estimate of the load. A held-out recording of that kind beside others is left out of the check.
"""

from __future__ import annotations

from dataclasses import dataclass

from identification.calibration.prior_pull import PriorPull
from identification.calibration.robot_file_check import FileCheck, check_against_file

__all__ = ["FileJudged", "file_check", "file_judged", "file_training"]


@dataclass(frozen=True)
class FileJudged:
    """The held-out recordings the robot file is judged on (``recordings``), or why it cannot be (``reason``)."""

    recordings: tuple = ()
    reason: str = ""
    left_out: int = 0  # held-out recordings left out: they carry the training recordings' unknown payload


def file_judged(validation, held, configurations) -> FileJudged:
    """The :class:`FileJudged` of the held-out recordings ``validation`` (as judged: every load taken off), ``held``
    the load each states (``PayloadConfiguration``; None: none known), ``configurations`` the training recordings'."""
    validation = tuple(validation)
    unknown = {c.name for c in configurations or () if c.unknown}
    if held is None or not unknown:
        return FileJudged(validation)
    shared = [c is not None and c.unknown and c.name in unknown for c in held]
    kept = tuple(r for r, s in zip(validation, shared) if not s)
    if validation and not kept:
        return FileJudged(reason="every held-out recording carries the training recordings' unknown payload, taken "
                          "off as the fit estimates it: the robot file cannot be judged on that torque without the "
                          "identified load (hold out a recording without it)", left_out=len(validation))  # fmt: skip
    return FileJudged(kept, left_out=len(validation) - len(kept))


def file_training(robot, recordings, options, configurations) -> list:
    """The training recordings the robot file's friction is fitted on, prepared as the fit prepares them: each known
    payload's torque taken off, each recording with an unknown payload left out (empty: every one carries one)."""
    from identification.calibration.column_candidates import prepare_training
    from identification.calibration.payload_fit import subtract_known_payloads

    prepared = subtract_known_payloads(robot, prepare_training(robot, recordings, options).prepared, configurations)
    if configurations is None:
        return prepared
    return [r for r, c in zip(prepared, configurations) if not c.unknown]


def file_check(problem, judged: FileJudged, fit, calibrated, columns=None) -> FileCheck:
    """The ``robot_file_check.FileCheck`` of ``calibrated`` (its ``fit``) against the robot file on the ``judged``
    held-out recordings, ``problem = (robot, model, recordings, options, configurations)`` the training recordings'. A
    known payload (stated in a sidecar) is the robot file's too: its torque is taken off the training recordings the
    file's friction is fitted on, as the identification takes it off. A training recording with an unknown payload is
    left out of that friction fit (``file_training``); the check is made unless every training recording carries
    one. ``columns``: the fit whose friction columns the file's friction takes (a LuGre model's Stribeck start;
    default ``fit``)."""
    robot, model, recordings, options, configurations = problem
    if judged.reason:
        return FileCheck(reason=judged.reason)
    if not judged.recordings or robot.links is None:
        return check_against_file(robot, model, calibrated, fit, (), judged.recordings, options, columns=columns)
    prepared = file_training(robot, recordings, options, configurations)
    if not prepared:
        return FileCheck(reason="every training recording carries an unknown payload the robot file does not: its "
                         "friction has no recording to be fitted on without that load (record one without it, or "
                         "state the load in a sidecar)")  # fmt: skip
    pull = dict(fit.envelope_bounds).get("prior")
    samples = None if pull is None else PriorPull.from_note(pull).effective_samples
    return check_against_file(robot, model, calibrated, fit, prepared, judged.recordings, options, samples, columns)
