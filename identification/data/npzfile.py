"""Reading a recording's NPZ archive (one 1-D numeric array per column) into a ColumnTable, never unpickling.

``numpy.load`` runs with ``allow_pickle=False``: an archive holding object arrays is refused with
the fix, as are corrupt archives, text or compressed files named ``.npz``, a single ``.npy`` array,
and columns that are not 1-D real numbers or differ in length.
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path

import numpy as np

from identification.data.csvfile import read_head
from identification.data.table import ColumnTable
from psdm_casadi.errors import RecordingError

_SAVE = "Save it with numpy.savez(path, t=t, q1=q1, ..., tau1=tau1, ...)."
# what a damaged archive raises from numpy.load or from reading a member (MemoryError: a corrupt
# header announcing an impossible array)
_DAMAGED = (OSError, ValueError, EOFError, KeyError, RuntimeError, NotImplementedError, MemoryError)
_DAMAGED += (zipfile.BadZipFile, zlib.error)


def _is_text(head: bytes) -> bool:
    """Whether the first bytes of a file read as UTF-8 text without control characters other than blanks."""
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if exc.reason != "unexpected end of data":  # more than a character cut at the end of the head
            return False
        text = head[: exc.start].decode("utf-8-sig")
    return all(c.isprintable() or c in "\t\r\n" for c in text)


def _check_signature(source: str, head: bytes) -> None:
    if head.startswith(b"PK"):
        return
    if head.startswith(b"\x1f\x8b"):
        problem = "is gzip-compressed, not an NPZ archive. Decompress it (gunzip) or save it with numpy.savez."
    elif head.startswith(b"\x93NUMPY"):
        problem = f"is a single .npy array, not an NPZ archive of named columns. {_SAVE}"
    elif not head:
        problem = f"is empty. {_SAVE}"
    elif _is_text(head):
        problem = "is text, not an NPZ archive (a CSV named .npz?). Rename it to .csv."
    else:
        problem = f"is not an NPZ archive (no ZIP signature). {_SAVE}"
    raise RecordingError(f"{source} {problem}")


def _member(source: str, archive, name: str) -> np.ndarray:
    try:
        value = np.asarray(archive[name])
    except _DAMAGED as exc:
        if "allow_pickle" in str(exc):
            raise RecordingError(
                f"{source}: array {name!r} holds Python objects, which are not unpickled (a file could run code). "
                f"Save plain numbers: numpy.savez(path, {name}=np.asarray({name}, dtype=float), ...)."
            ) from None
        raise RecordingError(f"{source}: array {name!r} is damaged ({exc}). {_SAVE}") from None
    if value.ndim == 0 and value.dtype.kind == "S":
        raise RecordingError(f"{source}: member {name!r} is not a NumPy array (a ZIP archive of other files?). {_SAVE}")
    if value.ndim != 1:
        raise RecordingError(
            f"{source}: array {name!r} has shape {value.shape}; every key must be one 1-D column "
            "(t, q1, ..., tau1, ...). Save one array per column."
        )
    if value.dtype.kind not in "iuf":
        raise RecordingError(
            f"{source}: array {name!r} has dtype {value.dtype}; a column must hold real numbers. "
            f"Save it as floats: {name}=np.asarray({name}, dtype=float)."
        )
    return value


def read_npz_table(path) -> ColumnTable:
    """Read an NPZ recording (one 1-D real array per column name) into a :class:`ColumnTable`.

    Parameters
    ----------
    path : str or Path
        An existing regular file.

    Returns
    -------
    ColumnTable
        Columns in the archive's order, rows located as ``row k`` (0-based).

    Raises
    ------
    RecordingError
        Naming the file, the array and the fix: not a ZIP archive, damaged data, object (pickled)
        arrays, arrays that are not 1-D real numbers, columns of unequal length, NaN, infinite or
        implausibly large values.
    """
    path = Path(path)
    source = path.name
    _check_signature(source, read_head(path))
    try:
        archive = np.load(path, allow_pickle=False)
    except _DAMAGED as exc:
        raise RecordingError(f"{source}: not a readable NPZ archive ({exc}). {_SAVE}") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise RecordingError(f"{source}: holds one array, not an NPZ archive of named columns. {_SAVE}")
    with archive:
        columns = {name: _member(source, archive, name) for name in archive.files}
    lengths = {name: v.shape[0] for name, v in columns.items()}
    if len(set(lengths.values())) > 1:
        n_t = lengths.get("t", max(lengths.values()))
        bad = next(name for name, n in lengths.items() if n != n_t)
        raise RecordingError(
            f"{source}: column {bad} has {lengths[bad]} samples but t has {n_t}. Make all columns equal length."
        )
    names = tuple(columns)
    # column-major, so that each column is contiguous; each array is released once copied
    data = np.empty((next(iter(lengths.values()), 0), len(names)), order="F")
    for k, name in enumerate(names):
        data[:, k] = columns.pop(name)
    data.setflags(write=False)  # handed over to the table without a copy
    return ColumnTable(source=source, names=names, data=data)
