"""Reading a recording's CSV text into a ColumnTable with numpy's C parser, refusing what is not CSV text.

Grammar: the first line that is neither blank nor a ``#`` comment is the header of column names;
every later such line is one sample. ``#`` starts a comment anywhere on a line. Fields are separated
by commas, or by semicolons, tabs or blanks when the header uses those instead. A UTF-8 (Excel) or
UTF-16 byte-order mark is read; bytes that are not UTF-8 (a Latin-1 degree sign in a comment) are
replaced, so they only matter where a number is expected. A joint's temperature column may be empty between a
slow logger's readings (read as NaN, ``temperature``).

The numbers are parsed in one ``np.loadtxt`` call (numpy's C parser). When it refuses a row, the
file is read again line by line to name the line, the column and the fix; a line number is likewise
looked up only when a message needs one.
"""

from __future__ import annotations

import logging
import re
import warnings
from datetime import datetime, timezone
from pathlib import Path
from typing import NoReturn

import numpy as np

from identification.data.layout import ColumnLayout, check_standard_header
from identification.data.table import ColumnTable
from identification.data.temperature import is_temperature_column
from identification.data.units import header_unit
from psdm_casadi.errors import RecordingError

logger = logging.getLogger(__name__)
_HEAD_BYTES = 1 << 16  # bytes inspected to tell text from binary data
_DELIMITERS = {",": "','", ";": "';'", "\t": "tab", None: "blanks"}
_SIGNATURES = (  # leading bytes of formats a recording is mistaken for, and what to do with them
    (b"\x1f\x8b", "is gzip-compressed, not CSV text. Decompress it first (gunzip -c {name} > plain.csv)."),
    (
        b"PK\x03\x04",
        "is a ZIP archive (an Excel .xlsx workbook, or an NPZ named .csv?), not CSV text. "
        "Save the sheet as CSV (comma-separated) or rename an NPZ archive to .npz.",
    ),
    (b"\x93NUMPY", "is a NumPy .npy array, not CSV text. Save the columns with numpy.savez(..., t=t, q1=q1, ...)."),
    (b"\x89HDF", "is an HDF5 file (MATLAB v7.3?), not CSV text. Export the recording as CSV or NPZ."),
    (b"MATLAB", "is a MATLAB .mat file, not CSV text. Export the recording as CSV or NPZ."),
)


def read_head(path: Path) -> bytes:
    """The first 64 KiB of a file; an unreadable file raises :class:`RecordingError` with the fix."""
    try:
        with open(path, "rb") as handle:
            return handle.read(_HEAD_BYTES)
    except OSError as exc:
        raise RecordingError(
            f"recording {path.name!r} cannot be read ({exc.strerror or exc}). "
            "Check its permissions (chmod u+r) and that the disk is mounted."
        ) from None


def _text_encoding(source: str, head: bytes) -> str:
    """``utf-16`` or ``utf-8-sig`` for CSV text; :class:`RecordingError` naming the format of binary data."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "utf-16"  # Excel's "Unicode text": tab-separated UTF-16 with a byte-order mark
    for signature, problem in _SIGNATURES:
        if head.startswith(signature):
            raise RecordingError(f"{source} {problem.format(name=source)}")
    nul = head.find(b"\x00")
    if nul >= 0:
        raise RecordingError(
            f"{source} holds binary data (a NUL byte at byte {nul}), not CSV text. "
            "Export the recording as CSV text (t,q1,...,tau1,...) or as NPZ."
        )
    return "utf-8-sig"


def _content(line: str) -> str:
    """A line without its ``#`` comment and surrounding blanks ('' for a blank or comment line)."""
    return line.split("#", 1)[0].strip()


def _is_data_line(line: str) -> bool:
    """Whether a line holds fields: neither blank nor a comment, even an indented one."""
    return not line.isspace() and line.lstrip()[:1] != "#"


def _is_number(field: str) -> bool:
    """Whether numpy's parser reads ``field`` as a float (Python's ``float`` also takes ``1_0``, non-ASCII digits)."""
    text = field.strip()
    if not text.isascii() or "_" in text:
        return False
    try:
        float(text)
    except ValueError:
        return False
    return True


def _split_fields(text: str, delimiter: str | None) -> list:
    return text.split() if delimiter is None else [f.strip() for f in text.split(delimiter)]


def _guess_delimiter(header: str) -> str | None:
    """The separator of a header line: the most frequent of ``,``, ``;`` and tab, else blanks (``None``)."""
    best = max((",", ";", "\t"), key=header.count)
    if header.count(best):
        return best
    return None if len(header.split()) > 1 else ","


def _header_names(source: str, text: str, number: int, delimiter: str | None) -> tuple:
    names = tuple(name.strip('"').strip() for name in _split_fields(text, delimiter))
    if all(_is_number(name) for name in names):
        raise RecordingError(
            f"{source}: line {number} holds numbers where the header row of column names is expected. "
            "Add a header line such as t,q1,...,tau1,... above the data."
        )
    if "" in names:
        k = names.index("")
        raise RecordingError(
            f"{source}: the header (line {number}) has an empty column name at position {k + 1} of {len(names)} "
            f"(a trailing {_DELIMITERS[delimiter]}?). Name that column or remove it, with the trailing "
            f"{_DELIMITERS[delimiter]} of every line."
        )
    return names


def _stated_units(source: str, names: tuple, data: np.ndarray) -> tuple:
    """The header's names without the units they state (``q1 [deg]`` -> ``q1``), and the data in SI."""
    pairs = [header_unit(source, name) for name in names]
    factors = np.array([factor for _, factor in pairs])
    if np.all(factors == 1.0):
        return tuple(name for name, _ in pairs), data
    return tuple(name for name, _ in pairs), data * factors


def _open_text(path: Path, encoding: str):
    return open(path, encoding=encoding, errors="replace", newline=None)


def _load_rows(path: Path, encoding: str, header_line: int, delimiter: str | None, filtered: bool) -> np.ndarray:
    """The samples after the header line, parsed by numpy's C parser; ``filtered`` drops blank and comment lines first.

    numpy skips empty lines and lines starting with ``#`` itself, which is all a well-formed file
    needs; only a file with lines of blanks or indented comments pays for the filter.
    """
    with _open_text(path, encoding) as handle:
        for _ in zip(range(header_line), handle):
            pass
        rows = (line for line in handle if _is_data_line(line)) if filtered else handle
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data": refused by the caller
            return np.loadtxt(rows, dtype=float, delimiter=delimiter, comments="#", ndmin=2)


def _decimal_comma_rows(path: Path, encoding: str, header_line: int, delimiter: str | None):
    """The samples of a file separated by ``;`` or tabs whose numbers have a decimal comma (``0,5``, as a spreadsheet
    in a European locale writes), or None when it is not one (the comma cannot be a decimal mark beside ``,``)."""
    if delimiter not in (";", "\t"):
        return None
    with _open_text(path, encoding) as handle:
        for _ in zip(range(header_line), handle):
            pass
        rows = (line.replace(",", ".") for line in handle if _is_data_line(line))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                data = np.loadtxt(rows, dtype=float, delimiter=delimiter, comments="#", ndmin=2)
        except ValueError:
            return None
    logger.info("%s: numbers with a decimal comma read as decimals", path.name)
    return data


def _sparse_rows(path: Path, encoding: str, header_line: int, delimiter: str | None, names: tuple):
    """The samples of a file whose joints' temperature columns (``temperature``) are empty between a slow logger's
    readings, those cells read as NaN (a decimal comma too, as ``_decimal_comma_rows``); None when it is not one."""
    columns = [k for k, name in enumerate(names) if is_temperature_column(name)]
    if delimiter is None or not columns:
        return None

    def filled(line: str) -> str:
        fields = line.rstrip("\r\n").split("#", 1)[0].split(delimiter)
        for k in columns:
            if k < len(fields) and not fields[k].strip():
                fields[k] = "nan"
        text = delimiter.join(fields)
        return text.replace(",", ".") if delimiter in (";", "\t") else text

    with _open_text(path, encoding) as handle:
        for _ in zip(range(header_line), handle):
            pass
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                rows = (filled(line) for line in handle if _is_data_line(line) and _content(line))
                return np.loadtxt(rows, dtype=float, delimiter=delimiter, comments="#", ndmin=2)
        except ValueError:
            return None


_CLOCK = re.compile(r"^\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d+)?)?(Z|[+-]\d{2}:?\d{2})?$")


def _clock(field: str) -> datetime:
    stamp = datetime.fromisoformat(field.strip().strip('"'))
    return stamp if stamp.tzinfo else stamp.replace(tzinfo=timezone.utc)


def _clock_time_rows(path: Path, encoding: str, header_line: int, delimiter: str | None):
    """The samples of a file whose time column holds ISO 8601 date-times (``2026-12-05T04:13:29.123``, as pandas and
    many loggers write), that column as seconds from the first; None when no column of the first row is one."""
    with _open_text(path, encoding) as handle:
        lines = [_content(line) for number, line in enumerate(handle, start=1) if number > header_line]
    lines = [line for line in lines if line]
    if not lines:
        return None
    first = [f.strip('"') for f in _split_fields(lines[0], delimiter)]
    clock = [k for k, f in enumerate(first) if _CLOCK.match(f)]
    if len(clock) != 1:
        return None
    try:
        rows = [_split_fields(line, delimiter) for line in lines]
        origin = _clock(rows[0][clock[0]])  # seconds from the first stamp: exact, where Unix seconds lose digits
        k0 = clock[0]
        data = np.array([[(_clock(f) - origin).total_seconds() if k == k0 else float(f) for k, f in enumerate(r)]
                         for r in rows])  # fmt: skip
    except ValueError:
        return None
    logger.info("%s: column %d holds date-times; read as seconds", path.name, clock[0] + 1)
    return data if data.ndim == 2 else None


def _data_lines(path: Path, encoding: str, header_line: int):
    """``(line number, content)`` of every data line after the header (the slow path, for messages)."""
    with _open_text(path, encoding) as handle:
        for number, line in enumerate(handle, start=1):
            if number > header_line and _is_data_line(line) and _content(line):
                yield number, _content(line)


def _locator(path: Path, encoding: str, header_line: int):
    def locate(row: int) -> str:
        for k, (number, _) in enumerate(_data_lines(path, encoding, header_line)):
            if k == row:
                return f"line {number}"
        return f"data row {row}"

    return locate


def _explain_parse_error(path: Path, encoding: str, header_line: int, names: tuple, delimiter, error: str) -> NoReturn:
    """Raise the message naming the first line numpy could not read (its line, column and the fix)."""
    source = path.name
    for number, text in _data_lines(path, encoding, header_line):
        fields = _split_fields(text, delimiter)
        if len(fields) != len(names):
            others = [label for d, label in _DELIMITERS.items() if d and d != delimiter and d in text]
            hint = f" It is separated by {others[0]}, the header by {_DELIMITERS[delimiter]}." if others else ""
            raise RecordingError(
                f"{source}: line {number} has {len(fields)} field{'' if len(fields) == 1 else 's'} but the header "
                f"(line {header_line}) has "
                f"{len(names)}.{hint} Fix that line."
            )
        for name, value in zip(names, fields):
            if not _is_number(value):
                hint = ""
                if value == "":
                    hint = " (an empty cell)"
                elif "," in value and delimiter != ",":
                    hint = " (a decimal comma? write 0.5, not 0,5)"
                raise RecordingError(
                    f"{source}: column {name} holds {value!r} at line {number}, which is not a number{hint}. "
                    "Fix or remove that line."
                )
    raise RecordingError(f"{source}: numpy could not read the samples ({error}). Fix the file.")


def read_csv_table(path, layout: ColumnLayout | None = None) -> ColumnTable:
    """Read a CSV recording into a :class:`ColumnTable` (grammar in the module docstring).

    Parameters
    ----------
    path : str or Path
        An existing regular file.
    layout : ColumnLayout, optional
        Which columns to read, renamed to ``t, q1..``; the others are dropped unchecked (a controller's log
        with NaN in its reference columns). Without it, every column is checked; a header of numbered
        groups without ``q1`` whose values are refused is refused naming the ``--columns`` that reads it
        (``layout.check_standard_header``).

    Returns
    -------
    ColumnTable
        Columns named by the header, values as float64, rows located by their file line.

    Raises
    ------
    RecordingError
        Naming the file and the fix: binary or compressed data, no header, an empty or repeated
        column name, a row with another field count, a cell that is not a number (line and column),
        NaN, infinite or implausibly large values.
    """
    path = Path(path)
    source = path.name
    encoding = _text_encoding(source, read_head(path))
    header_line, header = 0, ""
    with _open_text(path, encoding) as handle:
        for line in handle:
            header_line += 1
            header = _content(line)
            if header:
                break
        if not header:
            what = "is empty" if path.stat().st_size == 0 else "holds only comments and blank lines"
            raise RecordingError(
                f"{source}: no header row found; the file {what}. Start it with a header such as t,q1,...,tau1,..."
            )
        delimiter = _guess_delimiter(header)
        names = _header_names(source, header, header_line, delimiter)
    try:
        data = _load_rows(path, encoding, header_line, delimiter, filtered=False)
    except ValueError:
        try:  # lines of blanks or indented comments trip numpy's parser: drop them and parse again
            data = _load_rows(path, encoding, header_line, delimiter, filtered=True)
        except ValueError as exc:
            data = _decimal_comma_rows(path, encoding, header_line, delimiter)
            data = _sparse_rows(path, encoding, header_line, delimiter, names) if data is None else data
            data = _clock_time_rows(path, encoding, header_line, delimiter) if data is None else data
            if data is None:
                _explain_parse_error(path, encoding, header_line, names, delimiter, str(exc))
    if data.shape[0] and data.shape[1] != len(names):
        _explain_parse_error(path, encoding, header_line, names, delimiter, f"{data.shape[1]} columns")
    if data.shape[0] == 0:
        data = np.empty((0, len(names)))
    names, data = _stated_units(source, names, data)
    locate = _locator(path, encoding, header_line)
    if layout is None:
        data.setflags(write=False)  # handed over to the table without a copy
        try:
            return ColumnTable(source=source, names=names, data=data, locate=locate)
        except RecordingError as exc:  # NaN in a controller's reference column: say how to leave it unread
            check_standard_header(source, names, because=str(exc))
            raise
    mapping = layout.columns(source, names)
    data = np.ascontiguousarray(data[:, [names.index(name) for name in mapping]])
    data.setflags(write=False)
    checked = ColumnTable(source=source, names=tuple(mapping), data=data, locate=locate)  # messages name file columns
    return ColumnTable(source=source, names=tuple(mapping.values()), data=checked.data, locate=checked.locate)
