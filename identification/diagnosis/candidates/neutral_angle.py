"""A counterbalance's neutral angle: where its odd torque law is centred, fitted by variable projection.

A gas spring or a coil spring pulling through a linkage gives the joint ``F(l) a b sin(x) / l`` with ``x = q - q0``
and the spring's length ``l`` even in ``x``: the torque is odd about the angle ``q0`` where spring and lever align
(zero torque there, equal and opposite on either side). A cam profiled to cancel a link's gravity is odd about that
link's hanging angle in the same way. ``SpringTerm(odd=True)`` is this law as a polynomial of odd powers of ``x``
(``x``, ``x^3``, ``x^5``); the data fix the coefficients linearly and the neutral angle ``q0`` here: the angle whose
odd columns leave the lowest training SSE, the coefficients solved inside ``sse`` (variable projection, as
``gas_spring.fit_geometry`` fits the lever law's geometry).

Why odd and not every power: the odd law has fewer parameters for the same order (the quintic 4 coefficients and the
angle against 6 coefficients) and carries its shape to the mirror side of the neutral angle, where a polynomial of
every power extrapolates freely. An odd cubic about a fitted angle plus a constant is every cubic (odd about its
inflection point), so the law starts at order 5 (``torque.ODD_MIN_ORDER``). On the virtual Denso's cam
(``CamCounterbalance``, odd about 0; training range -0.25 to 0.75 rad, held out down to -0.53 rad) the diagnosis's
odd quintic put the neutral angle at -0.006 rad and left 0.041 N m of joint 2's torque held out, the quintic of every
power 0.044 and the cubic 0.123; over that short range the link's gravity and a linear spring fit the training data as
well (BIC), so the data do not choose it there. Swept over 1.8 rad, identify's training residual chooses it (BIC,
neutral angle -0.023 rad) and the block cross-validation takes it: joint 2 from 5.46 to 0.114 N m on the held-out
blocks, against 0.674 for the cubic and 1.34 for the linear spring.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

__all__ = ["GRID_POINTS", "REACH", "fit_neutral_angle", "odd_columns"]

#: angles of the grid the search starts from, over the recorded range
GRID_POINTS = 41
#: the neutral angle may lie this fraction of the recorded range beyond either end: the law's symmetry is seen only
#: where the motion crosses the neutral angle (about an angle outside the range, odd powers are a polynomial of every
#: power: an odd quintic about 1.25 rad fitted one about 0.12 rad over -0.25 to 0.75 rad to the noise); a strut
#: aligned outside the range is the lever law's (``gas_spring``)
REACH = 0.0


def odd_columns(q, q0: float, order: int) -> np.ndarray:
    """The odd law's columns ``(x, x^3, .., x^order, 1)`` (n_samples, (order + 1) / 2 + 1) at joint angles ``q``
    [rad], ``x = q - q0``; the constant is the offset a fit may leave to the joint's torque offset."""
    x = np.asarray(q, dtype=float) - q0
    return np.column_stack([x**i for i in range(1, order + 1, 2)] + [np.ones_like(x)])


def fit_neutral_angle(q, sse, order: int) -> tuple:
    """``(q0, sse)``: the neutral angle [rad] of the odd law of ``order`` that minimises ``sse(columns)``, the weighted
    training SSE with the law's columns (``odd_columns`` at the joint angles ``q``) added, and that SSE.

    A grid of ``GRID_POINTS`` angles over the recorded range (widened by ``REACH`` of it on each side), then a bounded
    scalar search between the best grid point's neighbours."""
    q = np.asarray(q, dtype=float)
    lo, hi = float(np.min(q)), float(np.max(q))
    reach = REACH * (hi - lo)
    angles = np.linspace(lo - reach, hi + reach, GRID_POINTS)

    def cost(q0):
        return float(sse(odd_columns(q, float(q0), order)))

    grid = np.array([cost(a) for a in angles])
    k = int(np.argmin(grid))
    bounds = (angles[max(k - 1, 0)], angles[min(k + 1, angles.size - 1)])
    fit = minimize_scalar(cost, bounds=bounds, method="bounded", options={"xatol": 1e-4 * (hi - lo)})
    if float(fit.fun) < grid[k]:
        return float(fit.x), float(fit.fun)
    return float(angles[k]), float(grid[k])
