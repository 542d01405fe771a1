"""JointScore: the weighted training SSE of the diagnosis's current fit with one more set of columns, by variable
projection on a subset of rows (the cheap score shape parameters are searched with, ``selection``)."""

from __future__ import annotations

import numpy as np

from identification.diagnosis.design import solve_scaled

SCORE_ROWS = 2000  # training rows a ``JointScore`` sums over


class JointScore:
    """``score(joint, values)``: the weighted training SSE of ``design``'s current fit with columns ``values``
    (len(rows), k) on the training rows ``rows`` added on joint ``joint``, by the normal equations of the base (no
    refit of the base columns).

    With ``e`` the joint's weighted residual, ``B`` its weighted base rows and ``C`` the weighted columns, the SSE
    drops by ``g^T S^+ g`` with ``g = C^T e`` and ``S = C^T C - (B^T C)^T G^-1 (B^T C)``: the variable projection a
    term with shape parameters (a gas spring's geometry) is fitted by. The sums run over at most ``SCORE_ROWS``
    evenly spaced rows, scaled to the whole recording (the signals are low-pass filtered, so this loses little),
    cheap enough for a grid of starts; the design then fits the chosen shape on every row."""

    def __init__(self, design, sse: float):
        self.design, self.sse = design, float(sse)
        n = design.y_train.shape[0]
        self.rows = np.unique(np.linspace(0, n - 1, min(n, SCORE_ROWS)).astype(int))
        self.scale = n / self.rows.size
        self.beta = solve_scaled(design.G, design.b)
        self._joints = {}

    def _joint(self, j: int) -> tuple:
        if j not in self._joints:
            d = self.design
            rows = d.base_train.joint(j, slice(None), d.sigma[j])[self.rows]
            self._joints[j] = (rows, d.ytw[self.rows, j] - rows @ self.beta)
        return self._joints[j]

    def __call__(self, joint: int, values) -> float:
        rows, e = self._joint(int(joint))
        c = np.asarray(values, dtype=float).reshape(rows.shape[0], -1) / self.design.sigma[joint]
        bc = self.scale * (rows.T @ c)
        s = self.scale * (c.T @ c) - bc.T @ solve_scaled(self.design.G, bc)
        g = self.scale * (c.T @ e)
        return max(self.sse - float(g @ np.linalg.lstsq(s, g, rcond=1e-12)[0]), 1e-300)

    def fixed(self, values) -> float:
        """The weighted training SSE with the torque ``values`` (len(rows), n_dof) [N m] added to the model as it is
        (coefficient one, the base refitted): the exact profile of a robot-wide signal term at one value of its
        parameter (a delay's torque ``tau(t) - tau(t + d)``)."""
        values = np.asarray(values, dtype=float)
        br, rr, er = 0.0, 0.0, 0.0
        for j in range(values.shape[1]):
            rows, e = self._joint(j)
            r = values[:, j] / self.design.sigma[j]
            br, rr, er = br + rows.T @ r, rr + r @ r, er + e @ r
        br = self.scale * br  # the base refitted: the part of the torque its columns take up is given back
        sse = self.sse - 2.0 * self.scale * er + self.scale * rr - float(br @ solve_scaled(self.design.G, br))
        return max(sse, 1e-300)
