"""MJCF out (issue 28, part 1): MuJoCo's own inverse dynamics on the written file computes the calibrated model.

The oracle is the ``mujoco`` package: ``mj_inverse`` on the written MJCF against ``CalibratedModel.predict``
without the parts MJCF does not hold as a torque (Coulomb, offsets, findings other than a linear spring), to
1e-9 relative. MuJoCo's ``frictionloss`` is a constraint: with it, ``qfrc_inverse`` differs by a force bounded
by ``fc`` that opposes the motion (``fc sign(qd)`` on most sliding samples, anything within ``[-fc, fc]`` else).
"""

import copy
import dataclasses
import json
import re

import mujoco
import numpy as np
import pytest

from codegen.mjcf_check import mjcf_round_trip, mujoco_inverse
from codegen.mjcf_elements import MIN_BODY
from codegen.mjcf_export import export_mjcf, render_mjcf
from codegen.urdf_export import render_urdf
from identification.calibration.calibrated_model import CalibratedModel
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.errors import ModelFileError
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot
from tests.catalogue.model_files import SCARA_FILE, model_text, nominal_fit
from tests.codegen.export_refusals import assert_cli_refuses_inconsistent, assert_refuses_bad_models
from tests.codegen.sine_motion import sines_about_mid_range
from tests.conftest import DATASETS, DENSO_FILE
from tests.psdm_casadi.test_mjcf_robot import ARM, HAND

TX40_URDF = DATASETS / "staubli_tx40_figaroh" / "tx40_mdh_modified.urdf"
IA = {1: 0.03, 2: 0.02}  # drive inertias identified as columns of their own (1-based joints)
SPRING = {
    "effect": "spring",
    "label": "spring[j2]",
    "kind": "torque",
    "joints": [2],
    "term": {"effect": "spring", "joint": 2},
    "feature_names": ["spring_k_2", "spring_c_2"],
    "coefficients": [19.078944408223368, 0.5165913046084039],
    "parameters": {"k": 19.078944408223368},
}
RIPPLE = {
    "effect": "torque_ripple",
    "label": "torque_ripple[j1,h=3]",
    "kind": "torque",
    "joints": [1],
    "term": {"effect": "torque_ripple", "joint": 1, "harmonic": 3},
    "feature_names": ["ripple_sin3_1", "ripple_cos3_1"],
    "coefficients": [0.25, -0.125],
    "parameters": {},
}
DELAY = {"effect": "delay", "label": "delay", "kind": "signal", "joints": [], "parameters": {"delay_s": 0.007}}
# fmt: skip


def _calibrated(robot_file, findings=(), friction=("fc", "fv", "offset"), ia=None):
    """A calibrated model of the robot file's nominal inertia with drive inertias ``ia`` (``{joint: Ia}``, 1-based)
    identified as columns of their own, friction, offsets and findings."""
    robot = load_robot(robot_file)
    model = derive_psdm(robot)
    fit = nominal_fit(robot, model, friction)
    ia = ia or {}
    joints = tuple(j - 1 for j in ia)
    extra = np.array(list(ia.values()))
    standard = fit.standard.copy()
    standard[list(joints), 10] = extra
    fit = dataclasses.replace(
        fit, standard=standard, inertia_joints=joints, drive=np.r_[fit.drive, extra],
        drive_names=fit.drive_names + tuple(f"Ia{j}" for j in ia), drive_ols=np.r_[fit.drive_ols, extra],
        drive_std=np.r_[fit.drive_std, 0.01 * extra],
    )  # fmt: skip
    calibrated = CalibratedModel.from_fit(robot, model, fit, robot_source=robot_file)
    document = copy.deepcopy(calibrated.document)
    document["findings"] = list(findings)
    if any(f["kind"] == "signal" for f in findings):
        document["corrections"] = {"delay": {"effect": "delay", "delay_s": 0.007}}
    return CalibratedModel(document), robot, model


def _states(robot, n, seed=0):
    """Random states strictly inside the joint ranges (MuJoCo's limits are constraints)."""
    rng = np.random.default_rng(seed)
    low, high = robot.q_min + 0.05 * (robot.q_max - robot.q_min), robot.q_max - 0.05 * (robot.q_max - robot.q_min)
    q = rng.uniform(low, high, size=(n, robot.n_dof))
    qd, qdd = rng.normal(scale=2.0, size=(2, n, robot.n_dof))
    return q, qd, qdd


@pytest.fixture(scope="module")
def scara():
    return _calibrated(SCARA_FILE, findings=[SPRING, RIPPLE, DELAY], ia=IA)


def test_mujoco_computes_the_scara_model_with_drive_inertias_a_spring_and_a_slide(scara):
    calibrated, robot, model = scara
    text = render_mjcf(calibrated, robot)
    result = mjcf_round_trip(calibrated, model, text, *_states(robot, 200))
    assert result.max_rel_error < 1e-9, result
    mj = mujoco.MjModel.from_xml_string(text)
    # the file's numbers are the model's, exactly (MuJoCo reads the shortest round-trip floats back)
    drive = dict(zip(calibrated.document["drive"]["names"], calibrated.drive))
    np.testing.assert_array_equal(mj.dof_armature, [IA.get(j + 1, 0.0) for j in range(4)])
    np.testing.assert_array_equal(mj.dof_damping, [drive[f"fv{j + 1}"] for j in range(4)])
    np.testing.assert_array_equal(mj.dof_frictionloss, [drive[f"fc{j + 1}"] for j in range(4)])
    np.testing.assert_array_equal(mj.body_mass[1:], calibrated.standard[:, 0])
    np.testing.assert_array_equal(mj.jnt_range, np.c_[robot.q_min, robot.q_max])
    np.testing.assert_array_equal(mj.opt.gravity, robot.gravity)
    assert list(mj.jnt_type) == [mujoco.mjtJoint.mjJNT_HINGE] * 2 + [
        mujoco.mjtJoint.mjJNT_SLIDE,
        mujoco.mjtJoint.mjJNT_HINGE,
    ]
    k, c = SPRING["coefficients"]
    assert mj.jnt_stiffness[1] == k and mj.qpos_spring[1] == pytest.approx(-c / k, rel=1e-15)


def test_friction_loss_is_a_bounded_force_against_the_motion(scara):
    """MuJoCo's frictionloss: |f| <= fc on every joint, fc sign(qd) on most sliding samples."""
    calibrated, robot, model = scara
    q, qd, qdd = _states(robot, 200, seed=1)
    result = mjcf_round_trip(calibrated, model, render_mjcf(calibrated, robot), q, qd, qdd)
    assert result.friction_excess <= 1e-9
    assert result.friction_saturated > 0.5, result  # measured 0.76 on these states
    mj = mujoco.MjModel.from_xml_string(render_mjcf(calibrated, robot))
    friction = mujoco_inverse(mj, q, qd, qdd, True) - mujoco_inverse(mj, q, qd, qdd, False)
    assert np.abs(friction).max() > 0.5 * mj.dof_frictionloss.min()  # it acts


def test_what_mjcf_cannot_hold_is_named_with_its_values(scara):
    calibrated, robot, _ = scara
    text = render_mjcf(calibrated, robot)
    flat = " ".join(text.split())
    assert "torque_ripple[j1,h=3] (torque term, NOT in the MJCF): ripple_sin3_1 = 0.25, ripple_cos3_1 = -0.125" in flat
    assert "Finding delay (measurement correction, NOT in the MJCF): delay_s = 0.007" in flat
    assert "spring[j2] (torque term" not in flat  # a linear spring is stiffness and springref
    offsets = re.findall(r"constant torque offset (\S+) (N m|N) \(not an MJCF field\)", text)
    drive = dict(zip(calibrated.document["drive"]["names"], calibrated.drive))
    assert [float(v) for v, _ in offsets] == [drive[f"offset{j + 1}"] for j in range(4)]  # exact
    assert [unit for _, unit in offsets] == ["N m", "N m", "N", "N m"]


def test_a_counterbalance_odd_law_is_in_the_exported_functions_and_named_outside_the_mjcf(scara):
    """An odd law of order 5 about its neutral angle (``SpringTerm(odd=True)``, a finding by its spec): the CasADi
    functions ``psdm codegen`` compiles compute ``predict`` with it, the law written out here is their difference from
    the model without it, and MJCF (which holds only a linear spring) names it with its exact coefficients."""
    from codegen.calibrated import build_calibrated_functions
    from identification.diagnosis.candidates import SpringTerm

    calibrated, robot, model = scara
    law = SpringTerm(joint=1, order=5, centre=0.2, q_range=(-1.0, 1.5), odd=True)
    entry = {"effect": "spring", "label": law.label, "kind": "torque", "joints": [2],
             "term": {"effect": "spring", "joint": 2, "spec": law.spec()}, "feature_names": law.feature_names(),
             "coefficients": [12.5, -3.25, 0.75, 0.125], "parameters": {}}  # fmt: skip
    document = copy.deepcopy(calibrated.document)
    document["findings"] = [*document["findings"], entry]
    with_law = CalibratedModel(json.loads(model_text(document)))
    q, qd, qdd = _states(robot, 50, seed=2)
    functions = build_calibrated_functions(with_law, model, robot)
    tau = np.array(functions.inverse_dynamics.map(50)(q.T, qd.T, qdd.T), dtype=float).T
    np.testing.assert_allclose(tau, with_law.predict(model, q, qd, qdd), rtol=0, atol=1e-9 * np.abs(tau).max())
    x = q[:, 1] - 0.2
    added = with_law.predict(model, q, qd, qdd) - calibrated.predict(model, q, qd, qdd)
    np.testing.assert_allclose(added[:, 1], 12.5 * x - 3.25 * x**3 + 0.75 * x**5 + 0.125, atol=1e-9)
    np.testing.assert_allclose(np.delete(added, 1, axis=1), 0.0, atol=1e-9)
    flat = " ".join(render_mjcf(with_law, robot).split())
    assert ("spring[j2,order=5,odd] (torque term, NOT in the MJCF): k1_q2 = 12.5, k3_q2 = -3.25, k5_q2 = 0.75, "
            "c_2 = 0.125") in flat  # fmt: skip


def test_the_denso_dh_model_round_trips_with_gravity_along_x_and_its_massless_link():
    """Rotor inertias inside the base parameters (armature); the Denso's link 6 is massless in its robot file:
    MuJoCo refuses that, so it gets 1e-12 kg (said so)."""
    calibrated, robot, model = _calibrated(DENSO_FILE)
    assert np.all(calibrated.standard[5, :10] == 0.0)
    text = render_mjcf(calibrated, robot)
    mj = mujoco.MjModel.from_xml_string(text)
    assert mj.opt.gravity[0] == robot.gravity[0] != 0.0 and mj.body_mass[6] == MIN_BODY
    assert "MuJoCo needs a positive mass" in text
    np.testing.assert_array_equal(mj.dof_armature, calibrated.standard[:, 10])
    assert np.all(mj.dof_armature > 0)
    result = mjcf_round_trip(calibrated, model, text, *_states(robot, 100))
    assert result.max_rel_error < 1e-9, result


@pytest.mark.slow  # derives the TX40: about 10 s
def test_a_urdf_robot_is_generated_from_its_kinematics(tmp_path):
    """The TX40's URDF through a robot file (gravity along +y, drive inertias in the base parameters): the generated
    MJCF's bodies are Pinocchio's joint frames of the URDF."""
    if not TX40_URDF.exists():
        pytest.skip(f"{TX40_URDF} is not present")
    source = tmp_path / "tx40.toml"
    source.write_text(f'name = "tx40"\ngravity = [0.0, 9.81, 0.0]\n[urdf]\npath = "{TX40_URDF}"\n'
                      "[assumptions]\ndrive_inertia = true\n")  # fmt: skip
    calibrated, robot, model = _calibrated(source)
    text = render_mjcf(calibrated, robot)
    result = mjcf_round_trip(calibrated, model, text, *_states(robot, 100))
    assert result.max_rel_error < 1e-9, result
    assert "generated from its kinematics" in text and 'gravity="0.0 9.81 0.0"' in text


def test_an_mjcf_robot_is_written_into_a_copy_of_its_file(tmp_path):
    """The arm of test_mjcf_robot (degrees, classes, a joint off its body origin and with ref, a welded tool, meshes
    that are absent): its own file with the identified bodies and joints, computing the model in MuJoCo."""
    source = tmp_path / "arm4.xml"
    source.write_text(ARM)
    calibrated, robot, model = _calibrated(source, findings=[SPRING], ia=IA)
    text = render_mjcf(calibrated)  # the robot rebuilt from the model file's copy of the MJCF
    result = mjcf_round_trip(calibrated, model, text, *_states(robot, 100))
    assert result.max_rel_error < 1e-9, result
    for kept in ('<mesh name="link" file="link.stl"/>', 'class="wrist"', 'ref="10"', '<site name="tcp"/>', "gear="):
        assert kept in text
    assert 'inertiafromgeom="false"' in text and "the inertia of this welded body is part of" in text
    assert "boundinertia" not in text and '<pair geom1="g1" geom2="g3"/>' in text
    assert text.count("<inertial pos") == 4  # the tool's is in link4's identified body
    from psdm_casadi.mjcf import compile_mjcf

    mj = compile_mjcf(text)
    k, c = SPRING["coefficients"]
    assert mj.jnt_stiffness[1] == k and mj.qpos_spring[1] == pytest.approx(-c / k, rel=1e-12)  # degrees in the file
    np.testing.assert_array_equal(mj.dof_armature, [IA.get(j + 1, 0.0) for j in range(4)])
    with pytest.raises(ModelFileError, match="read from MJCF .*psdm export-mjcf"):
        render_urdf(calibrated)


def test_an_mjcf_robot_with_locked_fingers_is_generated(tmp_path):
    """A robot file naming an MJCF gripper arm with its fingers locked: MuJoCo would keep the fingers moving in a
    copy of the file, so the MJCF is generated from the locked kinematics (the hand and fingers in link4's body)."""
    (tmp_path / "hand.xml").write_text(HAND)
    source = tmp_path / "arm.toml"
    source.write_text('name = "gripper arm"\n[urdf]\npath = "hand.xml"\nlocked_joints = ["f1", "f2"]\n')
    calibrated, robot, model = _calibrated(source, ia=IA)
    text = render_mjcf(calibrated)  # the robot rebuilt from the model file's copies of both files
    assert "generated from its kinematics" in text and "f1" not in text
    result = mjcf_round_trip(calibrated, model, text, *_states(robot, 100))
    assert result.max_rel_error < 1e-9, result


def test_a_model_without_standard_parameters_or_inconsistent_is_refused(tmp_path, scara):
    assert_refuses_bad_models(scara[0], render_mjcf, export_mjcf, tmp_path / "bad.xml")


def test_cli_export_mjcf_warns_writes_once_and_refuses_bad_input(tmp_path, capsys, scara):
    model = tmp_path / "model.json"
    model.write_text(model_text(scara[0].document))
    out = tmp_path / "robot.xml"
    assert main(["export-mjcf", str(model), str(out)]) == 0
    err = capsys.readouterr().err
    assert "torque_ripple[j1,h=3]" in err and "delay" in err and "torque offsets" in err and "spring[j2]" not in err
    first = out.read_text()
    assert first == render_mjcf(scara[0])
    assert main(["export-mjcf", str(model), str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err and out.read_text() == first
    assert main(["export-mjcf", str(model), str(out), "--overwrite", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["source"] == "generated" and len(summary["left_out"]) == 2  # the findings, the offsets
    assert main(["export-mjcf", str(model), str(tmp_path / "robot.urdf")]) == 2
    assert "OUT" in capsys.readouterr().err
    assert main(["export-mjcf", str(tmp_path / "missing.json"), str(tmp_path / "x.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert_cli_refuses_inconsistent("export-mjcf", model, tmp_path / "bad.xml", capsys)


def _sine_csv(robot, path, duration=8.0, seed=4):
    """Joint torques of the robot's own inertia along sums of sines about mid-range, with friction and noise, as a
    CSV a user would log (t, q1..qn, tau1..taun)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 2e-3)
    q, qd, qdd = sines_about_mid_range(robot, t, rng, (0.15, 0.5), 0.25)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + 0.3 * np.tanh(qd / 0.05) + 0.2 * qd
    tau += rng.normal(scale=0.02, size=tau.shape)
    n = robot.n_dof
    header = ",".join(["t", *(f"q{j + 1}" for j in range(n)), *(f"tau{j + 1}" for j in range(n))])
    np.savetxt(path, np.column_stack([t, q, tau]), delimiter=",", header=header, comments="")
    return q, qd, qdd


@pytest.mark.slow  # identifies the 4-joint arm from a recording: about 15 s
def test_a_user_takes_an_mjcf_arm_from_a_recording_back_to_mujoco(tmp_path, capsys):
    """psdm identify arm4.xml --data rec.csv, then psdm export-mjcf: MuJoCo computes the identified model."""
    source = tmp_path / "arm4.xml"
    source.write_text(ARM)
    robot = load_robot(source)
    q, qd, qdd = _sine_csv(robot, tmp_path / "rec.csv")
    model_file, out = tmp_path / "model.json", tmp_path / "arm4_identified.xml"
    assert main(["identify", str(source), "--data", str(tmp_path / "rec.csv"), "--out", str(model_file)]) == 0
    assert main(["export-mjcf", str(model_file), str(source), "--overwrite"]) == 2  # never the robot's own file
    assert main(["export-mjcf", str(model_file), str(out)]) == 0
    capsys.readouterr()
    from identification.calibration.calibrated_model import load_calibrated_model

    calibrated = load_calibrated_model(model_file)
    result = mjcf_round_trip(calibrated, derive_psdm(robot), out.read_text(), q[::20], qd[::20], qdd[::20])
    assert result.max_rel_error < 1e-9, result
    assert 'class="wrist"' in out.read_text() and source.read_text() == ARM
