"""Beyond the library (issue 16 item 7): sparse symbolic terms of a structured residual, and their CasADi form."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from identification.data.preprocessing import preprocess
from identification.diagnosis import DiagnosisOptions, diagnose
from identification.diagnosis.context import build_context
from identification.diagnosis.sparse_fit import LOBE_CENTRES, best_lobes, fit_sparse_term
from identification.diagnosis.sparse_terms import SparseFeature, SparseTerm, sparse_features
from identification.diagnosis.term_spec import term_from_spec
from identification.virtual import effects as xp
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import ParameterError
from tests.identification.diagnosis_data import recording_pair
from trajopt.experiments import sine_experiment


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


def _cam_law(ctx, cam):
    """The lobed cam's torque on the grid of a context, from the virtual robot's own law (the reference)."""
    return np.array([cam.torque(0.0, q, q, q)[cam.joint] for q in ctx.q])


def test_a_lobe_of_the_angle_is_found_with_its_centre_and_width(contexts):
    ctx_t, ctx_v = contexts
    lo, hi = np.percentile(ctx_t.q[:, 1], [1.0, 99.0])
    cam = xp.LobedCam(joint=1, amplitude=2.0, q0=lo + 0.45 * (hi - lo), width=0.09 * (hi - lo))
    rng = np.random.default_rng(2)
    r_t = _cam_law(ctx_t, cam) + 0.05 * rng.standard_normal(ctx_t.n_samples)
    r_v = _cam_law(ctx_v, cam) + 0.05 * rng.standard_normal(ctx_v.n_samples)
    # the scan puts the lobe of the true width within one grid step of the true centre
    lobes = dict((round(w / (hi - lo), 3), c) for c, w in best_lobes(ctx_t.q[:, 1], r_t, np.zeros((r_t.size, 0))))
    assert abs(lobes[0.09] - cam.q0) <= (hi - lo) / (LOBE_CENTRES - 1)
    proposal = fit_sparse_term(ctx_t, ctx_v, 1, r_t, r_v)
    assert proposal.validation_gain > 0.9 and len(proposal.coefficients) <= 3
    assert any(f.position[0] == "lobe" for f in proposal.term.features)
    fitted_v = proposal.term.columns(ctx_v)[:, 1, :] @ proposal.coefficients
    law_v = _cam_law(ctx_v, cam)
    assert np.sqrt(np.mean((fitted_v - law_v) ** 2)) < 0.05 * np.sqrt(np.mean(law_v**2))
    # stored by its definition: the spec rebuilds the same term, whose CasADi form is the same torque
    rebuilt = term_from_spec(proposal.term.spec())
    assert rebuilt == proposal.term
    q, qd, qdd = (ca.SX.sym(name, 6) for name in ("q", "qd", "qdd"))
    f = ca.Function(
        "f", [q, qd, qdd], [rebuilt.casadi_expression(q, qd, qdd, ca.SX.sym("t"), q, proposal.coefficients)]
    )
    rows = np.arange(0, ctx_v.n_samples, 53)
    exported = np.array([float(f(ctx_v.q[k], ctx_v.qd[k], ctx_v.qdd[k])[1]) for k in rows])
    np.testing.assert_allclose(exported, fitted_v[rows], rtol=1e-9, atol=1e-9)


def test_lobed_cam_law_and_its_checks():
    cam = xp.LobedCam(joint=0, amplitude=3.0, q0=0.2, width=0.3)
    q = np.array([[0.5], [-0.1], [0.2], [2.0]])
    torque = [cam.torque(0.0, x, x, x)[0] for x in q]
    # largest (the amplitude) one width from the centre, restoring about it, and fading far from it
    assert torque[0] == pytest.approx(3.0) and torque[1] == pytest.approx(-3.0) and torque[2] == 0.0
    assert abs(torque[3]) < 1e-3
    with pytest.raises(ParameterError, match="LobedCam.width"):
        xp.LobedCam(joint=0, amplitude=1.0, width=0.0).validate(6)
    with pytest.raises(ParameterError, match="lobe_width"):
        SparseFeature(("lobe", 1), "one")


def _sliced_pair(robot, extras, seed):
    """Training (first 12 s) and validation (last 6 s) parts of one 18 s sine experiment (as the benchmark does)."""
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=18.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    rec, _ = simulate_recording(robot, reference, options, np.random.default_rng(seed + 1), extras=extras)
    return rec.time_slice(-np.inf, 12.0), rec.time_slice(12.0, np.inf)


@pytest.mark.slow
@pytest.mark.parametrize("cv_folds", [4, 0])
def test_a_cam_lobe_is_one_unnamed_effect_not_a_stack_of_ripples(denso, denso_model, tmp_path, cv_folds):
    """Over the recorded range ripples of several harmonics (and an odd spring) fit the lobe on the training recording.
    By default (``cv_folds=4``) they do not hold on its held-out blocks and are reported unstable, never kept; without
    that second opinion (``cv_folds=0``) the selection stacks them (4 shapes, 10 coefficients) and the lobe found beyond
    the library replaces them. Either way the one finding on the joint is the lobe, with the cam's law."""
    q = _sliced_pair(denso, [], seed=3)[0].q[:, 2]
    cam = xp.LobedCam(joint=2, amplitude=5.0, q0=float(np.mean(q) + 0.2 * np.std(q)), width=0.3 * float(np.std(q)))
    train, val = _sliced_pair(denso, [cam], seed=3)
    report = diagnose(denso, train, val, DiagnosisOptions(cv_folds=cv_folds), model=denso_model)
    on_joint = [f for f in report.findings if 2 in f.joints]
    assert [f.effect for f in on_joint] == ["unnamed_effect"]
    replaced = [text for text in report.dropped if "replaced by unnamed_effect[j3]" in text]
    unstable = [u.label for u in report.unstable if u.joints == (2,) and u.effect in ("torque_ripple", "spring")]
    assert (len(replaced), bool(unstable)) == ((0, True) if cv_folds else (1, False)), (replaced, unstable)
    assert report.rmse_after[2] < 0.1 * report.rmse_before[2]
    assert all(f.rmse_after[j] <= f.rmse_before[j] for f in report.findings for j in f.joints)
    assert on_joint[0].validation_gain == pytest.approx(1 - on_joint[0].rmse_after[2] / on_joint[0].rmse_before[2])
    term, c = report.augmented.terms[-1], report.augmented.coefficients[-1]
    from identification.diagnosis.unnamed_plot import unnamed_torque

    torque = unnamed_torque(report, term, c)
    law = np.array([cam.torque(0.0, x, x, x)[2] for x in report.validation_q])
    error = torque - law - np.mean(torque - law)  # up to a constant, which the joint's friction offset may take
    assert np.sqrt(np.mean(error**2)) < 0.05 * np.sqrt(np.mean(law**2))
    paths = report.save(tmp_path)
    markdown = paths["markdown"].read_text()
    assert paths["unnamed_effects"].exists() and all(f"`{label}` is unstable" in markdown for label in unstable)
    assert ("replaced by unnamed_effect[j3]" in markdown) == (not cv_folds)


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


@pytest.mark.slow
def test_a_sparse_term_is_kept_only_if_it_holds_on_every_validation_recording(contexts):
    """Judged on each validation recording (issue 25): a law present in the first validation recording and absent from
    the second is not kept, though it halves the first one's error; present in both, it is kept, judged on each."""
    from identification.diagnosis.sparse_fit import propose_sparse_terms

    ctx_t, ctx_v = contexts
    truth = _features("sign(qd2) exp(-(qd2/0.2)^2)")
    rng = np.random.default_rng(4)

    def residual(ctx, size):
        out = 0.05 * rng.standard_normal((ctx.n_samples, 6))
        out[:, 1] += size * SparseTerm(joint=1, features=truth).columns(ctx)[:, 1, 0]
        return out

    r_t, r_v = residual(ctx_t, 2.0), residual(ctx_v, 2.0)
    held = [(ctx_t, residual(ctx_t, 2.0), None)]  # a second validation recording with the law
    kept = propose_sparse_terms(ctx_t, ctx_v, r_t, r_v, 0.3, more=held)
    assert [p.term.joint for p in kept] == [1]
    p = kept[0]
    assert len(p.each_before) == 2 and all(a < 0.5 * b for a, b in zip(p.each_after, p.each_before))
    assert p.rmse_before == p.each_before[0] and p.pooled_after < 0.5 * p.pooled_before
    without = [(ctx_t, residual(ctx_t, 0.0), None)]  # the second recording has none of it: noise only
    alone = propose_sparse_terms(ctx_t, ctx_v, r_t, r_v, 0.3)
    assert [p.term.joint for p in alone] == [1]  # the first recording by itself would keep it
    assert propose_sparse_terms(ctx_t, ctx_v, r_t, r_v, 0.3, more=without) == ()


def test_a_lobe_is_no_narrower_than_the_grid_a_standstill_at_one_angle_is_no_lobe():
    """A recording that starts with the arm standing still holds many samples at one angle, where the torque is
    whatever the stuck friction holds (a 210 kg-class arm's joint 3: a 0.0003 rad wide lobe at its home pose, refined
    off the grid without a lower bound, fitted that torque and diagnose --apply wrote it as an unnamed effect). The
    refinement keeps the width at least the grid's smallest; a true lobe of the grid's widths is still found there."""
    from identification.diagnosis.sparse_fit import LOBE_WIDTHS

    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 30.0, 3000)
    q = 0.3 * np.sin(0.7 * t) + 0.2 * np.sin(1.9 * t + 1.0)
    still = t < 2.0
    q[still] = q[~still][0]  # the home pose, held before the motion
    stuck = np.where(still, 40.0, 0.0)  # the stuck friction's torque at standstill
    target = stuck + rng.normal(0.0, 1.0, t.size)
    lo, hi = np.percentile(q, [1.0, 99.0])
    ones = np.ones((t.size, 1))  # the constant, as the joint's friction columns project it out
    lobes = best_lobes(q, target - target.mean(), ones)
    assert lobes and min(w for _, w in lobes) >= LOBE_WIDTHS[0] * (hi - lo) * (1 - 1e-9)
    # a true lobe 0.045 of the range wide, centred at 60 % of it: the scan finds it within one step of its centre
    centre, width = lo + 0.6 * (hi - lo), 0.045 * (hi - lo)
    law = 30.0 * np.exp(-0.5 * ((q - centre) / width) ** 2)
    found = dict((round(w / (hi - lo), 3), c) for c, w in best_lobes(q, law - law.mean(), ones))
    assert abs(found[0.045] - centre) <= (hi - lo) / (LOBE_CENTRES - 1)
