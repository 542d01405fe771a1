"""Beyond the library: the sparse search of one joint's residual over the function library (``sparse_terms``).

The joint's training residual, with its nominal friction columns projected out (they are refitted with the term),
is regressed on the library by sequentially thresholded least squares (pysindy's ``STLSQ``, as in SINDy) on
unit-RMS columns for a few thresholds, and each fit is pruned by backward elimination; the sparsest fit within
``VALIDATION_SLACK`` of the best validation RMSE is taken. The library's lobes of the angle get their centre
and width here: per width on a grid (fractions of the recorded range), the centre whose odd and even lobe fit the
training residual best (a scan, like the ripple's harmonic). With several validation recordings the fit is chosen on
all of them together (their samples pooled), and ``propose_sparse_terms`` keeps a joint's term only when it holds on
each (``SparseProposal.holds``): it lowers the joint's pooled validation RMSE by ``DiagnosisOptions.sparse_min_gain``
and by ``MIN_TORQUE_FRACTION`` of its torque RMS (the size of the effect, measured on all the held-out data), and
the joint's RMSE on every recording by ``sparse_min_gain`` (the library's candidates must hold on each recording as
well, ``second_opinion``).
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.residual_tests import cross_correlation, ljung_box
from identification.diagnosis.sparse_terms import SparseTerm, feature_matrix, sparse_features
from identification.metrics import rms

logger = logging.getLogger(__name__)

THRESHOLDS = (0.03, 0.06, 0.1, 0.2)  # STLSQ thresholds on unit-RMS columns and target (fractions of the residual)
VALIDATION_SLACK = 0.02  # the sparsest fit whose validation RMSE is within this fraction of the best one
MAX_FEATURES = 8  # a fit needing more features than this is not a sparse term
RIDGE = 1e-4  # STLSQ ridge per sample (unit-RMS columns)
MIN_TORQUE_FRACTION = 0.01  # least validation RMSE drop of a kept term, as a fraction of its joint's torque RMS
LOBE_WIDTHS = (0.03, 0.045, 0.065, 0.09, 0.13, 0.18)  # lobe widths tried, fractions of the recorded range
LOBE_CENTRES = 41  # lobe centres tried per width, evenly over the recorded range


def _lobe_explained(q, target, nuisance, centres, width: float) -> np.ndarray:
    """Sum of squares of ``target`` that the odd and even lobe of ``width`` explain beyond ``nuisance``, per centre."""
    n = centres.size
    u = (q[:, None] - centres[None, :]) / width
    even = np.exp(-0.5 * u * u)
    columns = np.concatenate([u * even, even], axis=1)
    if nuisance.shape[1]:
        columns = columns - nuisance @ np.linalg.lstsq(nuisance, columns, rcond=None)[0]
    odd, even = columns[:, :n], columns[:, n:]
    a, b, c = (odd * odd).sum(axis=0), (odd * even).sum(axis=0), (even * even).sum(axis=0)
    p, r = odd.T @ target, even.T @ target
    det = a * c - b * b
    ok = det > 1e-9 * a * c
    return np.where(ok, (c * p * p - 2.0 * b * p * r + a * r * r) / np.where(ok, det, 1.0), 0.0)


def best_lobes(q, target, nuisance) -> tuple:
    """``((lobe_centre, lobe_width), ...)`` [rad]: per width of ``LOBE_WIDTHS`` (times the range of ``q`` between its
    1st and 99th percentiles), the centre whose odd and even lobe together fit ``target`` best beyond the ``nuisance``
    columns, and last the best of those with its centre and width refined off the grid (Nelder-Mead), all on
    training data (``target`` is already orthogonal to ``nuisance``)."""
    from scipy.optimize import minimize

    lo, hi = np.percentile(q, [1.0, 99.0])
    if not hi - lo > 0:
        return ()
    centres = np.linspace(lo, hi, LOBE_CENTRES)
    out, scores = [], []
    for fraction in LOBE_WIDTHS:
        explained = _lobe_explained(q, target, nuisance, centres, fraction * (hi - lo))
        out.append((float(centres[int(np.argmax(explained))]), float(fraction * (hi - lo))))
        scores.append(float(np.max(explained)))
    start = out[int(np.argmax(scores))]
    span = hi - lo

    def loss(x):
        centre, width = start[0] + x[0] * span, start[1] * np.exp(x[1])
        if not (lo <= centre <= hi and width >= LOBE_WIDTHS[0] * span):
            return 0.0
        return -float(_lobe_explained(q, target, nuisance, np.array([centre]), width)[0]) / max(max(scores), 1e-300)

    x = minimize(loss, np.zeros(2), method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 200}).x
    if loss(x) < loss(np.zeros(2)):
        out.append((float(start[0] + x[0] * span), float(start[1] * np.exp(x[1]))))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class SparseProposal:
    """A kept unnamed term with its evidence: validation RMSE of its joint before/after (on the first validation
    recording, the report's; on each; on all pooled), the residual tests."""

    term: SparseTerm
    coefficients: np.ndarray
    prediction_t: np.ndarray  # (n_samples_t,) on the term's joint
    prediction_v: np.ndarray  # on the first validation recording
    rmse_before: float
    rmse_after: float
    ljung_box_p: float
    state_correlation: float
    delta_bic: float
    nuisance: np.ndarray  # change of the nuisance columns' coefficients (the joint's friction)
    each_before: tuple = ()  # the joint's RMSE on every validation recording (the first one first)
    each_after: tuple = ()
    pooled_before: float = 0.0  # over the samples of every validation recording together
    pooled_after: float = 0.0

    @property
    def validation_gain(self) -> float:
        return 1.0 - self.rmse_after / self.rmse_before if self.rmse_before > 0 else 0.0

    def holds(self, min_gain: float, floor: float) -> bool:
        """The term lowers its joint's pooled validation RMSE by ``min_gain`` (fraction) and by ``floor`` [N m], and its
        RMSE on each validation recording by ``min_gain``."""
        pairs = list(zip(self.each_before, self.each_after)) or [(self.rmse_before, self.rmse_after)]
        pooled = (self.pooled_before, self.pooled_after) if self.each_before else pairs[0]
        if pooled[0] - pooled[1] < floor:
            return False
        return all(before > 0 and 1.0 - after / before >= min_gain for before, after in [pooled, *pairs])


def _stlsq(matrix, target, threshold: float) -> np.ndarray:
    """Sparse coefficients of ``target ~ matrix @ w`` by pysindy's STLSQ (columns and target already unit RMS)."""
    import pysindy as ps

    optimizer = ps.STLSQ(threshold=threshold, alpha=RIDGE * matrix.shape[0], max_iter=20, unbias=True)
    with warnings.catch_warnings():  # a threshold that removes every feature is a result here, not a problem
        warnings.simplefilter("ignore", UserWarning)
        optimizer.fit(matrix, target[:, None])
    return np.asarray(optimizer.coef_, dtype=float).ravel()


def _validation_rmse(theta_t, residual_t, theta_v, residual_v, support, project, nuisance_v) -> tuple:
    """Least-squares coefficients on ``support`` (training, nuisance projected out) and the validation RMSE."""
    coefficients = np.linalg.lstsq(theta_t[:, support], residual_t, rcond=None)[0]
    nuisance = project[:, -1] - project[:, support] @ coefficients
    return coefficients, float(rms(residual_v - theta_v[:, support] @ coefficients - nuisance_v @ nuisance))


def _prune(theta_t, residual_t, theta_v, residual_v, support, best, project, nuisance_v) -> tuple:
    """Backward elimination after STLSQ: drop the feature whose removal costs least while the validation RMSE stays
    within ``VALIDATION_SLACK`` of ``best`` (STLSQ is greedy, and over a short range of the angle its sines and
    polynomials are nearly collinear, so it keeps stand-ins for each other); ``(support, coefficients)``."""
    support = list(support)
    coefficients, _ = _validation_rmse(theta_t, residual_t, theta_v, residual_v, support, project, nuisance_v)
    while len(support) > 1:
        trials = []
        for k in range(len(support)):
            rest = support[:k] + support[k + 1 :]
            c, after = _validation_rmse(theta_t, residual_t, theta_v, residual_v, rest, project, nuisance_v)
            trials.append((after, rest, c))
        after, rest, c = min(trials, key=lambda x: x[0])
        if after > (1 + VALIDATION_SLACK) * best:
            break
        support, coefficients = rest, c
    return np.asarray(support, dtype=int), coefficients


def fit_sparse_term(
    context_t, context_v, joint: int, residual_t, residual_v, nuisance_t=None, nuisance_v=None, more=()
) -> SparseProposal | None:
    """The sparsest good STLSQ fit of one joint's residual (training) judged on validation, or None.

    Parameters
    ----------
    context_t, context_v : DiagnosisContext
    joint : int
    residual_t, residual_v : arrays (n_samples,)
        The joint's residual of the model with the library's terms [N m].
    nuisance_t, nuisance_v : arrays (n_samples, k), optional
        Columns refitted with the term without being thresholded (the joint's nominal friction, which a hump
        or a position-dependent friction otherwise bends): they are projected out of the features and the
        residual before the sparse regression, and their coefficient change is ``SparseProposal.nuisance``.
    more : sequence of (DiagnosisContext, array, array or None)
        Further validation recordings, each as its context, the joint's residual and its nuisance columns: the fit
        is chosen on every validation recording together, and judged on each (``SparseProposal.each_after``).
    """
    if nuisance_t is None:
        nuisance_t, nuisance_v = np.zeros((context_t.n_samples, 0)), np.zeros((context_v.n_samples, 0))
    held = [(context_v, residual_v, nuisance_v)] + [
        (c, r, np.zeros((c.n_samples, 0)) if n is None else n) for c, r, n in more
    ]
    q_t = context_t.q[:, joint]
    target = residual_t - nuisance_t @ np.linalg.lstsq(nuisance_t, residual_t, rcond=None)[0]
    features = sparse_features(best_lobes(q_t, target, nuisance_t))
    centre = float(np.mean(q_t))
    theta_t = feature_matrix(context_t, joint, features, centre)
    thetas = [feature_matrix(c, joint, features, centre) for c, _, _ in held]
    # every validation recording together: the fit is chosen (and pruned) on their pooled samples
    theta_v, pooled_v, pooled_n = (np.concatenate(x) for x in (thetas, [h[1] for h in held], [h[2] for h in held]))
    # Frisch-Waugh: the sparse fit on what the nuisance columns cannot explain
    project = np.linalg.lstsq(nuisance_t, np.column_stack([theta_t, residual_t]), rcond=None)[0]
    theta_t_full, residual_t_full = theta_t, residual_t
    theta_t = theta_t - nuisance_t @ project[:, :-1]
    residual_t = residual_t - nuisance_t @ project[:, -1]
    scale = rms(theta_t)
    usable = scale > 1e-9 * max(float(np.max(scale)), 1e-300)
    r_scale = float(rms(residual_t))
    if r_scale <= 0 or float(rms(residual_v)) <= 0:
        return None
    fits = []
    for threshold in THRESHOLDS:
        w = np.zeros(len(features))
        w[usable] = _stlsq(theta_t[:, usable] / scale[usable], residual_t / r_scale, threshold)
        support = np.flatnonzero(w)
        if support.size == 0 or support.size > MAX_FEATURES:
            continue
        coefficients = w[support] * r_scale / scale[support]
        nuisance = project[:, -1] - project[:, support] @ coefficients
        after = float(rms(pooled_v - theta_v[:, support] @ coefficients - pooled_n @ nuisance))
        fits.append((after, support.size, support, coefficients))
    if not fits:
        return None
    best = min(f[0] for f in fits)
    _, _, support, _ = min((f for f in fits if f[0] <= (1 + VALIDATION_SLACK) * best), key=lambda f: f[1])
    support, coefficients = _prune(theta_t, residual_t, theta_v, pooled_v, support, best, project, pooled_n)
    term = SparseTerm(joint=joint, features=tuple(features[k] for k in support), centre=centre)
    nuisance = project[:, -1] - project[:, support] @ coefficients
    pred_t = theta_t_full[:, support] @ coefficients + nuisance_t @ nuisance
    predictions = [theta[:, support] @ coefficients + n @ nuisance for theta, (_, _, n) in zip(thetas, held)]
    each_before = tuple(float(rms(r)) for _, r, _ in held)
    each_after = tuple(float(rms(r - p)) for (_, r, _), p in zip(held, predictions))
    residual_t = residual_t_full
    n = residual_t.size
    sse0, sse1 = float(residual_t @ residual_t), float(np.sum((residual_t - pred_t) ** 2))
    return SparseProposal(
        term=term,
        coefficients=coefficients,
        prediction_t=pred_t,
        prediction_v=predictions[0],
        rmse_before=each_before[0],
        rmse_after=each_after[0],
        ljung_box_p=ljung_box(residual_v)[1],
        state_correlation=_state_correlation(context_v, joint, residual_v),
        delta_bic=float(n * np.log(max(sse1, 1e-300) / max(sse0, 1e-300)) + support.size * np.log(n)),
        nuisance=nuisance,
        each_before=each_before,
        each_after=each_after,
        pooled_before=float(rms(pooled_v)),
        pooled_after=float(rms(pooled_v - np.concatenate(predictions))),
    )


def _state_correlation(context, joint: int, residual) -> float:
    """The largest correlation (lag 0) of ``residual`` with the joint's angle, speed, acceleration and speed sign."""
    signals = (context.q[:, joint], context.qd[:, joint], context.qdd[:, joint], np.sign(context.qd[:, joint]))
    return float(max(abs(cross_correlation(residual, s, max_lag=0)[0]) for s in signals))


def propose_sparse_terms(
    context_t, context_v, residual_t, residual_v, min_gain: float, nuisance=None, more=()
) -> tuple:
    """One ``SparseProposal`` per joint whose term holds (``SparseProposal.holds``), best first.

    Parameters
    ----------
    context_t, context_v : DiagnosisContext
    residual_t, residual_v : arrays (n_samples, n_dof)
        Residual of the model with the library's kept terms on training and validation [N m].
    min_gain : float
        Validation RMSE reduction a joint must show, pooled and on each validation recording, for its term to be kept
        (and at least ``MIN_TORQUE_FRACTION`` of the joint's torque RMS in N m pooled, as the library's terms must
        clear a floor, see ``selection``).
    nuisance : list of (array, array), optional
        Per joint, its training and validation columns refitted with the term (``fit_sparse_term``).
    more : sequence of (DiagnosisContext, array (n_samples, n_dof), list of arrays or None)
        Further validation recordings: each one's context, residual and per-joint nuisance columns.
    """
    out = []
    for j in range(context_t.n_dof):
        extra = (None, None) if nuisance is None else nuisance[j]
        others = [(c, r[:, j], None if n is None else n[j]) for c, r, n in more]
        proposal = fit_sparse_term(context_t, context_v, j, residual_t[:, j], residual_v[:, j], *extra, more=others)
        if proposal is None:
            continue
        logger.info(
            f"diagnose: sparse term on joint {j + 1}: {len(proposal.term.features)} features, validation RMSE "
            + ", ".join(f"{b:.4g} -> {a:.4g}" for b, a in zip(proposal.each_before, proposal.each_after))
            + " N m"
        )
        # a relative gain on a residual already near the noise is not worth a term: an absolute floor too
        if proposal.holds(min_gain, MIN_TORQUE_FRACTION * float(rms(context_t.tau[:, j]))):
            out.append(proposal)
    return tuple(sorted(out, key=lambda p: -p.validation_gain))
