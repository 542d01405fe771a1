"""Beyond the library: a sparse symbolic term for a joint whose residual stays structured after the library's terms.

After the selection and refinement of the named terms (``diagnose``), each joint's training residual is
regressed on a larger function library of the joint's own state (``sparse_features``): products of a
position factor (1, a cubic polynomial in the centred angle, sines and cosines of 1-3 times the angle)
with a velocity factor (1, the velocity sign), low-speed humps ``sign(qd) exp(-(qd/v)^2)`` of several
widths, and ``qd``, ``qd |qd|``, ``qdd``. The sparse solution is found by sequentially thresholded least
squares (pysindy's ``STLSQ``, as in SINDy) on unit-RMS columns, for a few thresholds; the sparsest fit
within ``VALIDATION_SLACK`` of the best validation RMSE is taken. The term is kept only when it lowers the
joint's validation RMSE by ``DiagnosisOptions.sparse_min_gain`` and is reported as an unnamed effect with its
formula (``SparseTerm``), which is a CasADi expression of (q, qd, qdd) like every other term, so the
augmented model carries it.

Why not pysindy's feature libraries: the velocity-sign columns must be filtered like the recording (see
``context``) and every feature must also exist as a CasADi expression; the feature set is therefore
written out here, and pysindy provides the sparse optimiser.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from identification.diagnosis.candidates.base import SMOOTH_VELOCITY, CandidateTerm, joint_columns, joint_expression
from identification.diagnosis.nominal import friction_feature_names
from identification.diagnosis.report import Finding
from identification.diagnosis.residual_tests import cross_correlation, ljung_box
from identification.metrics import rms, rmse
from psdm_casadi.errors import ParameterError

logger = logging.getLogger(__name__)

HUMP_VELOCITIES = (0.05, 0.1, 0.2, 0.4)  # [rad/s] widths of the low-speed hump features
HARMONICS = (1, 2, 3)  # sines and cosines of these multiples of the angle
POLY_DEGREE = 3  # polynomial of the centred angle
THRESHOLDS = (0.03, 0.06, 0.1, 0.2)  # STLSQ thresholds on unit-RMS columns and target (fractions of the residual)
VALIDATION_SLACK = 0.02  # the sparsest fit whose validation RMSE is within this fraction of the best one
MAX_FEATURES = 8  # a fit needing more features than this is not a sparse term
RIDGE = 1e-4  # STLSQ ridge per sample (unit-RMS columns)
MIN_TORQUE_FRACTION = 0.01  # least validation RMSE drop of a kept term, as a fraction of its joint's torque RMS


@dataclass(frozen=True)
class SparseFeature:
    """One feature ``position factor x velocity factor`` of a joint.

    ``position``: ``("one", 0)``, ``("poly", p)`` (``(q - centre)^p``), ``("sin", k)`` or ``("cos", k)`` (of ``k q``);
    ``velocity``: ``"one"``, ``"sign"``, ``"hump"`` (``sign(qd) exp(-(qd/width)^2)``), ``"qd"``, ``"qd_abs"``
    (``qd |qd|``) or ``"qdd"``.
    """

    position: tuple
    velocity: str
    width: float = 0.0

    def name(self, joint: int) -> str:
        q, qd = f"q{joint + 1}", f"qd{joint + 1}"
        kind, order = self.position
        pos = {
            "one": "",
            "poly": f"(dq{joint + 1})" + ("" if order == 1 else f"^{order}"),
            "sin": f"sin({order if order != 1 else ''}{q})",
            "cos": f"cos({order if order != 1 else ''}{q})",
        }[kind]
        vel = {
            "one": "",
            "sign": f"sign({qd})",
            "hump": f"sign({qd}) exp(-({qd}/{self.width:g})^2)",
            "qd": qd,
            "qd_abs": f"{qd}|{qd}|",
            "qdd": f"qdd{joint + 1}",
        }[self.velocity]
        return " ".join(x for x in (pos, vel) if x) or "1"

    def position_factor(self, q, centre: float, sin=np.sin, cos=np.cos):
        kind, order = self.position
        if kind == "one":
            return 1.0 + 0.0 * q
        if kind == "poly":
            return (q - centre) ** order
        return sin(order * q) if kind == "sin" else cos(order * q)


def sparse_features() -> tuple:
    """The function library of one joint (see the module docstring), in a fixed order."""
    positions = [("one", 0)] + [("poly", p) for p in range(1, POLY_DEGREE + 1)]
    positions += [(kind, k) for k in HARMONICS for kind in ("sin", "cos")]
    out = [SparseFeature(p, v) for v in ("one", "sign") for p in positions]
    out += [SparseFeature(("one", 0), "hump", w) for w in HUMP_VELOCITIES]
    out += [SparseFeature(("one", 0), v) for v in ("qd", "qd_abs", "qdd")]
    return tuple(out)


@dataclass(frozen=True)
class SparseTerm(CandidateTerm):
    """An unnamed effect on one joint: a sparse sum of library features with fitted coefficients.

    Parameters
    ----------
    joint : int
    features : tuple of SparseFeature
        The features the sparse regression kept.
    centre : float
        Centre of the angle polynomials [rad] (the training recording's mean angle).
    """

    joint: int | None = None
    features: tuple = ()
    centre: float = 0.0

    key = "unnamed_effect"
    explanation = "a torque outside the library of named effects, found by sparse regression"
    signature = "residual still structured (not white, correlated with the joint's state) after the library's terms"
    per_joint = False

    def __post_init__(self):
        if not self.features:
            raise ParameterError("SparseTerm.features must hold at least one SparseFeature; got none.")

    @property
    def joints(self) -> tuple:
        return (int(self.joint),)

    @property
    def label(self) -> str:
        return f"{self.key}[j{self.joint + 1}]"

    def feature_names(self) -> list:
        return [f.name(self.joint) for f in self.features]

    def columns(self, context) -> np.ndarray:
        """Columns on a ``DiagnosisContext`` (the velocity signs filtered like the recording); on a context of the
        joint state only (``t, q, qd, qdd``, as the calibration's) the smooth sign of ``casadi_expression``."""
        if not hasattr(context, "friction_sign"):
            j = self.joint
            values = self.smooth_values(context.q[:, j], context.qd[:, j], context.qdd[:, j], np)
            return joint_columns(context, j, np.column_stack([v + 0.0 * context.q[:, j] for v in values]))
        return joint_columns(context, self.joint, feature_matrix(context, self.joint, self.features, self.centre))

    def smooth_values(self, qj, qdj, qddj, lib=ca) -> list:
        """Each feature's value on the joint with the smooth sign ``tanh(qd / SMOOTH_VELOCITY)``, for arrays
        (``lib=np``) or CasADi scalars (``lib=ca``): the model-file form of the term."""
        fabs = lib.fabs if lib is ca else np.abs
        s = lib.tanh(qdj / SMOOTH_VELOCITY)
        out = []
        for feature in self.features:
            pos = feature.position_factor(qj, self.centre, lib.sin, lib.cos)
            vel = {
                "one": 1.0,
                "sign": s,
                "hump": s * lib.exp(-((qdj / max(feature.width, 1e-12)) ** 2)),
                "qd": qdj,
                "qd_abs": qdj * fabs(qdj),
                "qdd": qddj,
            }[feature.velocity]
            out.append(pos * vel)
        return out

    def casadi_expression(self, q, qd, qdd, t, tau_nominal, coefficients):
        j = self.joint
        total = 0
        for value, c in zip(self.smooth_values(q[j], qd[j], qdd[j]), coefficients):
            total = total + float(c) * value
        return joint_expression(q.shape[0], j, total)

    def formula(self, coefficients) -> str:
        """``tau_j += c1 f1 + c2 f2 ...`` with the coefficients in SI units (N m per feature unit)."""
        parts = [f"{float(c):+.4g} {name}" for c, name in zip(coefficients, self.feature_names())]
        return (
            f"tau{self.joint + 1} += "
            + " ".join(parts)
            + (f"  (dq{self.joint + 1} = q{self.joint + 1} - {self.centre:.4g} rad)" if self._has_poly else "")
        )

    @property
    def _has_poly(self) -> bool:
        return any(f.position[0] == "poly" for f in self.features)

    def interpret(self, coefficients) -> tuple:
        return self.key, f"{self.explanation}: {self.formula(coefficients)}"


def feature_matrix(context, joint: int, features, centre: float) -> np.ndarray:
    """The features of ``joint`` on a ``DiagnosisContext``'s grid, (n_samples, n_features).

    Velocity-sign features are built at full rate with the exact sign and filtered like the recording
    (``DiagnosisContext.friction_sign``); the full-rate angle is interpolated from the grid."""
    q, qd, qdd = context.q[:, joint], context.qd[:, joint], context.qdd[:, joint]
    full_q = np.interp(context.full_t, context.t, q)
    full_qd = context.full_qd[:, joint]
    out = np.empty((context.n_samples, len(features)))
    for c, f in enumerate(features):
        if f.velocity in ("sign", "hump"):
            factor = f.position_factor(full_q, centre)
            if f.velocity == "hump":
                factor = factor * np.exp(-((full_qd / f.width) ** 2))
            out[:, c] = context.friction_sign(joint, np.broadcast_to(factor, full_qd.shape))
        else:
            vel = {"one": 1.0, "qd": qd, "qd_abs": qd * np.abs(qd), "qdd": qdd}[f.velocity]
            out[:, c] = f.position_factor(q, centre) * vel
    return out


@dataclass(frozen=True, eq=False)
class SparseProposal:
    """A kept unnamed term with its evidence: validation RMSE of its joint before/after, the residual tests."""

    term: SparseTerm
    coefficients: np.ndarray
    prediction_t: np.ndarray  # (n_samples_t,) on the term's joint
    prediction_v: np.ndarray
    rmse_before: float
    rmse_after: float
    ljung_box_p: float
    state_correlation: float
    delta_bic: float
    nuisance: np.ndarray  # change of the nuisance columns' coefficients (the joint's friction)

    @property
    def validation_gain(self) -> float:
        return 1.0 - self.rmse_after / self.rmse_before if self.rmse_before > 0 else 0.0


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
    context_t, context_v, joint: int, residual_t, residual_v, nuisance_t=None, nuisance_v=None
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
    """
    features = sparse_features()
    centre = float(np.mean(context_t.q[:, joint]))
    theta_t = feature_matrix(context_t, joint, features, centre)
    theta_v = feature_matrix(context_v, joint, features, centre)
    if nuisance_t is None:
        nuisance_t, nuisance_v = np.zeros((theta_t.shape[0], 0)), np.zeros((theta_v.shape[0], 0))
    # Frisch-Waugh: the sparse fit on what the nuisance columns cannot explain
    project = np.linalg.lstsq(nuisance_t, np.column_stack([theta_t, residual_t]), rcond=None)[0]
    theta_t_full, residual_t_full = theta_t, residual_t
    theta_t = theta_t - nuisance_t @ project[:, :-1]
    residual_t = residual_t - nuisance_t @ project[:, -1]
    scale = rms(theta_t)
    usable = scale > 1e-9 * max(float(np.max(scale)), 1e-300)
    r_scale = float(rms(residual_t))
    before = float(rms(residual_v))
    if r_scale <= 0 or before <= 0:
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
        after = float(rms(residual_v - theta_v[:, support] @ coefficients - nuisance_v @ nuisance))
        fits.append((after, support.size, support, coefficients))
    if not fits:
        return None
    best = min(f[0] for f in fits)
    _, _, support, _ = min((f for f in fits if f[0] <= (1 + VALIDATION_SLACK) * best), key=lambda f: f[1])
    support, coefficients = _prune(theta_t, residual_t, theta_v, residual_v, support, best, project, nuisance_v)
    term = SparseTerm(joint=joint, features=tuple(features[k] for k in support), centre=centre)
    nuisance = project[:, -1] - project[:, support] @ coefficients
    pred_t = theta_t_full[:, support] @ coefficients + nuisance_t @ nuisance
    pred_v = theta_v[:, support] @ coefficients + nuisance_v @ nuisance
    after = float(rms(residual_v - pred_v))
    residual_t = residual_t_full
    n = residual_t.size
    sse0, sse1 = float(residual_t @ residual_t), float(np.sum((residual_t - pred_t) ** 2))
    correlation = max(
        abs(cross_correlation(residual_v, s, max_lag=0)[0])
        for s in (
            context_v.q[:, joint],
            context_v.qd[:, joint],
            context_v.qdd[:, joint],
            np.sign(context_v.qd[:, joint]),
        )
    )
    return SparseProposal(
        term=term,
        coefficients=coefficients,
        prediction_t=pred_t,
        prediction_v=pred_v,
        rmse_before=before,
        rmse_after=after,
        ljung_box_p=ljung_box(residual_v)[1],
        state_correlation=float(correlation),
        delta_bic=float(n * np.log(max(sse1, 1e-300) / max(sse0, 1e-300)) + support.size * np.log(n)),
        nuisance=nuisance,
    )


def propose_sparse_terms(context_t, context_v, residual_t, residual_v, min_gain: float, nuisance=None) -> tuple:
    """One ``SparseProposal`` per joint whose validation RMSE falls by at least ``min_gain`` (fraction), best first.

    Parameters
    ----------
    context_t, context_v : DiagnosisContext
    residual_t, residual_v : arrays (n_samples, n_dof)
        Residual of the model with the library's kept terms on training and validation [N m].
    min_gain : float
        Validation RMSE reduction a joint must show for its term to be kept (and at least ``MIN_TORQUE_FRACTION`` of
        the joint's torque RMS in N m, as the library's terms must, see ``selection``).
    nuisance : list of (array, array), optional
        Per joint, its training and validation columns refitted with the term (``fit_sparse_term``).
    """
    out = []
    for j in range(context_t.n_dof):
        extra = (None, None) if nuisance is None else nuisance[j]
        proposal = fit_sparse_term(context_t, context_v, j, residual_t[:, j], residual_v[:, j], *extra)
        if proposal is None:
            continue
        logger.info(
            f"diagnose: sparse term on joint {j + 1}: {len(proposal.term.features)} features, validation RMSE "
            f"{proposal.rmse_before:.4g} -> {proposal.rmse_after:.4g} N m"
        )
        # a relative gain on a residual already near the noise is not worth a term: an absolute floor too
        floor = MIN_TORQUE_FRACTION * float(rms(context_t.tau[:, j]))
        if proposal.validation_gain >= min_gain and proposal.rmse_before - proposal.rmse_after >= floor:
            out.append(proposal)
    return tuple(sorted(out, key=lambda p: -p.validation_gain))


def look_beyond_library(problem, final, options) -> tuple:
    """``(final, unnamed)``: the final fit (``diagnose.FinalFit``) of a ``DiagnosisProblem`` with the sparse terms
    of ``propose_sparse_terms`` added (one per joint whose residual they explain, ``DiagnosisOptions.sparse_min_gain``)
    and their ``Finding`` values."""
    if not options.sparse:
        return final, ()
    residual_t, residual_v = problem.y_t - final.prediction_t, problem.y_v - final.prediction_v
    logger.info("diagnose: looking beyond the library (sparse regression of the residual) ...")
    n_friction = _friction_column_count(problem, options)
    nuisance, columns = [], []
    for j in range(problem.ctx_t.n_dof):
        mask = problem.base_t.index[j] < n_friction
        columns.append(problem.base_t.index[j][mask])
        nuisance.append((problem.base_t.values[j][:, mask], problem.base_v.values[j][:, mask]))
    proposals = propose_sparse_terms(
        problem.ctx_t, problem.ctx_v, residual_t, residual_v, options.sparse_min_gain, nuisance
    )
    if not proposals:
        return final, ()
    prediction_t, prediction_v = final.prediction_t.copy(), final.prediction_v.copy()
    before = rmse(problem.y_v, final.prediction_v)
    findings = []
    friction = np.array(final.friction_coefficients, dtype=float)
    for p in proposals:
        j = p.term.joint
        friction[columns[j]] += p.nuisance
        prediction_t[:, j] += p.prediction_t
        prediction_v[:, j] += p.prediction_v
        after = before.copy()
        after[j] = p.rmse_after
        effect, explanation = p.term.interpret(p.coefficients)
        findings.append(
            Finding(
                effect=effect,
                label=p.term.label,
                joints=(j,),
                parameters=dict(zip(p.term.feature_names(), (float(c) for c in p.coefficients))),
                coefficients=tuple(float(c) for c in p.coefficients),
                feature_names=tuple(p.term.feature_names()),
                explanation=f"{explanation}; residual Ljung-Box p = {p.ljung_box_p:.2g}, largest correlation "
                f"with the joint's state {p.state_correlation:.2f}",
                signature=p.term.signature,
                rmse_before=tuple(float(x) for x in before),
                rmse_after=tuple(float(x) for x in after),
                delta_bic=p.delta_bic,
                validation_gain=p.validation_gain,
            )
        )
    final = replace(
        final,
        terms=final.terms + tuple(p.term for p in proposals),
        coefficients=final.coefficients + tuple(np.asarray(p.coefficients) for p in proposals),
        friction_coefficients=friction,
        prediction_t=prediction_t,
        prediction_v=prediction_v,
    )
    return final, tuple(findings)


def _friction_column_count(problem, options) -> int:
    """Number of nominal friction columns (the first columns of ``problem.base_t``; rigid-body ones follow)."""
    n = problem.ctx_t.n_dof
    dynamic = options.friction == "lugre" and problem.ctx_t.drives is not None
    return len(friction_feature_names(options.friction, n)) + (n if dynamic else 0)
