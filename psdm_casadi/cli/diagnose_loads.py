"""The loads ``psdm diagnose``'s recordings carry: taken off before the diagnosis, named beside its findings.

A load a recording's sidecar states (or the model file lists for its content) is taken off its torque, so that the
diagnosis and its refit see the arm; with a model file, a validation recording that states none is checked for one as
``psdm validate`` checks it (``held_out_load``) and a plausible one taken off and named; the payload check beside the
findings says what the validation recording carries that the model file does not have, in validate's words. With the
robot file, whose rigid body may be what is wrong, the validation recordings are checked as identify checks its
held-out ones (``held_out_arm``: the flange fit on their residual of a fit of the training recording), and a plausible
load nothing states is taken off and named likewise. Each validation recording is checked and named by its file
(``validation_loads``), not the first alone: with ``--validate A B`` each may carry a load of its own.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from psdm_casadi.log_context import held_back

__all__ = ["ValidationLoad", "load_sentence", "payload_check", "robot_file_loads", "stated_load_off", "stated_loads",
           "validation_loads"]  # fmt: skip


def stated_loads(args, loaded, robot, recordings, preparation) -> tuple:
    """(recordings, their configurations, per validation recording its ``held_out_load.LoadCheck`` or None): each
    with the load its sidecar states (a known one as given, an unknown one as the model file identified it) taken off
    (``payload_check.without_load``), so that the diagnosis and its refit see the arm; with a model file, a validation
    recording stating none checked for one as validate does (``held_out_arm.without_unstated_loads``)."""

    from identification.calibration.held_out_arm import without_unstated_loads

    calibrated = None if loaded is None else loaded.calibrated
    out, configurations = [], []
    for path, recording in zip((args.train, *args.validate), recordings):
        recording, configuration = stated_load_off(args, calibrated, robot, (path, recording), preparation.cutoff_hz)
        out.append(recording)
        configurations.append(configuration)
    if calibrated is None:  # the robot file: each validation recording's load as identify weighs it (its own statement)
        arm = robot_file_loads(args, robot, recordings, configurations, preparation)
        if arm is None:  # not checked (said): the stated loads taken off only
            return out, configurations, [None] * len(args.validate)
        return [out[0], *arm.recordings], configurations, list(arm.loads)
    held, checks = without_unstated_loads(robot, calibrated, loaded.model, out[1:], configurations[1:], args.validate,
                                          preparation.cutoff_hz)  # fmt: skip
    return [out[0], *held], configurations, checks


def stated_load_off(args, calibrated, robot, entry, cutoff_hz) -> tuple:
    """``(recording, its configuration)`` of ``entry`` = ``(path, raw recording)``: the load its sidecar states (or the
    model file ``calibrated`` lists for its content) taken off its torque (``payload_check.without_load``), said on
    stderr when only the model file names it."""
    from identification.calibration.payload_check import without_load
    from identification.calibration.payload_fit import stated_payload
    from identification.calibration.refit_training import listed_configuration
    from identification.data.configuration import stated_configuration
    from identification.data.torque_constants import recording_kt

    path, recording = entry
    stored = [] if calibrated is None else calibrated.configurations
    configuration = listed_configuration(None if calibrated is None else calibrated.document, path)
    body, note = stated_payload(configuration, stored, args.robot)
    if note:
        print(f"psdm diagnose: warning: {path}: {note}", file=sys.stderr)
    elif body is not None and not stated_configuration(path).stated:
        print(f"psdm diagnose: note: {path}: carries {configuration.name!r} as the model file lists it for this "
              "recording (no sidecar beside it); its torque is taken off", file=sys.stderr)  # fmt: skip
    if body is None:
        return recording, configuration
    return without_load(robot, recording, body, recording_kt(robot, recording), cutoff_hz), configuration


def robot_file_loads(args, robot, recordings, configurations, preparation):
    """The ``held_out_arm.HeldOutArm`` of the raw validation recordings ``recordings[1:]`` (``recordings[0]`` the raw
    training one, ``configurations`` what each states) as ``psdm identify`` judges its held-out recordings: a stated
    load taken off, and one nothing states looked for on their residual of the training fit (``held_out_load``), a
    plausible one taken off (``loads``: the ``UnstatedLoad`` found on each, or None). None, with a note, where that
    training fit cannot be made (a joint that does not move: the diagnosis of the robot file may still run)."""
    from identification.calibration.held_out_arm import held_out_arm
    from identification.calibration.trajectory_fit import TrajectoryOptions
    from psdm_casadi.cli.checks import command_model
    from psdm_casadi.cli.output import progress
    from psdm_casadi.errors import RecordingError

    options = TrajectoryOptions(cutoff_hz=preparation.cutoff_hz)
    progress("diagnose: checking the validation recordings for a load nothing states (on their residual of a "
             "least-squares fit of the training recording, as identify checks its held-out ones) ...")  # fmt: skip
    psdm = command_model(args, robot)
    try:
        with held_back("identification.calibration"):  # that fit's progress lines are identify's: said above
            return held_out_arm(robot, psdm, recordings[:1], recordings[1:], configurations[:1], configurations[1:],
                                options, args.validate)  # fmt: skip
    except RecordingError as exc:
        print(f"psdm diagnose: note: the validation recordings were not checked for a load nothing states (the "
              f"training fit it is read against failed: {exc})", file=sys.stderr)  # fmt: skip
        return None


def payload_check(args, calibrated, robot, model, validation, check=None, path=None, temperature=True):
    """``(load, temperature)``: a load the model file does not have in the validation recording ``path`` (default the
    first ``--validate``), as ``psdm validate`` names it (one nothing states as ``check`` found it,
    ``held_out_load``; else one beyond the stated load, ``payload_check.new_payload``), or None; and, with
    ``temperature``, the temperatures the file's friction law was read at on it (``TemperatureFriction.sentence``), or
    None without a law."""

    from identification.calibration.payload_check import model_columns, new_payload, validation_with_payload
    from identification.data.torque_constants import recording_kt

    path = str(args.validate[0] if path is None else path)
    kt = recording_kt(robot, validation)
    _, _, prepared, predicted = validation_with_payload(robot, calibrated, model, validation, kt)
    sentence = None
    if temperature and (laws := calibrated.temperature_friction) is not None:  # where the file's law was evaluated
        from identification.data.temperature import temperatures_at

        sentence = laws.sentence(temperatures_at(validation, prepared.t), robot.joint_names)
        print(f"psdm diagnose: note: {path}: the model file's {sentence}", file=sys.stderr)
    if check is not None:
        return check.load, sentence
    load = new_payload(robot, prepared, predicted, path, model_columns(calibrated, model, prepared))
    return load, sentence


@dataclass(frozen=True)
class ValidationLoad:
    """The load a validation recording (``recording``: its file) carries that the model does not have, as the payload
    check names it (``load``: ``held_out_load.UnstatedLoad`` or ``payload_check.NewPayload``; None: none), and the
    ``held_out_load.LoadCheck`` that weighed it (None: the robot file's check, or a stated load)."""

    recording: str
    load: object = None
    check: object = None

    def sentence(self) -> str:
        return load_sentence(self.load, self.check)

    def to_dict(self) -> dict:
        return {"recording": self.recording, "load": None if self.load is None else self.load.to_dict()}


def validation_loads(args, calibrated, robot, model, validations, checks) -> tuple:
    """``(loads, temperature)``: one :class:`ValidationLoad` per validation recording (``args.validate``, the
    recordings ``validations`` as the diagnosis judges them, ``checks`` what ``stated_loads`` found on each), each
    named by its file; and the temperatures the model file's friction law was read at on the first (``payload_check``).
    With the robot file, a load is the ``UnstatedLoad`` its check found (``checks``)."""
    if calibrated is None:
        return [ValidationLoad(str(p), c) for p, c in zip(args.validate, checks)], None
    loads, temperature = [], None
    for k, (path, validation, check) in enumerate(zip(args.validate, validations, checks)):
        load, said = payload_check(args, calibrated, robot, model, validation, check, path, temperature=k == 0)
        loads.append(ValidationLoad(str(path), load, check))
        temperature = said if k == 0 else temperature
    return loads, temperature


def load_sentence(load, check) -> str:
    """The payload check's line: a load nothing states with what was done (``check``, a ``held_out_load.LoadCheck``;
    the robot file's ``UnstatedLoad``, which says it itself), else one beyond the stated."""
    if check is None or check is load:
        return load.sentence()
    return load.sentence([float(v) for v in check.rmse_left_in] if check.taken_off else None)
