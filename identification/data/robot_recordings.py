"""Reading a robot's recordings as its robot file describes them: the entry of every command's measured data.

``load_robot_recording`` reads one recording (a file, a ROS 2 bag, or the folder of a recording split
into one file per signal) with the robot's ``RecordingLayout``: files without a ``t`` column are timed by
its ``sample_rate``, split files are joined, and motor-side signals are mapped to the joint side once
(``motor_side.to_joint_side``). ``recording_paths`` turns the paths a user names (``--data pos.csv
torques.csv``) into one path per recording (their folder), so each command sees one entry per recording.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from identification.data.io import read_table, recording_from_table, sample_times, time_column
from identification.data.layout import UnreadColumnGroups
from identification.data.motor_side import to_joint_side
from identification.data.recording import MIN_SAMPLES, Recording
from psdm_casadi.errors import RecordingError

__all__ = [
    "is_split_recording",
    "load_robot_recording",
    "no_torque_constants",
    "rated_currents",
    "recording_paths",
    "torque_constants_place",
]


def _split_names(robot) -> dict:
    """file name -> signal of a recording written as one file per signal (empty without such a layout)."""
    layout = robot.recording_layout
    return {} if layout is None else {name: signal for signal, name in layout.files}


def is_split_recording(path, robot) -> bool:
    """Whether ``path`` is a folder holding every file of the robot file's ``[recording].files``."""
    names = _split_names(robot)
    folder = Path(path)
    return bool(names) and folder.is_dir() and all((folder / name).is_file() for name in names)


def recording_paths(paths, robot) -> list:
    """One path per recording: the files of a split recording (``[recording].files``) become their folder.

    Other paths are kept as given, in order; a folder is named once however many of its files are given.

    Raises
    ------
    RecordingError
        When a split recording's file is given but a partner named in the robot file is not beside it.
    """
    names = _split_names(robot)
    out = []
    for path in map(str, paths):
        entry = path
        if names and Path(path).name in names and Path(path).is_file():
            folder = Path(path).parent
            missing = [name for name in names if not (folder / name).is_file()]
            if missing:
                raise RecordingError(
                    f"{path} is one file of a recording split per signal ({', '.join(names)} in the robot file's "
                    f"[recording].files), but {', '.join(missing)} is not beside it in {folder}. Put the files "
                    "of one recording in one folder."
                )
            entry = str(folder)
        if entry not in out:
            out.append(entry)
    return out


def load_robot_recording(path, robot, topic: str | None = None, columns=None) -> Recording:
    """A joint-side recording of ``robot`` read from ``path`` (module docstring).

    Parameters
    ----------
    path : str or Path
        A recording file or ROS 2 bag (``io.load_recording``), or the folder of a split recording.
    robot : RobotDescription
        Its ``recording_layout`` (sample rate, split files, motor-side signals) and ``transmission``.
    topic : str, optional
        A bag's JointState topic.
    columns : layout.ColumnLayout, optional
        A controller's log with its own column names (``--columns``, ``--rate``): which columns to read; its
        rate, when given, replaces the robot file's ``sample_rate``.

    Returns
    -------
    Recording
        With joint-side signals.

    Raises
    ------
    FileNotFoundError, RecordingError
        As ``io.load_recording``; for a split recording, a file whose column count is not the robot's
        joint count, files of different lengths, or no time column and no ``sample_rate``.
    """
    layout = robot.recording_layout
    rate = None if layout is None else layout.sample_rate
    rate = columns.rate if columns is not None and columns.rate is not None else rate
    if is_split_recording(path, robot):
        recording = _read_split(Path(path), robot, rate)
    else:
        try:
            table = read_table(path, robot.joint_names, topic, columns)
            recording = recording_from_table(table, robot.n_dof, sample_rate=rate, joint_names=robot.joint_names)
        except UnreadColumnGroups as exc:  # the readers know no robot: name where this one's constants are
            raise exc.naming(torque_constants_place(robot)) from None
        if columns is not None and columns.percent_current:
            recording = rated_currents(recording, robot, str(path))
    return to_joint_side(recording, robot)


def rated_currents(recording: Recording, robot, source: str) -> Recording:
    """``recording`` whose currents a controller logged in per cent of each motor's rated current (``--columns
    i=CurrAct_A:%``, as industrial controllers trace them) in amperes: ``i = % / 100 x rated_current`` of the robot
    file's ``[transmission]``, per logged channel (motor ``k``'s column ``k``), before the motor side is mapped.

    Raises
    ------
    RecordingError
        When the robot file states no rated currents (naming the table, the key and the datasheet's value), or the
        recording holds no currents.
    """
    transmission = robot.transmission
    rated = None if transmission is None else transmission.rated_current
    if recording.current is None:
        raise RecordingError(f"{source}: --columns states currents in % (i=PREFIX:%), but the file's currents were not "
                             "read. Name the current group: --columns i=PREFIX:%.")  # fmt: skip
    if rated is None:
        raise RecordingError(
            f"{source}: the currents are logged in % of each motor's rated current (--columns i=...:%), but the robot "
            f"file of {robot.name} states no rated currents. Add rated_current = [...] ({robot.n_dof} numbers, the "
            "motors' rated currents in A from their datasheet) to its [transmission] table (with gear_ratios and "
            "motor_kt), or convert the currents to A and drop the :%."
        )
    return recording.with_signals(current=recording.current * (rated / 100.0))


def torque_constants_place(robot) -> str:
    """Where ``robot``'s file states the torque constants its currents are read with, in a refusal's words: its
    ``[transmission] motor_kt`` (the drives' ``kt`` are then derived from it), else its ``[[drive]]`` tables' ``kt``,
    else the two places it may add them."""
    transmission = robot.transmission
    if transmission is not None and transmission.motor_kt is not None:
        return "read through the robot file's [transmission] motor_kt and gear_ratios"
    if robot.drives is not None:
        return "read through the torque constants kt of the robot file's [[drive]] tables (N m/A at the joint)"
    return ("which need torque constants the robot file does not state yet: add motor_kt and gear_ratios to "
            "[transmission], or kt (N m/A at the joint) to [[drive]] tables") + _robot_file_route(robot)  # fmt: skip


def no_torque_constants(robot) -> str:
    """The refusal of recordings of currents for ``robot``, whose file states no torque constants: where to add them
    (for a URDF or MJCF file, which has no place for them, a TOML robot file that names it)."""
    where = _robot_file_route(robot)
    return (f"recordings of currents need torque constants; {robot.name} has no [[drive]] tables. Add kt (N m/A at "
            "the joint) to [[drive]] tables, or, for motor currents, motor_kt and gear_ratios to [transmission] with "
            f'[recording] side = {{ current = "motor" }}{where}; or record joint torques.')  # fmt: skip


def _robot_file_route(robot) -> str:
    """For a robot read from a URDF or MJCF file (no tables there): the TOML robot file that takes its kinematics and
    inertials and holds the tables; "" for a TOML robot file."""
    source = Path(robot.source) if robot.source else None
    if source is None or source.suffix.lower() == ".toml":
        return ""
    return (f" ({source.name} cannot hold these tables: write a robot file robot.toml beside it with "
            f'[urdf] path = "{source.name}" and the tables, and give robot.toml in its place; '
            "docs/formats/robot-file.md)")  # fmt: skip


def _read_split(folder: Path, robot, rate) -> Recording:
    """One recording from the per-signal files of ``folder`` (every column but ``t`` in joint order)."""
    n = robot.n_dof
    tables = {signal: read_table(folder / name) for name, signal in _split_names(robot).items()}
    arrays, times = {}, []
    for signal, table in tables.items():
        columns = [name for name in table.names if name != "t"]
        if len(columns) != n:
            raise RecordingError(
                f"{folder / table.source}: {len(columns)} columns of {signal} ({', '.join(columns)}), but "
                f"{robot.name} has {n} joints. Write one column per joint (any header), in joint order."
            )
        arrays[signal] = np.take(table.data, [table.names.index(c) for c in columns], axis=1)
        if "t" in table.names:
            times.append(time_column(table))
    lengths = {table.source: table.n_samples for table in tables.values()}
    if len(set(lengths.values())) != 1:
        raise RecordingError(
            f"{folder}: the files of one recording must hold the same samples; got "
            f"{', '.join(f'{k}: {v}' for k, v in lengths.items())} rows. Check that they belong together."
        )
    n_samples = next(iter(lengths.values()))
    if n_samples < MIN_SAMPLES:
        raise RecordingError(f"{folder}: {n_samples} samples; a recording needs at least {MIN_SAMPLES}.")
    if times:
        t = times[0]
    elif rate is not None:
        t = sample_times(n_samples, rate)
    else:
        raise RecordingError(
            f"{folder}: the files {', '.join(lengths)} have no t column and the robot file states no sample rate. "
            "Add sample_rate = <Hz> to its [recording] table, or a t column [s] to the files."
        )
    return Recording(t=t, name=str(folder), **arrays)
