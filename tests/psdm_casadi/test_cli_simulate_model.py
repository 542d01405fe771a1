"""``psdm simulate MODEL.json`` and the drive-inertia columns of ``psdm codegen MODEL.json``, end to end.

The calibrated model is identified here from the virtual Denso (rotor inertia and LuGre friction in
the plant) with a robot file whose rigid body has no drive inertia, so the fit adds ``Ia<j>`` columns.
That one file serves both checks:

- ``psdm simulate model.json`` writes the model's torques: equal to Pinocchio's rigid body of the
  file's standard parameters (drive inertias as armature) plus the friction formula, on the
  recording's own states; and ``psdm identify`` on a noisy simulated recording recovers the file's
  base parameters within three of their reported standard deviations;
- ``psdm codegen model.json --compile``: the compiled inverse dynamics equals ``predict``, the compiled
  mass matrix equals Pinocchio's with the identified drive inertias as armature.
"""

import json
import shutil

import casadi as ca
import numpy as np
import pytest

from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import load_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.derive import derive_psdm
from psdm_casadi.oracle import PinocchioOracle
from psdm_casadi.robot import load_robot
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _without_drive_inertia(text: str) -> str:
    """The Denso's robot file with no rotor inertia in its rigid body (and none in its prior)."""
    text = text.replace("drive_inertia = true", "drive_inertia = false")
    return "\n".join(line for line in text.splitlines() if not line.startswith("rotor_inertia")) + "\n"


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory, denso):
    """(folder, robot without drive inertia, its PSDM model, saved model path): the calibrated model.json."""
    folder = tmp_path_factory.mktemp("simulate_model")
    robot_file = folder / "denso_no_rotor.toml"
    robot_file.write_text(_without_drive_inertia(DENSO_FILE.read_text()))
    robot = load_robot(robot_file)
    model = derive_psdm(robot)
    model.save(folder / "model.npz")
    rng = np.random.default_rng(41)
    reference = sine_experiment(denso, duration=12.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    recording, _ = simulate_recording(denso, reference, options, rng)  # the plant has rotor inertias
    fit = identify_trajectories(robot, model, [recording], TrajectoryOptions())
    CalibratedModel.from_fit(robot, model, fit, robot_source=robot_file).save(folder / "model.json")
    return folder, robot, model


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def test_the_fit_gives_drive_inertia_columns_where_the_rigid_body_has_none(calibrated):
    folder, _, _ = calibrated
    drive = load_calibrated_model(folder / "model.json").document["drive"]
    assert drive["inertia_joints"] and all(f"Ia{j}" in drive["names"] for j in drive["inertia_joints"])
    values = dict(zip(drive["names"], drive["values"]))
    assert all(values[f"Ia{j}"] > 0 for j in drive["inertia_joints"])  # the plant's rotors are there


def _friction(calibrated, qd):
    """fc tanh(qd / v) + fv qd per joint, from the file's labelled values (independent of drive_columns)."""
    drive = calibrated.document["drive"]
    values = dict(zip(drive["names"], drive["values"]))
    fc = np.array([values[f"fc{j + 1}"] for j in range(calibrated.n_dof)])
    fv = np.array([values[f"fv{j + 1}"] for j in range(calibrated.n_dof)])
    return fc * np.tanh(qd / drive["coulomb_velocity"]) + fv * qd


def test_simulated_torques_are_the_models_own(calibrated, tmp_path, capsys):
    folder, robot, _ = calibrated
    out = tmp_path / "exact"
    argv = ["simulate", str(folder / "model.json"), "--experiment", "sine", "--duration", "4", "--rate", "200"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["recordings"][0]["samples"] == 801 and summary["tau_noise_std"] == 0.0
    recording = load_recording(out / "sine.csv", robot.n_dof)
    model_file = load_calibrated_model(folder / "model.json")
    oracle = PinocchioOracle(robot, model_file.standard)  # drive inertias as Pinocchio's armature
    x = (recording.q, recording.qd, recording.qdd)
    expected = oracle.rnea(*x) + _friction(model_file, recording.qd)
    np.testing.assert_allclose(recording.tau, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    assert main([*argv, "--out", str(out)]) == 2  # an existing recording is not replaced without --overwrite
    assert "--overwrite" in capsys.readouterr().err


@pytest.mark.slow
def test_identify_on_a_simulated_recording_recovers_the_models_base_parameters(calibrated, tmp_path, capsys):
    folder, _, model = calibrated
    sim = tmp_path / "sim"
    argv = ["simulate", str(folder / "model.json"), "--experiment", "sine", "--duration", "20", "--rate", "500"]
    assert main([*argv, "--tau-noise", "0.1", "--seed", "5", "--out", str(sim), "--json"]) == 0
    capsys.readouterr()
    robot_file = str(folder / "denso_no_rotor.toml")
    out = tmp_path / "again.json"
    argv = ["identify", robot_file, "--data", str(sim / "sine.csv"), "--model", str(folder / "model.npz")]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    truth = load_calibrated_model(folder / "model.json").theta
    again = load_calibrated_model(out)
    z = (np.array(again.document["base"]["ols"]) - truth) / np.array(again.document["base"]["std"])
    assert np.abs(z).max() < 3.0, np.round(z, 2)
    assert summary["consistent"] and len(truth) == model.n_base


def test_simulate_model_refuses_what_it_cannot_do(calibrated, tmp_path, capsys):
    folder, _, _ = calibrated
    base = ["simulate", str(folder / "model.json"), "--out", str(tmp_path / "x")]
    assert main([*base, "--experiment", "motor"]) == 2
    assert "--experiment motor needs the virtual robot" in capsys.readouterr().err
    assert main([*base, "--experiment", "sine", "--tau-noise", "-1"]) == 2
    assert "--tau-noise must be >= 0" in capsys.readouterr().err
    assert main([*base, "--experiment", "sine", "--lock", "joint1=0"]) == 2
    assert "--lock must not be given with a calibrated model" in capsys.readouterr().err
    (tmp_path / "other.json").write_text("{}")
    assert main(["simulate", str(tmp_path / "other.json"), "--experiment", "sine", "--out", str(tmp_path / "y")]) == 2
    assert "format must be" in capsys.readouterr().err


@pytest.mark.needs_cc
@needs_cc
def test_exported_drive_inertia_columns_match_predict_and_pinocchio_armature(calibrated, tmp_path, capsys):
    folder, robot, model = calibrated
    out = tmp_path / "c_code"
    assert main(["codegen", str(folder / "model.json"), "--out", str(out), "--compile", "--json"]) == 0
    capsys.readouterr()
    library = str(out / "libpsdm_dynamics.so")
    inverse, mass = ca.external("psdm_inverse_dynamics", library), ca.external("psdm_mass_matrix", library)
    model_file = load_calibrated_model(folder / "model.json")
    rng = np.random.default_rng(8)
    q = rng.uniform(robot.q_min, robot.q_max, (100, robot.n_dof))
    qd, qdd = rng.normal(size=(2, *q.shape))
    tau = np.array(inverse.map(q.shape[0])(q.T, qd.T, qdd.T), dtype=float).T
    predicted = model_file.predict(model, q, qd, qdd)
    assert np.max(np.abs(tau - predicted).max(axis=0) / np.abs(predicted).max(axis=0)) < 1e-9
    oracle = PinocchioOracle(robot, model_file.standard)
    inertia_joints = [j - 1 for j in model_file.document["drive"]["inertia_joints"]]
    assert np.all(model_file.standard[inertia_joints, 10] > 0)  # the armature Pinocchio adds
    for k in range(10):
        compiled = np.array(mass(q[k]), dtype=float)
        reference = oracle.crba(q[k])
        np.testing.assert_allclose(compiled, reference, rtol=1e-9, atol=1e-9 * np.abs(reference).max())


@pytest.mark.slow
def test_a_negative_drive_inertia_in_the_data_is_named_with_its_likely_cause(calibrated, tmp_path, capsys):
    """Torques with less inertia than any rotor adds (as a link-side torque sensor can show): dropped by default,
    a warning when the column is asked for."""
    folder, _, _ = calibrated
    document = json.loads((folder / "model.json").read_text())
    drive = document["drive"]
    joint = drive["inertia_joints"][0]
    drive["values"][drive["names"].index(f"Ia{joint}")] = -0.3
    (tmp_path / "negative.json").write_text(json.dumps(document))
    sim = tmp_path / "sim"
    argv = ["simulate", str(tmp_path / "negative.json"), "--experiment", "sine", "--duration", "10", "--rate", "200"]
    assert main([*argv, "--tau-noise", "0.05", "--out", str(sim)]) == 0
    capsys.readouterr()
    argv = ["identify", str(folder / "denso_no_rotor.toml"), "--data", str(sim / "sine.csv"), "--model",
            str(folder / "model.npz")]  # fmt: skip
    assert main([*argv, "--drive-inertia", "on", "--out", str(tmp_path / "m.json")]) == 0
    err = capsys.readouterr().err
    assert f"negative drive inertia on joint {joint}" in err and "--drive-inertia auto" in err
    # by default the data decide: the column is dropped, stated, and nothing is left to warn about
    assert main([*argv, "--out", str(tmp_path / "auto.json")]) == 0
    out, err = capsys.readouterr()
    assert (
        "negative drive inertia" not in err
        and f"Ia{joint}" not in json.loads((tmp_path / "auto.json").read_text())["drive"]["names"]
    )
    assert "the data want it negative" in out


def test_simulate_model_follows_a_reference_file(calibrated, tmp_path, capsys, denso):
    folder, robot, _ = calibrated
    experiment = sine_experiment(denso, duration=3.0, rng=np.random.default_rng(9))
    experiment.to_csv(tmp_path / "traj.csv", rate=100.0)
    out = tmp_path / "ref"
    assert main(["simulate", str(folder / "model.json"), "--reference", str(tmp_path / "traj.csv"), "--rate", "100",
                 "--out", str(out)]) == 0  # fmt: skip
    recording = load_recording(out / "reference.csv", robot.n_dof)
    q, qd, qdd = experiment.sample(recording.t)  # the knots of the file are the experiment's samples
    np.testing.assert_allclose(recording.q, q, atol=1e-9)
    model_file = load_calibrated_model(folder / "model.json")
    expected = PinocchioOracle(robot, model_file.standard).rnea(q, qd, qdd) + _friction(model_file, qd)
    np.testing.assert_allclose(recording.tau, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())


@pytest.mark.slow
def test_identify_with_the_stribeck_shape_writes_it_and_validate_reproduces_it(calibrated, tmp_path, capsys):
    folder, robot, _ = calibrated
    sim = tmp_path / "sim"
    for name, seed in (("train", "11"), ("valid", "12")):
        argv = ["simulate", str(folder / "model.json"), "--experiment", "sine", "--duration", "10", "--rate", "200"]
        assert main([*argv, "--tau-noise", "0.05", "--seed", seed, "--out", str(sim / name)]) == 0
    capsys.readouterr()
    out = tmp_path / "stribeck.json"
    argv = ["identify", str(folder / "denso_no_rotor.toml"), "--data", str(sim / "train" / "sine.csv"),
            "--model", str(folder / "model.npz"), "--friction", "stribeck",
            "--validate", str(sim / "valid" / "sine.csv")]  # fmt: skip
    assert main([*argv, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert len(summary["stribeck_velocity"]) == robot.n_dof and all(v > 0 for v in summary["stribeck_velocity"])
    assert {"fs1", "fc1", "fv1"} <= set(summary["drive"])
    drive = load_calibrated_model(out).document["drive"]
    assert drive["friction_shape"] == "stribeck" and drive["stribeck_velocity"] == summary["stribeck_velocity"]
    assert main(["validate", str(out), str(sim / "valid" / "sine.csv"), "--json"]) == 0
    validated = json.loads(capsys.readouterr().out)["recordings"][0]["rmse"]
    np.testing.assert_allclose(validated, summary["validation"][0]["rmse"], rtol=1e-9)
    # --friction lugre on recordings is built now: tests/identification/test_lugre_recordings.py
