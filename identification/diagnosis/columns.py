"""BlockColumns: the columns of the diagnosis's least squares stored per joint, without their zeros, used in chunks.

The fit's columns are laid out (n_samples, n_dof, n_columns): column ``c`` on the rows of joint ``j``. Most act
on one joint only (each joint's friction, most candidate terms), so that layout is mostly zeros: on a
60-minute recording (240 000 rows on its grid) the 24 friction columns of a 6-joint robot take 276 MB dense
and 46 MB per joint. ``BlockColumns`` keeps, for each joint, the columns that are non-zero on its rows;
``dense(rows)`` rebuilds any range of rows, so the least squares (``selection``) works through a long
recording in chunks of ``CHUNK_ROWS`` rows, with the memory of a chunk. A grid of up to ``CHUNK_ROWS`` rows
(250 s at the default 200 Hz) is one chunk, and every product is then the one of the whole dense array.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psdm_casadi.errors import ShapeError

CHUNK_ROWS = 50_000  # rows of the grid per chunk of the least squares (250 s at the default 200 Hz grid)


def row_chunks(n_rows: int, chunk: int | None = None) -> list:
    """Slices covering ``range(n_rows)`` in order, each of at most ``chunk`` rows (default ``CHUNK_ROWS``; one
    slice when they fit)."""
    chunk = CHUNK_ROWS if chunk is None else int(chunk)
    return [slice(start, min(start + chunk, n_rows)) for start in range(0, max(n_rows, 1), chunk)]


@dataclass(frozen=True, eq=False)
class BlockColumns:
    """Columns (n_samples, n_dof, n_columns) held as, per joint, the columns non-zero on its rows.

    Parameters
    ----------
    n_columns : int
    index : tuple of int arrays, one per joint
        The columns (0-based) that are non-zero on the joint's rows, increasing.
    values : tuple of arrays (n_samples, len(index[j])), one per joint
        Their values on the joint's rows.

    Raises
    ------
    ShapeError
        When the blocks do not match each other or ``n_columns``.
    """

    n_columns: int
    index: tuple
    values: tuple

    def __post_init__(self):
        index = tuple(np.asarray(i, dtype=int).reshape(-1) for i in self.index)
        values = tuple(np.asarray(v, dtype=float) for v in self.values)
        rows = {v.shape[0] for v in values}
        if len(index) != len(values) or not values or len(rows) != 1:
            raise ShapeError(
                f"BlockColumns.values must hold one (n_samples, k) block per joint, all with the same rows; got "
                f"{[v.shape for v in values]} for {len(index)} index arrays."
            )
        for j, (i, v) in enumerate(zip(index, values)):
            if v.ndim != 2 or v.shape[1] != i.size or (i.size and (i.min() < 0 or i.max() >= self.n_columns)):
                raise ShapeError(
                    f"BlockColumns.values[{j}] must have shape (n_samples, {i.size}) with columns in "
                    f"0..{self.n_columns - 1}; got {v.shape} for columns {i.tolist()}."
                )
        object.__setattr__(self, "index", index)
        object.__setattr__(self, "values", values)

    @classmethod
    def from_dense(cls, columns) -> BlockColumns:
        """The blocks of dense ``columns`` (n_samples, n_dof, n_columns); all-zero columns of a joint are dropped."""
        columns = np.asarray(columns, dtype=float)
        if columns.ndim != 3:
            raise ShapeError(f"BlockColumns.from_dense columns must be (n_samples, n_dof, k); got {columns.shape}.")
        index, values = [], []
        for j in range(columns.shape[1]):
            nonzero = np.flatnonzero(np.any(columns[:, j, :] != 0, axis=0))
            index.append(nonzero)
            values.append(columns[:, j, nonzero])
        return cls(columns.shape[2], tuple(index), tuple(values))

    @property
    def n_samples(self) -> int:
        return int(self.values[0].shape[0])

    @property
    def n_dof(self) -> int:
        return len(self.values)

    @property
    def shape(self) -> tuple:
        """The dense shape (n_samples, n_dof, n_columns)."""
        return (self.n_samples, self.n_dof, self.n_columns)

    def dense(self, rows: slice = slice(None)) -> np.ndarray:
        """The dense columns of ``rows``, (n_rows, n_dof, n_columns)."""
        n_rows = len(range(*rows.indices(self.n_samples)))
        out = np.zeros((n_rows, self.n_dof, self.n_columns))
        for j, (index, values) in enumerate(zip(self.index, self.values)):
            out[:, j, index] = values[rows]
        return out

    def joint(self, j: int, rows: slice = slice(None), scale: float = 1.0) -> np.ndarray:
        """Dense rows of joint ``j`` divided by ``scale``, (n_rows, n_columns) (zeros where the joint has none)."""
        values = self.values[j][rows]
        out = np.zeros((values.shape[0], self.n_columns))
        out[:, self.index[j]] = values / scale
        return out

    def take(self, rows) -> BlockColumns:
        """The columns of the rows ``rows`` (an index array), in that order (a held-out block of the training data,
        ``second_opinion``)."""
        return BlockColumns(self.n_columns, self.index, tuple(v[rows] for v in self.values))

    def concatenate(self, other: BlockColumns) -> BlockColumns:
        """The columns of ``self`` followed by those of ``other`` (same rows and joints)."""
        if other.n_dof != self.n_dof or other.n_samples != self.n_samples:
            raise ShapeError(
                f"BlockColumns.concatenate needs the same rows and joints; got {other.shape} after {self.shape}."
            )
        return BlockColumns(
            self.n_columns + other.n_columns,
            tuple(np.concatenate([a, b + self.n_columns]) for a, b in zip(self.index, other.index)),
            tuple(np.hstack([a, b]) for a, b in zip(self.values, other.values)),
        )

    def predict(self, beta) -> np.ndarray:
        """``columns @ beta`` (n_samples, n_dof), evaluated chunk by chunk of rows."""
        beta = np.asarray(beta, dtype=float)
        out = np.empty((self.n_samples, self.n_dof))
        for rows in row_chunks(self.n_samples):
            out[rows] = self.dense(rows) @ beta
        return out

    def weighted_r(self, joint_scale) -> np.ndarray:
        """R (n_columns, n_columns) of the QR decomposition of the stacked rows, joint ``j``'s divided by
        ``joint_scale[j]``: ``R^T R`` is their Gram matrix, and R has their singular values and column norms
        (accumulated chunk by chunk, never squaring the condition number)."""
        r = np.zeros((0, self.n_columns))
        for rows in row_chunks(self.n_samples):
            block = self.dense(rows) / np.asarray(joint_scale, dtype=float)[None, :, None]
            r = np.linalg.qr(np.vstack([r, block.reshape(-1, self.n_columns)]), mode="r")
        return r


def as_blocks(columns) -> BlockColumns:
    """``columns`` as BlockColumns (dense (n_samples, n_dof, k) arrays are converted)."""
    return columns if isinstance(columns, BlockColumns) else BlockColumns.from_dense(columns)


def as_dense(columns) -> np.ndarray:
    """``columns`` as a dense (n_samples, n_dof, k) array."""
    return columns.dense() if isinstance(columns, BlockColumns) else np.asarray(columns, dtype=float)
