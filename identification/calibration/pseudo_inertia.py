"""Physical consistency of a link's inertial parameters: the pseudo-inertia and its log-Cholesky chart.

A link's ten standard parameters ``(m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz)`` (Pinocchio's
order, first moments ``h = m c`` and the inertia ``I`` about the link frame's origin) are physically
consistent, i.e. some mass distribution has them, exactly when the 4 x 4 pseudo-inertia

    J = [[Sigma, h], [h^T, m]],   Sigma = tr(I)/2 * 1 - I

is positive definite (Wensing, Kim and Slotine, IEEE RA-L 2017). This is stronger than a positive
mass and a positive-definite inertia: it also implies the triangle inequalities of the principal
moments about the centre of mass.

The log-Cholesky chart (Rucker and Wensing, IEEE RA-L 2022) writes ``J = L L^T`` with ``L`` lower
triangular and ``exp`` of free numbers on its diagonal: every point of R^10 is a consistent link, and
every consistent link is one point. An unconstrained optimiser over that chart (here Ipopt, in
``identification.calibration.recordings``) can therefore only return consistent parameters.
:func:`link_from_log_cholesky` works on numbers and on CasADi expressions alike.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from psdm_casadi.errors import ParameterError

__all__ = [
    "CONSISTENCY_MARGIN",
    "LINK_PARAMETER_COUNT",
    "lifted_link",
    "link_from_log_cholesky",
    "link_from_pseudo_inertia",
    "log_cholesky_from_link",
    "pseudo_inertia",
    "pseudo_inertia_eigenvalues",
    "semidefinite_links",
]

LINK_PARAMETER_COUNT = 10
#: [kg m^2] by which a fit keeps every pseudo-inertia positive definite (``TrajectoryOptions.margin``'s default).
CONSISTENCY_MARGIN = 1e-6


def pseudo_inertia(link) -> np.ndarray:
    """The 4 x 4 pseudo-inertia of one link's ten standard parameters."""
    m, mx, my, mz, ixx, ixy, iyy, ixz, iyz, izz = np.asarray(link, dtype=float).reshape(LINK_PARAMETER_COUNT)
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out = np.empty((4, 4))
    out[:3, :3] = sigma
    out[:3, 3] = out[3, :3] = (mx, my, mz)
    out[3, 3] = m
    return out


def link_from_pseudo_inertia(matrix) -> np.ndarray:
    """The ten standard parameters of a 4 x 4 pseudo-inertia (the inverse of :func:`pseudo_inertia`)."""
    matrix = np.asarray(matrix, dtype=float)
    sigma = matrix[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([matrix[3, 3], *matrix[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                     inertia[1, 2], inertia[2, 2]])  # fmt: skip


def pseudo_inertia_eigenvalues(standard) -> np.ndarray:
    """Smallest eigenvalue of each link's pseudo-inertia, shape (n_links,); standard is (n_links, >= 10)."""
    standard = np.atleast_2d(np.asarray(standard, dtype=float))
    return np.array([np.linalg.eigvalsh(pseudo_inertia(row[:LINK_PARAMETER_COUNT]))[0] for row in standard])


def semidefinite_links(standard) -> tuple:
    """The links (0-based) of ``standard`` (one row of at least ten parameters per link, e.g. the robot file's
    ``RobotDescription.nominal_dynamic_parameters``) that are not strictly physically consistent: a pseudo-inertia
    whose smallest eigenvalue is not above zero beyond round-off (numpy's ``matrix_rank`` tolerance, ``4 eps`` times its
    largest), such as a point mass (no inertia about its centre of mass) or a thin rod (none about its own axis)."""
    out = []
    for i, row in enumerate(np.atleast_2d(np.asarray(standard, dtype=float))):
        eigenvalues = np.linalg.eigvalsh(pseudo_inertia(row[:LINK_PARAMETER_COUNT]))
        if not eigenvalues[0] > 4 * np.finfo(float).eps * max(abs(eigenvalues[-1]), np.finfo(float).tiny):
            out.append(i)
    return tuple(out)


def lifted_link(link, margin: float = CONSISTENCY_MARGIN) -> np.ndarray:
    """The ten parameters of ``link`` with each eigenvalue of its pseudo-inertia below ``margin`` [kg m^2] raised to it:
    the strictly consistent link nearest to ``link`` (Frobenius norm of the pseudo-inertia) whose smallest eigenvalue is
    at least ``margin``, as every link a fit identifies is (``link_from_log_cholesky``). A semi-definite link (a
    point mass) is held this way (``consistent_fit.held_standard``): at its stated values it leaves the model
    inconsistent, its mass matrix singular where no other inertia acts about its joint."""
    values, vectors = np.linalg.eigh(pseudo_inertia(link))
    raised = vectors @ np.diag(np.maximum(values, margin) - values) @ vectors.T
    return np.asarray(link, dtype=float)[:LINK_PARAMETER_COUNT] + link_from_pseudo_inertia(raised)


def _lower_factor(phi):
    """L (as nested lists) from 10 chart coordinates: 4 log-diagonal entries, then 6 below the diagonal."""
    exp = ca.exp if isinstance(phi, (ca.SX, ca.MX)) else np.exp
    diagonal = [exp(phi[k]) for k in range(4)]
    below = [phi[4 + k] for k in range(6)]
    return [
        [diagonal[0], 0.0, 0.0, 0.0],
        [below[0], diagonal[1], 0.0, 0.0],
        [below[1], below[2], diagonal[2], 0.0],
        [below[3], below[4], below[5], diagonal[3]],
    ]


def link_from_log_cholesky(phi, margin: float = 0.0, floor=None):
    """Ten standard parameters from ten log-Cholesky coordinates (numbers or a CasADi column).

    ``margin`` [kg m^2] is added to the pseudo-inertia's diagonal, ``J = L L^T + margin * 1``, so that
    its eigenvalues stay at least ``margin`` above zero even where an optimiser drives ``L`` towards
    the boundary. ``floor`` (3 x 3, ``inertia_floor``: the link's second moment about its centre of mass per unit
    mass is at least it) adds ``m diag(floor, 0)``, ``m = J[3, 3]``: every point of the chart keeps the floor.
    """
    lower = _lower_factor(phi)
    j = [[sum(lower[r][k] * lower[c][k] for k in range(4)) + (margin if r == c else 0.0) for c in range(4)]
         for r in range(4)]  # fmt: skip
    if floor is not None:
        j = [[j[r][c] + (j[3][3] * float(floor[r][c]) if r < 3 and c < 3 else 0.0) for c in range(4)] for r in range(4)]
    trace_sigma = j[0][0] + j[1][1] + j[2][2]
    entries = [j[3][3], j[0][3], j[1][3], j[2][3], trace_sigma - j[0][0], -j[0][1], trace_sigma - j[1][1], -j[0][2],
               -j[1][2], trace_sigma - j[2][2]]  # fmt: skip
    if isinstance(phi, (ca.SX, ca.MX)):
        return ca.vertcat(*entries)
    return np.array([float(e) for e in entries])


def log_cholesky_from_link(link, floor: float = 0.0) -> np.ndarray:
    """The log-Cholesky coordinates of a consistent link.

    Parameters
    ----------
    link : array, shape (10,)
    floor : float
        Eigenvalues of the pseudo-inertia below ``floor`` are raised to it first (a start value for an
        optimiser from an inconsistent prior); 0 refuses inconsistent links.

    Raises
    ------
    ParameterError
        When the link is not physically consistent and ``floor`` is 0.
    """
    matrix = pseudo_inertia(link)
    values, vectors = np.linalg.eigh(matrix)
    if values[0] <= 0.0:
        if floor <= 0.0:
            raise ParameterError(
                f"link parameters must have a positive-definite pseudo-inertia; got smallest eigenvalue "
                f"{values[0]:.3g}. Pass floor > 0 to project them onto consistent ones."
            )
        matrix = (vectors * np.maximum(values, floor)) @ vectors.T
    lower = np.linalg.cholesky(matrix)
    return np.array([*np.log(np.diag(lower)), lower[1, 0], lower[2, 0], lower[2, 1], lower[3, 0], lower[3, 1],
                     lower[3, 2]])  # fmt: skip
