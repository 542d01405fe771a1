"""Contract tests over every candidate term of the diagnosis, and the library composition."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis import (
    ALL_TERMS,
    CandidateLibrary,
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
    default_library,
)
from identification.diagnosis.context import build_context
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import ParameterError
from tests.identification.diagnosis_data import sine_context
from trajopt.experiments import sine_experiment


@pytest.fixture(scope="module")
def context(request):
    denso = request.getfixturevalue("denso")
    model = request.getfixturevalue("denso_model")
    return sine_context(denso, model, seed=3)


def _instances(n_dof):
    out = []
    for cls in ALL_TERMS:
        inst = cls().expand(n_dof)
        out.append(inst[0])
    return out


@pytest.mark.parametrize("index", range(len(ALL_TERMS)), ids=[cls.key for cls in ALL_TERMS])
def test_names_match_columns_and_inputs_unmutated(context, index):
    term = _instances(context.n_dof)[index]
    before = {k: np.array(getattr(context, k)) for k in ("q", "qd", "qdd", "tau", "full_tau")}
    cols = term.columns(context)
    again = term.columns(context)
    assert cols.shape == (context.n_samples, context.n_dof, len(term.feature_names()))
    assert np.all(np.isfinite(cols))
    np.testing.assert_array_equal(cols, again)  # deterministic
    for k, v in before.items():
        np.testing.assert_array_equal(getattr(context, k), v)
    params = term.physical_parameters(np.ones(len(term.feature_names())))
    assert params and all(np.isfinite(float(v)) or np.isinf(float(v)) for v in params.values())
    assert term.key and term.explanation and term.signature


@pytest.mark.parametrize("index", range(len(ALL_TERMS)), ids=[cls.key for cls in ALL_TERMS])
def test_casadi_expression_matches_columns(context, index):
    """Where a term has a CasADi expression, it equals columns @ coefficients (except load friction, which uses the
    model torque)."""
    term = _instances(context.n_dof)[index]
    n = context.n_dof
    q, qd, qdd, tau = (ca.SX.sym(s, n) for s in ("q", "qd", "qdd", "tau"))
    t = ca.SX.sym("t")
    coefficients = np.linspace(0.5, 1.5, len(term.feature_names()))
    expr = term.casadi_expression(q, qd, qdd, t, tau, coefficients)
    if expr is None:
        pytest.skip(f"{term.key} is a signal correction or a base-parameter change")
    f = ca.Function("f", [q, qd, qdd, t, tau], [expr])
    cols = term.columns(context)
    samples, rtol, atol = (0, context.n_samples // 2, context.n_samples - 1), 1e-9, 1e-9
    if term.key in FILTERED:
        # the columns hold the sign of the velocity filtered like the recording; away from reversals (the
        # filter has settled) it is the expression's smooth sign
        samples, rtol, atol = _settled_samples(context, term.joint), 1e-3, 1e-4
        assert len(samples) >= 3
    for k in samples:
        got = np.array(f(context.q[k], context.qd[k], context.qdd[k], context.t[k], context.tau[k])).ravel()
        np.testing.assert_allclose(got, cols[k] @ coefficients, rtol=rtol, atol=atol)


FILTERED = ("coulomb_asymmetry", "load_dependent_friction", "friction_drift")


def _settled_samples(context, joint, window_s=0.3):
    """Samples whose velocity keeps one sign, above 0.2 rad/s, for ``window_s`` either side (at most 5)."""
    sign = np.sign(context.full_qd[:, joint]) * (np.abs(context.full_qd[:, joint]) > 0.2)
    half = int(round(window_s / float(np.median(np.diff(context.full_t)))))
    out = [
        k
        for k, i in enumerate(context.keep)
        if i - half >= 0 and i + half < sign.size and abs(sign[i - half : i + half + 1].sum()) == 2 * half + 1
    ]
    return out[:: max(1, len(out) // 5)][:5]


def test_friction_columns_are_filtered_like_the_recording(context):
    """The recorded torque holds the filtered friction step, not a sharp one at the filtered velocity's zero: the
    friction-like columns are the full-rate sign filtered like the recording, which differs from the sign of the
    filtered velocity around reversals."""
    from identification.data.preprocessing import zero_phase_filter
    from identification.diagnosis import CoulombAsymmetryTerm

    j = 1
    col = CoulombAsymmetryTerm(joint=j).columns(context)[:, j, 0]
    expected = zero_phase_filter(
        0.5 * (1.0 + np.sign(context.full_qd[:, j])), 1.0 / float(np.median(np.diff(context.full_t))), 15.0, 8
    )[context.keep]
    np.testing.assert_allclose(col, expected, atol=1e-12)
    sharp = 0.5 * (1.0 + np.sign(context.qd[:, j]))
    assert np.max(np.abs(col - sharp)) > 0.2  # a reversal is smeared over the filter's response


def test_library_composes_and_expands():
    lib = SpringTerm() + TorqueOffsetTerm() + TorqueRippleTerm(harmonics=(3, 6))
    assert isinstance(lib, CandidateLibrary)
    assert lib.keys == ("spring", "torque_offset", "torque_ripple")
    labels = [t.label for t in lib.expand(2)]
    assert labels == [
        "spring[j1]",
        "spring[j2]",
        "torque_offset[j1]",
        "torque_offset[j2]",
        "torque_ripple[j1,h=3]",
        "torque_ripple[j1,h=6]",
        "torque_ripple[j2,h=3]",
        "torque_ripple[j2,h=6]",
    ]
    assert len(set(t.label for t in default_library().expand(6))) == len(default_library().expand(6))


def test_required_keys_present():
    keys = set(default_library().keys)
    assert {
        "spring",
        "payload",
        "coulomb_asymmetry",
        "load_dependent_friction",
        "friction_drift",
        "torque_ripple",
        "backlash",
        "joint_elasticity",
        "delay",
        "torque_offset",
        "rotor_inertia",
        "gravity_tilt",
        "coupling",
    } <= keys


def test_bad_joint_and_library_errors():
    with pytest.raises(ParameterError, match="SpringTerm.joint"):
        SpringTerm(joint=9).expand(6)
    with pytest.raises(ParameterError, match="CandidateLibrary.terms"):
        CandidateLibrary(("spring",))
    with pytest.raises(ParameterError, match="joint is None"):
        SpringTerm().feature_names()


def test_without_a_friction_prior_the_smooth_sign_of_the_filtered_velocity_is_kept(denso, denso_model):
    """Without drives (no LuGre prior) filtered low-speed columns of a guessed shape would trade against inertia
    at reversals (Staubli TX40: validation RMSE of joint 6 1.6 -> 25 N m), so the smooth-sign columns stay."""
    import dataclasses

    from identification.diagnosis.candidates import SMOOTH_VELOCITY
    from identification.diagnosis.nominal import filtered_friction_columns, friction_columns, friction_shapes

    bare = dataclasses.replace(denso, drives=None)
    rng = np.random.default_rng(3)
    rec, _ = simulate_recording(
        denso,
        sine_experiment(denso, duration=3.0, rng=rng).reference(),
        SimulationOptions(record_tau=True, record_current=False),
        rng,
    )
    ctx = build_context(bare, denso_model, preprocess(rec, PreprocessOptions(cutoff_hz=15.0)), rate_hz=100.0)
    assert not ctx.filtered_friction
    vs, dv = friction_shapes(bare)
    np.testing.assert_array_equal(
        filtered_friction_columns(bare, "lugre", ctx), friction_columns("lugre", ctx.qd, vs, dv)
    )
    np.testing.assert_allclose(ctx.friction_sign(2), np.tanh(ctx.qd[:, 2] / SMOOTH_VELOCITY))
