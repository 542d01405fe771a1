"""ExcitationOptions and ExcitationTrajectory: what ``optimize_excitation`` is asked for and what it returns.

``ExcitationOptions`` names the trajectory family, the criterion, the limits and the multi-start budget,
and builds the parametrisation and the limits they describe; ``ExcitationTrajectory`` is the verified
optimum, which samples and writes itself (``sample``, ``to_csv``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from psdm_casadi.errors import ParameterError
from trajopt.constraints import JointLimits
from trajopt.criteria import CRITERIA
from trajopt.csvfile import write_trajectory_csv
from trajopt.parametrization import FourierTrajectory, SumOfSinesTrajectory

__all__ = ["FAMILIES", "ExcitationOptions", "ExcitationTrajectory"]

FAMILIES = ("fourier", "sum_of_sines")


@dataclass(frozen=True)
class ExcitationOptions:
    """Options of ``optimize_excitation``.

    Parameters
    ----------
    family : {"fourier", "sum_of_sines"}
        Trajectory family: finite Fourier series (periodic) or the paper's sum of sines (eq. 22).
    duration : float
        Period of the Fourier series, or length of the sum of sines [s].
    harmonics : int
        Harmonics of the Fourier series.
    n_terms : int
        Sines per joint of the sum of sines (3 in the paper).
    frequency_min, frequency_max : float
        Frequency bounds of the sum of sines [rad/s]; ``frequency_max`` defaults to the highest
        Fourier harmonic ``2 pi harmonics / duration``.
    rest_to_rest : bool
        Start and end at rest (zero velocity and acceleration).
    columns : tuple of int or bool mask, optional
        Regressor columns to excite (None: all). The paper excites the inertial ones,
        ``~model.gravity_mask``.
    criterion : {"cond", "logdet"}
        Smooth condition-number surrogate or D-optimal information (see ``criteria``).
    column_scaling : bool
        Scale the selected columns to unit RMS (on the first start) inside the objective. The
        reported ``cond`` is always that of the raw columns; ``cond_scaled`` that of the scaled ones.
    n_samples : int
        Objective grid size.
    n_constraint_samples : int, optional
        Constraint grid size (default: 12 samples per period of the fastest component, >= 50).
    limit_backoff : float
        Fraction by which limits are tightened on the constraint grid.
    limit_scale : float
        Fraction of the robot's limits to use, in (0, 1].
    torque_limits : bool
        Constrain ``|tau| <= tau_max`` with the nominal model (needs ``nominal_parameters``).
    limits : JointLimits, optional
        Limits to use instead of the robot's.
    n_starts : int
        Random starts.
    max_iter : int
        Ipopt iterations per solve.
    sharpness : tuple of float
        Continuation of the ``cond`` surrogate's power-mean order.
    start_fill : float
        Fraction of the limits used by the random starts.
    time_limit : float, optional
        Wall-time budget [s]: no new start or stage begins after it, and a running Ipopt solve stops
        at it (its iterate is verified and kept like any other).
    ipopt_options : dict, optional
        Raw Ipopt options passed through unchanged.
    quiet : bool
        Log no progress lines (they go to the ``trajopt.optimize`` logger at INFO; the ``psdm`` command
        shows them on stderr).
    """

    family: str = "fourier"
    duration: float = 10.0
    harmonics: int = 5
    n_terms: int = 3
    frequency_min: float = 0.1
    frequency_max: float | None = None
    rest_to_rest: bool = False
    columns: tuple | None = None
    criterion: str = "cond"
    column_scaling: bool = False
    n_samples: int = 100
    n_constraint_samples: int | None = None
    limit_backoff: float = 0.02
    limit_scale: float = 1.0
    torque_limits: bool = False
    limits: JointLimits | None = None
    n_starts: int = 3
    max_iter: int = 300
    sharpness: tuple = (8.0, 32.0)
    start_fill: float = 0.7
    time_limit: float | None = None
    ipopt_options: dict | None = field(default=None, hash=False)
    quiet: bool = False

    def __post_init__(self):
        owner = "ExcitationOptions"
        if self.family not in FAMILIES:
            raise ParameterError(f"{owner}.family must be one of {FAMILIES}; got {self.family!r}.")
        if self.criterion not in CRITERIA:
            raise ParameterError(f"{owner}.criterion must be one of {CRITERIA}; got {self.criterion!r}.")
        for key in ("harmonics", "n_terms", "n_samples", "n_starts", "max_iter"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ParameterError(f"{owner}.{key} must be an integer >= 1; got {value!r}.")
        if not (isinstance(self.duration, (int, float)) and math.isfinite(self.duration) and self.duration > 0):
            raise ParameterError(f"{owner}.duration must be a positive number of seconds; got {self.duration!r}.")
        if not (0 < self.start_fill <= 1):
            raise ParameterError(f"{owner}.start_fill must be in (0, 1]; got {self.start_fill!r}. Use e.g. 0.7.")
        if not self.sharpness or any(not (isinstance(p, (int, float)) and p > 0) for p in self.sharpness):
            raise ParameterError(f"{owner}.sharpness must be positive numbers; got {self.sharpness!r}. Use (8, 32).")
        if not (isinstance(self.limit_scale, (int, float)) and 0 < self.limit_scale <= 1):
            raise ParameterError(f"{owner}.limit_scale must be in (0, 1]; got {self.limit_scale!r}. Use e.g. 0.9.")
        if self.time_limit is not None and not self.time_limit > 0:
            raise ParameterError(f"{owner}.time_limit must be positive seconds or None; got {self.time_limit!r}.")

    def build_parametrization(self, n_dof: int):
        """The trajectory family these options describe, for ``n_dof`` joints."""
        if self.family == "fourier":
            return FourierTrajectory(
                n_dof=n_dof, n_harmonics=self.harmonics, period=float(self.duration), rest_to_rest=self.rest_to_rest
            )
        fmax = self.frequency_max if self.frequency_max is not None else 2 * math.pi * self.harmonics / self.duration
        return SumOfSinesTrajectory(
            n_dof=n_dof,
            n_terms=self.n_terms,
            duration=float(self.duration),
            frequency_min=self.frequency_min,
            frequency_max=fmax,
            rest_to_rest=self.rest_to_rest,
        )

    def build_limits(self, robot) -> JointLimits:
        """The limits to impose: ``limits`` if given, else the robot's scaled by ``limit_scale``."""
        if self.limits is not None:
            limits = self.limits
            if self.torque_limits and limits.tau_max is None:
                limits = JointLimits(limits.q_min, limits.q_max, limits.qd_max, limits.qdd_max, robot.tau_max)
            return limits
        return JointLimits.from_robot(robot, torque=self.torque_limits, scale=self.limit_scale)


@dataclass(frozen=True)
class ExcitationTrajectory:
    """An optimised excitation trajectory whose limits were verified on a 10x finer grid.

    Attributes
    ----------
    parametrization : FourierTrajectory or SumOfSinesTrajectory
    parameters : array, shape (n_parameters,)
    cond : float
        True condition number of the stacked regressor on the raw selected columns, over the
        objective grid (the paper's figure).
    cond_scaled : float or None
        The same on the scaled columns when ``column_scaling`` was used.
    worst_margin : float
        Smallest relative margin to any limit on the fine grid (>= 0).
    worst_limit : str
        Which limit and joint that margin belongs to.
    seconds : float
        Wall time of the optimisation.
    columns : tuple of int
    limits : JointLimits
    status : str
        Ipopt status of the winning start.
    start_conds : tuple of float
        True condition number reached by every start (inf for failed starts).
    """

    parametrization: object
    parameters: np.ndarray
    cond: float
    worst_margin: float
    seconds: float
    columns: tuple
    limits: JointLimits
    worst_limit: str = ""
    cond_scaled: float | None = None
    status: str = ""
    start_conds: tuple = ()

    def __post_init__(self):
        params = np.array(self.parameters, dtype=float).reshape(-1)
        params.setflags(write=False)
        object.__setattr__(self, "parameters", params)

    @property
    def duration(self) -> float:
        return float(self.parametrization.duration)

    @property
    def n_dof(self) -> int:
        return self.parametrization.n_dof

    def sample(self, t) -> tuple:
        """q, qd, qdd at times ``t`` [s], arrays (n_samples, n_dof)."""
        return self.parametrization.evaluate(t, self.parameters)

    def time_grid(self, rate: float, periods: int = 1) -> np.ndarray:
        """Times at ``rate`` Hz over ``periods`` periods (end excluded for periodic families)."""
        if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
            raise ParameterError(f"ExcitationTrajectory rate must be a positive sampling rate [Hz]; got {rate!r}.")
        if isinstance(periods, bool) or not isinstance(periods, int) or periods < 1:
            raise ParameterError(f"ExcitationTrajectory periods must be an integer >= 1; got {periods!r}.")
        if periods > 1 and not self.parametrization.periodic:
            raise ParameterError(
                "ExcitationTrajectory periods must be 1 for a non-periodic family (sum of sines); "
                f"got {periods}. Use family='fourier' to repeat periods."
            )
        total = self.duration * periods
        n = int(math.floor(total * rate + 1e-9))
        if not self.parametrization.periodic:
            n += 1
        return np.arange(n) / float(rate)

    def to_csv(self, path, rate: float = 100.0, *, periods: int = 1, overwrite: bool = False) -> Path:
        """Write columns ``t, q1..qn, qd1..qdn, qdd1..qddn`` sampled at ``rate`` Hz, atomically.

        Raises
        ------
        FileExistsError
            When ``path`` exists and ``overwrite`` is False.
        """
        t = self.time_grid(rate, periods)
        comment = f"excitation: cond={self.cond:.6g} worst_limit_margin={self.worst_margin:.6g}"
        return write_trajectory_csv(path, t, *self.sample(t), comment=comment, overwrite=overwrite)
