"""ColumnTable: the named numeric columns of a recording file, checked, before ``io`` makes them a Recording.

The readers (``csvfile`` for CSV text, ``npzfile`` for NPZ archives) return one; it holds one float64
array ``(n_samples, n_columns)`` and knows how to name a row of it in the file (``line 12`` of a CSV,
``row 11`` of an NPZ), so every message points at the sample to fix.

A logger drops a sample now and then and writes its row as NaN (or leaves its fields empty): up to
``MAX_DROPOUT_FRACTION`` of the rows in which a signal's columns are NaN together (every joint of ``q``, of
``tau``, ...; a column NaN throughout was never logged and is left to the Recording) are taken out, with a
warning naming the file and their lines (the time steps may be uneven, so the recording stays exact);
a NaN in one joint's column only, or more rows, is refused, counted, with the fix. A row whose time stamp repeats
the one before it (a coarse logger clock under jitter) is left out the same way. A joint's temperature column
(``temperature.TEMPERATURE_COLUMN``) is logged slowly: its NaN are readings not taken and are kept as they are.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from identification.data.temperature import is_temperature_column
from psdm_casadi.errors import RecordingError

# No joint signal in SI units comes near this (positions in rad or m, torques in N m, currents in A,
# times in s); values beyond it are a unit or export error and overflow once differentiated.
MAX_MAGNITUDE = 1e12
#: Largest share of a file's rows that may be logger dropouts (a NaN in a column logged elsewhere) and are left out.
MAX_DROPOUT_FRACTION = 0.01

logger = logging.getLogger(__name__)


def row_label(row: int) -> str:
    """How a sample is named when the file has no line numbers (NPZ): ``row k``, 0-based."""
    return f"row {row}"


@dataclass(frozen=True, eq=False)
class ColumnTable:
    """Named columns of numbers read from one recording file.

    Parameters
    ----------
    source : str
        The file name, used in every message.
    names : tuple of str
        Column names in file order; unique and non-empty.
    data : array, shape (n_samples, n_columns)
        The values [SI units], finite and within ``±MAX_MAGNITUDE``; a read-only float64 array is kept
        as is, anything else is copied.
    locate : callable, optional
        ``locate(row)`` names sample ``row`` in the file, e.g. ``"line 12"``; ``row 11`` by default.
    dropped : tuple of str
        Set by the table: where the dropout rows it left out were in the file (``locate`` of each).

    Raises
    ------
    RecordingError
        Naming the file, the column, the place and the fix: empty or repeated names, a value that is
        NaN, infinite or beyond ``±MAX_MAGNITUDE``.
    """

    source: str
    names: tuple
    data: np.ndarray
    locate: Callable[[int], str] = field(default=row_label)
    dropped: tuple = field(default=(), init=False)

    def __post_init__(self):
        names = tuple(str(name) for name in self.names)
        object.__setattr__(self, "names", names)
        data = np.asarray(self.data, dtype=float)
        if data.ndim != 2 or data.shape[1] != len(names):
            raise RecordingError(
                f"{self.source}: ColumnTable.data must have shape (n_samples, {len(names)}) for the columns "
                f"{', '.join(names)}; got {data.shape}. Give one value per column in every row."
            )
        seen = set()
        for k, name in enumerate(names):
            if not name:
                raise RecordingError(f"{self.source}: column {k + 1} has no name. Name it (t, q1, ...) or remove it.")
            if name in seen:
                raise RecordingError(f"{self.source}: column {name} appears twice in the header. Rename or remove one.")
            seen.add(name)
        if data.flags.writeable:  # the caller's array stays theirs; a reader hands over a read-only one
            data = data.copy()
            data.setflags(write=False)
        object.__setattr__(self, "data", data)
        if data.shape[0]:
            self._drop_dropouts(names, data)
            if "t" in names:
                self._drop_repeated_stamps(names.index("t"))
            data = self.data
            # one pass each over the whole array; min and max are NaN where a NaN is, which fails both tests
            good = (data.min(axis=0) >= -MAX_MAGNITUDE) & (data.max(axis=0) <= MAX_MAGNITUDE)
            good |= np.isnan(data).all(axis=0)  # a column never logged (NaN throughout): the Recording judges it
            for k in np.flatnonzero(~good):
                column = data[:, k]
                if is_temperature_column(names[k]):  # readings between NaN: only what is neither is refused
                    column = np.where(np.isnan(column), 0.0, column)
                    if np.all(np.abs(column) <= MAX_MAGNITUDE):
                        continue
                self._refuse_values(names[k], column)

    def _drop_dropouts(self, names: tuple, data: np.ndarray) -> None:
        """Leave out the rows in which a signal's logged columns are NaN together, when they are at most
        MAX_DROPOUT_FRACTION of the rows (a logger's dropouts); a NaN of one column alone, or more rows, is refused."""
        nan = np.isnan(data)
        logged = ~nan.all(axis=0)  # a column NaN throughout was never logged: the Recording judges it
        logged &= [not is_temperature_column(name) for name in names]  # NaN between a slow logger's readings
        if not nan[:, logged].any():
            return
        groups: dict = {}
        for k in np.flatnonzero(logged):  # q1..q6 -> q: the columns of one signal
            groups.setdefault(re.sub(r"[0-9]+$", "", names[k]), []).append(k)
        partial = np.zeros(data.shape[0], dtype=bool)
        for columns in groups.values():
            partial |= nan[:, columns].any(axis=1) & ~nan[:, columns].all(axis=1)
        rows = np.flatnonzero(nan[:, logged].any(axis=1))
        if rows.size > MAX_DROPOUT_FRACTION * data.shape[0] or partial.any():
            first = int(np.flatnonzero(partial)[0]) if partial.any() else int(rows[0])
            column = names[int(np.flatnonzero(nan[first] & logged)[0])]
            raise RecordingError(
                f"{self.source}: column {column} holds nan at {self.locate(first)}; {rows.size} of {data.shape[0]} "
                "rows hold NaN. Rows whose signal is NaN on every joint (a logger's dropouts) are left out by "
                f"themselves, up to {MAX_DROPOUT_FRACTION:.0%} of the rows. Remove or interpolate the non-finite "
                "samples, or leave the column unread (--columns names only the signals to read)."
            )
        keep = np.flatnonzero(~nan[:, logged].any(axis=1))
        where = tuple(self.locate(int(r)) for r in rows)
        locate = self.locate
        kept = data[keep]
        kept.setflags(write=False)
        object.__setattr__(self, "data", kept)
        object.__setattr__(self, "locate", lambda row: locate(int(keep[row])))
        object.__setattr__(self, "dropped", where)
        shown = ", ".join(where[:5]) + (f" and {len(where) - 5} more" if len(where) > 5 else "")
        logger.warning(
            "%s: %d of %d rows hold NaN on every joint (a logger's dropouts: %s); they are left out (the time steps "
            "may be uneven)", self.source, rows.size, data.shape[0], shown,
        )  # fmt: skip

    def _drop_repeated_stamps(self, column: int) -> None:
        """Leave out a row whose time stamp repeats the row before it (a logger's clock of coarse resolution under
        jitter), when they are at most MAX_DROPOUT_FRACTION of the rows; more, or a stamp that goes back, are left
        to ``io.time_column`` to refuse."""
        t = self.data[:, column]
        repeated = np.flatnonzero(t[1:] == t[:-1]) + 1
        if repeated.size == 0 or repeated.size > MAX_DROPOUT_FRACTION * t.size:
            return
        keep = np.setdiff1d(np.arange(t.size), repeated)
        where = tuple(self.locate(int(r)) for r in repeated)
        locate = self.locate
        kept = self.data[keep]
        kept.setflags(write=False)
        object.__setattr__(self, "data", kept)
        object.__setattr__(self, "locate", lambda row: locate(int(keep[row])))
        object.__setattr__(self, "dropped", self.dropped + where)
        shown = ", ".join(where[:5]) + (f" and {len(where) - 5} more" if len(where) > 5 else "")
        logger.warning("%s: %d of %d rows repeat the time stamp before them (%s); they are left out",
                       self.source, repeated.size, t.size, shown)  # fmt: skip

    def _refuse_values(self, name: str, values: np.ndarray) -> None:
        """Refuse the first NaN, infinite or implausibly large value of a column, naming where it is."""
        row = int(np.argmax(~(np.abs(values) <= MAX_MAGNITUDE)))
        value = float(values[row])
        where = self.locate(row)
        if not np.isfinite(value):
            raise RecordingError(
                f"{self.source}: column {name} holds {value!r} at {where}. Remove or interpolate non-finite samples."
            )
        raise RecordingError(
            f"{self.source}: column {name} holds {value!r} at {where}; values beyond ±{MAX_MAGNITUDE:g} are not "
            "joint signals in SI units and overflow when differentiated. Check the units "
            "(t [s], q [rad or m], tau [N m], i [A]) and the export."
        )

    @property
    def n_samples(self) -> int:
        return int(self.data.shape[0])

    def column(self, name: str) -> np.ndarray:
        """The values of column ``name``, shape (n_samples,) (a read-only view)."""
        return self.data[:, self.names.index(name)]
