"""Reading and writing recordings (CSV with a header row, or NPZ), the entry of measured data into the flow.

Column names (CSV header or NPZ keys): ``t`` [s], ``q1..qn`` [rad or m], optional ``qd1..qdn``
[rad/s] and ``qdd1..qddn`` [rad/s^2], and joint torques ``tau1..taun`` [N m] and/or motor
currents ``i1..in`` [A]. CSV lines starting with ``#`` are comments. Time steps may be uneven.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from identification.data.recording import MIN_SAMPLES, Recording
from psdm_casadi.errors import RecordingError
from psdm_casadi.fileio import atomic_write

# signal -> column prefix, in the order columns are written
COLUMN_PREFIXES = {"q": "q", "qd": "qd", "qdd": "qdd", "tau": "tau", "current": "i"}
_COLUMN = re.compile(r"^(qdd|qd|q|tau|i)([1-9][0-9]*)$")
_PREFIX_TO_SIGNAL = {v: k for k, v in COLUMN_PREFIXES.items()}
FORMAT_COMMENT = "# psdm recording: t [s], q [rad|m], qd [rad/s], qdd [rad/s^2], tau [N m], i [A]"


def recording_columns(recording: Recording) -> list:
    """The column names ``save_recording`` writes for a recording, in order."""
    names = ["t"]
    for signal, prefix in COLUMN_PREFIXES.items():
        if getattr(recording, signal) is not None:
            names += [f"{prefix}{j + 1}" for j in range(recording.n_dof)]
    return names


def _assemble(columns: dict, source: str, n_dof: int | None, lines=None) -> Recording:
    """Build a Recording from a name -> 1-D array mapping, refusing bad columns with a fix."""
    if "t" not in columns:
        raise RecordingError(f"{source}: column t is missing. Add a time column named 't' [s].")
    groups = {signal: {} for signal in COLUMN_PREFIXES}
    for name, values in columns.items():
        if name == "t":
            continue
        match = _COLUMN.match(name)
        if not match:
            raise RecordingError(
                f"{source}: column {name!r} is not a recording column; expected t, q1..qn, qd1..qdn, qdd1..qddn, "
                "tau1..taun or i1..in. Rename or remove it."
            )
        groups[_PREFIX_TO_SIGNAL[match.group(1)]][int(match.group(2))] = values
    if not groups["q"]:
        raise RecordingError(f"{source}: column q1 is missing. Add joint positions q1..qn [rad or m].")
    n_found = max(groups["q"])
    for j in range(1, n_found + 1):
        if j not in groups["q"]:
            raise RecordingError(f"{source}: column q{j} is missing (q1..q{n_found} expected). Add it.")
    if n_dof is not None and n_found != n_dof:
        raise RecordingError(
            f"{source}: columns q1..q{n_found} give {n_found} joints but the robot has n_dof={n_dof}. "
            f"Record q1..q{n_dof} (one column per joint) or load with the matching robot."
        )
    n = n_found
    if not groups["tau"] and not groups["current"]:
        raise RecordingError(
            f"{source}: columns tau1..tau{n} and i1..i{n} are both missing. "
            f"Add joint torques tau1..tau{n} [N m] or motor currents i1..i{n} [A]."
        )
    arrays = {}
    for signal, found in groups.items():
        if not found:
            continue
        prefix = COLUMN_PREFIXES[signal]
        for j in sorted(found):
            if j > n:
                raise RecordingError(
                    f"{source}: column {prefix}{j} has no matching q{j} (the file has q1..q{n}). "
                    f"Remove {prefix}{j} or add q{j}."
                )
        for j in range(1, n + 1):
            if j not in found:
                raise RecordingError(
                    f"{source}: column {prefix}{j} is missing ({prefix}1..{prefix}{n} expected). Add it."
                )
        arrays[signal] = np.column_stack([found[j] for j in range(1, n + 1)])
    t = np.asarray(columns["t"], dtype=float)
    if t.shape[0] < MIN_SAMPLES:
        raise RecordingError(
            f"{source}: {t.shape[0]} samples; a recording needs at least {MIN_SAMPLES}. Record a longer experiment."
        )
    # name the column, the row (and the file line) of the first bad value
    for name, values in columns.items():
        values = np.asarray(values, dtype=float)
        bad = ~np.isfinite(values)
        if np.any(bad):
            row = int(np.argmax(bad))
            at = f"line {lines[row]}" if lines is not None else f"row {row}"
            raise RecordingError(
                f"{source}: column {name} holds {float(values[row])!r} at {at}. "
                "Remove or interpolate non-finite samples."
            )
    steps = np.diff(t)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 1
        at = f"line {lines[row]}" if lines is not None else f"row {row}"
        raise RecordingError(
            f"{source}: column t must be strictly increasing; got t={t[row]!r} at {at} after t={t[row - 1]!r}. "
            "Sort the samples and drop repeated time stamps."
        )
    return Recording(t=t, name=source, **arrays)


def _read_csv(path: Path, n_dof: int | None) -> Recording:
    source = path.name
    header, rows, lines = None, [], []
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = [f.strip() for f in text.split(",")]
            if header is None:
                header = fields
                header_line = number
                continue
            if len(fields) != len(header):
                raise RecordingError(
                    f"{source}: line {number} has {len(fields)} fields but the header (line {header_line}) has "
                    f"{len(header)}. Fix that line."
                )
            try:
                rows.append([float(f) for f in fields])
            except ValueError:
                bad = next(i for i, f in enumerate(fields) if not _is_float(f))
                raise RecordingError(
                    f"{source}: column {header[bad]} holds {fields[bad]!r} at line {number}, which is not a number. "
                    "Fix or remove that line."
                ) from None
            lines.append(number)
    if header is None:
        raise RecordingError(f"{source}: no header row found. Start the file with a header such as t,q1,...,tau1,...")
    seen = set()
    for name in header:
        if name in seen:
            raise RecordingError(f"{source}: column {name} appears twice in the header. Rename or remove one.")
        seen.add(name)
    data = np.array(rows, dtype=float).reshape(len(rows), len(header))
    columns = {name: data[:, k] for k, name in enumerate(header)}
    return _assemble(columns, source, n_dof, lines)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_npz(path: Path, n_dof: int | None) -> Recording:
    source = path.name
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{source}: not a readable NPZ archive ({exc}). Save it with numpy.savez.") from None
    columns = {}
    with archive:
        for name in archive.files:
            value = np.asarray(archive[name])
            if value.ndim != 1:
                raise RecordingError(
                    f"{source}: array {name!r} has shape {value.shape}; every key must be one 1-D column "
                    "(t, q1, ..., tau1, ...). Save one array per column."
                )
            columns[name] = value
    lengths = {name: v.shape[0] for name, v in columns.items()}
    if len(set(lengths.values())) > 1:
        n_t = lengths.get("t", max(lengths.values()))
        bad = next(name for name, n in lengths.items() if n != n_t)
        raise RecordingError(
            f"{source}: column {bad} has {lengths[bad]} samples but t has {n_t}. Make all columns equal length."
        )
    return _assemble(columns, source, n_dof)


def load_recording(path, n_dof: int | None = None) -> Recording:
    """Read a recording from a CSV (header row, ``#`` comments) or NPZ file.

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.npz`` file with the columns described in the module docstring.
    n_dof : int, optional
        Number of joints of the robot; when given, the file must have exactly ``q1..q{n_dof}``.

    Returns
    -------
    Recording

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    RecordingError
        Naming the column and the fix: missing, duplicated or unknown columns, non-numbers, NaN/inf,
        non-increasing time, too few samples, joint count not matching ``n_dof``.

    Examples
    --------
    >>> rec = load_recording("friction_j1.csv", n_dof=6)       # doctest: +SKIP
    >>> rec.q.shape
    (20000, 6)
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"recording {str(path)!r} does not exist. Check the path.")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _read_csv(path, n_dof)
    if suffix == ".npz":
        return _read_npz(path, n_dof)
    raise RecordingError(f"recording {path.name!r} must end in .csv or .npz; got {path.suffix!r}. Convert it.")


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
        getattr(recording, s) for s in COLUMN_PREFIXES if getattr(recording, s) is not None
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
