"""Model selection: greedy forward selection of candidate terms on top of the nominal model, judged on held-out data.

Every step fits the nominal friction, the terms kept so far and one more candidate jointly by
weighted least squares on the training recording (each joint's rows weighted by its torque RMS,
so joints count alike), predicts the validation recording, and keeps the candidate
that lowers the weighted validation error most, if it earns its parameters:

- the validation RMSE of at least one joint drops by ``min_improvement`` (default 20 %) and by at
  least ``min_torque_fraction`` (default 0.4 %) of that joint's torque RMS and ``ROBOT_FLOOR`` of the
  robot's largest joint torque RMS (floors in N m, so the small misfits of the nominal model that
  filtering and sampling leave, and noise-level changes on the weakest joints, do not count, while
  effects that are small against the torque of loaded joints, such as a slightly tilted base, still do);
- the fitted parameters are physically plausible (``CandidateTerm.implausibility``: a positive inertia,
  a friction coefficient below 0.5, a delay between 0 and 0.1 s, ...);
- the weighted validation error of all joints drops;
- the Bayesian information criterion on the training data drops, counted with the effective
  number of independent samples of a low-pass filtered signal (2 x cut-off x duration per joint).

Ties (gains within 2 %) go to the candidate with fewer parameters, then to the earlier term of the
library. Selection stops when no candidate qualifies or ``max_effects`` are kept. Each round's best
candidates, the rejected ones and the kept term are logged at INFO (logger ``identification.diagnosis.selection``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.columns import BlockColumns, as_blocks, row_chunks
from identification.metrics import rms, rmse
from psdm_casadi.errors import ParameterError

logger = logging.getLogger(__name__)

ROBOT_FLOOR = 0.0004  # least RMSE drop on any joint as a fraction of the robot's largest joint torque RMS


@dataclass(frozen=True)
class SelectionStep:
    """One kept term: its instance, the per-joint validation RMSE before and after adding it, the criterion gains."""

    term: object
    joints: tuple
    rmse_before: np.ndarray
    rmse_after: np.ndarray
    rmse_train_before: np.ndarray
    rmse_train_after: np.ndarray
    delta_bic: float
    validation_gain: float


@dataclass(frozen=True)
class SelectionResult:
    """Kept terms with their jointly fitted coefficients, and the fits before and after.

    Attributes
    ----------
    steps : tuple of SelectionStep
    coefficients : tuple of arrays
        Final coefficients of each kept term (same order as ``steps``).
    friction_coefficients : array
    rigid_coefficients : array or None
        Base parameters when the rigid body was identified.
    prediction_validation, prediction_train : arrays (n_samples, n_dof)
        Final model torque.
    nominal_validation, nominal_train : arrays (n_samples, n_dof)
        Torque of the nominal model alone.
    """

    steps: tuple
    coefficients: tuple
    friction_coefficients: np.ndarray
    rigid_coefficients: np.ndarray | None
    nominal_train: np.ndarray
    nominal_validation: np.ndarray
    prediction_train: np.ndarray
    prediction_validation: np.ndarray
    candidates_tried: int


def _solve(gram, rhs):
    d = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    scaled = gram / np.outer(d, d) + 1e-10 * np.eye(gram.shape[0])
    try:
        beta = np.linalg.solve(scaled, rhs / d)
    except np.linalg.LinAlgError:
        beta = np.linalg.lstsq(scaled, rhs / d, rcond=None)[0]
    return beta / d


class _Design:
    """Weighted stacked least squares with fixed base columns; adds candidate columns through the normal equations.

    The base columns are ``BlockColumns``; their normal equations, and a candidate's cross products with them,
    are summed over chunks of rows (``columns.row_chunks``), so a long recording never has its dense base held.
    Candidate columns are usually non-zero on one joint only, so the cross products are summed over the
    joints where a candidate is non-zero.
    """

    def __init__(self, base_train, base_val, y_train, y_val, sigma):
        self.sigma = sigma
        self.y_train, self.y_val = y_train, y_val
        self.ytw = y_train / sigma
        self.yy = float(np.sum(self.ytw**2))
        self.set_base(base_train, base_val)

    def set_base(self, base_train: BlockColumns, base_val: BlockColumns):
        self.base_train, self.base_val = base_train, base_val
        self.G, self.b = 0, 0
        for rows in row_chunks(base_train.n_samples):
            xs = [base_train.joint(j, rows, self.sigma[j]) for j in range(base_train.n_dof)]
            self.G = self.G + sum(x.T @ x for x in xs)
            self.b = self.b + sum(x.T @ self.ytw[rows, j] for j, x in enumerate(xs))

    def _cross(self, ct):
        """Cross products of the weighted candidate columns ``ct`` (n_samples, n_dof, k) with the base, with
        themselves and with the weighted torque."""
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
            cross, cc, cy = self._cross(cand_train / self.sigma[None, :, None])
            gram = np.block([[self.G, cross], [cross.T, cc]])
            rhs = np.concatenate([self.b, cy])
        beta = _solve(gram, rhs)
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


@dataclass(frozen=True)
class _Limits:
    """What a candidate must achieve (see the module docstring): joint weights, floors, the BIC sample count."""

    sigma: np.ndarray
    torque_rms: np.ndarray
    floor: np.ndarray
    min_improvement: float
    n_eff_total: float


def _screen(design, remaining, train_ctx, val_ctx, sse, rmse_v, limits):
    """Fit each remaining candidate with the kept terms; the qualifying ones as
    ``(gain, k, index, term, rmse_v, dBIC)``."""
    qualified, scored, rejected = [], [], []
    wval0 = float(np.sum(rmse_v**2 / limits.sigma**2))
    for index, term in enumerate(remaining):
        logger.debug("diagnose:   screening %s", term.label, extra={"progress": (index + 1, len(remaining))})
        ct, cv = term.columns(train_ctx), term.columns(val_ctx)
        beta, sse1, rv1 = design.fit(ct, cv)
        k = ct.shape[2]
        reason = term.implausibility(beta[design.G.shape[0] :], train_ctx)
        if reason is not None:
            rejected.append((term.label, reason))
            continue
        rel = 1.0 - rv1 / np.maximum(rmse_v, 1e-300)
        absolute = (rmse_v - rv1) >= limits.floor
        wval1 = float(np.sum(rv1**2 / limits.sigma**2))
        delta_bic = limits.n_eff_total * np.log(sse1 / sse) + k * np.log(limits.n_eff_total)
        gain = (wval0 - wval1) / wval0
        scored.append(
            (gain, term.label, float(np.max(rel)), float(np.max((rmse_v - rv1) / limits.torque_rms)), float(delta_bic))
        )
        if np.any((rel >= limits.min_improvement) & absolute) and wval1 < wval0 and delta_bic < 0:
            qualified.append((gain, k, index, term, rv1, delta_bic))
    for g, label, r, a, b in sorted(scored, reverse=True)[:5]:
        logger.info(
            f"diagnose:   candidate {label}: gain {g:.1%}, best joint -{r:.0%}, "
            f"drop {a:.2%} of torque RMS, dBIC {b:.0f}"
        )
    for label, reason in rejected[:5]:
        logger.info(f"diagnose:   rejected {label}: {reason}")
    return qualified


def _choose(qualified):
    """The best qualifying candidate; gains within 2 % of the best tie, and ties go to fewer parameters, then the
    earlier term."""
    top = max(q[0] for q in qualified)
    near = [q for q in qualified if q[0] >= top - 0.02 * abs(top)]
    return min(near, key=lambda q: (q[1], q[2]))


def _named_joints(term, rmse_before, rmse_after, joint_threshold) -> tuple:
    """The joints a kept term acts on: its own, or for a robot-wide term those it improves by ``joint_threshold``."""
    if term.joints:
        return term.joints
    rel = 1.0 - rmse_after / np.maximum(rmse_before, 1e-300)
    order = np.argsort(-rel)
    return tuple(int(j) for j in order if rel[j] >= joint_threshold) or (int(order[0]),)


def forward_select(
    instances,
    train_ctx,
    val_ctx,
    base_train,
    base_val,
    y_train,
    y_val,
    *,
    min_improvement=0.2,
    max_effects=4,
    effective_samples=None,
    joint_threshold=0.1,
    min_torque_fraction=0.004,
) -> SelectionResult:
    """Greedy forward selection of candidate term instances (see the module docstring).

    Parameters
    ----------
    instances : sequence of CandidateTerm
        Concrete instances (``CandidateLibrary.expand``).
    train_ctx, val_ctx : DiagnosisContext
    base_train, base_val : BlockColumns or arrays (n_samples, n_dof, p)
        Columns of the nominal model's free parameters (friction, and base parameters if identified).
    y_train, y_val : arrays (n_samples, n_dof)
        Measured torque minus the fixed part of the nominal model.
    min_improvement : float
        Fraction by which one joint's validation RMSE must drop.
    max_effects : int
    effective_samples : float, optional
        Independent samples per joint in the training data (for the BIC); default n_samples.
    joint_threshold : float
        Relative validation RMSE reduction above which a joint is named for a robot-wide term.
    min_torque_fraction : float
        Least absolute RMSE drop on the improving joint, as a fraction of that joint's torque RMS
        (a floor in N m below which a change is not worth reporting; default 0.4 %).
    """
    if not 0.0 < min_improvement < 1.0:
        raise ParameterError(f"DiagnosisOptions.min_improvement must be in (0, 1); got {min_improvement!r}.")
    if not (isinstance(max_effects, (int, np.integer)) and max_effects >= 0):
        raise ParameterError(f"DiagnosisOptions.max_effects must be an integer >= 0; got {max_effects!r}.")
    n_eff = float(effective_samples) if effective_samples is not None else float(y_train.shape[0])
    # joint weights: torque RMS of each joint on the training data, so joints count alike whatever their size
    torque_rms = rms(train_ctx.tau)
    sigma = np.maximum(torque_rms, 1e-6 * max(float(np.max(torque_rms)), 1e-12))
    # least RMSE drop per joint in N m: a fraction of that joint's own torque RMS (joints count alike), and
    # at least ROBOT_FLOOR of the robot's largest joint torque RMS (noise-level changes on the weakest joints)
    floor = np.maximum(min_torque_fraction * torque_rms, ROBOT_FLOOR * float(np.max(torque_rms)))
    limits = _Limits(
        sigma=sigma,
        torque_rms=torque_rms,
        floor=floor,
        min_improvement=min_improvement,
        n_eff_total=n_eff * y_train.shape[1],
    )
    design = _Design(as_blocks(base_train), as_blocks(base_val), y_train, y_val, sigma)
    _, sse, rmse_t, rmse_v, nominal_train, nominal_val = design.fit(full=True)
    kept, steps, sizes, tried, remaining = [], [], [], 0, list(instances)
    while len(kept) < max_effects and remaining:
        qualified = _screen(design, remaining, train_ctx, val_ctx, sse, rmse_v, limits)
        tried += len(remaining)
        if not qualified:
            break
        gain, _, _, term, _, delta_bic = _choose(qualified)
        ct, cv = term.columns(train_ctx), term.columns(val_ctx)
        _, _, rt1, rv1, _, _ = design.fit(ct, cv, full=True)
        steps.append(
            SelectionStep(
                term=term,
                joints=_named_joints(term, rmse_v, rv1, joint_threshold),
                rmse_before=rmse_v.copy(),
                rmse_after=rv1.copy(),
                rmse_train_before=rmse_t.copy(),
                rmse_train_after=rt1.copy(),
                delta_bic=float(delta_bic),
                validation_gain=float(gain),
            )
        )
        logger.info(f"diagnose: kept {term.label} (validation gain {gain:.1%}, dBIC {delta_bic:.0f})")
        kept.append(term)
        sizes.append(ct.shape[2])
        design.set_base(
            design.base_train.concatenate(BlockColumns.from_dense(ct)),
            design.base_val.concatenate(BlockColumns.from_dense(cv)),
        )
        _, sse, rmse_t, rmse_v, _, _ = design.fit(full=True)
        remaining = [r for r in remaining if r.label != term.label]
    beta, _, _, _, pred_t, pred_v = design.fit(full=True)
    p0 = base_train.shape[2]
    bounds = np.cumsum([p0] + sizes)
    coefficients = [beta[start:stop].copy() for start, stop in zip(bounds[:-1], bounds[1:])]
    return SelectionResult(
        steps=tuple(steps),
        coefficients=tuple(coefficients),
        friction_coefficients=beta[:p0].copy(),
        rigid_coefficients=None,
        nominal_train=nominal_train,
        nominal_validation=nominal_val,
        prediction_train=pred_t,
        prediction_validation=pred_v,
        candidates_tried=tried,
    )
