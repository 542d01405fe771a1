"""URDF out: the written URDF, loaded by Pinocchio, computes the calibrated model's torques (issue 15, part 3).

The oracle is Pinocchio's URDF parser and rnea on the written file (with the locked joints locked
again, the drive inertias added back as ``model.armature`` from the file's comments, and the
friction Pinocchio read from ``<dynamics>``) against ``CalibratedModel.predict``.
"""

import json
import re

import numpy as np
import pinocchio as pin
import pytest

from codegen.urdf_export import export_urdf, render_urdf, urdf_armature
from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.trajectory_fit import identify_trajectories
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi import derive_psdm, load_robot
from psdm_casadi.cli import main
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import BUILTIN_ROBOTS_DIR, from_urdf
from tests.codegen.export_refusals import assert_cli_refuses_inconsistent, assert_refuses_bad_models
from tests.codegen.sine_motion import sines_about_mid_range
from tests.conftest import DATASETS, DENSO_FILE, example_robot_urdf
from trajopt.experiments import sine_experiment

PANDA_LOCKED = ("panda_finger_joint1", "panda_finger_joint2")
TX40_URDF = DATASETS / "staubli_tx40_figaroh" / "tx40_mdh_modified.urdf"
ARMATURE = re.compile(r"<!-- psdm: drive inertia \(armature, reflected to the joint\) Ia = (\S+) kg")


def _sine_recording(robot, duration: float, rng) -> Recording:
    """Joint torques of the robot file's inertia along sums of sines about mid-range, with friction and noise."""
    t = np.arange(0.0, duration, 1e-3)
    q, qd, qdd = sines_about_mid_range(robot, t, rng, (0.1, 0.4), 0.3)
    tau = PinocchioOracle(robot).rnea(q, qd, qdd) + 0.4 * np.tanh(qd / 0.05) + 0.2 * qd
    return Recording(t=t, q=q, tau=tau + rng.normal(scale=0.05, size=tau.shape), name=f"sines {robot.name}")


def _calibrate(robot, model, source, path, *, duration=10.0, seed=3):
    """A calibrated-model file of ``robot`` from one recording with friction and torque noise.

    Robots with drives (the Denso): the virtual robot along a sine experiment; others: :func:`_sine_recording`.
    """
    rng = np.random.default_rng(seed)
    if robot.drives is not None:
        reference = sine_experiment(robot, duration=duration, rng=rng).reference()
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
        recording, _ = simulate_recording(robot, reference, options, rng)
    else:
        recording = _sine_recording(robot, duration, rng)
    fit = identify_trajectories(robot, model, [recording])
    assert fit.consistent
    CalibratedModel.from_fit(robot, model, fit, robot_source=source).save(path)
    return load_calibrated_model(path)


def _round_trip_error(calibrated, model, urdf, robot, n_samples=50, seed=0):
    """Largest relative difference between Pinocchio on the written URDF and the calibrated model's torque."""
    text = urdf.read_text()
    pin_model = pin.buildModelFromUrdf(str(urdf))
    if robot.locked_joints:
        locked = [(item, 0.0) if isinstance(item, str) else item for item in robot.locked_joints]
        reference = pin.neutral(pin_model)
        for name, value in locked:
            reference[pin_model.joints[pin_model.getJointId(name)].idx_q] = value
        pin_model = pin.buildReducedModel(pin_model, [pin_model.getJointId(name) for name, _ in locked], reference)
    assert tuple(pin_model.names)[1:] == robot.joint_names
    armature = np.array([float(x) for x in ARMATURE.findall(text)])  # the drive inertias, from the file's comments
    np.testing.assert_array_equal(armature, urdf_armature(calibrated, robot))
    pin_model.armature = armature
    pin_model.gravity.linear = np.array([0.0, 0.0, -np.linalg.norm(robot.gravity)])  # the file's root has g along -z
    data = pin_model.createData()
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max, size=(n_samples, robot.n_dof))
    qd, qdd = rng.normal(size=(2, n_samples, robot.n_dof))
    velocity = calibrated.document["drive"]["coulomb_velocity"]
    ours = np.array([pin.rnea(pin_model, data, *x) for x in zip(q, qd, qdd)])
    ours += pin_model.damping * qd + pin_model.friction * np.tanh(qd / velocity)  # <dynamics> as Pinocchio read it
    expected = calibrated.predict(model, q, qd, qdd)
    return float(np.abs(ours - expected).max() / np.abs(expected).max())


@pytest.fixture(scope="module")
def denso_calibrated(tmp_path_factory, denso, denso_model):
    return _calibrate(denso, denso_model, DENSO_FILE, tmp_path_factory.mktemp("denso") / "model.json")


def test_the_denso_dh_urdf_computes_the_calibrated_torques(tmp_path, denso, denso_model, denso_calibrated):
    path = export_urdf(denso_calibrated, tmp_path / "denso.urdf")
    error = _round_trip_error(denso_calibrated, denso_model, path, denso)
    assert error < 1e-9, error
    text = path.read_text()
    # gravity is along +x of the Denso's base frame: a root 'world' turns it to -z
    assert '<link name="world"/>' in text and "NOT physically" not in text
    model = pin.buildModelFromUrdf(str(path))
    drive = dict(zip(denso_calibrated.document["drive"]["names"], denso_calibrated.drive))
    np.testing.assert_array_equal(model.friction, [drive[f"fc{j + 1}"] for j in range(6)])
    np.testing.assert_array_equal(model.damping, [drive[f"fv{j + 1}"] for j in range(6)])
    np.testing.assert_array_equal(model.lowerPositionLimit, denso.q_min)
    np.testing.assert_array_equal(model.velocityLimit, denso.qd_max)
    # link<i> is DH frame i: the flange frame of the URDF is the robot's forward kinematics
    back = from_urdf(path)
    assert back.joint_names == denso.joint_names and np.all(back.tau_max == denso.tau_max)
    with pytest.raises(FileExistsError):
        export_urdf(denso_calibrated, path)


@pytest.mark.slow  # deriving the Panda: about 8 s
def test_the_panda_urdf_keeps_its_file_and_merges_the_hand_into_link7(tmp_path):
    urdf = example_robot_urdf("panda_description/urdf/panda.urdf")
    robot = from_urdf(urdf, locked_joints=PANDA_LOCKED)
    model = derive_psdm(robot)
    calibrated = _calibrate(robot, model, urdf, tmp_path / "panda.json", duration=5.0)
    path = export_urdf(calibrated, tmp_path / "panda.urdf")
    error = _round_trip_error(calibrated, model, path, robot)
    assert error < 1e-9, error
    text = path.read_text()
    assert text.count("<visual>") == urdf.read_text().count("<visual>")  # the rest of the file is kept
    assert "links 'panda_link8', 'panda_hand'" in text and "mass 0, its inertia is part of link 'panda_link7'" in text
    unlocked = pin.buildModelFromUrdf(str(path))  # the fingers: still prismatic joints, now massless
    finger = unlocked.getJointId("panda_finger_joint1")
    assert unlocked.inertias[finger].mass == 0.0 and unlocked.nq == 9
    assert unlocked.inertias[1].mass == pytest.approx(calibrated.standard[0, 0], rel=1e-15)


def test_the_tx40_from_a_robot_file_round_trips_with_its_base_turned(tmp_path):
    """A robot file with a [urdf] table: drive inertias in the model, gravity along +y of the URDF's base."""
    if not TX40_URDF.exists():
        pytest.skip(f"{TX40_URDF} is not present")
    source = tmp_path / "tx40.toml"
    source.write_text(f'name = "tx40"\ngravity = [0.0, 9.81, 0.0]\n[urdf]\npath = "{TX40_URDF}"\n'
                      "[assumptions]\ndrive_inertia = true\n")  # fmt: skip
    robot = load_robot(source)
    model = derive_psdm(robot)
    calibrated = _calibrate(robot, model, source, tmp_path / "tx40.json", duration=8.0)
    path = export_urdf(calibrated, tmp_path / "tx40.urdf")
    error = _round_trip_error(calibrated, model, path, robot)
    assert error < 1e-9, error
    text = path.read_text()
    # the recording holds no drive inertia: the model's are >= 0 (some at their bound 0), and some joint's is carried
    armature = urdf_armature(calibrated, robot)
    assert "RAL 1028" in text and '<child link="base_link"/>' in text and np.all(armature >= 0) and armature.max() > 0


@pytest.mark.parametrize("variant", ["modified", "scara"])
def test_modified_dh_and_prismatic_robots_round_trip(tmp_path, variant):
    """The Denso's rows read in the modified convention (another arm), and the SCARA's prismatic joint."""
    if variant == "modified":
        source = tmp_path / "denso_modified.toml"
        source.write_text(DENSO_FILE.read_text().replace('convention = "standard"', 'convention = "modified"'))
    else:
        source = BUILTIN_ROBOTS_DIR / "scara.toml"
    robot = load_robot(source)
    assert robot.convention == "standard" if variant == "scara" else robot.convention == "modified"
    model = derive_psdm(robot)
    calibrated = _calibrate(robot, model, source, tmp_path / "model.json", duration=8.0)
    path = export_urdf(calibrated, tmp_path / "robot.urdf")
    error = _round_trip_error(calibrated, model, path, robot)
    assert error < 1e-9, error
    back = from_urdf(path)
    assert [j.kind for j in back.joints] == [j.kind for j in robot.joints]
    assert ("world" in path.read_text()) == (variant == "modified")  # the Denso's gravity is along +x


def test_a_model_without_standard_parameters_or_inconsistent_is_refused(tmp_path, denso_calibrated):
    assert_refuses_bad_models(denso_calibrated, render_urdf, export_urdf, tmp_path / "bad.urdf")


def test_cli_export_urdf_writes_once_and_refuses_to_overwrite(tmp_path, capsys, denso_calibrated):
    model = tmp_path / "model.json"
    model.write_text(json.dumps(denso_calibrated.document))
    out = tmp_path / "out.urdf"
    assert main(["export-urdf", str(model), str(out)]) == 0
    first = out.read_text()
    assert first == render_urdf(denso_calibrated)
    assert main(["export-urdf", str(model), str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err and out.read_text() == first
    assert main(["export-urdf", str(model), str(out), "--overwrite", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["source"] == "dh" and summary["consistent"] is True
    assert_cli_refuses_inconsistent("export-urdf", model, tmp_path / "bad.urdf", capsys)
    assert main(["export-urdf", str(model), str(tmp_path / "bad.urdf"), "--allow-inconsistent"]) == 0
    assert "INCONSISTENT" in capsys.readouterr().err
    assert main(["export-urdf", str(tmp_path / "missing.json"), str(tmp_path / "x.urdf")]) == 2
    assert "does not exist" in capsys.readouterr().err
    model.write_text(json.dumps(denso_calibrated.document))  # consistent again
    deep = tmp_path / "new" / "sub" / "out.urdf"  # a folder that does not exist: made, and said so
    assert main(["export-urdf", str(model), str(deep)]) == 0 and deep.read_text() == first
    assert f"note: created the folder '{tmp_path / 'new'}' for OUT" in capsys.readouterr().err
    assert main(["export-urdf", str(model), str(tmp_path / "new" / "again.urdf")]) == 0
    assert "created the folder" not in capsys.readouterr().err
