"""CasADi functions against the numpy model, Pinocchio (rnea, crba, aba) and finite differences."""

import casadi as ca
import numpy as np
import pytest

from psdm_casadi.errors import ShapeError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.sampling import random_states
from psdm_casadi.symbolic import build_functions


@pytest.fixture(scope="module")
def nominal(denso, denso_model):
    params = denso.nominal_dynamic_parameters()
    return params, denso_model.base_parameters(params), PinocchioOracle(denso, params)


def test_inverse_dynamics_and_regressor_match_rnea(denso, denso_functions, nominal, rng):
    _, theta, oracle = nominal
    q, qd, qdd = random_states(denso, 20, rng)
    for a, b, c in zip(q, qd, qdd):
        reference = oracle.rnea(a, b, c)
        tau = np.array(denso_functions.inverse_dynamics(a, b, c, theta)).ravel()
        y = np.array(denso_functions.regressor(a, b, c))
        scale = np.abs(reference).max()
        assert np.abs(tau - reference).max() < 1e-12 * scale
        assert np.abs(y @ theta - reference).max() < 1e-12 * scale


def test_regressor_matches_numpy_model(denso, denso_model, denso_functions, rng):
    q, qd, qdd = random_states(denso, 5, rng)
    numeric = denso_model.regressor(q, qd, qdd)
    for k in range(5):
        assert np.allclose(
            np.array(denso_functions.regressor(q[k], qd[k], qdd[k])),
            numeric[k],
            rtol=1e-12,
            atol=1e-12 * np.abs(numeric).max(),
        )
    grav = np.array(denso_functions.gravity_regressor(q[0]))
    assert np.allclose(grav, denso_model.gravity_regressor(q[:1])[0], atol=1e-12)


def test_mass_matrix_bias_gravity_match_crba_and_rnea(denso, denso_functions, nominal, rng):
    _, theta, oracle = nominal
    q, qd, _ = random_states(denso, 10, rng)
    for a, b in zip(q, qd):
        mass = np.array(denso_functions.mass_matrix(a, theta))
        assert np.allclose(mass, oracle.crba(a), rtol=1e-12, atol=1e-12)
        assert np.allclose(mass, mass.T)
        bias = np.array(denso_functions.bias(a, b, theta)).ravel()
        assert np.allclose(bias, oracle.rnea(a, b, np.zeros(6)), atol=1e-11)
        gravity = np.array(denso_functions.gravity(a, theta)).ravel()
        assert np.allclose(gravity, oracle.gravity(a), atol=1e-11)


def test_forward_dynamics_matches_aba_and_inverts_inverse(denso, denso_functions, nominal, rng):
    _, theta, oracle = nominal
    q, qd, qdd = random_states(denso, 10, rng)
    tau = rng.uniform(-20, 20, size=(10, 6))
    for a, b, c, t in zip(q, qd, qdd, tau):
        qdd_ours = np.array(denso_functions.forward_dynamics(a, b, t, theta)).ravel()
        assert np.allclose(qdd_ours, oracle.aba(a, b, t), rtol=1e-9, atol=1e-9)
        round_trip = np.array(
            denso_functions.forward_dynamics(a, b, denso_functions.inverse_dynamics(a, b, c, theta), theta)
        ).ravel()
        assert np.allclose(round_trip, c, atol=1e-9)


def test_jacobian_from_casadi_matches_finite_differences(denso, denso_functions, nominal, rng):
    _, theta, _ = nominal
    q, qd, qdd = (x[0] for x in random_states(denso, 1, rng))
    q_sym = ca.SX.sym("q", 6)
    jac = ca.Function("j", [q_sym], [ca.jacobian(denso_functions.inverse_dynamics(q_sym, qd, qdd, theta), q_sym)])
    analytic = np.array(jac(q))
    step = 1e-6
    numeric = np.column_stack(
        [
            (
                np.array(denso_functions.inverse_dynamics(q + step * e, qd, qdd, theta)).ravel()
                - np.array(denso_functions.inverse_dynamics(q - step * e, qd, qdd, theta)).ravel()
            )
            / (2 * step)
            for e in np.eye(6)
        ]
    )
    assert np.allclose(analytic, numeric, rtol=1e-6, atol=1e-6 * np.abs(numeric).max())


def test_theta_can_be_symbolic(denso_functions, nominal):
    _, theta, _ = nominal
    theta_sym = ca.SX.sym("theta", 32)
    q = np.linspace(-1, 1, 6)
    tau = denso_functions.inverse_dynamics(q, q, q, theta_sym)
    jac = ca.Function("j", [theta_sym], [ca.jacobian(tau, theta_sym)])
    # tau is linear in theta: its Jacobian is the regressor
    assert np.allclose(np.array(jac(theta)), np.array(denso_functions.regressor(q, q, q)), atol=1e-12)


def test_baked_theta_gives_the_same_functions_without_the_input(denso_model, denso_functions, nominal, rng):
    _, theta, _ = nominal
    baked = build_functions(denso_model, theta=theta)
    assert baked.inverse_dynamics.n_in() == 3 and baked.forward_dynamics.name_in() == ["q", "qd", "tau"]
    q, qd, qdd = rng.uniform(-1, 1, size=(3, 6))
    assert np.allclose(
        np.array(baked.inverse_dynamics(q, qd, qdd)),
        np.array(denso_functions.inverse_dynamics(q, qd, qdd, theta)),
        rtol=1e-13,
        atol=1e-12,
    )
    assert baked.inverse_dynamics.n_instructions() < denso_functions.inverse_dynamics.n_instructions()
    with pytest.raises(ShapeError, match="theta must have 32"):
        build_functions(denso_model, theta=np.zeros(3))


def test_functions_are_named(denso_functions):
    assert denso_functions.inverse_dynamics.name_in() == ["q", "qd", "qdd", "theta"]
    assert denso_functions.inverse_dynamics.name_out() == ["tau"]
    assert [f.name() for f in denso_functions.all()] == [
        "regressor",
        "gravity_regressor",
        "inverse_dynamics",
        "mass_matrix",
        "bias",
        "gravity",
        "forward_dynamics",
    ]


def test_prismatic_robot_functions_match_pinocchio(rng):
    from psdm_casadi import derive_psdm
    from psdm_casadi.samples import scara
    from psdm_casadi.sampling import random_standard_parameters

    robot = scara()
    model = derive_psdm(robot)
    params = random_standard_parameters(robot, rng)
    theta = model.base_parameters(params)
    oracle = PinocchioOracle(robot, params)
    functions = build_functions(model)
    q, qd, qdd = random_states(robot, 5, rng)
    for a, b, c in zip(q, qd, qdd):
        assert np.allclose(
            np.array(functions.inverse_dynamics(a, b, c, theta)).ravel(), oracle.rnea(a, b, c), atol=1e-10
        )
        assert np.allclose(np.array(functions.mass_matrix(a, theta)), oracle.crba(a), atol=1e-10)
