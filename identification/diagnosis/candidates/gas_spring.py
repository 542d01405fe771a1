"""A gas-spring counterbalance on one joint: the lever law, a spring shape that competes with the polynomial spring.

A strut between a point at ``a`` from the joint axis on the previous link and one at ``b`` on the moving link (the
levers aligned at ``q = q0``) is ``l = sqrt(a^2 + b^2 - 2 a b cos(q - q0))`` long and pushes with ``F(l) = F0 +
k (l0 - l)``; the joint gets ``F(l) a b sin(q - q0) / l``, which the motors no longer supply. With ``a`` the longer
lever, ``rho = b / a < 1`` and ``lambda = l / a``, the torque the motors supply in addition is

    ``p1 * (-sin(x) / lambda) + p2 * sin(x)``,  ``x = q - q0``,  ``p1 = b (F0 + k l0)``,  ``p2 = k a b``,

linear in ``(p1, p2)`` once the geometry ``(rho, q0)`` is known. ``fit_geometry`` finds the geometry by variable
projection on the selection's current fit (a grid of starts, then bounded quasi-Newton from the best ones);
``SpringTerm.shape_variants`` offers the term beside the polynomial shapes and the selection chooses by BIC, with
the two geometry parameters counted (``n_shape_parameters``). Only the products are identifiable from torque (the
levers scale together), so the term reports ``rho``, ``q0``, ``F b`` over the recorded range and ``k a b``; given
the longer lever ``a`` from a drawing, ``b = rho a``, ``F0 = (F b) / b`` and ``k = (k a b) / (a b)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from identification.diagnosis.candidates.base import CandidateTerm, joint_columns, joint_expression
from psdm_casadi.errors import ParameterError

RATIO_BOUNDS = (0.02, 0.98)  # shorter over longer lever: the strut never reaches length 0
GRID = (10, 36)  # ratios x alignment angles of the start grid
MAX_ITERATIONS = 60  # quasi-Newton iterations per start
N_STARTS = 5  # lowest local minima of the grid refined by bounded quasi-Newton


def _shape(q, ratio: float, q0: float):
    """``(-sin(x) / lambda, sin(x), lambda)`` of the lever law at angles ``q`` (numpy or CasADi)."""
    sin, cos, sqrt = (ca.sin, ca.cos, ca.sqrt) if isinstance(q, (ca.SX, ca.MX)) else (np.sin, np.cos, np.sqrt)
    x = q - q0
    lam = sqrt(1.0 + ratio**2 - 2.0 * ratio * cos(x))
    return -sin(x) / lam, sin(x), lam


def lever_columns(q, ratio: float, q0: float) -> np.ndarray:
    """The term's two columns (n_samples, 2) at joint angles ``q`` (array, rad)."""
    u1, u2, _ = _shape(np.asarray(q, dtype=float), ratio, q0)
    return np.column_stack([u1, u2])


def fit_geometry(q, sse) -> tuple:
    """``(ratio, q0)`` of the lever law that minimises ``sse(columns)``, the weighted training SSE of the current
    model with the term's columns (n_samples, 2) at the joint angles ``q`` [rad] added (variable projection: the
    coefficients are solved for inside ``sse``).

    The landscape has several basins (the law is even in the ratio's inverse and nearly periodic in the angle), so
    a grid of ratios and alignment angles over a whole turn is evaluated, its ``N_STARTS`` lowest local minima are
    refined by bounded quasi-Newton on the logarithm of the SSE, and the best is kept; the angle is returned
    within half a turn of the middle of the recorded range."""
    q = np.asarray(q, dtype=float)
    middle = 0.5 * (float(np.min(q)) + float(np.max(q)))
    ratios = np.linspace(0.05, 0.95, GRID[0])
    angles = middle + np.linspace(-np.pi, np.pi, GRID[1], endpoint=False)

    def cost(p):
        return float(np.log(max(float(sse(lever_columns(q, p[0], p[1]))), 1e-300)))

    grid = np.array([[cost((rho, q0)) for q0 in angles] for rho in ratios])
    padded = np.pad(grid, ((1, 1), (0, 0)), constant_values=np.inf)
    neighbours = [np.roll(padded, (dr, dq), axis=(0, 1))[1:-1] for dr in (-1, 0, 1) for dq in (-1, 0, 1)]
    minima = np.argwhere(grid <= np.min(neighbours, axis=0))
    minima = sorted(minima, key=lambda rq: grid[rq[0], rq[1]])[:N_STARTS]
    best = None
    for i, k in minima:
        start = (ratios[i], angles[k])
        bounds = [RATIO_BOUNDS, (start[1] - np.pi, start[1] + np.pi)]
        fit = minimize(cost, start, method="L-BFGS-B", bounds=bounds, options={"maxiter": MAX_ITERATIONS})
        if best is None or fit.fun < best.fun:
            best = fit
    return float(best.x[0]), float(np.angle(np.exp(1j * (best.x[1] - middle))) + middle)


@dataclass(frozen=True)
class GasSpringTerm(CandidateTerm):
    """``gas_spring``: a gas-spring counterbalance on one joint (the lever law of the module docstring).

    Parameters
    ----------
    joint : int or None
    ratio : float
        Shorter over longer lever, in ``RATIO_BOUNDS``.
    q0 : float
        Joint angle at which the levers are aligned (the strut is shortest) [rad].
    q_range : tuple (q_min, q_max) or None
        The training recording's range of the joint [rad]: force and plausibility are judged over it.
    """

    joint: int | None = None
    ratio: float = 0.5
    q0: float = 0.0
    q_range: tuple | None = None
    key = "gas_spring"
    explanation = "a gas-spring counterbalance: a strut pushing on a lever, torque F(l) a b sin(q - q0) / l"
    signature = "residual follows joint position with the shape of a lever law"
    n_shape_parameters = 2  # ratio and q0, fitted on the residual: counted in the BIC

    def __post_init__(self):
        if not (RATIO_BOUNDS[0] <= self.ratio <= RATIO_BOUNDS[1]):
            raise ParameterError(f"GasSpringTerm.ratio must be in {RATIO_BOUNDS}; got {self.ratio!r}.")
        if not np.isfinite(self.q0):
            raise ParameterError(f"GasSpringTerm.q0 must be a finite angle [rad]; got {self.q0!r}.")

    def feature_names(self):
        self._require_joint()
        j = self.joint + 1
        return [f"gas_force_b_q{j}", f"gas_stiffness_ab_q{j}"]

    def columns(self, context):
        self._require_joint()
        return joint_columns(context, self.joint, lever_columns(context.q[:, self.joint], self.ratio, self.q0))

    def torque_of_angle(self, q, coefficients) -> np.ndarray:
        """The torque [N m] the motors supply for the strut at joint angles ``q`` (array, rad)."""
        u1, u2, _ = _shape(np.asarray(q, dtype=float), self.ratio, self.q0)
        return coefficients[0] * u1 + coefficients[1] * u2

    def _force_b(self, coefficients) -> np.ndarray:
        """``F(l) b`` [N m] over the recorded range (101 angles)."""
        lo, hi = self.q_range if self.q_range is not None else (self.q0 - np.pi, self.q0 + np.pi)
        lam = _shape(np.linspace(lo, hi, 101), self.ratio, self.q0)[2]
        return coefficients[0] - coefficients[1] * lam, lam

    def physical_parameters(self, coefficients):
        c = np.asarray(coefficients, dtype=float)
        force_b, lam = self._force_b(c)
        longest = int(np.argmax(lam))
        return {
            "ratio": float(self.ratio),
            "q0": float(self.q0),
            "F0_b": float(force_b[longest]),  # F b at the longest strut over the range [N m]
            "k_ab": float(c[1]),  # [N m]
            "force_b_min": float(np.min(force_b)),
            "force_b_max": float(np.max(force_b)),
            "length_min_over_a": float(np.min(lam)),
            "length_max_over_a": float(np.max(lam)),
        }

    def implausibility(self, coefficients, context=None):
        """A gas spring pushes (``F >= 0`` over the recorded range) and stiffens as it is compressed (``k >= 0``)."""
        c = np.asarray(coefficients, dtype=float)
        force_b, _ = self._force_b(c)
        scale = max(float(np.max(np.abs(force_b))), 1e-12)
        if float(np.min(force_b)) < -1e-6 * scale:
            return (
                f"the strut would pull (F b down to {float(np.min(force_b)):.3g} N m over the range): not a gas spring"
            )
        if c[1] < -1e-6 * scale:
            return f"negative strut stiffness (k a b = {c[1]:.3g} N m): not a gas spring"
        return None

    def interpret(self, coefficients):
        """Reported as a spring (the family) with the lever law's shape in words."""
        p = self.physical_parameters(coefficients)
        return "spring", (
            f"a gas-spring counterbalance (lever law): levers in ratio {p['ratio']:.3g}, aligned at q = {p['q0']:.3g} "
            f"rad, strut force times the short lever F b = {p['force_b_min']:.4g} to {p['force_b_max']:.4g} N m over "
            f"the recorded range, k a b = {p['k_ab']:.4g} N m (given the longer lever a: b = ratio a, F = (F b) / b)"
        )

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        u1, u2, _ = _shape(q[self.joint], self.ratio, self.q0)
        return joint_expression(q.shape[0], self.joint, coefficients[0] * u1 + coefficients[1] * u2)
