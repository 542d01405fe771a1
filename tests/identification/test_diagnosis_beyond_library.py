"""Beyond the library (issue 16 item 7): sparse symbolic terms of a structured residual, and their CasADi form."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from identification.data.preprocessing import preprocess
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.context import build_context
from identification.diagnosis.sparse_terms import SparseFeature, SparseTerm, fit_sparse_term, sparse_features
from identification.virtual import effects as xp
from psdm_casadi.errors import ParameterError
from tests.identification.diagnosis_data import recording_pair


@pytest.fixture(scope="module")
def contexts(denso, denso_model):
    """Training and validation contexts of a clean Denso pair, with the smooth velocity sign (``tanh``) that the
    CasADi form uses too."""
    train, val = recording_pair(denso, [], seed=11, train_s=8.0, val_s=5.0)
    return tuple(build_context(denso, denso_model, preprocess(rec), filtered_friction=False) for rec in (train, val))


def _features(*names):
    library = {f.name(1): f for f in sparse_features()}
    return tuple(library[name] for name in names)


def test_sparse_term_casadi_expression_equals_its_columns(contexts):
    ctx = contexts[0]
    features = _features("sin(2q2) sign(qd2)", "sign(qd2) exp(-(qd2/0.1)^2)", "(dq2)^2", "qd2|qd2|", "qdd2")
    term = SparseTerm(joint=1, features=features, centre=0.2)
    c = np.array([1.5, -2.0, 0.7, 0.3, 0.05])
    columns = term.columns(ctx) @ c  # (n_samples, n_dof)
    q, qd, qdd = (ca.SX.sym(name, 6) for name in ("q", "qd", "qdd"))
    f = ca.Function("f", [q, qd, qdd], [term.casadi_expression(q, qd, qdd, ca.SX.sym("t"), q, c)])
    rows = np.arange(0, ctx.n_samples, 97)
    expected = np.array([np.array(f(ctx.q[k], ctx.qd[k], ctx.qdd[k])).ravel() for k in rows])
    # the reference written out independently: the features' formulas in numpy
    qj, vj, aj = ctx.q[rows, 1], ctx.qd[rows, 1], ctx.qdd[rows, 1]
    s = np.tanh(vj / 0.02)
    by_hand = 1.5 * np.sin(2 * qj) * s - 2.0 * s * np.exp(-((vj / 0.1) ** 2)) + 0.7 * (qj - 0.2) ** 2
    by_hand += 0.3 * vj * np.abs(vj) + 0.05 * aj
    np.testing.assert_allclose(expected[:, 1], by_hand, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(columns[rows], expected, rtol=1e-9, atol=1e-9)
    assert np.all(expected[:, [0, 2, 3, 4, 5]] == 0.0)
    assert term.label == "unnamed_effect[j2]" and "sin(2q2) sign(qd2)" in term.formula(c)


def test_stlsq_recovers_a_sparse_law_from_a_synthetic_residual(contexts):
    ctx_t, ctx_v = contexts
    truth = _features("sin(2q2) sign(qd2)", "sign(qd2) exp(-(qd2/0.2)^2)")
    coefficients = np.array([3.0, -2.0])
    rng = np.random.default_rng(0)

    def law(ctx):
        return SparseTerm(joint=1, features=truth).columns(ctx)[:, 1, :] @ coefficients

    r_t = law(ctx_t) + 0.05 * rng.standard_normal(ctx_t.n_samples)
    r_v = law(ctx_v) + 0.05 * rng.standard_normal(ctx_v.n_samples)
    proposal = fit_sparse_term(ctx_t, ctx_v, 1, r_t, r_v)
    found = dict(zip(proposal.term.features, proposal.coefficients))
    # the hump is told apart exactly; over the recording's short range of q2 the sines of q2, 2 q2 and 3 q2 are
    # nearly collinear, so the position-dependent part may be written with other harmonics: judged by its values
    assert len(found) <= 3 and found[truth[1]] == pytest.approx(-2.0, rel=0.05)
    fitted_v = proposal.term.columns(ctx_v)[:, 1, :] @ proposal.coefficients
    assert np.sqrt(np.mean((fitted_v - law(ctx_v)) ** 2)) < 0.05 * np.sqrt(np.mean(law(ctx_v) ** 2))
    assert proposal.validation_gain > 0.9


def test_pure_noise_gives_no_structured_term(contexts):
    ctx_t, ctx_v = contexts
    rng = np.random.default_rng(1)
    proposal = fit_sparse_term(
        ctx_t, ctx_v, 2, 0.1 * rng.standard_normal(ctx_t.n_samples), 0.1 * rng.standard_normal(ctx_v.n_samples)
    )
    assert proposal is None or proposal.validation_gain < 0.05


def test_sparse_term_needs_features():
    with pytest.raises(ParameterError, match="SparseTerm.features"):
        SparseTerm(joint=0, features=())
    with pytest.raises(ParameterError, match="sparse_min_gain"):
        DiagnosisOptions(sparse_min_gain=1.5)
    assert SparseFeature(("poly", 2), "sign").name(0) == "(dq1)^2 sign(qd1)"


@pytest.mark.slow
def test_position_dependent_friction_is_reported_as_an_unnamed_effect(denso, denso_model, tmp_path):
    hidden = xp.PositionDependentFriction(joint=1, amplitude=3.0, harmonic=2.0, phase=0.4)
    train, val = recording_pair(denso, [hidden], seed=5, train_s=12.0, val_s=6.0)
    report = diagnose(denso, train, val, DiagnosisOptions(), model=denso_model)
    unnamed = [f for f in report.findings if f.effect == "unnamed_effect"]
    assert unnamed and unnamed[0].joints == (1,)
    assert report.rmse_after[1] < 0.5 * report.rmse_before[1]
    assert unnamed[0].validation_gain == pytest.approx(1 - unnamed[0].rmse_after[1] / unnamed[0].rmse_before[1])
    assert any("sign(qd2)" in name for name in unnamed[0].feature_names) and "tau2 +=" in unnamed[0].explanation
    # the augmented model carries the term: its torque equals the hidden law where the term acts (moving joint 2)
    term, c = report.augmented.terms[-1], report.augmented.coefficients[-1]
    from identification.diagnosis.unnamed_plot import unnamed_torque

    torque = unnamed_torque(report, term, c)
    moving = np.abs(report.validation_qd[:, 1]) > 0.1
    law = 3.0 * np.sin(2.0 * report.validation_q[:, 1] + 0.4) * np.sign(report.validation_qd[:, 1])
    error = torque[moving] - law[moving]
    # up to a Coulomb part, which the joint's nominal friction coefficient takes (refitted with the term)
    coulomb = np.column_stack([np.ones(error.size), np.sign(report.validation_qd[moving, 1])])
    error -= coulomb @ np.linalg.lstsq(coulomb, error, rcond=None)[0]
    assert np.sqrt(np.mean(error**2)) < 0.25 * np.sqrt(np.mean(law[moving] ** 2))
    paths = report.save(tmp_path)
    assert paths["unnamed_effects"].exists() and "unnamed_effect" in paths["markdown"].read_text()
