"""Bounded-memory least squares of the daily update: per-joint QR factors of the rows, streamed in chunks.

A robot-day's rows (one per sample and joint) arrive in chunks of samples. Each joint ``j`` keeps only the
triangular factor ``R_j`` of its augmented rows ``A_j`` (every column the update may combine: the measured signal,
the refitted columns, the held torque), so that ``||A_j c|| = ||R_j c||`` for every coefficient vector ``c``
(``A_j = Q_j R_j`` with ``Q_j`` orthonormal). Any least-squares problem over linear combinations of these columns,
with one weight per joint, is then solved from the small factors as from the whole matrix (to rounding: it is
a QR, not normal equations, so the conditioning is not squared). For the lag-one correlation of a residual (the
weights of the update) it also keeps the factor of the neighbour sums ``a_t + a_{t-1}``, the sum of the rows and
the first and last row: ``sum r_t r_{t-1} = (sum (r_t + r_{t-1})^2 - sum_{t>0} r_t^2 - sum_{t<n-1} r_t^2) / 2``.

Memory is ``O(n_dof width^2)`` plus one chunk, whatever the recording's length.
"""

from __future__ import annotations

import numpy as np

__all__ = ["StreamedRows"]


def _factor(previous: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The R factor of ``previous`` stacked on ``rows``."""
    return np.linalg.qr(np.vstack([previous, rows]), mode="r")


class StreamedRows:
    """Per-joint QR factors of augmented rows added in chunks (module docstring)."""

    def __init__(self, n_dof: int, width: int):
        self.n_dof, self.width = n_dof, width
        self.factors = [np.zeros((0, width)) for _ in range(n_dof)]
        self.pair_factors = [np.zeros((0, width)) for _ in range(n_dof)]
        self.total = np.zeros((n_dof, width))
        self.count = 0
        self.first = self.last = None

    def add(self, rows: np.ndarray) -> None:
        """Add the next samples' rows, ``rows`` of shape (n_samples, n_dof, width), in their time order."""
        if rows.shape[0] == 0:
            return
        pairs = rows[1:] + rows[:-1]
        if self.last is None:
            self.first = rows[0].copy()
        else:
            pairs = np.concatenate([(rows[0] + self.last)[None], pairs])
        for j in range(self.n_dof):
            self.factors[j] = _factor(self.factors[j], rows[:, j])
            self.pair_factors[j] = _factor(self.pair_factors[j], pairs[:, j])
        self.total += rows.sum(axis=0)
        self.count += rows.shape[0]
        self.last = rows[-1].copy()

    def squares(self, coefficients: np.ndarray) -> np.ndarray:
        """Per joint ``||A_j c_j||^2`` of the residual ``A_j c_j``; ``coefficients`` (n_dof, width)."""
        return np.array([np.sum((r @ c) ** 2) for r, c in zip(self.factors, coefficients)])

    def residual_moments(self, coefficients: np.ndarray) -> tuple:
        """(mean square, lag-one correlation of the centred residual) per joint of the residuals ``A_j c_j``."""
        c = np.asarray(coefficients, dtype=float)
        n = self.count
        squares = self.squares(c)
        pairs = np.array([np.sum((r @ cj) ** 2) for r, cj in zip(self.pair_factors, c)])
        first, last, total = (np.einsum("jw,jw->j", x, c) for x in (self.first, self.last, self.total))
        lag = 0.5 * (pairs - (squares - first**2) - (squares - last**2))
        mean = total / n
        centred_lag = lag - mean * ((total - first) + (total - last)) + (n - 1) * mean**2
        centred = squares - n * mean**2
        return squares / n, centred_lag / np.maximum(centred, 1e-300)

    def system(self, embedding: list, constant: np.ndarray, weights=None) -> tuple:
        """(matrix, target) of ``min sum_j w_j ||A_j (E_j x + c0_j)||^2`` on the small factors.

        ``embedding[j]`` (width, n_x) maps the parameters ``x`` to joint ``j``'s coefficients, ``constant[j]``
        (width,) is the fixed part; ``weights`` one per joint (default 1).
        """
        w = np.ones(self.n_dof) if weights is None else np.asarray(weights, dtype=float)
        matrix = np.vstack([np.sqrt(w[j]) * (r @ embedding[j]) for j, r in enumerate(self.factors)])
        target = np.concatenate([-np.sqrt(w[j]) * (r @ constant[j]) for j, r in enumerate(self.factors)])
        return matrix, target
