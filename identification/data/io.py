"""Reading and writing recordings (CSV, NPZ; read also MATLAB and ROS 2 bags), the entry of measured data into the flow.

Column names (CSV header, NPZ keys, MATLAB variables): ``t`` [s], ``q1..qn`` [rad or m], optional
``qd1..qdn`` [rad/s] and ``qdd1..qddn`` [rad/s^2], and joint torques ``tau1..taun`` [N m] and/or
motor currents ``i1..in`` [A]; optional joint temperatures ``temp1..tempn`` [°C] (or a controller's names,
``Temp1``, ``joint_temperatures_0``: ``temperature``), NaN where none was logged. CSV lines starting with ``#`` are
comments. Time steps may be uneven.
The reader of each format (``csvfile``, ``npzfile``, ``matfile`` with its matrix layout, ``rosbag``
for the JointState messages of a bag folder or ``.mcap`` file) gives a checked ``ColumnTable``; this
module makes its columns the signals of a ``Recording``.
"""

from __future__ import annotations

import filecmp
import logging
import re
from pathlib import Path

import numpy as np

from identification.data.csvfile import read_csv_table
from identification.data.layout import (
    SIGNAL_PREFIXES,
    TIME_NAMES,
    ColumnLayout,
    check_standard_header,
    seconds,
)
from identification.data.matfile import read_mat_table
from identification.data.npzfile import read_npz_table
from identification.data.recording import MIN_SAMPLES, Recording
from identification.data.rosbag import is_rosbag, read_rosbag_table
from identification.data.table import ColumnTable
from identification.data.temperature import TEMPERATURE_PREFIX, temperature_joints
from identification.data.units import to_si
from psdm_casadi.errors import RecordingError
from psdm_casadi.fileio import atomic_write
from psdm_casadi.near_names import did_you_mean

# signal -> column prefix, in the order columns are written
COLUMN_PREFIXES = {"q": "q", "qd": "qd", "qdd": "qdd", "tau": "tau", "current": "i"}
_COLUMN = re.compile(r"^(qdd|qd|q|tau|i)([1-9][0-9]*)$")
_PREFIX_TO_SIGNAL = {v: k for k, v in COLUMN_PREFIXES.items()}
logger = logging.getLogger(__name__)
FORMAT_COMMENT = "# psdm recording: t [s], q [rad|m], qd [rad/s], qdd [rad/s^2], tau [N m], i [A]"


def recording_columns(recording: Recording) -> list:
    """The column names ``save_recording`` writes for a recording, in order."""
    names = ["t"]
    for signal, prefix in COLUMN_PREFIXES.items():
        if getattr(recording, signal) is not None:
            names += [f"{prefix}{j + 1}" for j in range(recording.n_dof)]
    if recording.temperature is not None:
        names += [f"{TEMPERATURE_PREFIX}{j + 1}" for j in range(recording.n_dof)]
    return names


def _signal(table: ColumnTable, names: list) -> np.ndarray:
    """The columns ``names`` side by side, as a new read-only array that ``Recording`` keeps without copying."""
    index = [table.names.index(name) for name in names]
    if table.data.flags.c_contiguous:
        out = np.take(table.data, index, axis=1)  # a new C-ordered array in one pass
    else:
        out = np.empty((table.n_samples, len(names)))
        for k, j in enumerate(index):
            out[:, k] = table.data[:, j]
    out.setflags(write=False)
    return out


def _group(table: ColumnTable) -> dict:
    """signal -> {joint number: column name}, refusing a name that is not a recording column."""
    groups = {signal: {} for signal in COLUMN_PREFIXES}
    temperatures = temperature_joints(table.names)
    for name in table.names:
        if name == "t" or name in temperatures:
            continue
        match = _COLUMN.match(name)
        if not match:
            bytes_hint = (
                " (it holds bytes that are not UTF-8: write the header in plain ASCII)" if "\ufffd" in name else ""
            )
            raise RecordingError(
                f"{table.source}: column {name!r} is not a recording column{bytes_hint}; expected t, q1..qn, "
                "qd1..qdn, qdd1..qddn, tau1..taun or i1..in. Rename or remove it."
            )
        groups[_PREFIX_TO_SIGNAL[match.group(1)]][int(match.group(2))] = name
    return groups


def _check_joints(source: str, groups: dict, n_dof: int | None, joint_names=None) -> int:
    """The joint count the q columns give, after checking every signal has exactly the columns 1..n."""
    if not groups["q"]:
        raise RecordingError(f"{source}: column q1 is missing. Add joint positions q1..qn [rad or m].")
    n = max(groups["q"])
    for j in range(1, n + 1):
        if j not in groups["q"]:
            raise RecordingError(f"{source}: column q{j} is missing (q1..q{n} expected). Add it.")
    if n_dof is not None and n != n_dof:
        raise RecordingError(f"{source}: columns q1..q{n} give {n} joints but the robot has n_dof={n_dof}. "
                             + _joint_count_fix(n, n_dof, joint_names))  # fmt: skip
    if not groups["tau"] and not groups["current"]:
        raise RecordingError(
            f"{source}: columns tau1..tau{n} and i1..i{n} are both missing. "
            f"Add joint torques tau1..tau{n} [N m] or motor currents i1..i{n} [A]."
        )
    for signal, found in groups.items():
        prefix = COLUMN_PREFIXES[signal]
        for j in sorted(found):
            if j > n:
                raise RecordingError(
                    f"{source}: column {prefix}{j} has no matching q{j} (the file has q1..q{n}). "
                    f"Remove {prefix}{j} or add q{j}."
                )
        for j in range(1, n + 1):
            if found and j not in found:
                raise RecordingError(
                    f"{source}: column {prefix}{j} is missing ({prefix}1..{prefix}{n} expected). Add it."
                )
    return n


def time_column(table: ColumnTable, rate: float | None = None) -> np.ndarray:
    """The table's column ``t`` [s] as a new read-only array, after checking that it strictly increases.

    A column ``t`` that counts samples (a controller's row index: 0, 1, 2, ...) is divided by ``rate`` [Hz]
    (``--rate``, or the robot file's ``[recording].sample_rate``) and refused without one
    (``layout.seconds``); a column of times is kept as it is.

    Raises
    ------
    RecordingError
        When the column is missing, counts samples without a rate, or a time stamp repeats or goes back
        (naming its line and the fix).
    """
    if "t" not in table.names:
        raise RecordingError(f"{table.source}: column t is missing. Add a time column named 't' [s].")
    t = seconds(table.source, _signal(table, ["t"])[:, 0], rate)
    t.setflags(write=False)
    back = np.flatnonzero(t[1:] <= t[:-1])
    if back.size:
        row = int(back[0]) + 1
        raise RecordingError(
            f"{table.source}: column t must be strictly increasing; got t={float(t[row])!r} at {table.locate(row)} "
            f"after t={float(t[row - 1])!r}. Sort the samples and drop repeated time stamps."
        )
    return t


def sample_times(n_samples: int, sample_rate: float) -> np.ndarray:
    """``t = k / sample_rate`` [s] for k = 0..n_samples-1, read-only: the time of a file without a ``t`` column."""
    t = np.arange(n_samples) * (1.0 / float(sample_rate))  # k * dt, as a controller's clock counts
    t.setflags(write=False)
    return t


def _joint_count_fix(n: int, n_dof: int, joint_names=None) -> str:
    """The fix of a recording of ``n`` joint columns for a robot of ``n_dof`` joints: lock the joints it leaves out."""
    if n < n_dof:
        extra = list(joint_names)[n:] if joint_names is not None and len(joint_names) == n_dof else []
        named = f" ({', '.join(extra)})" if extra else ""
        locks = " ".join(f"--lock {name}" for name in extra) if extra else "--lock JOINT"
        return (f"If the robot's joints {n + 1}..{n_dof}{named} are not in the recording (a gripper's fingers), lock "
                f"them: {locks} (at a position: --lock JOINT=VALUE; in Python load_robot(..., locked_joints=[...])). "
                f"Otherwise record q1..q{n_dof}.")  # fmt: skip
    return f"Load it with the robot it was recorded on, or remove the columns of joints {n_dof + 1}..{n}."


def _time_named_t(table: ColumnTable) -> ColumnTable:
    """The table with its one time-like column (``time``, ``Timestamp``, ...) named ``t`` when it has no ``t``."""
    found = [k for k, n in enumerate(table.names) if n.lower() in TIME_NAMES]
    if "t" in table.names or len(found) != 1:
        return table
    names = list(table.names)
    logger.info("%s: column %s read as the time t [s]", table.source, names[found[0]])
    names[found[0]] = "t"
    return ColumnTable(source=table.source, names=tuple(names), data=table.data, locate=table.locate)


def recording_from_table(
    table: ColumnTable, n_dof: int | None = None, sample_rate: float | None = None, joint_names=None
) -> Recording:
    """The Recording of a table's columns (``t``, ``q1..qn``, ...), refusing bad columns and time with a fix.

    A table without a ``t`` column is timed ``t = k / sample_rate`` when a ``sample_rate`` [Hz] is given
    (the robot file's ``[recording].sample_rate``, or ``--rate``); a table's own ``t`` column of times always wins,
    and one that counts samples is divided by it.

    Raises
    ------
    RecordingError
        Naming the file, the column and the fix: missing, unknown or unmatched columns, a joint count
        other than ``n_dof``, too few samples, time that does not strictly increase (with its line), no
        ``t`` column and no ``sample_rate``.
    """
    source = table.source
    table = _time_named_t(table)
    check_standard_header(source, table.names)  # a controller's own column groups: name the --columns to give
    if "t" not in table.names and sample_rate is None:
        raise RecordingError(
            f"{source}: column t is missing. Add a time column named 't' [s], or state the sample rate "
            "(sample_rate = <Hz> in the robot file's [recording] table)."
        )
    groups = _group(table)
    n = _check_joints(source, groups, n_dof, joint_names)
    if table.n_samples < MIN_SAMPLES:
        raise RecordingError(
            f"{source}: {table.n_samples} sample{'' if table.n_samples == 1 else 's'}; a recording needs at least "
            f"{MIN_SAMPLES}. Record a longer experiment."
        )
    t = time_column(table, sample_rate) if "t" in table.names else sample_times(table.n_samples, sample_rate)
    arrays = {signal: _signal(table, [found[j] for j in range(1, n + 1)]) for signal, found in groups.items() if found}
    return Recording(t=t, name=source, temperature=_temperatures(table, n), **arrays)


def _temperatures(table: ColumnTable, n: int) -> np.ndarray | None:
    """The joints' temperature columns (``temperature``) as (n_samples, n), NaN for a joint without one; None without
    any. A column numbered beyond the joints (a controller's own) is not read."""
    found = {joint: name for name, joint in temperature_joints(table.names).items() if 1 <= joint <= n}
    if not found:
        return None
    out = np.full((table.n_samples, n), np.nan)
    for joint, name in found.items():
        out[:, joint - 1] = table.column(name)
    return out


def read_table(path, joint_names=None, topic: str | None = None, layout: ColumnLayout | None = None) -> ColumnTable:
    """The named columns of a recording (CSV, NPZ, MAT by the suffix; a ROS 2 bag), checked but not yet a Recording.

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.npz`` or ``.mat`` file, a ROS 2 bag folder (with ``metadata.yaml``) or a
        ``.mcap``/``.db3`` bag file.
    joint_names : sequence of str, optional
        The robot's joint names (``RobotDescription.joint_names``): the order of a bag's joints.
        Files with numbered columns ignore it.
    topic : str, optional
        The JointState topic of a bag (default: its only one); other files ignore it.
    layout : ColumnLayout, optional
        Which columns of a file with its own names to read (``layout``); the others are dropped.

    Returns
    -------
    ColumnTable

    Raises
    ------
    FileNotFoundError
        When nothing exists at ``path``.
    RecordingError
        When ``path`` is a folder that is not a bag or not a regular file, cannot be read, has another
        suffix, or its content is refused by the reader (see ``csvfile``, ``npzfile``, ``matfile``,
        ``rosbag``).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"recording {str(path)!r} does not exist. Check the path.{did_you_mean(path)}")
    if is_rosbag(path):
        table = read_rosbag_table(path, topic=topic, joint_names=joint_names)
        if layout is None:
            return table
        renamed = any(prefix != SIGNAL_PREFIXES[signal] for signal, prefix in layout.prefixes)
        if renamed or layout.time not in (None, "t"):  # a bag's fields have fixed names: only the units apply
            logger.warning("%s: a ROS 2 bag's JointState fields are read by name; --columns' prefixes are not used "
                           "(only its units)", table.source)  # fmt: skip
        data = to_si(table.names, table.data, layout.units)
        return table if data is table.data else ColumnTable(table.source, table.names, data, table.locate)
    if path.is_dir():
        raise RecordingError(
            f"recording {str(path)!r} is a folder, not a file or a ROS 2 bag (no metadata.yaml in it). Pass one .csv, "
            ".npz or .mat recording inside it, or a bag folder."
        )
    if not path.is_file():
        raise RecordingError(
            f"recording {str(path)!r} is not a regular file (a pipe or device?). Save the recording to a file first."
        )
    readers = {".csv": read_csv_table, ".npz": read_npz_table, ".mat": read_mat_table}
    reader = readers.get(path.suffix.lower())
    if path.suffix.lower() == ".toml":  # a payload manifest (identify --data) or a robot file in a recording's place
        raise RecordingError(
            f"recording {path.name!r} is a TOML file, not a recording: a configurations manifest is read by "
            "identify's --data only. Give its recordings themselves (each one's load: an A.payload.json beside it; "
            "diagnose of a model takes the load the model file lists for its own training recordings)."
        )
    if reader is None:
        raise RecordingError(
            f"recording {path.name!r} must end in .csv or .npz (named columns), .mat (MATLAB) or .mcap/.db3 (a ROS 2 "
            f"bag), or be a bag folder; got {path.suffix!r}. Rename it .csv if it is comma-separated text with a "
            f"header row, or convert it to a CSV with the columns t, q1..qn and tau1..taun (or i1..in; --columns "
            f"maps other names)."
        )
    if layout is None:
        return reader(path)
    if reader is read_csv_table:
        table = read_csv_table(path, layout)
    else:
        table = reader(path)
        mapping = layout.columns(table.source, table.names)
        data = table.data[:, [table.names.index(name) for name in mapping]]
        table = ColumnTable(source=table.source, names=tuple(mapping.values()), data=data, locate=table.locate)
    data = to_si(table.names, table.data, layout.units)
    if data is table.data:
        return table
    return ColumnTable(source=table.source, names=table.names, data=data, locate=table.locate)


def load_recording(
    path, n_dof: int | None = None, joint_names=None, topic: str | None = None, layout: ColumnLayout | None = None
) -> Recording:
    """Read a recording from a CSV (header row, ``#`` comments), NPZ or MATLAB file, or a ROS 2 bag.

    CSV text is parsed by numpy's C parser (``csvfile``); comma, semicolon, tab or blank separated,
    with or without a UTF-8 byte-order mark. NPZ archives are read without unpickling (``npzfile``).
    MATLAB files hold one vector per column or the matrices ``t, q, tau`` (``matfile``). A bag's
    ``sensor_msgs/msg/JointState`` messages give ``t``, ``q``, ``qd`` and ``tau`` (``rosbag``).

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.npz`` or ``.mat`` file with the columns described in the module docstring,
        or a ROS 2 bag (a folder with ``metadata.yaml``, or a ``.mcap``/``.db3`` file).
    n_dof : int, optional
        Number of joints of the robot; when given, the file must have exactly ``q1..q{n_dof}``.
    joint_names : sequence of str, optional
        The robot's joint names in its order (``RobotDescription.joint_names``): a bag's joints are
        matched to them by name. Without it a bag keeps its own order; other formats ignore it.
    topic : str, optional
        A bag's JointState topic (default: its only one); other formats ignore it.
    layout : ColumnLayout, optional
        For a controller's log with its own column names: which columns are ``t``, ``q``, ``tau``, ``i``
        (``--columns``) and the sample rate of a time column that counts samples (``--rate``); the
        file's other columns are not read.

    Returns
    -------
    Recording

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    RecordingError
        Naming the file, the column and the fix: a folder that is not a bag, binary or compressed
        data, missing, duplicated or unknown columns, non-numbers (with line and column), NaN/inf or
        implausibly large values, non-increasing time, too few samples, joint count not matching
        ``n_dof``; for a bag, a missing or ambiguous JointState topic or joints not matching
        ``joint_names``; for MATLAB, a v7.3 file without h5py or a transposed matrix.

    Examples
    --------
    >>> rec = load_recording("friction_j1.csv", n_dof=6)       # doctest: +SKIP
    >>> rec.q.shape
    (20000, 6)
    >>> rec = load_recording("run1.mcap", robot.n_dof, robot.joint_names)   # doctest: +SKIP
    """
    if layout is not None and layout.percent_current:  # the rated currents are the robot file's
        raise RecordingError(
            f"{path}: currents in % of the rated current (i=PREFIX:%) are read with the robot file "
            "that states them: robot_recordings.load_robot_recording(path, robot, columns=layout)."
        )
    rate = None if layout is None else layout.rate
    table = read_table(path, joint_names, topic, layout)
    return recording_from_table(table, n_dof, sample_rate=rate, joint_names=joint_names)


def save_recording(recording: Recording, path, overwrite: bool = False, comment: str | None = None) -> Path:
    """Write a recording as CSV or NPZ (by the suffix of ``path``), atomically.

    Parameters
    ----------
    recording : Recording
    path : str or Path
        Ends in ``.csv`` or ``.npz``.
    overwrite : bool
        Replace an existing file; by default an existing file raises ``FileExistsError``.
    comment : str, optional
        Extra ``#`` comment lines for the CSV header (ignored for NPZ).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    FileExistsError
        When the file exists and ``overwrite`` is false.
    RecordingError
        When the suffix is neither ``.csv`` nor ``.npz``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    names = recording_columns(recording)
    blocks = [recording.t[:, None]] + [
        getattr(recording, s) for s in (*COLUMN_PREFIXES, "temperature") if getattr(recording, s) is not None
    ]
    data = np.hstack(blocks)
    if suffix == ".csv":

        def write(handle):
            handle.write(FORMAT_COMMENT + "\n")
            if comment:
                for line in str(comment).splitlines():
                    handle.write(f"# {line}\n")
            handle.write(",".join(names) + "\n")
            np.savetxt(handle, data, delimiter=",", fmt="%.17g")

        return atomic_write(path, write, overwrite)
    if suffix == ".npz":

        def write(handle):
            np.savez(handle, **{name: data[:, k] for k, name in enumerate(names)})

        return atomic_write(path, write, overwrite, mode="wb")
    raise RecordingError(f"save_recording path {path.name!r} must end in .csv or .npz; got {path.suffix!r}.")


def _same_file(a: Path, b: Path) -> bool:
    """The same file or folder (links resolved), or two files with the same bytes."""
    try:
        if a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b)):
            return True
        return a.is_file() and b.is_file() and filecmp.cmp(a, b, shallow=False)
    except OSError:
        return False


def not_held_out(training, validation, option: str = "--data") -> list:
    """A warning (str) per validation recording that is also a training one: one file (or bag) named twice,
    through a link, or a byte-identical copy. Its validation is not held out: it measures the fit on the data
    it was fitted to, and says nothing about how the model predicts new motion. ``option`` names the training
    recordings' option in the message."""
    return [
        f"--validate {b} is the same recording as {option} {a}: the validation is then NOT held out (it measures "
        "the fit on its own data, not the prediction of new motion). Validate on another recording."
        for a in training
        for b in validation
        if _same_file(Path(str(a)), Path(str(b)))
    ]
