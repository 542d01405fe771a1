"""The held-out recordings as ``psdm identify``'s judges weigh them: the arm's own torque, every load taken off.

identify judges its model on the held-out recordings: the drive columns the training data alone do not decide, the
robot file's baseline and the never-worse margins, the holds. A load a held-out recording carries and the training
recordings do not (or another one) counts in every candidate's error there, though no candidate can explain it, and
the judges compare the models on a torque none of them has (the identified model was called worse than the robot file
on a joint where it was far better). So each held-out recording is judged on its arm's torque, the load it carries
taken off (``payload_check.without_load``) as the fit takes the training recordings' off:

- a known load (its sidecar, or ``--data``'s statement for a ``--holdout`` part) as stated;
- an unknown one under a name the training recordings share, as the training fit identifies it;
- a load nothing states, or an unknown one the training recordings do not carry, where the recording shows one
  (``held_out_load``: the flange fit on its residual of the training fit, least squares with the default columns,
  the model held fixed; a clear and plausible load only). Without a clear load nothing changes.

A load nothing states is then read again against the model the route identified (``HeldOutArm.rejudged``: the same
check as the report's and ``psdm validate``'s) and the route run once more on the recording with that estimate taken
off: the training fit's estimation error moves the load's centre of mass, and on a cobot's wrist a few millimetres are
a torque of the size of the never-worse margins (a joint called worse than the robot file that is not).
:class:`HeldOutArm` keeps what was taken off and why, for the command's warnings.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from identification.calibration.calibrated_model import CalibratedModel
from identification.calibration.held_out_load import find_unstated_load
from identification.calibration.payload_check import without_load
from identification.calibration.payload_fit import stated_payload
from identification.calibration.trajectory_fit import identify_trajectories
from identification.data.configuration import stated_configuration
from identification.data.torque_constants import recording_kt

__all__ = ["HeldOutArm", "held_out_arm", "held_out_configurations", "without_unstated_loads"]


@dataclass(frozen=True)
class HeldOutArm:
    """The held-out recordings as judged (``recordings``), the load each states (``configurations``) and, per
    recording, the load found on it that nothing states (``held_out_load.UnstatedLoad``; None: none found), judged
    against the training fit, or with ``by_model`` against the model identified with the first judgement
    (:meth:`rejudged`)."""

    recordings: tuple
    configurations: tuple
    loads: tuple
    by_model: bool = False

    def rejudged(self, robot, model, calibrated, validation, options) -> HeldOutArm | None:
        """The held-out recordings judged again without each load nothing states, as the model identified by judging
        these (``calibrated``) weighs it (``held_out_load.find_unstated_load``, as the report and validate), or None
        when none was taken off or this is already that second judgement. The training fit the first judgement read
        the load against is least squares with the default columns; its estimation error moves the load's centre of
        mass by millimetres, which on a cobot's wrist is a torque of the size of the never-worse margins."""
        if self.by_model or not any(load is not None and load.plausible for load in self.loads):
            return None
        out, loads = list(self.recordings), list(self.loads)
        for k, (recording, load) in enumerate(zip(validation, self.loads)):
            if load is None or not load.plausible:
                continue
            kt = recording_kt(robot, recording)
            check = find_unstated_load(robot, calibrated, model, recording, kt, load.found.recording)
            taken = check.taken_off
            out[k] = without_load(robot, recording, check.load.body, kt, options.cutoff_hz) if taken else recording
            loads[k] = check.load
        return HeldOutArm(tuple(out), self.configurations, tuple(loads), by_model=True)

    def said(self, path, load) -> str:
        """The line for a recording whose judges weighed it without ``load``, a load nothing states."""
        against = "the model identified with the load so taken off" if self.by_model else "the training fit"
        return (f"{path}: the judges of the columns and of the robot file weighed the arm without a load nothing "
                f"states ({load.found.mass:.3g} +- {load.found.mass_std:.2g} kg found against {against})")  # fmt: skip


def held_out_configurations(validate, paths, configurations) -> list:
    """The load each held-out recording (``validate``: their files) states: a part held out of a training recording
    (``--holdout``) the one ``--data`` states for it (its sidecar or the manifest), a ``--validate`` recording its
    sidecar's."""
    training = {str(path): configuration for path, configuration in zip(paths, configurations)}
    return [training.get(str(path)) or stated_configuration(path) for path in validate]


def held_out_arm(robot, model, training, validation, configurations, held, options, names=()) -> HeldOutArm:
    """The :class:`HeldOutArm` of the raw held-out recordings ``validation`` stating ``held`` (one
    ``PayloadConfiguration`` each, :func:`held_out_configurations`), given the raw ``training`` recordings, their
    ``configurations`` and identify's ``options`` (``trajectory_fit.TrajectoryOptions``: the cutoff); ``names`` the
    held-out files, for the sentences."""
    names = list(names) or [r.name or f"held-out recording {k + 1}" for k, r in enumerate(validation)]
    out, loads, fit, calibrated = [], [], None, None
    for recording, configuration, name in zip(validation, held, names):
        kt = recording_kt(robot, recording)
        if configuration.kind == "known":
            body = configuration.payload.dynamic_parameters()
            out.append(without_load(robot, recording, body, kt, options.cutoff_hz))
            loads.append(None)
            continue
        if fit is None:  # the model the held-out residual is read against: the training's, least squares
            fit = identify_trajectories(robot, model, training, replace(options, consistency=False),
                                        configurations=configurations)  # fmt: skip
            calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source=robot.source or robot.name)
        identified = {p.name: p for p in fit.payloads if p.identifiable}
        if configuration.unknown and configuration.name in identified:
            body = identified[configuration.name].parameters
            out.append(without_load(robot, recording, body, kt, options.cutoff_hz))
            loads.append(None)
            continue
        load = find_unstated_load(robot, calibrated, model, recording, kt, str(name)).load
        taken = load is not None and load.plausible
        out.append(without_load(robot, recording, load.body, kt, options.cutoff_hz) if taken else recording)
        loads.append(load)
    return HeldOutArm(tuple(out), tuple(held), tuple(loads))


def without_unstated_loads(robot, calibrated, model, recordings, configurations, names, cutoff_hz) -> tuple:
    """``(recordings, checks)``: raw recordings a calibrated model is judged on (``psdm diagnose MODEL``'s validation
    recordings), each that states no load the model weighs (``configurations``, after the stated ones were taken off)
    checked for one as ``psdm validate`` checks it (``held_out_load.find_unstated_load``) and a plausible one taken off
    (``payload_check.without_load`` at ``cutoff_hz``, the model's preparation); ``checks`` holds each check (None where
    a load is stated), so that the command names the load as validate and identify do."""
    out, checks = [], []
    for recording, configuration, name in zip(recordings, configurations, names):
        stated, _ = stated_payload(configuration, calibrated.configurations, "the model")
        if stated is not None:
            out.append(recording)
            checks.append(None)
            continue
        kt = recording_kt(robot, recording)
        check = find_unstated_load(robot, calibrated, model, recording, kt, str(name))
        taken = check.taken_off
        out.append(without_load(robot, recording, check.load.body, kt, cutoff_hz) if taken else recording)
        checks.append(check)
    return out, checks
