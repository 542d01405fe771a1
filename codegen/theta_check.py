"""check_theta(): is a bare theta (``psdm codegen --theta``) physically plausible before it is baked into C?

A file of base parameters carries no standard parameters, so the pseudo-inertia test of a calibrated model
cannot be run on it. What can be checked is the symptom that matters for simulation and control: the mass
matrix ``D(q)`` of theta must be positive definite. :func:`check_theta` samples
``identification.calibration.recalibrate.MASS_CHECK_CONFIGURATIONS`` configurations in the joint ranges
(``consistency.check_consistency``) and, where ``D(q)`` is not positive definite, names the base parameters
to blame: ``D(q)`` is linear in theta, so the smallest eigenvalue ``v^T D(q) v`` at the worst configuration is
the sum of ``theta_k v^T D_k(q) v`` over the base parameters, and the most negative of these terms are named.

A positive-definite mass matrix is necessary, not sufficient: a theta that passes may still have no
physically consistent preimage (a wrong gravity term, say). The check refuses what is certainly wrong.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.consistency import ConsistencyReport, check_consistency, mass_matrices
from identification.calibration.recalibrate import MASS_CHECK_CONFIGURATIONS
from psdm_casadi.errors import ShapeError

__all__ = ["FREE_PRISMATIC_RANGE", "ThetaCheck", "check_theta"]

#: Range [m] sampled for a prismatic joint when no robot file gives its limits (revolute joints: one turn).
FREE_PRISMATIC_RANGE = 0.5


@dataclass(frozen=True, eq=False)
class ThetaCheck:
    """Result of :func:`check_theta`.

    Attributes
    ----------
    report : ConsistencyReport
        The mass-matrix check (``consistency.check_consistency``): smallest eigenvalue, its configuration, the
        configurations sampled and those that failed.
    blamed : tuple of (str, float, float)
        ``(name, value, contribution)`` of the base parameters that pull the smallest eigenvalue down most
        (contribution < 0, most negative first) [kg m^2].
    ranges : str
        Where the configurations were sampled.
    """

    report: ConsistencyReport
    blamed: tuple
    ranges: str

    @property
    def consistent(self) -> bool:
        """True when D(q) was positive definite at every sample."""
        return self.report.consistent

    def problem(self, source: str) -> str | None:
        """None when consistent, else one sentence naming the eigenvalue and the parameters to blame."""
        if self.consistent:
            return None
        report = self.report
        blamed = ", ".join(f"{name} = {value:.6g} (adds {share:.3g})" for name, value, share in self.blamed)
        return (
            f"the base parameters of {source} are not physically consistent: the mass matrix is not positive "
            f"definite at {report.n_violations} of {report.n_samples} configurations ({self.ranges}); smallest "
            f"eigenvalue {report.min_eigenvalue:.4g} kg m^2 at q = [{', '.join(f'{v:.3f}' for v in report.worst_q)}];"
            f" the base parameters that pull it down most: {blamed or 'none alone'}"
        )


def check_theta(model, theta, robot=None, *, n_samples: int = MASS_CHECK_CONFIGURATIONS, rng=None) -> ThetaCheck:
    """Check that the mass matrix of base parameters ``theta`` is positive definite (module docstring).

    Parameters
    ----------
    model : PSDMModel
    theta : array, shape (n_base,)
    robot : RobotDescription, optional
        Its joint limits bound the configurations (infinite limits: one turn); without it revolute joints are
        sampled over one turn and prismatic ones over +-``FREE_PRISMATIC_RANGE``.
    n_samples : int
        Random configurations.
    rng : numpy.random.Generator, optional
        ``default_rng(0)`` when omitted.

    Returns
    -------
    ThetaCheck

    Raises
    ------
    ShapeError
        When ``theta`` does not have ``model.n_base`` values.

    Examples
    --------
    >>> check_theta(model, -theta, robot).consistent   # doctest: +SKIP
    False
    """
    theta = np.asarray(theta, dtype=float).reshape(-1)
    if theta.size != model.n_base:
        raise ShapeError(f"check_theta.theta must have {model.n_base} base parameters; got {theta.size}.")
    span = np.where(model.revolute, np.pi, FREE_PRISMATIC_RANGE)
    if robot is not None:
        q_min = np.where(np.isfinite(robot.q_min), robot.q_min, -span)
        q_max = np.where(np.isfinite(robot.q_max), robot.q_max, span)
        ranges = "within the robot's joint limits"
    else:
        q_min, q_max = -span, span
        ranges = f"revolute joints over one turn, prismatic over +-{FREE_PRISMATIC_RANGE} m: no robot file"
    report = check_consistency(model, theta, q_min, q_max, n_samples=n_samples, rng=rng)
    blamed = () if report.consistent else _blame(model, theta, report.worst_q)
    return ThetaCheck(report, blamed, ranges)


def _blame(model, theta, q, count: int = 3) -> tuple:
    """The base parameters whose terms ``theta_k v^T D_k(q) v`` are most negative at ``q`` (module docstring)."""
    values, vectors = np.linalg.eigh(mass_matrices(model, theta, q)[0])
    v = vectors[:, 0]
    unit = np.eye(model.n_base)
    shares = np.array([theta[k] * v @ mass_matrices(model, unit[k], q)[0] @ v for k in range(model.n_base)])
    floor = -1e-9 * float(np.max(np.abs(shares)))  # rounding noise of a zero term is no blame
    order = [k for k in np.argsort(shares)[:count] if shares[k] < floor]
    return tuple((model.base_names[k], float(theta[k]), float(shares[k])) for k in order)
