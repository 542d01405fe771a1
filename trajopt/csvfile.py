"""Trajectory CSV files: columns t, q1..qn, qd1..qdn, qdd1..qddn, written atomically (never over a user's file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from psdm_casadi.errors import ShapeError
from psdm_casadi.fileio import atomic_write


def trajectory_header(n_dof: int) -> list:
    """Column names ``t, q1..qn, qd1..qdn, qdd1..qddn``."""
    joints = range(1, n_dof + 1)
    return ["t"] + [f"q{i}" for i in joints] + [f"qd{i}" for i in joints] + [f"qdd{i}" for i in joints]


def write_trajectory_csv(path, t, q, qd, qdd, *, comment: str = "", overwrite: bool = False) -> Path:
    """Write a sampled trajectory to CSV through a temporary file in the same directory and ``os.replace``.

    Parameters
    ----------
    path : str or Path
    t : array, shape (n_samples,)
        Times [s].
    q, qd, qdd : arrays, shape (n_samples, n_dof)
    comment : str
        One line written first, prefixed by ``#``.
    overwrite : bool
        Replace an existing file; default False.

    Returns
    -------
    Path

    Raises
    ------
    FileExistsError
        When ``path`` exists and ``overwrite`` is False.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True (or --overwrite) to replace it.")
    t = np.asarray(t, dtype=float).reshape(-1)
    q, qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    if not (q.shape == qd.shape == qdd.shape and q.shape[0] == t.shape[0]):
        raise ShapeError(
            f"q, qd, qdd must all have shape (n_samples={t.shape[0]}, n_dof); got {q.shape}, {qd.shape}, {qdd.shape}."
        )

    def write(handle):
        if comment:
            handle.write(f"# {comment}\n")
        np.savetxt(
            handle,
            np.column_stack([t, q, qd, qdd]),
            delimiter=",",
            header=",".join(trajectory_header(q.shape[1])),
            comments="",
            fmt="%.10g",
        )

    atomic_write(path, write, overwrite=overwrite)
    return path
