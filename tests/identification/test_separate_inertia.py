"""Which joints' drive inertia is a column of its own (``separate_inertia``): one rank test for identify's columns,
its column choice and ``merged_rotors.holds_rotors``.

Reference: the span of the rigid body's torques computed by Pinocchio's inverse dynamics on random states for many
random admissible parameter sets (with the drive inertias the model derives on its joints as armature), and numpy's
rank of that span with each candidate joint's ``qdd_j`` column added in turn; nothing of the PSDM model's regressor or
map. Robots: the Denso as derived from its file (every drive inertia in the map) and without its drive inertias, the
Staubli TX40, the Franka Panda and the Kinova Gen3 (their URDFs state no rotor: every drive inertia is a candidate).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from identification.calibration import separate_inertia
from identification.calibration.merged_rotors import merged_rotor_map
from identification.calibration.separate_inertia import separate_inertia_joints
from psdm_casadi import derive_psdm
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot
from psdm_casadi.sampling import random_standard_parameters
from tests.conftest import DATASETS, ROOT, example_robot_urdf

RANK_TOLERANCE = 1e-9  # singular values below this fraction of the largest are zero (columns scaled to unit norm)


def pinocchio_separate_joints(robot, n_states: int = 60, seed: int = 11) -> list:
    """The joints whose ``qdd_j`` column raises the rank of Pinocchio's torques of random parameter sets (and of the
    columns kept before it), among those without a drive inertia in the derivation."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max, size=(n_states, robot.n_dof))
    qd, qdd = rng.normal(size=(2, n_states, robot.n_dof))
    draws = [random_standard_parameters(robot, rng, physical=False) for _ in range(11 * robot.n_dof)]
    span = np.column_stack([PinocchioOracle(robot, p).rnea(q, qd, qdd).reshape(-1) for p in draws])
    span /= np.linalg.norm(span, axis=0)

    def rank(matrix):
        singular = np.linalg.svd(matrix, compute_uv=False)
        return int(np.sum(singular > RANK_TOLERANCE * singular[0]))

    kept = []
    for j in [j for j in range(robot.n_dof) if not robot.drive_inertia[j]]:
        column = np.zeros_like(qdd)
        column[:, j] = qdd[:, j]
        column = column.reshape(-1, 1) / np.linalg.norm(column)
        trial = np.hstack([span, column])
        if rank(trial) > rank(span):
            kept.append(j)
            span = trial
    return kept


def check_robot(robot) -> list:
    """Assert the rank test agrees with Pinocchio's on ``robot`` and that the other candidates' drive inertias are the
    merged ones (``merged_rotor_map``); the separate joints."""
    model = derive_psdm(robot)
    expected = pinocchio_separate_joints(robot)
    assert separate_inertia_joints(model, robot) == expected
    candidates = [j for j in range(robot.n_dof) if not robot.drive_inertia[j]]
    merged = merged_rotor_map(model, robot, candidates)
    assert sorted(merged) == [j for j in candidates if j not in expected]
    return expected


def test_the_denso_derived_with_its_drive_inertias_has_no_separate_joint(denso, denso_model):
    assert all(denso.drive_inertia)
    assert separate_inertia_joints(denso_model, denso) == pinocchio_separate_joints(denso) == []


def test_the_denso_without_drive_inertias_separates_joints_3_to_6_as_pinocchio(denso):
    robot = replace(denso, drive_inertia=(False,) * denso.n_dof)
    assert check_robot(robot) == [2, 3, 4, 5]  # joints 1-2's add to base parameters (vertical axis, link 2's ZZ)


def test_the_answer_is_computed_once_per_model(denso_merged_rotors, monkeypatch):
    robot, model = denso_merged_rotors
    calls = []
    original = separate_inertia.random_states
    monkeypatch.setattr(separate_inertia, "random_states", lambda *a, **k: calls.append(1) or original(*a, **k))
    other = replace(model)  # equal content, another object: computed again
    first = separate_inertia_joints(other, robot)
    first.append(99)  # the caller's copy
    assert separate_inertia_joints(other, robot) == [2, 3, 4, 5] and len(calls) == 1
    joints = tuple(replace(joint, q_min=joint.q_min / 2, q_max=joint.q_max / 2) for joint in robot.joints)
    narrow = replace(robot, joints=joints)  # other limits, other states
    assert separate_inertia_joints(other, narrow) == [2, 3, 4, 5] and len(calls) == 2


@pytest.mark.slow
def test_the_tx40_separates_as_pinocchio():
    urdf = DATASETS / "staubli_tx40_figaroh" / "tx40_mdh_modified.urdf"
    if not urdf.exists():
        pytest.skip("the TX40's URDF (../shared/datasets/staubli_tx40_figaroh) is absent")
    assert check_robot(load_robot(urdf)) == [2, 3, 4, 5]


@pytest.mark.slow
def test_the_panda_separates_as_pinocchio():
    from psdm_casadi import from_urdf

    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    robot = from_urdf(urdf, locked_joints=("panda_finger_joint1", "panda_finger_joint2"))
    assert check_robot(robot) == [2, 3, 4, 5, 6]


@pytest.mark.slow
def test_the_kinova_gen3_separates_as_pinocchio(tmp_path):
    kinova = DATASETS / "kinova_gen3_dynid"
    if not (kinova / "gen3.urdf").exists():
        pytest.skip(f"the Kinova Gen3's URDF is absent in {kinova}")
    text = (ROOT / "examples" / "kinova_gen3.toml").read_text()
    (tmp_path / "kinova_gen3.toml").write_text(
        text.replace("../../shared/datasets/kinova_gen3_dynid/gen3.urdf", str(kinova / "gen3.urdf"))
    )
    assert check_robot(load_robot(tmp_path / "kinova_gen3.toml")) == [2, 3, 4, 5, 6]
