"""Contract tests over every candidate term of the diagnosis, and the library composition."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from identification.diagnosis import (ALL_TERMS, CandidateLibrary, SpringTerm, TorqueOffsetTerm, TorqueRippleTerm,
                                      default_library)
from identification.diagnosis.context import build_context
from identification.experiments import sine_reference
from identification.preprocessing import PreprocessOptions, preprocess
from identification.synthetic import SimulationOptions, simulate_recording
from psdm_casadi.errors import ParameterError


@pytest.fixture(scope="module")
def context(request):
    denso = request.getfixturevalue("denso")
    model = request.getfixturevalue("denso_model")
    rng = np.random.default_rng(3)
    rec, _ = simulate_recording(denso, sine_reference(denso, duration=3.0, rng=rng),
                                SimulationOptions(record_tau=True, record_current=False), rng)
    return build_context(denso, model, preprocess(rec, PreprocessOptions(cutoff_hz=15.0)), rate_hz=100.0)


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
    """Where a term has a CasADi expression, it equals columns @ coefficients (except load friction, which uses the model torque)."""
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
    for k in (0, context.n_samples // 2, context.n_samples - 1):
        got = np.array(f(context.q[k], context.qd[k], context.qdd[k], context.t[k], context.tau[k])).ravel()
        np.testing.assert_allclose(got, cols[k] @ coefficients, rtol=1e-9, atol=1e-9)


def test_library_composes_and_expands():
    lib = SpringTerm() + TorqueOffsetTerm() + TorqueRippleTerm(harmonics=(3, 6))
    assert isinstance(lib, CandidateLibrary)
    assert lib.keys == ("spring", "torque_offset", "torque_ripple")
    labels = [t.label for t in lib.expand(2)]
    assert labels == ["spring[j1]", "spring[j2]", "torque_offset[j1]", "torque_offset[j2]",
                      "torque_ripple[j1,h=3]", "torque_ripple[j1,h=6]", "torque_ripple[j2,h=3]", "torque_ripple[j2,h=6]"]
    assert len(set(t.label for t in default_library().expand(6))) == len(default_library().expand(6))


def test_required_keys_present():
    keys = set(default_library().keys)
    assert {"spring", "payload", "coulomb_asymmetry", "load_dependent_friction", "friction_drift", "torque_ripple",
            "backlash", "joint_elasticity", "delay", "torque_offset", "rotor_inertia", "gravity_tilt",
            "coupling"} <= keys


def test_bad_joint_and_library_errors():
    with pytest.raises(ParameterError, match="SpringTerm.joint"):
        SpringTerm(joint=9).expand(6)
    with pytest.raises(ParameterError, match="CandidateLibrary.terms"):
        CandidateLibrary(("spring",))
    with pytest.raises(ParameterError, match="joint is None"):
        SpringTerm().feature_names()
