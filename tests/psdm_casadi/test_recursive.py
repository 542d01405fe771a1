"""The recursive form (Newton-Euler on the base-parameter preimage) against the sum form and Pinocchio."""

import dataclasses

import numpy as np
import pytest

from psdm_casadi import derive_psdm, from_urdf
from psdm_casadi.errors import DerivationError, ShapeError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.preimage import standard_preimage
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.samples import kr6, scara
from psdm_casadi.sampling import random_standard_parameters
from psdm_casadi.symbolic import build_functions
from tests.conftest import example_robot_urdf

N_STATES = 20


def _states(rng, n, count=N_STATES):
    return rng.uniform(-np.pi, np.pi, (count, n)), rng.uniform(-2, 2, (count, n)), rng.uniform(-10, 10, (count, n))


def _value(function, *args):
    """The output as an array: vectors flat, matrices 2-D."""
    out = np.array(function(*args), dtype=float)
    return out.ravel() if out.shape[1] == 1 else out


def _rel(a, b):
    return np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)


@pytest.fixture(scope="module")
def denso_recursive(denso, denso_model):
    return build_recursive_functions(denso_model, denso)


def test_preimage_keeps_one_standard_parameter_per_base_parameter(denso, denso_model):
    preimage = standard_preimage(denso_model, denso)
    assert len(preimage.support) == denso_model.n_base
    assert preimage.max_rel_error < 1e-12
    # the reduction removes every mass and z first moment of the Denso (Khalil's grouping)
    assert not any(
        name.startswith(("m", "mz")) and not name.startswith(("mx", "my")) for name in preimage.support_names()
    )
    theta = np.random.default_rng(0).normal(size=denso_model.n_base)
    standard = preimage.standard_parameters(theta)
    assert standard.shape == (denso.n_dof, 11)
    assert np.count_nonzero(standard) <= denso_model.n_base
    with pytest.raises(ShapeError, match="theta must have 32"):
        preimage.standard_parameters(theta[:-1])


def test_preimage_coefficients_near_halves_are_exact(denso, denso_model):
    """Sums of inertias give coefficients 1, -1 and 1/2; the inverse carries roundoff on them
    (1.0000000000000002), which would cost the generated code a product each."""
    matrix = standard_preimage(denso_model, denso).matrix
    halves = np.round(2.0 * matrix) / 2.0
    near = np.abs(matrix - halves) < 1e-12
    assert near.sum() >= denso_model.n_base  # at least one unit coefficient per base parameter
    assert np.array_equal(matrix[near], halves[near])


def test_recursive_equals_sum_form_for_any_theta(denso_model, denso_recursive, rng):
    """Runtime theta: every function agrees with the sum form for arbitrary (non-physical) base parameters."""
    sums = build_functions(denso_model)
    q, qd, qdd = _states(rng, denso_model.n_dof, 10)
    for k in range(10):
        theta = rng.normal(size=denso_model.n_base)
        state = (q[k], qd[k], qdd[k])
        assert _rel(_value(denso_recursive.regressor, *state), _value(sums.regressor, *state)) < 1e-12
        assert _rel(_value(denso_recursive.gravity_regressor, q[k]), _value(sums.gravity_regressor, q[k])) < 1e-12
        assert (
            _rel(_value(denso_recursive.inverse_dynamics, *state, theta), denso_model.inverse_dynamics(*state, theta))
            < 1e-12
        )
        assert _rel(_value(denso_recursive.mass_matrix, q[k], theta), _value(sums.mass_matrix, q[k], theta)) < 1e-12
        assert _rel(_value(denso_recursive.bias, q[k], qd[k], theta), _value(sums.bias, q[k], qd[k], theta)) < 1e-12
        assert _rel(_value(denso_recursive.gravity, q[k], theta), _value(sums.gravity, q[k], theta)) < 1e-12


def test_recursive_matches_pinocchio_with_physical_parameters(denso, denso_model, rng):
    """Baked theta of random physical standard parameters: rnea, crba and aba of Pinocchio."""
    standard = random_standard_parameters(denso, rng)
    oracle = PinocchioOracle(denso, standard)
    fns = build_recursive_functions(denso_model, denso, denso_model.base_parameters(standard))
    assert fns.theta is not None and "theta" not in fns.inverse_dynamics.name_in()
    q, qd, qdd = _states(rng, denso.n_dof)
    tau = rng.uniform(-20, 20, q.shape)
    for k in range(N_STATES):
        assert _rel(_value(fns.inverse_dynamics, q[k], qd[k], qdd[k]), oracle.rnea(q[k], qd[k], qdd[k])) < 1e-12
        assert _rel(_value(fns.mass_matrix, q[k]), oracle.crba(q[k])) < 1e-12
        assert _rel(_value(fns.gravity, q[k]), oracle.gravity(q[k])) < 1e-12
        assert _rel(_value(fns.forward_dynamics, q[k], qd[k], tau[k]), oracle.aba(q[k], qd[k], tau[k])) < 1e-9


@pytest.mark.parametrize("make", [scara, kr6], ids=["scara-prismatic", "kr6"])
def test_recursive_matches_pinocchio_on_other_robots(make, rng):
    robot = make()
    model = derive_psdm(robot)
    standard = random_standard_parameters(robot, rng)
    oracle = PinocchioOracle(robot, standard)
    theta = model.base_parameters(standard)
    fns = build_recursive_functions(model, robot, theta)
    q, qd, qdd = _states(rng, robot.n_dof, 5)
    for k in range(5):
        tau = oracle.rnea(q[k], qd[k], qdd[k])
        assert _rel(_value(fns.inverse_dynamics, q[k], qd[k], qdd[k]), tau) < 1e-11
        assert _rel(_value(fns.regressor, q[k], qd[k], qdd[k]) @ theta, tau) < 1e-11


def test_recursive_matches_pinocchio_on_a_urdf(rng):
    robot = from_urdf(example_robot_urdf("ur_description/urdf/ur5_robot.urdf"))
    model = derive_psdm(robot)
    oracle = PinocchioOracle(robot)
    fns = build_recursive_functions(model, robot, model.base_parameters(robot.nominal_dynamic_parameters()))
    q, qd, qdd = _states(rng, robot.n_dof, 5)
    for k in range(5):
        assert _rel(_value(fns.inverse_dynamics, q[k], qd[k], qdd[k]), oracle.rnea(q[k], qd[k], qdd[k])) < 1e-11
        assert _rel(_value(fns.mass_matrix, q[k]), oracle.crba(q[k])) < 1e-11


def test_recursive_graph_is_smaller_than_the_sum_and_the_plain_newton_euler(denso, denso_model):
    from codegen.export import count_operations
    from codegen.peers.rnea_sx import build_rnea_functions

    theta = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    recursive = build_recursive_functions(denso_model, denso, theta)
    sums = build_functions(denso_model, theta)
    peer = build_rnea_functions(PinocchioOracle(denso).model)
    ops = {
        name: count_operations(getattr(fns, name)).n_operations
        for fns, name in ((recursive, "inverse_dynamics"), (recursive, "forward_dynamics"))
    }
    assert ops["inverse_dynamics"] < 0.75 * count_operations(peer.inverse_dynamics).n_operations
    assert ops["inverse_dynamics"] < 0.25 * count_operations(sums.inverse_dynamics).n_operations
    assert ops["forward_dynamics"] < 0.75 * count_operations(peer.forward_dynamics).n_operations


def test_model_of_another_robot_is_refused(denso, denso_model):
    joints = list(denso.joints)
    joints[1] = dataclasses.replace(joints[1], a=joints[1].a + 0.05)
    other = dataclasses.replace(denso, joints=tuple(joints))
    with pytest.raises(DerivationError, match="not the PSDM model of robot"):
        build_recursive_functions(denso_model, other)
    with pytest.raises(DerivationError, match="has 4 joints"):
        standard_preimage(denso_model, scara())


def test_baked_theta_length_checked(denso, denso_model):
    with pytest.raises(ShapeError, match="theta must have 32"):
        build_recursive_functions(denso_model, denso, np.ones(5))
