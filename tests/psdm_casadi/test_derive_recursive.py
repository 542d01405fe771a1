"""Derivation beyond the sum form: 9- and 12-joint serial arms and a 2 x 7 + 1 tree, against Pinocchio.

The references are Pinocchio's rnea with random standard parameters (the torques), Pinocchio's
joint torque regressor (the numerical rank of its stacked columns is the number of base
parameters, of its gravity columns the number of gravity ones) and, on the Denso, the sum form
of the paper (the same base-parameter space).
"""

import logging
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.derive import MAX_DOF, DeriveOptions
from psdm_casadi.errors import DerivationError, ParameterError
from psdm_casadi.model import load_model
from psdm_casadi.oracle import PinocchioOracle, build_pinocchio_model
from psdm_casadi.preimage import standard_preimage
from psdm_casadi.recursive import build_recursive_functions
from psdm_casadi.samples import serial_arm
from psdm_casadi.sampling import random_standard_parameters, random_states
from psdm_casadi.symbolic import build_functions

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TREE = EXAMPLES / "dual_arm_torso.toml"


@pytest.fixture(scope="module")
def tree():
    return load_robot(TREE)


@pytest.fixture(scope="module")
def tree_model(tree):
    return derive_psdm(tree)


def _torque_error(model, robot, rng, n_states=300):
    """Largest relative difference of Y_b theta_b from Pinocchio's rnea, random states and parameters."""
    worst = 0.0
    for _ in range(3):
        standard = random_standard_parameters(robot, rng)
        q, qd, qdd = random_states(robot, n_states // 3, rng)
        reference = PinocchioOracle(robot, standard).rnea(q, qd, qdd)
        ours = model.regressor(q, qd, qdd) @ model.base_parameters(standard)
        worst = max(worst, np.abs(ours - reference).max() / np.abs(reference).max())
    return worst


def _pinocchio_ranks(robot, rng, n_states=80):
    """(rank, gravity rank) of Pinocchio's stacked regressor: link columns, plus qdd_i for a joint with a rotor."""
    model = build_pinocchio_model(robot, np.zeros((robot.n_dof, 11)))
    model.gravity.linear = np.asarray(robot.gravity, dtype=float)
    data = model.createData()
    ranks = []
    for gravity_only in (False, True):
        q, qd, qdd = random_states(robot, n_states, rng)
        if gravity_only:
            qd, qdd = 0 * qd, 0 * qdd
        rows = []
        for k in range(n_states):
            link = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])
            rows.append(np.hstack([link, np.diag(qdd[k])[:, np.asarray(robot.drive_inertia)]]))
        stacked = np.vstack(rows)
        norms = np.linalg.norm(stacked, axis=0)
        stacked = stacked[:, norms > 1e-12 * norms.max()] / norms[norms > 1e-12 * norms.max()]
        singular = np.linalg.svd(stacked, compute_uv=False)
        ranks.append(int(np.sum(singular > 1e-9 * singular[0])))
    return tuple(ranks)


@pytest.mark.parametrize("n_dof", [9, 12])
def test_serial_arms_beyond_the_sum_form_equal_pinocchio(n_dof, rng):
    robot = serial_arm(n_dof)
    start = time.perf_counter()
    model = derive_psdm(robot)
    assert time.perf_counter() - start < 20.0
    assert not model.has_monomials and model.n_functions == 0 and model.metadata["form"] == "recursive"
    assert _torque_error(model, robot, rng) < 1e-12
    assert (model.n_base, model.n_gravity) == _pinocchio_ranks(robot, rng)


def test_the_tree_equals_pinocchio(tree, tree_model, rng):
    assert tree.n_dof == 2 * 7 + 1
    assert list(tree_model.chain.parents) == [-1, *range(7), 0, *range(8, 14)]  # both arms hang on the torso
    assert _torque_error(tree_model, tree, rng) < 1e-12
    assert (tree_model.n_base, tree_model.n_gravity) == _pinocchio_ranks(tree, rng)


def test_the_regressor_is_pinocchios_columns_on_the_preimage(tree, tree_model, rng):
    model = build_pinocchio_model(tree, np.zeros((tree.n_dof, 11)))
    data = model.createData()
    q, qd, qdd = random_states(tree, 5, rng)
    ours = tree_model.regressor(q, qd, qdd)
    link_rows = (np.arange(11 * tree.n_dof) % 11) < 10
    for k in range(5):
        reference = (
            pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]) @ (tree_model.chain.preimage[link_rows])
        )
        assert np.abs(ours[k] - reference).max() <= 1e-12 * np.abs(reference).max()


def test_gravity_parameters_have_the_only_gravity_columns(tree, tree_model, rng):
    q = random_states(tree, 20, rng)[0]
    gravity = tree_model.gravity_regressor(q)
    scale = np.abs(gravity).max()
    assert np.abs(gravity[:, :, ~tree_model.gravity_mask]).max() <= 1e-13 * scale
    assert np.all(np.abs(gravity[:, :, tree_model.gravity_mask]).max(axis=(0, 1)) > 1e-6 * scale)


def test_the_recursive_form_spans_the_sum_forms_base_parameters(denso, denso_model, rng):
    model = derive_psdm(denso, DeriveOptions(form="recursive"))
    assert (model.n_base, model.n_gravity) == (denso_model.n_base, denso_model.n_gravity) == (32, 9)
    both = np.vstack([denso_model.parameter_map, model.parameter_map])
    assert np.linalg.matrix_rank(both, tol=1e-8 * np.abs(both).max()) == 32
    gravity = np.vstack([denso_model.parameter_map[denso_model.gravity_mask], model.parameter_map[model.gravity_mask]])
    assert np.linalg.matrix_rank(gravity, tol=1e-8 * np.abs(gravity).max()) == 9
    q, qd, qdd = random_states(denso, 50, rng)
    standard = random_standard_parameters(denso, rng)
    sum_form = denso_model.inverse_dynamics(q, qd, qdd, denso_model.base_parameters(standard))
    recursive = model.inverse_dynamics(q, qd, qdd, model.base_parameters(standard))
    assert np.abs(sum_form - recursive).max() <= 1e-12 * np.abs(sum_form).max()


def test_small_robots_keep_the_sum_form(denso_model):
    assert denso_model.has_monomials and denso_model.chain is None and "form" not in denso_model.metadata


def test_casadi_functions_of_a_model_without_table(tree, tree_model, rng):
    with pytest.raises(ParameterError, match="monomial table.*build_recursive_functions"):
        build_functions(tree_model)
    standard = random_standard_parameters(tree, rng)
    theta = tree_model.base_parameters(standard)
    q, qd, qdd = random_states(tree, 3, rng)
    reference = PinocchioOracle(tree, standard).rnea(q, qd, qdd)
    for robot in (tree, None):  # None: the model's own joint tree
        functions = build_recursive_functions(tree_model, robot, theta)
        tau = np.array([np.array(functions.inverse_dynamics(q[k], qd[k], qdd[k])).ravel() for k in range(3)])
        assert np.abs(tau - reference).max() <= 1e-12 * np.abs(reference).max()


def test_a_model_without_table_refuses_another_robot(tree_model):
    with pytest.raises(DerivationError, match="not the PSDM model"):
        standard_preimage(tree_model, serial_arm(15))


def test_model_file_round_trip_without_table(tree_model, tmp_path, rng):
    path = tree_model.save(tmp_path / "tree.npz")
    loaded = load_model(path)
    assert loaded == tree_model and not loaded.has_monomials
    q, qd, qdd = random_states(load_robot(TREE), 4, rng)
    assert np.array_equal(loaded.regressor(q, qd, qdd), tree_model.regressor(q, qd, qdd))


def test_the_sum_form_still_refuses_large_robots_quickly():
    start = time.perf_counter()
    with pytest.raises(ParameterError, match=rf"at most {MAX_DOF} .*got 12 joints.*--form auto or recursive"):
        derive_psdm(serial_arm(12), DeriveOptions(form="sum"))
    assert time.perf_counter() - start < 2.0
    with pytest.raises(ParameterError, match="DeriveOptions.form must be one of"):
        DeriveOptions(form="grid")


@pytest.mark.slow
def test_a_thirty_joint_arm_derives_in_polynomial_time(rng):
    robot = serial_arm(30)
    start = time.perf_counter()
    model = derive_psdm(robot)
    assert time.perf_counter() - start < 60.0
    assert _torque_error(model, robot, rng, n_states=60) < 1e-12
    assert (model.n_base, model.n_gravity) == _pinocchio_ranks(robot, rng, n_states=40)


def test_the_model_cache_keeps_a_model_without_table(tree, tree_model, caplog):
    from psdm_casadi.model_cache import ModelCache

    cache = ModelCache()
    first = cache.derive(tree)
    with caplog.at_level(logging.INFO, logger="psdm_casadi.model_cache"):
        again = cache.derive(tree)
    assert "read from the cache" in caplog.text  # a model file of version 2, read back
    assert first == again == tree_model and not again.has_monomials


def test_a_small_tree_in_both_forms(rng):
    """1 + 2 + 2 joints (the torso's arms locked beyond their second joint): the sum form and the recursive one."""
    locks = {f"{side}_panda_joint{k}": (-1.5 if k == 4 else 0.3) for side in ("left", "right") for k in range(3, 8)}
    robot = load_robot(EXAMPLES / "dual_arm_torso.urdf", locked_joints=locks)
    sum_form, recursive = derive_psdm(robot), derive_psdm(robot, DeriveOptions(form="recursive"))
    assert robot.n_dof == 5 and sum_form.has_monomials and not recursive.has_monomials
    assert (
        (sum_form.n_base, sum_form.n_gravity) == (recursive.n_base, recursive.n_gravity) == _pinocchio_ranks(robot, rng)
    )
    both = np.vstack([sum_form.parameter_map, recursive.parameter_map])
    assert np.linalg.matrix_rank(both, tol=1e-8 * np.abs(both).max()) == sum_form.n_base
    assert max(_torque_error(sum_form, robot, rng), _torque_error(recursive, robot, rng)) < 1e-12


def test_base_parameters_from_the_free_directions_when_no_coordinate_fits(denso, denso_model, monkeypatch, rng):
    """The fallback of assumptions not aligned with joint-frame coordinates: the preimage from the free directions."""
    import psdm_casadi.column_space

    monkeypatch.setattr(psdm_casadi.column_space, "_inside", lambda columns, space: np.zeros(columns.shape[1], bool))
    model = derive_psdm(denso, DeriveOptions(form="recursive"))
    assert (model.n_base, model.n_gravity) == (32, 9)
    assert _torque_error(model, denso, rng) < 1e-12
    both = np.vstack([denso_model.parameter_map, model.parameter_map])
    assert np.linalg.matrix_rank(both, tol=1e-8 * np.abs(both).max()) == 32
