"""One definition of a finding's torque: every torque-type candidate term is stored as a JSON spec and rebuilt.

``term_from_spec(json(term.spec()))`` must give the same columns and the same CasADi expression (reference: the
original term, and for the spring and the unnamed term their formulas written out here); the calibrated model's
findings (``FindingTerm`` with a spec) and the four-step ``IdentifiedModel`` carry a polynomial spring and an
unnamed term through save and load.
"""

import json

import casadi as ca
import numpy as np
import pytest

from identification.calibration.extra_terms import ExtraTerms, TermContext
from identification.calibration.findings import FindingTerm, term_values
from identification.data.preprocessing import preprocess
from identification.diagnosis.candidates import (
    CoulombAsymmetryTerm,
    CouplingTerm,
    FrictionShapeTerm,
    LoadDependentFrictionTerm,
    RotorInertiaTerm,
    SpringTerm,
    TorqueOffsetTerm,
    TorqueRippleTerm,
)
from identification.diagnosis.context import build_context
from identification.diagnosis.sparse_terms import SparseTerm, sparse_features
from identification.diagnosis.term_spec import term_from_spec
from psdm_casadi.errors import ModelFileError, ParameterError
from tests.identification.diagnosis_data import recording_pair

N_DOF = 6


def _sparse(joint=2):
    library = {f.name(joint): f for f in sparse_features()}
    names = (f"sin(2q{joint + 1}) sign(qd{joint + 1})", f"(dq{joint + 1})^3", f"qd{joint + 1}|qd{joint + 1}|")
    return SparseTerm(joint=joint, features=tuple(library[n] for n in names), centre=0.3)


#: a counterbalance's odd law of order 5 about its neutral angle
ODD_LAW = SpringTerm(joint=1, order=5, centre=-0.05, q_range=(-0.3, 0.8), odd=True)
TORQUE_TERMS = (
    SpringTerm(joint=1),
    SpringTerm(joint=1, order=2, centre=0.2, q_range=(-1.0, 1.4)),
    SpringTerm(joint=3, order=3, centre=-0.1, q_range=(-2.0, 1.8)),
    SpringTerm(joint=3, order=5, centre=0.3, q_range=(-0.2, 0.8)),
    ODD_LAW,
    TorqueOffsetTerm(joint=5),
    TorqueRippleTerm(joint=4, harmonic=6),
    CouplingTerm(joint=3, source=0),
    CoulombAsymmetryTerm(joint=2),
    RotorInertiaTerm(joint=2),
    LoadDependentFrictionTerm(joint=1),
    _sparse(),
    FrictionShapeTerm(joint=4, shape="stribeck", scale=0.08, velocity=0.01),
    FrictionShapeTerm(joint=0, shape="smooth_coulomb", scale=0.3),
)


@pytest.fixture(scope="module")
def context(denso, denso_model):
    train, _ = recording_pair(denso, [], seed=5, train_s=3.0, val_s=1.0)
    return build_context(denso, denso_model, preprocess(train), filtered_friction=False)


def _rebuilt(term):
    return term_from_spec(json.loads(json.dumps(term.spec())))


@pytest.mark.parametrize("term", TORQUE_TERMS, ids=lambda t: t.label)
def test_every_torque_term_is_rebuilt_from_its_json_spec(term, context):
    back = _rebuilt(term)
    assert back == term and back.label == term.label and back.feature_names() == term.feature_names()
    np.testing.assert_allclose(back.columns(context), term.columns(context), rtol=0, atol=1e-12)
    n = len(term.feature_names())
    c = np.random.default_rng(3).normal(size=n)
    q, qd, qdd, tau = (ca.SX.sym(name, N_DOF) for name in ("q", "qd", "qdd", "tau"))
    t = ca.SX.sym("t")
    expressions = [x.casadi_expression(q, qd, qdd, t, tau, c) for x in (term, back)]
    if expressions[0] is None:  # a change of the base parameters (rotor inertia), no torque expression of its own
        assert expressions[1] is None
        return
    functions = [ca.Function("f", [q, qd, qdd, t, tau], [e]) for e in expressions]
    x = np.random.default_rng(4).uniform(-1, 1, (4, N_DOF))
    a, b = (np.array(f(x[0], x[1], x[2], 0.1, 5 * x[3])).ravel() for f in functions)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    assert np.any(a != 0.0)


def test_polynomial_spring_and_unnamed_term_columns_are_their_formulas(context):
    """Reference: the laws written out here, on the rebuilt terms (one definition for the fit and the C code)."""
    spring = _rebuilt(SpringTerm(joint=3, order=3, centre=-0.1, q_range=(-2.0, 1.8)))
    k = np.array([2.0, -0.5, 0.25, 0.7])
    x = context.q[:, 3] + 0.1
    np.testing.assert_allclose(spring.columns(context)[:, 3] @ k, 2 * x - 0.5 * x**2 + 0.25 * x**3 + 0.7, atol=1e-12)
    law = _rebuilt(ODD_LAW)
    x = context.q[:, 1] + 0.05  # about the neutral angle -0.05: odd powers only
    assert law.feature_names() == ["k1_q2", "k3_q2", "k5_q2", "c_2"] and law.label == "spring[j2,order=5,odd]"
    np.testing.assert_allclose(law.columns(context)[:, 1] @ k, 2 * x - 0.5 * x**3 + 0.25 * x**5 + 0.7, atol=1e-12)
    sparse = _rebuilt(_sparse())
    c = np.array([1.2, -0.4, 0.05])
    state = TermContext(context.t, context.q, context.qd, context.qdd)  # the calibration's context: smooth sign
    q, v = context.q[:, 2], context.qd[:, 2]
    law = 1.2 * np.sin(2 * q) * np.tanh(v / 0.02) - 0.4 * (q - 0.3) ** 3 + 0.05 * v * np.abs(v)
    np.testing.assert_allclose(sparse.columns(state)[:, 2] @ c, law, atol=1e-12)


@pytest.mark.parametrize(
    "candidate",
    [TORQUE_TERMS[2], ODD_LAW, TORQUE_TERMS[11], *TORQUE_TERMS[-2:]],
    ids=["spring3", "odd5", "unnamed", "stribeck", "smooth"],
)
def test_finding_term_with_a_spec_evaluates_its_candidate_in_numbers_and_casadi(candidate, context):
    entry = FindingTerm(effect=candidate.key, joint=candidate.joint, spec=candidate.spec()).to_dict()
    term = FindingTerm.from_dict(json.loads(json.dumps(entry)))
    assert term.label == candidate.label and len(term.feature_names()) == len(candidate.feature_names())
    assert all(name.endswith(str(candidate.joint + 1)) for name in term.feature_names())  # the fit reads the joint
    rows = slice(0, None, 53)
    q, qd, qdd = context.q[rows], context.qd[rows], context.qdd[rows]
    numeric = np.column_stack(term_values(term, q, qd, qdd))
    symbols = [ca.SX.sym(name, N_DOF) for name in ("q", "qd", "qdd")]
    f = ca.Function("f", symbols, [ca.vertcat(*term_values(term, *symbols))])
    symbolic = np.array(f.map(q.shape[0])(q.T, qd.T, qdd.T)).T
    np.testing.assert_allclose(symbolic, numeric, rtol=0, atol=1e-12)
    expected = candidate.columns(TermContext(context.t[rows], q, qd, qdd))[:, candidate.joint, :]
    np.testing.assert_allclose(numeric, expected, rtol=0, atol=1e-12)


def test_friction_shape_columns_are_their_formulas(context):
    """Reference: the Stribeck peak and the smooth Coulomb friction written out here, as a torque of the state (a model
    file's finding, the exported code: the smooth sign ``tanh(qd / velocity)``); on the diagnosis' context the
    Stribeck peak takes the recorded sign (``friction_sign``) and agrees away from the reversals."""
    state = TermContext(context.t, context.q, context.qd, context.qdd)
    v4, v1 = context.qd[:, 4], context.qd[:, 0]
    stribeck, smooth = (_rebuilt(t) for t in TORQUE_TERMS[-2:])
    law = np.exp(-((v4 / 0.08) ** 2)) * np.tanh(v4 / 0.01)
    np.testing.assert_allclose(stribeck.columns(state)[:, 4, 0], law, atol=1e-12)
    np.testing.assert_allclose(smooth.columns(state)[:, 0, 0], np.tanh(v1 / 0.3), atol=1e-12)
    moving = np.abs(v4) > 0.15
    np.testing.assert_allclose(stribeck.columns(context)[moving, 4, 0], law[moving], atol=1e-5)
    assert np.sum(moving) > 50
    assert np.all(stribeck.columns(state)[:, [0, 1, 2, 3, 5], :] == 0.0)


def test_friction_shapes_refuse_a_dip_and_an_unknown_shape():
    stribeck = TORQUE_TERMS[-2]
    assert "not a peak" in stribeck.implausibility([-0.2])
    assert stribeck.implausibility([0.2]) is None
    # a smooth Coulomb friction below zero falls with the speed: a Stribeck peak's shape, not a level reached smoothly
    assert "Stribeck peak's shape" in TORQUE_TERMS[-1].implausibility([-0.2])
    assert TORQUE_TERMS[-1].implausibility([0.2]) is None
    with pytest.raises(ParameterError, match="shape must be one of"):
        FrictionShapeTerm(joint=1, shape="lugre")
    term = FindingTerm("friction_shape", 4, spec=stribeck.spec()).to_dict()
    entry = {"label": "friction_shape[j5,stribeck]", "effect": "friction_shape", "kind": "torque", "joints": [5],
             "coefficients": [-0.1], "term": term}  # fmt: skip
    from identification.calibration.finding_value import implausibility

    assert "Stribeck peak" in implausibility(entry)
    assert FindingTerm("friction_shape", 4, spec=stribeck.spec()).lower_bounds() == [0.0]
    assert FindingTerm("friction_shape", 0, spec=TORQUE_TERMS[-1].spec()).lower_bounds() == [0.0]
    smooth = {**entry, "label": "friction_shape[j1,smooth_coulomb]", "joints": [1],
              "term": FindingTerm("friction_shape", 0, spec=TORQUE_TERMS[-1].spec()).to_dict()}  # fmt: skip
    assert "Stribeck peak's shape" in implausibility(smooth)
    assert implausibility({**smooth, "coefficients": [0.1]}) is None
    # pre-sliding is a state of the friction, not a torque of (q, qd, qdd): reported with its route, not applied
    from identification.calibration.findings import finding_kind
    from identification.diagnosis.candidates import PreslidingTerm

    assert finding_kind("friction_shape") == "torque" and finding_kind("presliding") == "reported"
    presliding = PreslidingTerm(joint=2, scale=1e-3)
    assert presliding.casadi_expression(None, None, None, None, None, [1.0]) is None
    assert "not a" not in (presliding.implausibility([0.3]) or "") and "<= 0" in presliding.implausibility([-0.3])


def test_a_linear_spring_finding_of_a_file_without_spec_still_loads():
    """Version 2 files written before specs: ``{"effect": "spring", "joint": j}`` keeps its columns [q, 1]."""
    term = FindingTerm.from_dict({"effect": "spring", "joint": 2, "velocity": 0.05})
    q = np.random.default_rng(0).uniform(-1, 1, (7, N_DOF))
    values = term_values(term, q, q, q)
    np.testing.assert_allclose(values[0], q[:, 1], atol=0)
    np.testing.assert_allclose(values[1], 1.0, atol=0)
    assert term.feature_names() == ["spring_k_2", "spring_c_2"]


def test_a_polynomial_spring_of_a_file_before_odd_laws_still_loads(context):
    """A spec written before the odd law (no ``odd``, ``max_order`` 3) is the polynomial of every power it was."""
    old = {"key": "spring", "joint": 1, "order": 3, "max_order": 3, "centre": 0.2, "q_range": [-1.0, 1.4],
           "lever_law": True}  # fmt: skip
    term = term_from_spec(old)
    assert not term.odd and term.label == "spring[j2,order=3]"
    x = context.q[:, 1] - 0.2
    np.testing.assert_allclose(term.columns(context)[:, 1, :3], np.column_stack([x, x**2, x**3]), atol=1e-12)


def test_bad_specs_are_refused_with_the_spec_named():
    with pytest.raises(ParameterError, match="'key' one of"):
        term_from_spec({"key": "gravity_flip", "joint": 0})
    with pytest.raises(ParameterError, match="unknown fields \\['stiffness'\\]"):
        term_from_spec({"key": "spring", "joint": 0, "stiffness": 3.0})
    with pytest.raises(ParameterError, match="integer 1..5"):
        term_from_spec({"key": "spring", "joint": 0, "order": 7})
    with pytest.raises(ParameterError, match="odd law must be 3 or 5"):
        term_from_spec({"key": "spring", "joint": 0, "order": 4, "odd": True})
    with pytest.raises(ModelFileError, match="unnamed effect"):
        FindingTerm(effect="unnamed_effect", joint=1)
    with pytest.raises(ModelFileError, match="not unnamed_effect on joint 3"):
        FindingTerm(effect="unnamed_effect", joint=2, spec=_sparse(joint=1).spec())


def test_identified_model_with_a_polynomial_spring_and_an_unnamed_term_saves_and_loads(denso, denso_model, tmp_path):
    """The four-step route's model file stores the terms by spec; predict_torque and the feed-forward keep them."""
    from identification.calibration.report import StepScore, ValidationReport
    from identification.calibration.result import IdentifiedModel, load_identified
    from identification.friction.models import LuGreParameters

    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    lugre = tuple(LuGreParameters.from_drive(d) for d in denso.drives)
    spring, sparse = SpringTerm(joint=1, order=3, centre=0.2, q_range=(-1.0, 1.4)), _sparse()
    k, c = [3.0, -1.0, 0.5, 0.2], [1.2, -0.4, 0.05]
    extra = ExtraTerms((spring, sparse), k + c, [0.01] * 7)
    report = ValidationReport((StepScore("all", np.zeros(6), np.ones(6)),), tuple(denso.joint_names))
    model = IdentifiedModel(
        denso.name, denso_model, theta, [d.kt for d in denso.drives], lugre, report, None, {}, extra
    )
    back = load_identified(model.save(tmp_path / "m"))
    assert back.extra_terms.labels == ("spring[j2,order=3]", "unnamed_effect[j3]")
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.uniform(-1, 1, size=(3, 5, 6))
    t = np.linspace(0.0, 0.004, 5)
    plain = IdentifiedModel(denso.name, denso_model, theta, back.kt, lugre, report)
    difference = back.predict_torque(t, q, qd, qdd) - plain.predict_torque(t, q, qd, qdd)
    x = q[:, 1] - 0.2
    np.testing.assert_allclose(difference[:, 1], 3 * x - x**2 + 0.5 * x**3 + 0.2, atol=1e-12)
    q3, v3 = q[:, 2], qd[:, 2]
    law = 1.2 * np.sin(2 * q3) * np.tanh(v3 / 0.02) - 0.4 * (q3 - 0.3) ** 3 + 0.05 * v3 * np.abs(v3)
    np.testing.assert_allclose(difference[:, 2], law, atol=1e-12)
    np.testing.assert_allclose(np.delete(difference, [1, 2], axis=1), 0.0, atol=1e-12)
    feedforward = back.build_feedforward(denso)
    got = np.array([feedforward(*x).full().ravel() for x in zip(q, qd, qdd)])
    plain_ff = plain.build_feedforward(denso)
    ref = np.array([plain_ff(*x).full().ravel() for x in zip(q, qd, qdd)])
    np.testing.assert_allclose(got - ref, difference, atol=1e-9)


def test_refitted_findings_with_meaningless_coefficients_are_named():
    from identification.calibration.finding_value import implausibility

    def entry(effect, value, kind="torque"):
        return {"label": f"{effect}[j5]", "effect": effect, "kind": kind, "joints": [5], "coefficients": [value]}

    assert "mu = 1.22" in implausibility(entry("load_dependent_friction", 1.22))
    assert "mu = -0.1" in implausibility(entry("load_dependent_friction", -0.1))
    assert implausibility(entry("load_dependent_friction", 0.2)) is None
    assert "negative" in implausibility(entry("rotor_inertia", -0.01))
    assert implausibility(entry("rotor_inertia", 0.01)) is None
    assert implausibility(entry("load_dependent_friction", None)) is None  # absorbed: nothing to judge
    assert implausibility(entry("delay", -5.0, kind="signal")) is None
