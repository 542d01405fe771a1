"""Has a robot-day's validation error risen? A prediction test per joint against the robot's baseline window.

The client takes, per robot, the window of its baseline (its first ``baseline_days`` ok recording days, or those
after its newest re-identification) and per joint the mean ``m`` and standard deviation ``s`` of the window's
``log RMSE`` over its ``n`` days (:func:`error_reference`). In the robot-day's task, a joint's statistic is

    t = (log RMSE_day - m) / (s sqrt(1 + 1/n)),

which follows Student's t with ``n - 1`` degrees of freedom when the robot is as it was in the window (the
prediction-interval statistic: the window's own uncertainty is included). The error has risen when ``t`` exceeds
the ``1 - alpha / n_dof`` quantile (one-sided, Bonferroni over the joints): a healthy robot's day is flagged with
probability at most ``alpha`` (default 0.001, about one day in three years of daily checks), whatever the window's
size. ``s`` is at least ``min_scatter`` (0.02 in log: changes of a few % are not news).

Both errors of the day are tested: the baseline model's (``rmse_baseline``, did the robot change?) and the day's
refit's (``rmse_refit``, does the refit of the tracked terms explain the change?). A rise the refit explains is
``explained`` (the drift tests name it: friction, a spring, a payload, ...); a rise it does not explain is
``unexplained``, and the day's recordings go to the diagnosis (``day_diagnosis``).

A rise the refit leaves unexplained may still be friction: wear raises the static friction with the Coulomb one
(a Stribeck hump) and the daily Coulomb-viscous refit follows only part of its shape. The reference also holds
each joint's window log Coulomb friction (mean, scatter) and :func:`friction_changes` tests the day's refitted
``fc<j>`` of the unexplained joints with the same prediction statistic and critical value: a joint whose friction
moved names its drift (``joint 3 Coulomb friction +38 % against the window from 2026-10-01, 9 sigma: gearbox
wear or lubrication``), and a day whose every unexplained joint does is ``friction_drift``, not diagnosed further.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from identification.fleet.phrases import MEANINGS
from psdm_casadi.errors import ParameterError

__all__ = ["CheckOptions", "DayCheck", "ErrorReference", "FrictionChange", "check_day", "error_reference",
           "friction_changes"]  # fmt: skip

MIN_WINDOW = 3  # days: fewer give no reference (no check, no diagnosis)


@dataclass(frozen=True)
class CheckOptions:
    """The false-alarm rate ``alpha`` of a healthy robot-day, the scatter floor (log) and whether an unexplained
    rise runs the diagnosis."""

    alpha: float = 1e-3
    min_scatter: float = 0.02
    diagnose: bool = True

    def __post_init__(self):
        if not 0.0 < self.alpha < 0.5:
            raise ParameterError(f"CheckOptions.alpha must be in (0, 0.5); got {self.alpha!r}. Use 0.001.")
        if not self.min_scatter >= 0.0:
            raise ParameterError(f"CheckOptions.min_scatter must be >= 0; got {self.min_scatter!r}. Use 0.02.")


@dataclass(frozen=True)
class ErrorReference:
    """Per joint the window's log-RMSE mean and scatter, of the baseline model and of the refit, over ``n`` days
    from ``since`` (the window's first day), and of its log Coulomb friction (NaN for a joint without a positive
    one; None: not known)."""

    robot_id: str
    since: str
    n: int
    mean_baseline: np.ndarray
    scatter_baseline: np.ndarray
    mean_refit: np.ndarray
    scatter_refit: np.ndarray
    options: CheckOptions = CheckOptions()
    friction_mean: np.ndarray | None = None
    friction_scatter: np.ndarray | None = None

    @property
    def threshold(self) -> float:
        """The statistic's critical value (module docstring)."""
        return float(stats.t.isf(self.options.alpha / self.mean_baseline.size, self.n - 1))


@dataclass(frozen=True)
class DayCheck:
    """The check of one robot-day: ``verdict`` is ``quiet``, ``explained`` or ``unexplained``; ``joints`` the
    risen joints (1-based) and the largest statistics of the baseline's and of the refit's error."""

    verdict: str
    joints: tuple
    statistic: float
    refit_statistic: float
    threshold: float
    since: str


def error_reference(robot_id: str, rows, options: CheckOptions | None = None, friction=()) -> ErrorReference | None:
    """The reference of a robot's window from its ``(day, joint, rmse_baseline, rmse_refit)`` rows and its
    ``(day, joint, fc)`` ``friction`` rows; None for fewer than ``MIN_WINDOW`` days."""
    options = options or CheckOptions()
    days = sorted({str(r[0]) for r in rows})
    if len(days) < MIN_WINDOW:
        return None
    joints = sorted({int(r[1]) for r in rows})
    table = np.full((len(days), len(joints), 2), np.nan)
    for day, joint, base, refit in rows:
        table[days.index(str(day)), joints.index(int(joint))] = (base, refit)
    logs = np.log(np.maximum(table, 1e-300))
    mean, scatter = logs.mean(axis=0), np.maximum(logs.std(axis=0, ddof=1), options.min_scatter)
    fc_mean = fc_scatter = None
    if friction:
        fc = np.full((len(days), len(joints)), np.nan)
        for day, joint, value in friction:
            if str(day) in days and int(joint) in joints and value > 0:
                fc[days.index(str(day)), joints.index(int(joint))] = np.log(value)
        whole = np.all(np.isfinite(fc), axis=0)  # a joint with a missing or non-positive day is not tested
        fc_mean = np.where(whole, np.mean(fc, axis=0), np.nan)
        fc_scatter = np.where(whole, np.maximum(np.std(fc, axis=0, ddof=1), options.min_scatter), np.nan)
    return ErrorReference(robot_id, days[0], len(days), mean[:, 0], scatter[:, 0], mean[:, 1], scatter[:, 1],
                          options, fc_mean, fc_scatter)  # fmt: skip


def _statistic(rmse, mean, scatter, n) -> np.ndarray:
    return (np.log(np.maximum(np.asarray(rmse, dtype=float), 1e-300)) - mean) / (scatter * np.sqrt(1.0 + 1.0 / n))


def check_day(reference: ErrorReference, rmse_baseline, rmse_refit) -> DayCheck:
    """The verdict of a day's errors against the reference (module docstring)."""
    r = reference
    base = _statistic(rmse_baseline, r.mean_baseline, r.scatter_baseline, r.n)
    refit = _statistic(rmse_refit, r.mean_refit, r.scatter_refit, r.n)
    threshold = r.threshold
    risen = np.flatnonzero(base > threshold)
    unexplained = risen[refit[risen] > threshold]
    verdict = "quiet" if risen.size == 0 else ("unexplained" if unexplained.size else "explained")
    joints = tuple(int(j) + 1 for j in (unexplained if unexplained.size else risen))
    refit_max = float(np.max(refit[risen])) if risen.size else float(np.max(refit))
    return DayCheck(verdict, joints, float(np.max(base)), refit_max, threshold, r.since)


@dataclass(frozen=True)
class FrictionChange:
    """A joint (1-based) whose refitted Coulomb friction left its window's: the relative change [%] and the
    prediction statistic (``z``, in sigma of the window's day-to-day scatter)."""

    joint: int
    relative_percent: float
    z: float
    since: str

    @property
    def text(self) -> str:
        m = MEANINGS["fc"]
        cause = m.rise if self.relative_percent > 0 else m.fall
        return (f"joint {self.joint} {m.label} {self.relative_percent:+.0f} % against the window from {self.since} "
                f"({abs(self.z):.0f} sigma): {cause}; the daily Coulomb-viscous refit does not follow its whole "
                "shape (a static-friction hump)")  # fmt: skip


def friction_changes(reference: ErrorReference, names, values, joints) -> tuple:
    """The :class:`FrictionChange` of ``joints`` (1-based) whose refitted ``fc<j>`` (among ``names``, ``values``)
    leaves the window's (module docstring); empty without the window's friction."""
    r = reference
    if r.friction_mean is None:
        return ()
    fitted = dict(zip(names, values))
    out = []
    for joint in joints:
        value = fitted.get(f"fc{joint}")
        mean, scatter = r.friction_mean[joint - 1], r.friction_scatter[joint - 1]
        if value is None or not value > 0 or not np.isfinite(mean):
            continue
        z = float(_statistic(value, mean, scatter, r.n))
        if abs(z) > r.threshold:
            out.append(FrictionChange(joint, 100.0 * float(np.expm1(np.log(value) - mean)), z, r.since))
    return tuple(out)
