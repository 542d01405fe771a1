"""Physical-consistency check of identified base parameters: is the mass matrix positive definite over the workspace?

Base parameters fitted by least squares need not belong to any physical robot; the symptom that
matters for simulation and control is a mass matrix D(q) that is not positive definite somewhere
(the paper's published Denso parameters fail this). :func:`check_consistency` samples joint
configurations uniformly in the joint ranges and reports the smallest eigenvalue of D(q).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.calibration.pseudo_inertia import pseudo_inertia_eigenvalues
from psdm_casadi.errors import ParameterError, ShapeError
from psdm_casadi.model import PSDMModel
from psdm_casadi.oracle import LINK_PARAMETER_NAMES

__all__ = [
    "MASS_CHECK_CONFIGURATIONS",
    "ConsistencyReport",
    "check_consistency",
    "consistency_failure",
    "mass_matrices",
    "min_mass_eigenvalue",
]

#: Random configurations of the mass-matrix check of a recalibrated model (``min_mass_eigenvalue``).
MASS_CHECK_CONFIGURATIONS = 2000


@dataclass(frozen=True, eq=False)
class ConsistencyReport:
    """Result of :func:`check_consistency`.

    Attributes
    ----------
    min_eigenvalue : float
        Smallest eigenvalue of D(q) over the samples [kg m^2].
    worst_q : array, shape (n_dof,)
        Configuration of that eigenvalue [rad].
    n_samples : int
    n_violations : int
        Samples with an eigenvalue <= ``tolerance``.
    tolerance : float
    """

    min_eigenvalue: float
    worst_q: np.ndarray
    n_samples: int
    n_violations: int
    tolerance: float

    @property
    def consistent(self) -> bool:
        """True when D(q) was positive definite (beyond ``tolerance``) at every sample."""
        return self.n_violations == 0

    def to_dict(self) -> dict:
        return {
            "consistent": self.consistent,
            "min_eigenvalue": self.min_eigenvalue,
            "worst_q": self.worst_q.tolist(),
            "n_samples": self.n_samples,
            "n_violations": self.n_violations,
            "tolerance": self.tolerance,
        }

    @classmethod
    def from_dict(cls, data: dict) -> ConsistencyReport:
        return cls(
            float(data["min_eigenvalue"]),
            np.asarray(data["worst_q"], dtype=float),
            int(data["n_samples"]),
            int(data["n_violations"]),
            float(data["tolerance"]),
        )


def mass_matrices(model: PSDMModel, theta, q) -> np.ndarray:
    """D(q) from the regressor: column k is ``Y(q, 0, e_k) theta - Y(q, 0, 0) theta``; shape (n_samples, n, n)."""
    theta = np.asarray(theta, dtype=float).reshape(-1)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = model.n_dof
    zeros = np.zeros_like(q)
    base = model.inverse_dynamics(q, zeros, zeros, theta)
    out = np.empty((q.shape[0], n, n))
    for k in range(n):
        qdd = zeros.copy()
        qdd[:, k] = 1.0
        out[:, :, k] = model.inverse_dynamics(q, zeros, qdd, theta) - base
    return 0.5 * (out + out.transpose(0, 2, 1))


def check_consistency(
    model: PSDMModel,
    theta,
    q_min,
    q_max,
    n_samples: int = 200,
    rng: np.random.Generator | None = None,
    tolerance: float = 0.0,
) -> ConsistencyReport:
    """Smallest eigenvalue of the mass matrix over random configurations in ``[q_min, q_max]``.

    Parameters
    ----------
    model : PSDMModel
    theta : array, shape (n_base,)
    q_min, q_max : array, shape (n_dof,)
        Joint ranges [rad or m].
    n_samples : int
        Random configurations, >= 1.
    rng : numpy.random.Generator, optional
        ``default_rng(0)`` when omitted.
    tolerance : float
        Eigenvalues at or below it count as violations [kg m^2].

    Returns
    -------
    ConsistencyReport

    Examples
    --------
    >>> report = check_consistency(model, theta, robot.q_min, robot.q_max)   # doctest: +SKIP
    >>> report.consistent
    True
    """
    if not isinstance(model, PSDMModel):
        raise ParameterError(f"check_consistency.model must be a PSDMModel; got {type(model).__name__}.")
    if not (isinstance(n_samples, (int, np.integer)) and n_samples >= 1):
        raise ParameterError(f"check_consistency.n_samples must be an integer >= 1; got {n_samples!r}.")
    theta = np.asarray(theta, dtype=float).reshape(-1)
    if theta.size != model.n_base:
        raise ShapeError(f"check_consistency.theta must have {model.n_base} base parameters; got {theta.size}.")
    rng = np.random.default_rng(0) if rng is None else rng
    q = rng.uniform(np.asarray(q_min, dtype=float), np.asarray(q_max, dtype=float), (n_samples, model.n_dof))
    eig = np.linalg.eigvalsh(mass_matrices(model, theta, q))[:, 0]
    k = int(np.argmin(eig))
    return ConsistencyReport(
        float(eig[k]), q[k].copy(), int(n_samples), int(np.sum(eig <= tolerance)), float(tolerance)
    )


def min_mass_eigenvalue(robot, standard, seed: int = 0) -> float:
    """Smallest eigenvalue of the mass matrix of ``standard`` over random configurations within the limits."""
    from psdm_casadi.oracle import PinocchioOracle

    oracle = PinocchioOracle(robot, standard)
    q = np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, size=(MASS_CHECK_CONFIGURATIONS, robot.n_dof))
    return float(min(np.linalg.eigvalsh(m)[0] for m in oracle.crba(q)))


def consistency_failure(recalibration) -> str | None:
    """None for a consistent recalibrated model (a ``recalibrate.Recalibration``: its ``after`` model and
    ``min_mass_eigenvalue``), else a sentence naming the eigenvalue and the parameters to blame."""
    after = recalibration.after
    standard = after.document["standard"]
    if not standard.get("checked", True):
        return "the recalibrated model was not checked for physical consistency (identified with --no-consistency)"
    mass = recalibration.min_mass_eigenvalue
    if after.consistent and not (np.isfinite(mass) and mass <= 0):
        return None
    values = after.standard
    eigen = pseudo_inertia_eigenvalues(values) if np.all(np.isfinite(values[:, :10])) else np.full(len(values), -1.0)
    bad = [i for i in np.argsort(eigen) if eigen[i] <= 0] or [int(np.argmin(eigen))]
    blamed = "; ".join(
        f"link {i + 1} ({', '.join(f'{n}{i + 1}' for n in LINK_PARAMETER_NAMES)}, pseudo-inertia "
        f"eigenvalue {eigen[i]:.3g})"
        for i in bad
    )
    return (
        f"the recalibrated model is not physically consistent (smallest pseudo-inertia eigenvalue "
        f"{standard['min_pseudo_inertia_eigenvalue']}, smallest mass-matrix eigenvalue {mass:.3g}): {blamed}"
    )
