"""WeightedDesign: the diagnosis's weighted stacked least squares, shared by the selection and the confounding check.

Each joint's rows are divided by its weight ``sigma[j]`` (its torque RMS, so joints count alike). The fixed base
columns (the nominal model's free parameters, then the kept terms) are ``BlockColumns`` whose normal equations
are summed over chunks of rows (``columns.row_chunks``), so a long recording never has its dense base held.
Candidate columns enter through their cross products with the base (``fit``), and ``project`` measures how much
of a candidate lies in the span of the base columns (what the nominal parameters would absorb of it).
"""

from __future__ import annotations

import numpy as np

from identification.diagnosis.columns import BlockColumns, row_chunks
from identification.metrics import rms, rmse

#: The weight of a left-out joint (``DiagnosisContext.missing``) is this many times the largest: its rows count for
#: 1e-16 of a measured joint's (they are the nominal model's own torque, no measurement).
LEFT_OUT = 1e8


def left_out(context) -> tuple:
    """The joints of a context left out of the fits (``DiagnosisContext.missing``; none for a context without it)."""
    return tuple(getattr(context, "missing", ()))


def joint_weights(tau, missing=()) -> np.ndarray:
    """Joint weights [N m] (n_dof,): each joint's torque RMS on the training recording ``tau`` (n_samples, n_dof),
    at least 1e-6 of the largest, so that joints count alike whatever their size; the ``missing`` joints (no torque
    measured, ``DiagnosisContext.missing``) ``LEFT_OUT`` times the largest, so that their rows count for nothing."""
    torque_rms = rms(tau)
    sigma = np.maximum(torque_rms, 1e-6 * max(float(np.max(torque_rms)), 1e-12))
    sigma[list(missing)] = LEFT_OUT * float(np.max(sigma))
    return sigma


def solve_scaled(gram, rhs):
    """Solution of ``gram x = rhs`` after scaling the columns to unit norm (a tiny ridge keeps it defined)."""
    d = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    scaled = gram / np.outer(d, d) + 1e-10 * np.eye(gram.shape[0])
    try:
        beta = np.linalg.solve(scaled, (rhs.T / d).T)
    except np.linalg.LinAlgError:
        beta = np.linalg.lstsq(scaled, (rhs.T / d).T, rcond=None)[0]
    return (beta.T / d).T


class WeightedDesign:
    """Weighted stacked least squares with fixed base columns; adds candidate columns through the normal equations.

    Candidate columns are usually non-zero on one joint only, so their cross products are summed over the joints
    where a candidate is non-zero.

    Parameters
    ----------
    base_train, base_val : BlockColumns
        Columns (n_samples, n_dof, p) of the fixed part of the fit.
    y_train, y_val : arrays (n_samples, n_dof)
        Torque the columns are fitted to [N m].
    sigma : array (n_dof,)
        Joint weights [N m].
    """

    def __init__(self, base_train, base_val, y_train, y_val, sigma):
        self.sigma = sigma
        self.y_train, self.y_val = y_train, y_val
        self.ytw = y_train / sigma
        self.yy = float(np.sum(self.ytw**2))
        self.set_base(base_train, base_val)

    def set_base(self, base_train: BlockColumns, base_val: BlockColumns):
        """Replace the base columns and sum their normal equations."""
        self.base_train, self.base_val = base_train, base_val
        self.G, self.b = 0, 0
        for rows in row_chunks(base_train.n_samples):
            xs = [base_train.joint(j, rows, self.sigma[j]) for j in range(base_train.n_dof)]
            self.G = self.G + sum(x.T @ x for x in xs)
            self.b = self.b + sum(x.T @ self.ytw[rows, j] for j, x in enumerate(xs))

    def cross(self, ct):
        """Cross products of the weighted candidate columns ``ct`` (n_samples, n_dof, k) with the base, with
        themselves and with the weighted torque: ``(B^T C, C^T C, C^T y)``."""
        p, k = self.G.shape[0], ct.shape[2]
        joints = np.flatnonzero(np.any(ct != 0, axis=(0, 2)))
        cross, cc, cy = np.zeros((p, k)), np.zeros((k, k)), np.zeros(k)
        for rows in row_chunks(ct.shape[0]):
            for j in joints:
                c = ct[rows, j, :]
                cross += self.base_train.joint(j, rows, self.sigma[j]).T @ c
                cc += c.T @ c
                cy += c.T @ self.ytw[rows, j]
        return cross, cc, cy

    def fit(self, cand_train=None, cand_val=None, full=False):
        """Coefficients, weighted train SSE, validation RMSE per joint (and, with ``full``, train RMSE and
        predictions)."""
        p = self.G.shape[0]
        if cand_train is None:
            gram, rhs = self.G, self.b
        else:
            cross, cc, cy = self.cross(cand_train / self.sigma[None, :, None])
            gram = np.block([[self.G, cross], [cross.T, cc]])
            rhs = np.concatenate([self.b, cy])
        beta = solve_scaled(gram, rhs)
        sse = max(self.yy - 2.0 * beta @ rhs + beta @ gram @ beta, 1e-300)
        pred_v = self.base_val.predict(beta[:p])
        if cand_train is not None:
            pred_v = pred_v + cand_val @ beta[p:]
        rmse_v = rmse(self.y_val, pred_v)
        if not full:
            return beta, sse, rmse_v
        pred_t = self.base_train.predict(beta[:p])
        if cand_train is not None:
            pred_t = pred_t + cand_train @ beta[p:]
        rmse_t = rmse(self.y_train, pred_t)
        return beta, sse, rmse_t, rmse_v, pred_t, pred_v

    def project(self, ct, coefficients=None) -> tuple:
        """How much of the candidate columns ``ct`` (n_samples, n_dof, k) on the training rows the base columns
        absorb: ``(fraction, change)``.

        ``fraction`` is the share of the weighted squared norm of the columns (of ``ct @ coefficients`` when
        given) that lies in the span of the base columns (0: orthogonal, 1: a change of the base parameters
        reproduces it exactly); ``change`` (p, k) or (p,) is the base-parameter change that reproduces it best.
        """
        cross, cc, _ = self.cross(ct / self.sigma[None, :, None])
        if coefficients is not None:
            c = np.asarray(coefficients, dtype=float)
            cross, cc = cross @ c, float(c @ cc @ c)
        change = solve_scaled(self.G, cross)
        total = float(np.trace(np.atleast_2d(cc)))
        if total <= 0.0:
            return 0.0, change
        absorbed = float(np.sum(cross * change))
        return float(np.clip(absorbed / total, 0.0, 1.0)), change
