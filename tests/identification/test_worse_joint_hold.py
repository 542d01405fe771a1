"""A joint worse than the robot file is held to what the file predicts there, step by step (``worse_joint_hold``).

A step is kept when it leaves no new joint worse and fewer joints worse, or the same joints each predicted better on
the held-out recording beyond the paired margin: a step that brings a joint close to its baseline can leave it named
worse by a hair, the margin being only the paired difference's noise once its links are the file's; a gain within the
paired margin is noise, no step; each step tried is stated with the RMSE and margin that kept or refused it. A link the
robot file states semi-definite (a point mass) is held at the file's lifted by the fit's consistency margin: at the
file's own the model would fail the consistency check and nothing would be written.

References: (1) the rule's bookkeeping on a scripted check, each step's held-out RMSE stated per joint; (2) known
synthetic truth, fast: the virtual SCARA of ``test_one_way_friction`` whose robot file is its truth, its link 4 a point
mass (the hold held links 1-4 at the file's and the model was inconsistent; with link 4 left fitted joint 3 stayed
worse; lifted, links 1-4 held bring it to the file's); (3) known synthetic truth, slow: the KR6-like arm of
``benchmarks/unseen_cases.py`` moved slowly through gravity poses (``industrial_slow_gravity_tool``, seed 1), whose
robot file is its truth. Its joint 3 moves one way on most of the training recording, so its Coulomb friction trades
with the gravity of links 3-6, and the identified model was worse than the robot file there on the held-out recording
(0.595 against 0.224 N m). Holding links 3-6 at the file's brought it to 0.229 N m, still named worse by 0.005 N m
(margin 0.003), and a rule of fewer joints only wrote the model as identified. Its diagnosis named joint 1's friction
falling with speed (the truth's Stribeck peak, beside the identified model's narrower one) a smooth Coulomb friction of
-0.73 N m: a smooth Coulomb friction is > 0 (``FrictionShapeTerm.implausibility``), below zero it is a Stribeck peak's
shape.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.never_worse import JointComparison
from identification.calibration.pseudo_inertia import (
    CONSISTENCY_MARGIN,
    lifted_link,
    pseudo_inertia,
    pseudo_inertia_eigenvalues,
    semidefinite_links,
)
from identification.calibration.robot_file_check import FileCheck
from identification.calibration.trajectory_fit import TrajectoryOptions
from identification.calibration.worse_joint_hold import hold_worse_joints

BASELINE = np.array([0.30, 0.224, 0.31])  # the robot file's held-out RMSE per joint [N m]


def _scripted(rmse_of):
    """(refit, (judge, compare)): the refit returns its options as the fit; the judge states the held-out RMSE per joint
    that ``rmse_of(held friction?, held links)`` gives, with margins as the check gives them (2 % of the baseline); the
    comparison of two fits on the one held-out recording, with the paired margin's floor (1 % of the RMSE before)."""

    def rmse(options):
        return np.array(rmse_of(bool(options.held_friction), tuple(options.held_links)), dtype=float)

    def judge(options):
        comparison = JointComparison(before=BASELINE, after=rmse(options), margin=0.02 * BASELINE)
        return FileCheck(comparison=comparison, recordings=1, baselines=("friction",) * 3)

    def compare(before, after):
        return (JointComparison(before=rmse(before), after=rmse(after), margin=0.01 * rmse(before)),)

    return (lambda options: options), (judge, compare)


def _hold(rmse_of, semidefinite=()):
    refit, judges = _scripted(rmse_of)
    options = TrajectoryOptions(friction=("fc", "fv"))
    friction_of = lambda fit, joints: tuple((f"{t}{j + 1}", 1.0) for j in joints for t in ("fc", "fv"))  # noqa: E731
    return hold_worse_joints((refit, options, 3), options, judges, friction_of, semidefinite=semidefinite)


def test_steps_that_bring_the_worse_joint_nearer_its_baseline_are_kept_until_it_is_not_worse():
    table = {  # (friction held, links held) -> joint 2's held-out RMSE; joints 1 and 3 at their baselines
        (False, ()): 0.595, (True, ()): 0.415, (False, (1,)): 0.598, (True, (1,)): 0.40, (False, (1, 2)): 0.229,
        (True, (1, 2)): 0.224,
    }  # fmt: skip
    _, options, record = _hold(lambda friction, links: (0.30, table[friction, links], 0.31))
    assert record.worse == (1,) and record.left == ()
    assert options.held_links == (1, 2) and dict(options.held_friction) == {"fc2": 1.0, "fv2": 1.0}
    assert [kept for _, _, kept, _ in record.steps] == [True, True, True]
    nearer = "kept: each nearer beyond the paired margin on each held-out recording, "
    assert record.steps[0][3] == nearer + "joint 2 0.595 -> 0.415 N m (margin 0.0059)"


def test_a_step_that_makes_another_joint_worse_or_the_worse_one_no_better_is_refused():
    def rmse_of(friction, links):
        if friction:  # the worse joint better, joint 1 worse beyond its margin: a new one
            return 0.40, 0.30, 0.31
        return 0.30, 0.595 if len(links) < 2 else 0.60, 0.31  # the links leave it no nearer

    fit, options, record = _hold(rmse_of)
    assert record.left == (1,) and options.held_links == () and options.held_friction == ()
    assert [kept for _, _, kept, _ in record.steps] == [False, False, False]
    assert "the model stands as identified" in record.reason
    assert record.steps[0][3] == "refused: joint 1 newly worse, 0.4 N m against the file's 0.3 (margin 0.006)"
    refused = "refused: not each nearer beyond the paired margin on each held-out recording, "
    assert record.steps[1][3] == refused + "joint 2 0.595 -> 0.595 N m (margin 0.0059)"
    assert f"with links 2 held: joint(s) 2 worse ({record.steps[1][3]})" in record.reason


def test_a_step_nearer_only_within_the_paired_margin_is_refused():
    """The TX40's joint 5 (``docs/results/real-data.md``): a coupling the model lacks, 4.714 N m against the robot
    file's 1.375; its friction and link 5 held gave 4.682, steps within the paired margin that the rule of each nearer
    kept: the held-out recording decided the model for the comparison's noise, and ``diagnose --apply`` could not
    refit the held friction beside the coupling it found (joint 5 2.769 N m at the end against 1.812). Such steps are
    refused (scripted here, the margin 1 % of the RMSE before); one nearer beyond the margin is kept."""
    table = {(False, ()): 4.714, (True, ()): 4.70, (False, (1,)): 4.68, (False, (1, 2)): 4.69}
    _, options, record = _hold(lambda friction, links: (0.30, table[friction, links], 0.31))
    assert record.left == (1,) and options.held_links == () and options.held_friction == ()
    assert [kept for _, _, kept, _ in record.steps] == [False, False, False] and not record.decided_by_held_out
    assert "not each nearer beyond the paired margin" in record.reason
    assert record.to_dict()["steps"][2]["why"].endswith("joint 2 4.714 -> 4.69 N m (margin 0.047)")  # not 0.047 nearer
    table[False, (1, 2)] = 4.0  # nearer beyond the margin, still worse
    _, options, record = _hold(lambda friction, links: (0.30, table[friction, links], 0.31))
    assert options.held_links == (1, 2) and [kept for _, _, kept, _ in record.steps] == [False, False, True]


def test_a_link_the_robot_file_states_semidefinite_is_held_lifted_and_named():
    """Joint 2 is mended only with links 2 and 3 held; link 3 of the robot file is semi-definite (a point mass): the
    step holds it (the fit lifts it by its consistency margin, ``consistent_fit.held_standard``), and the record names
    it as lifted."""
    table = {(False, ()): 0.595, (True, ()): 0.594, (False, (1,)): 0.40, (False, (1, 2)): 0.224}
    _, options, record = _hold(lambda friction, links: (0.30, table[friction, links], 0.31), semidefinite=(2,))
    assert [what for what, _, _, _ in record.steps] == ["friction fc2 1, fv2 1", "links 2", "links 2, 3 (3 lifted)"]
    assert options.held_links == (1, 2) and record.lifted == (2,) and record.left == ()
    assert "link(s) 3 held at the robot file's lifted by 1e-06 kg m^2 to be strictly consistent" in record.describe()
    assert record.to_dict()["lifted_links"] == [3] and record.to_dict()["lift_margin"] == CONSISTENCY_MARGIN


def test_a_semidefinite_link_is_lifted_to_the_nearest_link_at_the_consistency_margin():
    """``lifted_link``: the pseudo-inertia's eigenvalues below the margin raised to it, the others and their directions
    kept (the nearest such pseudo-inertia, Frobenius norm); a link at or above the margin is left as it is. The margin
    is the fit's (``TrajectoryOptions.margin``), the one every identified link keeps."""
    assert TrajectoryOptions().margin == CONSISTENCY_MARGIN
    point = np.array([0.2, 0, 0, 0.2 * 0.042, 0.2 * 0.042**2, 0, 0.2 * 0.042**2, 0, 0, 0])  # 0.2 kg at z = 42 mm
    lifted = lifted_link(point, 1e-6)
    before, after = np.linalg.eigvalsh(pseudo_inertia(point)), np.linalg.eigvalsh(pseudo_inertia(lifted))
    np.testing.assert_allclose(after, [1e-6, 1e-6, 1e-6, before[3]], rtol=1e-9)
    direction = np.array([0, 0, 0.042, 1]) / np.hypot(0.042, 1)  # of the one nonzero eigenvalue: [c, 1]
    raised = 1e-6 * (np.eye(4) - np.outer(direction, direction))  # the three others raised from 0 to the margin
    np.testing.assert_allclose(pseudo_inertia(lifted) - pseudo_inertia(point), raised, atol=1e-15)
    assert semidefinite_links(lifted[None]) == () and pseudo_inertia_eigenvalues(lifted[None])[0] > 0
    box = np.array([1.0, 0.1, 0, 0, 0.02, 0, 0.03, 0, 0, 0.04])
    assert np.array_equal(lifted_link(box, 1e-6), box)


def test_semidefinite_links_are_those_whose_pseudo_inertia_has_an_eigenvalue_at_zero():
    """A point mass (no inertia about its centre of mass; the TX40 URDF's link 6) and a thin rod (none about its own
    axis) are semi-definite, whatever their masses; a solid box, however small, is not."""
    box = np.array([0.01, 0, 0, 0, 2e-9, 0, 2e-9, 0, 0, 2e-9])  # 10 g, about its centre (1 mm cube-like)
    point = np.array([0.2, 0, 0, 0.2 * 0.042, 0.2 * 0.042**2, 0, 0.2 * 0.042**2, 0, 0, 0])  # 0.2 kg at z = 42 mm
    rod = np.array([1.0, 0, 0, 0, 1 / 12, 0, 1 / 12, 0, 0, 0])  # 1 kg, 1 m along z
    assert semidefinite_links(np.array([box, point, rod, 1e3 * box])) == (1, 2)


def test_the_links_held_lifted_are_the_files_semidefinite_ones_the_model_holds():
    """``consistent_fit.lifted_links``, which both the consistent fit (``held_standard``) and identify's hold of the
    worse joints (the links it names lifted) read: of the SCARA with links 3 and 4 point masses (their inertia about
    the centre of mass zero, by construction semi-definite), the model lacking link 3 (its columns zero), only link 4
    is held lifted; without a model both are; a link stated strictly consistent never is. ``held_standard`` lifts
    exactly those of its held links, the others held at the file's."""
    from types import SimpleNamespace

    from identification.calibration.consistent_fit import held_standard, lifted_links
    from psdm_casadi import load_robot

    scara = load_robot("scara")
    robot = scara.with_links([replace(link, inertia=np.zeros((3, 3))) if i in (2, 3) else link
                              for i, link in enumerate(scara.links)])  # fmt: skip
    file = robot.nominal_dynamic_parameters()
    assert [np.linalg.eigvalsh(pseudo_inertia(row[:10]))[0] <= 1e-15 for row in file] == [False, False, True, True]
    mapping = np.ones((5, file.size))
    mapping[:, 2 * 11 : 2 * 11 + 10] = 0.0  # link 3's inertial parameters reach no base parameter
    model = SimpleNamespace(parameter_map=mapping)
    assert lifted_links(robot, model=model) == (3,) and lifted_links(robot) == (2, 3)
    assert lifted_links(robot, (0, 1, 3), model) == (3,) and lifted_links(robot, (0, 1), model) == ()
    assert lifted_links(scara, model=model) == ()
    held = held_standard(robot, (1, 2, 3), CONSISTENCY_MARGIN, model)
    np.testing.assert_array_equal(held[:3], file[:3])  # link 2 strictly consistent, link 3 not in the model
    np.testing.assert_allclose(held[3, :10], lifted_link(file[3, :10], CONSISTENCY_MARGIN), rtol=1e-12, atol=1e-18)
    assert np.linalg.eigvalsh(pseudo_inertia(held[3, :10]))[0] >= CONSISTENCY_MARGIN * (1 - 1e-9)
    np.testing.assert_allclose(held_standard(robot, (1, 2, 3))[2, :10], lifted_link(file[2, :10]), atol=1e-18)


def test_a_scara_whose_last_link_is_a_point_mass_is_held_lifted_and_mended_with_a_consistent_model():
    """Known truth: the SCARA of ``test_one_way_friction`` (its robot file is the simulated arm; joints 3 and 4 move one
    way only in training, their friction fitted: joint 3's trades with its gravity load), with link 4 a 0.3 kg point
    mass on joint 4's axis, as the TX40's URDF states its link 6. Joints 1 and 3 are worse than the robot file. Links
    1-4 held at the file's made the model inconsistent (link 4's pseudo-inertia eigenvalue 0; without a drive inertia no
    inertia about joint 4): ``psdm identify`` wrote nothing; link 4 left fitted, links 1-3 held, joint 3 stayed worse
    (0.065 against the file's 0.0066 N m, margin 0.022). Now link 4 is held lifted by the fit's consistency margin:
    links 1-3 at the truth, link 4 within the margin of it, no joint worse (joint 3 at the file's within its margin),
    and the model passes the consistency check, its mass matrix positive definite."""
    from identification.calibration.consistency import min_mass_eigenvalue
    from identification.calibration.identify_route import identify_recordings
    from psdm_casadi import derive_psdm, load_robot
    from tests.identification.test_one_way_friction import recording

    scara = load_robot("scara")
    links = list(scara.links)
    links[3] = replace(links[3], inertia=np.zeros((3, 3)))  # 0.3 kg at 2 cm along joint 4's axis
    robot = scara.with_links(links)
    assert semidefinite_links(robot.nominal_dynamic_parameters()) == (3,)
    train, held = [recording(robot, 0, one_way=(2, 3), duration=2.0)], [recording(robot, 1)]
    result = identify_recordings(robot, derive_psdm(robot), train, validation=held, counterbalance=False,
                                 one_way="fit")  # fmt: skip
    record = result.worse_joints
    assert 2 in record.worse and record.decided_by_held_out and record.lifted == (3,)
    assert record.held_links == (0, 1, 2, 3) and record.left == () and result.file_check.worse == ()
    assert record.steps[-1][:3] == ("links 1, 2, 3, 4 (4 lifted)", (), True)
    truth, margin = robot.nominal_dynamic_parameters(), result.options.margin
    np.testing.assert_allclose(result.fit.standard[:3, :10], truth[:3, :10], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.fit.standard[3, :10], lifted_link(truth[3, :10], margin), rtol=1e-9, atol=1e-15)
    assert np.max(np.abs(result.fit.standard[3, :10] - truth[3, :10])) < 3 * margin  # as near the file as allowed
    assert result.fit.consistent and result.fit.min_pseudo_inertia_eigenvalue >= margin * (1 - 1e-9)
    assert min_mass_eigenvalue(robot, result.fit.standard) > 0
    c = result.file_check.comparison
    assert c.after[2] <= c.before[2] + c.margin[2]  # joint 3 at the file's (0.065 with link 4 fitted; 0.252 identified)
    text = record.describe()
    assert "link(s) 4 held at the robot file's lifted by 1e-06 kg m^2 to be strictly consistent" in text
    assert text in result.describe() and "(kept: fewer worse, joint 1 within," in text
    stored = result.calibrated.document["identification"]["worse_joints"]
    assert stored["lifted_links"] == [4] and stored["held_links"] == [1, 2, 3, 4]
    assert result.calibrated.document["standard"]["consistent"] is True


@pytest.mark.slow
def test_the_slow_kr6_joint_3_is_held_to_the_robot_file_where_it_was_worse(benchmark_modules, tmp_path, capsys):
    """Known truth: the robot file is the arm's truth, so links 3-6 held at it are the truth's, and joint 3 predicts the
    held-out motion as the file's rigid body with its friction fitted does; the diagnosis then names no friction shape
    the truth lacks (about 40 s)."""
    from unseen_cases import build

    from psdm_casadi.cli import main

    case = build("industrial_slow_gravity_tool", tmp_path, 1)
    model = tmp_path / "model.json"
    code = main(["identify", str(case.robot), "--data", *map(str, case.train), "--validate", str(case.validate),
                 "--out", str(model), "--no-html"])  # fmt: skip
    assert code == 0
    document = json.loads(model.read_text())
    mended = document["identification"]["worse_joints"]
    assert mended["worse_joints"] == [3] and mended["left_worse"] == []
    assert mended["held_links"] == [3, 4, 5, 6]
    rmse = np.asarray(document["validation"]["recordings"][0]["rmse"], dtype=float)
    assert rmse[2] < 1.05 * mended["before"]["joint 3"]["baseline"]  # the file's 0.224 N m; identified 0.595
    masses = np.asarray(document["standard"]["values"], dtype=float).reshape(6, -1)[:, 0]
    np.testing.assert_allclose(masses[2:], case.true_links[2:], rtol=1e-9)
    # the diagnosis names no friction shape the truth lacks: its friction falls with speed (a Stribeck peak, fs > fc,
    # on every joint) and its viscous friction is linear; joint 1's falling friction was named a negative smooth
    # Coulomb friction ("friction_shape[j1,smooth_coulomb]"), a shape it does not have
    capsys.readouterr()
    assert main(["diagnose", str(model), "--train", *map(str, case.train), "--validate", str(case.validate),
                 "--json"]) == 0  # fmt: skip
    findings = json.loads(capsys.readouterr().out)["findings"]
    shapes = [f["label"] for f in findings if f["effect"] == "friction_shape"]
    assert all(label.endswith(",stribeck]") for label in shapes), shapes
