"""ExperimentTrajectory: the value a calibration experiment design returns, and the check of its joint limits.

The designs of :mod:`trajopt.experiments` build knots ``(t, q)``; ``verify_experiment`` wraps them in an
``ExperimentTrajectory`` with the worst limit margin of its spline on a 1 kHz grid.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline

from psdm_casadi.errors import ExcitationWarning, ParameterError, ShapeError
from trajopt.constraints import JointLimits, check_same_dof, describe_violation, limit_margins, worst_margin
from trajopt.csvfile import write_trajectory_csv

__all__ = ["VERIFY_HZ", "ExperimentTrajectory", "verify_experiment"]

VERIFY_HZ = 1000.0  # grid of the limit check


@dataclass(frozen=True, eq=False)
class ExperimentTrajectory:
    """A calibration experiment: knots of a smooth path and the joint limits it was checked against.

    Attributes
    ----------
    name : str
        "motor", "gravity", "friction" or "sine".
    t : array, shape (n_knots,)
        Knot times [s], strictly increasing from 0.
    q : array, shape (n_knots, n_dof)
        Positions at the knots [rad or m]; ``sample`` interpolates them with a not-a-knot cubic spline.
    limits : JointLimits
    joints : tuple of int
        0-based joints the experiment moves or identifies.
    worst_margin : float
        Smallest relative margin to a limit on a 1 kHz grid; negative when the path leaves a limit.
    """

    name: str
    t: np.ndarray
    q: np.ndarray
    limits: JointLimits
    joints: tuple
    worst_margin: float = float("nan")

    def __post_init__(self):
        t = np.array(self.t, dtype=float)
        q = np.array(self.q, dtype=float)
        if t.ndim != 1 or t.size < 2 or t[0] != 0.0 or np.any(np.diff(t) <= 0):
            raise ParameterError(
                "ExperimentTrajectory.t must be strictly increasing knot times from 0 [s]; got "
                f"{t.size} values starting at {t[:1].tolist()}."
            )
        if q.shape != (t.size, self.limits.n_dof):
            raise ShapeError(
                f"ExperimentTrajectory.q must have shape (n_knots, n_dof) = ({t.size}, "
                f"{self.limits.n_dof}); got {q.shape}."
            )
        t.setflags(write=False)
        q.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "joints", tuple(int(j) for j in self.joints))

    @property
    def duration(self) -> float:
        """Length [s]."""
        return float(self.t[-1])

    @property
    def n_dof(self) -> int:
        return self.limits.n_dof

    def reference(self) -> tuple:
        """The knots ``(t, q)`` as plain arrays: what the virtual robot interpolates and tracks."""
        return self.t, self.q

    def sample(self, t) -> tuple:
        """q, qd, qdd at times ``t`` in [0, duration] [s], arrays (n_samples, n_dof), from the spline of the knots."""
        t = np.asarray(t, dtype=float).reshape(-1)
        spline = CubicSpline(self.t, self.q, axis=0)
        return spline(t), spline(t, 1), spline(t, 2)

    def time_grid(self, rate: float) -> np.ndarray:
        """Sample times ``0, 1/rate, ...`` up to the duration [s]."""
        if not (isinstance(rate, (int, float)) and rate > 0):
            raise ParameterError(f"ExperimentTrajectory rate must be a positive sampling rate [Hz]; got {rate!r}.")
        return np.arange(int(np.floor(self.duration * rate + 1e-9)) + 1) / float(rate)

    def to_csv(self, path, rate: float = 100.0, *, overwrite: bool = False):
        """Write ``t, q, qd, qdd`` sampled at ``rate`` Hz (atomic; FileExistsError unless ``overwrite``)."""
        t = self.time_grid(rate)
        comment = (
            f"{self.name} experiment, joints {[j + 1 for j in self.joints]}, worst_limit_margin={self.worst_margin:.6g}"
        )
        return write_trajectory_csv(path, t, *self.sample(t), comment=comment, overwrite=overwrite)


def verify_experiment(name, t, q, robot, joints, limits) -> ExperimentTrajectory:
    """The experiment of knots ``(t, q)`` with its worst limit margin on a ``VERIFY_HZ`` grid.

    ``limits`` defaults to the robot's (``None``); an ``ExcitationWarning`` is emitted (attributed to the
    caller of the design function) when the path leaves a limit.
    """
    limits = JointLimits.from_robot(robot) if limits is None else limits
    check_same_dof(limits, robot.n_dof)
    draft = ExperimentTrajectory(name, t, q, limits, joints)
    margins = limit_margins(limits, *draft.sample(draft.time_grid(VERIFY_HZ)))
    worst = worst_margin(margins)
    if worst < -1e-9:
        warnings.warn(
            f"the {name} experiment leaves the joint limits: {describe_violation(margins)}. Check it "
            "before running it on a robot.",
            ExcitationWarning,
            stacklevel=3,
        )
    return replace(draft, worst_margin=worst)
