"""Plot of a trajectory (excitation or experiment): q, qd, qdd per joint with the limits drawn, saved as PNG."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def plot_trajectory(
    trajectory, path, *, rate: float = 100.0, title: str | None = None, overwrite: bool = False
) -> Path:
    """Save a PNG with one row per joint and columns q, qd, qdd; limits as dashed red lines.

    Parameters
    ----------
    trajectory : ExcitationTrajectory or ExperimentTrajectory
        Anything with ``time_grid(rate)``, ``sample(t)`` and ``limits`` (JointLimits).
    path : str or Path
        Output PNG.
    rate : float
        Sampling rate of the drawn curves [Hz].
    title : str, optional
        Figure title; default names the condition number when the trajectory has one.
    overwrite : bool
        Replace an existing file (default False -> FileExistsError).

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True (or --overwrite) to replace it.")
    t = trajectory.time_grid(rate)
    q, qd, qdd = trajectory.sample(t)
    limits = trajectory.limits
    n = q.shape[1]
    fig, axes = plt.subplots(n, 3, figsize=(11, 1.7 * n + 0.8), sharex=True, squeeze=False)
    bounds = [(limits.q_min, limits.q_max), (-limits.qd_max, limits.qd_max), (-limits.qdd_max, limits.qdd_max)]
    for col, (data, label, (low, high)) in enumerate(zip((q, qd, qdd), ("q", "qd", "qdd"), bounds)):
        for i in range(n):
            ax = axes[i, col]
            ax.plot(t, data[:, i], lw=0.9)
            ax.axhline(low[i], color="tab:red", ls="--", lw=0.8)
            ax.axhline(high[i], color="tab:red", ls="--", lw=0.8)
            if i == 0:
                ax.set_title(label)
            if col == 0:
                ax.set_ylabel(f"joint {i + 1}")
            ax.grid(alpha=0.3)
        axes[-1, col].set_xlabel("t [s]")
    if title is None:
        cond = getattr(trajectory, "cond", None)
        margin = getattr(trajectory, "worst_margin", np.nan)
        title = (
            f"cond = {cond:.4g}, worst limit margin = {margin:.3g}"
            if cond is not None
            else f"{getattr(trajectory, 'name', 'trajectory')} experiment, worst limit margin = {margin:.3g}"
        )
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=90)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
