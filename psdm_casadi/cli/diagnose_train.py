"""``psdm diagnose --train A [B ...]``: the training recordings the diagnosis pools and the refit trains on.

With a calibrated model the diagnosis fits and selects on every ``--train`` recording at once (each prepared on its
own, their samples pooled: ``diagnosis.pooled_context``), and the refit with the findings (``--apply``, and the
report's "after") trains on them and on the model file's own training recordings, found again by their content
(``calibration.refit_training``): a finding is chosen on the data its refit fits, not on the first recording's part of
it (a quartic spring chosen over a third of a joint's travel is no spring over all of it). A user whose recordings
moved hands them back, a new recording is added (read as the first is, the load its sidecar states taken off; where
identify corrected a friction drift, its friction is fitted beside the model and corrected as the file's recordings
are). A robot file has no refit, so several recordings there are refused naming the route that uses them all
(identify, then diagnose the model).
"""

from __future__ import annotations

from pathlib import Path

from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.near_names import did_you_mean

__all__ = ["TRAIN_HELP", "check_recordings_exist", "pooled_training", "read_more_training", "training_paths"]

TRAIN_HELP = (
    "training recording(s) (.csv, .npz, .mat, or a ROS 2 bag). With a calibrated model the diagnosis fits and selects "
    "on all of them at once, and the refit with the findings (--apply, and the report's 'after') trains on them and "
    "on the model file's own training recordings, found again by their content: hand back those that moved, or "
    "add new ones (read as identify reads them; a friction drift identify corrected is corrected on them too). With "
    "--holdout each is cut: its first part trains, its last part validates on its own"
)


def training_paths(args) -> tuple:
    """``(the first --train, the others)``; several with a robot file are refused naming the fix (it has no refit
    for the others to train)."""
    first, *more = (str(p) for p in args.train)
    if more and not str(args.robot).lower().endswith(".json"):
        names = ", ".join(Path(p).name for p in args.train)
        raise ParameterError(
            f"--train takes one recording with a robot file; got {len(args.train)} ({names}). Only a calibrated "
            "model's diagnosis pools several, with its refit training on them: identify on all of them first, then "
            "diagnose the model with them, psdm "
            f"identify {args.robot} --data {' '.join(args.train)} --out model.json; psdm diagnose model.json --train "
            f"{' '.join(args.train)} --validate C.csv. Or pass one, --train {first}, and give the others to --validate."
        )
    return first, more


def pooled_training(args, loaded, robot, cutoff_hz) -> list:
    """The other ``--train`` recordings (``args.more``, ``holdout.other_training_parts``) as the diagnosis pools them
    beside the first: each one's training part (``holdout.training_part``: cut as the model file or ``--holdout`` cut
    it), the load its sidecar states taken off (``diagnose_loads.stated_load_off``) and a dead torque channel marked
    (``missing_torque.find_missing_torque``), as the first is."""
    from identification.data.holdout import training_part
    from identification.data.missing_torque import find_missing_torque
    from psdm_casadi.cli.diagnose_loads import stated_load_off

    calibrated = loaded.calibrated
    out = []
    for entry in getattr(args, "more", ()):
        part = training_part(entry, calibrated.document, args.robot)
        recording, _ = stated_load_off(args, calibrated, robot, (entry[0], part), cutoff_hz)
        out.append(find_missing_torque(recording))
    return out


def check_recordings_exist(paths) -> None:
    """Refuse a ``--train`` or ``--validate`` recording that does not exist before anything is loaded: a model file
    read (and its model derived or read from the cache) before a mistyped path was a wait for a one-line error."""
    for path in paths:
        if not Path(path).exists():
            raise RecordingError(f"recording {str(path)!r} does not exist. Check the path.{did_you_mean(path)}")


def read_more_training(paths, load, robot) -> list:
    """``[(path, raw recording)]`` of the other ``--train`` recordings, each read with ``load(path)`` as the first
    (joint side, timed, the model's column layout) and checked as identify checks its training recordings
    (``plausibility.check_plausible_recording``: positions in degrees, torques in mN m): a missing file, another
    robot's joint count or the wrong units are refused here, before any fit, naming the file and the fix."""
    from identification.data.plausibility import check_plausible_recording

    out = []
    for path in paths:
        recording = load(path)
        check_plausible_recording(recording, robot)
        out.append((path, recording))
    return out
