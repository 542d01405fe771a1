"""Checks of ``psdm`` options, run by every command before any work: one line naming the option and the fix.

Every command that loads a robot takes it through :func:`add_robot_argument` and
:func:`load_robot_argument`, so ``--lock JOINT[=VALUE]`` reads and is refused the same everywhere.

Values are printed as plain numbers (``0``, ``-1``, ``1e+09``), never as numpy reprs. The outputs of a
command are checked here too (:func:`output_file`, :func:`output_folder`) and written through
:func:`staged`, so that a refusal, a failure or Ctrl-C leaves no partial file. No output may be, hold or lie
inside an input of the same command (:func:`check_not_input`), and a folder's ``--overwrite`` replaces only
what its manifest lists (``psdm_casadi.manifest``).
"""

from __future__ import annotations

import math
import os
import sys
from contextlib import ExitStack, contextmanager
from numbers import Integral, Real
from pathlib import Path

from psdm_casadi.errors import ParameterError
from psdm_casadi.fileio import OutputFile
from psdm_casadi.manifest import ManifestFolder

__all__ = [
    "MAX_SAMPLES",
    "ROBOT_HELP",
    "add_lock_argument",
    "add_robot_argument",
    "add_topic_argument",
    "check_count",
    "check_not_input",
    "check_positive",
    "check_samples",
    "check_seed",
    "check_suffix",
    "command_model",
    "derive_model",
    "load_locked_robot",
    "load_robot_argument",
    "output_file",
    "output_folder",
    "read_calibrated_argument",
    "parse_joints",
    "parse_locks",
    "plain",
    "staged",
]

#: The help of every command's robot argument.
ROBOT_HELP = "robot file (.toml with DH rows or a [urdf] table, .urdf, or MJCF .xml) or the name of a built-in robot"
_LOCK_HELP = (
    "fix JOINT at VALUE [rad or m] (default 0); the model keeps the other joints. Repeat for several, e.g. "
    "--lock panda_finger_joint1=0.02 (robots read from a URDF only)"
)

#: Most samples a command writes or simulates per recording (memory and time stay within a workstation's).
MAX_SAMPLES = 2_000_000


def plain(value) -> str:
    """A number as a user typed it: ``0``, ``-2``, ``0.5``, ``1e+09`` (numpy scalars included)."""
    if isinstance(value, bool) or not isinstance(value, Real):
        return repr(value)
    if isinstance(value, Integral):
        return str(int(value))
    return f"{float(value):g}"


def check_positive(value, option: str, fix: str, unit: str = "") -> None:
    """``value`` (None allowed: the default applies) must be a finite number > 0."""
    if value is None:
        return
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"{option} must be a positive number{unit}; got {plain(value)}. {fix}")


def check_count(value, option: str, fix: str, minimum: int = 1) -> None:
    """``value`` (None allowed) must be an integer >= ``minimum``."""
    if value is None:
        return
    if value < minimum:
        raise ParameterError(f"{option} must be an integer >= {minimum}; got {plain(value)}. {fix}")


def check_seed(value) -> None:
    """``--seed`` must be >= 0 (numpy's generators take no negative seed)."""
    if value is not None and value < 0:
        raise ParameterError(f"--seed must be an integer >= 0; got {plain(value)}. Pass e.g. --seed 0.")


def check_samples(duration: float, rate: float, option: str, subject: str, fix: str) -> None:
    """``duration * rate`` samples must stay within :data:`MAX_SAMPLES` (memory and time of one recording)."""
    n_samples = duration * rate
    if n_samples > MAX_SAMPLES:
        raise ParameterError(
            f"{option} must give at most {MAX_SAMPLES} samples {subject} ({plain(MAX_SAMPLES / rate)} s at "
            f"{plain(rate)} Hz); got {plain(duration)} s at {plain(rate)} Hz = {plain(n_samples)} samples. {fix}"
        )


def parse_joints(text: str | None, n_dof: int, option: str = "--joints") -> list:
    """0-based joints from a comma-separated list of 1-based joint numbers (None: every joint)."""
    if text is None:
        return list(range(n_dof))
    joints = []
    for item in text.split(","):
        try:
            number = int(item.strip())
        except ValueError:
            raise ParameterError(
                f"{option} must be comma-separated joint numbers 1..{n_dof}; got {text!r}. Pass e.g. {option} 1,3."
            ) from None
        if not 1 <= number <= n_dof:
            raise ParameterError(
                f"{option} must hold joint numbers 1..{n_dof} (the robot has {n_dof} joints); got {number}. "
                f"Pass e.g. {option} 1,{n_dof}."
            )
        if number - 1 not in joints:
            joints.append(number - 1)
    return joints


def output_file(path, option: str, overwrite: bool, overwrite_option: str = "--overwrite") -> OutputFile | None:
    """The checked output file of ``option`` (None when the option was not given)."""
    if path is None:
        return None
    output = OutputFile(path, option, overwrite_option)
    output.check(overwrite)
    return output


def output_folder(
    path,
    names,
    force: bool,
    force_option: str = "--overwrite",
    shared: bool = False,
    command: str = "psdm",
    label: str = "--out",
) -> ManifestFolder:
    """The checked ``label`` folder of a command that writes ``names``: its manifest limits what ``force`` replaces
    (see ``ManifestFolder``)."""  # fmt: skip
    folder = ManifestFolder(path, names, command, force_option, shared, label)
    folder.check(force)
    return folder


def check_suffix(path, option: str, suffixes, what: str) -> None:
    """``path`` (None allowed) must end with one of ``suffixes`` (``.json``): the format the command writes."""
    if path is None or Path(str(path)).suffix.lower() in suffixes:
        return
    name = Path(str(path))
    raise ParameterError(
        f"{option} {str(path)!r} must end with {' or '.join(suffixes)}: the command writes {what}. "
        f"Pass e.g. {option} {name.with_suffix(suffixes[0]) if name.suffix else str(name) + suffixes[0]}."
    )


def _resolved(path) -> Path:
    return Path(os.path.realpath(Path(str(path)).expanduser()))


def check_not_input(output, option: str, inputs, force_option: str = "--overwrite", example=None) -> None:
    """Refuse an output that is, holds or lies inside an input of the same command (paths and symlinks resolved).

    ``inputs`` is an iterable of ``(option, path)``; None paths and names that are not files (a built-in
    robot) are skipped. ``force_option`` never replaces an input: the message names both options and the fix
    (``example``, default the output's name with ``_out``).
    """
    if output is None:
        return
    target = _resolved(output)
    for input_option, path in inputs:
        if path is None or not os.path.lexists(Path(str(path)).expanduser()):
            continue
        source = _resolved(path)
        if target == source:
            relation = "is"
        elif target in source.parents:
            relation = "is a folder holding"
        elif source.is_dir() and source in target.parents:
            relation = "lies inside"
        else:
            continue
        raise ParameterError(
            f"{option} {str(output)!r} {relation} the {input_option} input {str(path)!r} of this command; "
            f"{force_option} never replaces an input. Name another {option}, e.g. {example or _suggestion(output)}."
        )


def _suggestion(output) -> str:
    path = Path(str(output))
    path = path if path.name else _resolved(path)
    return (
        str(path.with_name(f"{path.stem}_out{path.suffix}")) if path.suffix else str(path.with_name(path.name + "_out"))
    )


@contextmanager
def staged(*outputs):
    """Staging paths of several outputs (None entries give None), all moved into place only at the end.

    A failure or interrupt inside the block removes every staged output and leaves the targets as they were.
    """
    with ExitStack() as stack:
        yield [None if output is None else stack.enter_context(output.staging()) for output in outputs]


def add_lock_argument(parser) -> None:
    """``--lock JOINT[=VALUE]`` (repeatable) for a command that loads a robot; read by :func:`load_robot_argument`."""
    parser.add_argument("--lock", action="append", default=[], metavar="JOINT[=VALUE]", help=_LOCK_HELP)


def add_robot_argument(parser, help: str = ROBOT_HELP) -> None:
    """The positional ``robot`` argument and ``--lock``, the same on every command that loads a robot."""
    parser.add_argument("robot", help=help)
    add_lock_argument(parser)


def add_topic_argument(parser) -> None:
    """How recordings are read: ``--topic`` (a ROS 2 bag's JointState topic), ``--columns`` and ``--rate`` (a
    controller's log with its own column names; read by :func:`recording_layout`)."""
    parser.add_argument(
        "--topic",
        default=None,
        help="sensor_msgs/msg/JointState topic of ROS 2 bag recordings (default: the bag's only one)",
    )
    parser.add_argument(
        "--columns",
        default=None,
        metavar="SIGNAL=PREFIX,...",
        help="for a log with its own column names: which numbered columns are which signal, e.g. "
        "t=Time,q=Position,tau=TorqueSm (joint-torque sensors) or t=Time,q=Position,i=Cur (motor currents, with "
        "the robot file's torque constants); signals t, q, qd, qdd, tau, i; a unit other than SI after a colon: "
        "t=Time:ms,q=Position:deg,tau=Torque:mNm (units t: s ms us ns; q: rad deg mrad m mm; tau: Nm mNm kNm; "
        "i: A mA); a group numbered from 0 is joints 1..n; the file's other columns are not read",
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=None,
        metavar="HZ",
        help="sample rate [Hz] of recordings whose time column counts samples (0, 1, 2, ...) or that have none",
    )


def recording_layout(args):
    """The ``ColumnLayout`` of ``--columns`` and ``--rate``, or None when neither is given."""
    from identification.data.layout import ColumnLayout

    return ColumnLayout.parse(getattr(args, "columns", None), getattr(args, "rate", None))


def stored_layout(args) -> dict | None:
    """``provenance.columns`` of a model file: the ``--columns`` and ``--rate`` identify read its recordings with
    (None when it was given neither)."""
    given = {"columns": getattr(args, "columns", None), "rate": getattr(args, "rate", None)}
    return given if any(v is not None for v in given.values()) else None


def model_layout(args, document, command: str):
    """``recording_layout``, or when neither ``--columns`` nor ``--rate`` is given, the ones identify read the model
    file's recordings with (``document``'s ``provenance.columns``; older files have none), said on stderr: a
    vendor's log is then read by every command as identify read it, without repeating the options."""
    from identification.data.layout import model_file_layout

    layout = recording_layout(args)
    stored = (document or {}).get("provenance", {}).get("columns") if layout is None else None
    if not stored:
        return layout
    given = " ".join(f"--{key} {value}" for key, value in stored.items() if value is not None)
    print(f"psdm {command}: note: the recordings are read as identify read the model's ({given}, stored in the "
          f"model file); pass --columns to read them otherwise (--columns q=q for the standard columns t, "
          f"q1..qn, tau1..taun).", file=sys.stderr)  # fmt: skip
    return model_file_layout(document)


def parse_locks(items) -> dict:
    """``{joint name: value}`` from ``--lock`` items ``NAME`` or ``NAME=VALUE`` (VALUE [rad or m], default 0)."""
    locks = {}
    for item in items or ():
        name, sep, text = str(item).partition("=")
        name = name.strip()
        if not name:
            raise ParameterError(f"--lock must be JOINT or JOINT=VALUE; got {item!r}. Pass e.g. --lock wrist=0.5.")
        try:
            value = float(text) if sep else 0.0
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise ParameterError(
                f"--lock {name} must be locked at a finite number [rad or m]; got {text.strip()!r}. "
                f"Pass e.g. --lock {name}=0.5, or --lock {name} for 0."
            )
        if name in locks:
            raise ParameterError(f"--lock names {name!r} twice. Lock each joint once.")
        locks[name] = value
    return locks


def load_locked_robot(path, items):
    """The robot of ``path`` (a file or a built-in name) with the ``--lock`` items ``items`` applied.

    Raises
    ------
    ParameterError
        For a malformed item, a joint the robot does not have (naming its joints), or a lock on a robot
        of DH rows (which cannot lock joints).
    RobotFileError
        For a bad robot file, or a value outside the joint's limits.
    """
    from psdm_casadi.robot import load_robot

    locks = parse_locks(items)
    robot = load_robot(path)
    if not locks:
        return robot
    if robot.urdf_path is None:
        raise ParameterError(
            f"--lock applies to robots read from a URDF (a .urdf file, or a robot file with a [urdf] table); "
            f"{robot.name!r} is described by DH rows. Remove --lock, or describe the robot by a URDF."
        )
    already = [name for name, _ in robot.locked_joints]
    for name in locks:
        if name not in robot.joint_names and name not in already:
            raise ParameterError(
                f"--lock {name} must name a joint of {robot.name!r}; its joints are {', '.join(robot.joint_names)}"
                + (f" (the robot file locks {', '.join(already)})" if already else "")
                + ". Check the spelling."
            )
    return load_robot(path, locked_joints=locks)


def load_robot_argument(args, path=None):
    """The robot of a command: ``path`` (default ``args.robot``) with the command's ``--lock`` options."""
    return load_locked_robot(args.robot if path is None else path, getattr(args, "lock", ()))


def derive_model(args, robot, seed: int = 0):
    """The PSDM model of ``robot`` through the model cache (``psdm --no-cache`` derives without it)."""
    from psdm_casadi.derive import DeriveOptions
    from psdm_casadi.model_cache import ModelCache

    options = DeriveOptions(seed=seed, form=getattr(args, "derive_form", None) or "auto")
    return ModelCache(enabled=not getattr(args, "no_cache", False)).derive(robot, options)


def command_model(args, robot):
    """The command's one PSDM model of ``robot``: derived (``derive_model``) where a step first asks for it and kept
    on ``args`` for the later steps. A later step's robot differs from the first's only in how it reads torques (the
    torque constants a known payload corrected), which the model, a function of the kinematics, does not hold; derived
    again it cost a second cache read, or a second derivation with ``--no-cache`` or a corrected constant's new key."""
    held = getattr(args, "derived_model", None)
    if held is None or held.n_dof != robot.n_dof:
        held = args.derived_model = derive_model(args, robot)
    return held


def read_calibrated_argument(args, path):
    """The checked calibrated model of ``path`` (a ``LoadedModel``), its robot's model through the model cache."""
    from identification.calibration.calibrated_model import read_calibrated_model

    return read_calibrated_model(path, derive=lambda robot: derive_model(args, robot))


def check_recordings_first(robot, training, validation) -> None:
    """Refuse recordings in the wrong units before a model is derived or fitted: the training ones first (their
    units; the fit checks their motion), then the validation ones (units, joint order and motion)."""
    from identification.calibration.trajectory_checks import check_validation_recording
    from identification.data.plausibility import check_plausible_recording

    for recording in training:
        check_plausible_recording(recording, robot)
    for recording in validation:
        check_validation_recording(robot, recording)
