"""A model file whose Coulomb smoothing width differs per joint (``drive.coulomb_velocity`` a list, ``coulomb_width``).

Virtual SCARA at its robot file's inertia with Coulomb-viscous friction smoothed over a different width on each joint
(0.02, 0.1 rad/s, 0.01 m/s, 0.15 rad/s). The model file that states those widths is predicted as the truth by
``CalibratedModel.predict`` (against the torque written out by hand), by ``psdm validate``, by its generated C and by
the nominal model of ``diagnose MODEL``; the same file with one width (0.05) is not. A file with one number still
predicts as the same widths listed per joint; a list of the wrong length or a width <= 0 is an exit-2 error naming the
field.
"""

from __future__ import annotations

import copy
import json
import shutil

import numpy as np
import pytest

from identification.calibration.calibrated_model import (
    WIDTH_VERSION,
    CalibratedModel,
    calibrated_robot,
    read_calibrated_model,
)
from identification.calibration.finding_value import validation_rmse
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.data.recording import Recording
from identification.diagnosis.candidates import SpringTerm, TorqueOffsetTerm
from identification.diagnosis.diagnose import DiagnosisOptions, diagnose
from identification.diagnosis.model_file import model_file_options
from psdm_casadi.cli import main
from psdm_casadi.errors import ModelFileError, ParameterError
from psdm_casadi.oracle import PinocchioOracle
from tests.catalogue.model_files import model_document, model_text

WIDTHS = [0.02, 0.1, 0.01, 0.15]  # [rad/s, rad/s, m/s, rad/s] per joint of the SCARA
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _truth(robot, document, q, qd, qdd, widths):
    """The SCARA's torque written out: Pinocchio's rigid body plus ``fc_j tanh(qd_j / v_j) + fv_j qd_j``."""
    values = dict(zip(document["drive"]["names"], document["drive"]["values"]))
    fc = np.array([values[f"fc{j + 1}"] for j in range(4)])
    fv = np.array([values[f"fv{j + 1}"] for j in range(4)])
    return PinocchioOracle(robot).rnea(q, qd, qdd) + fc * np.tanh(qd / np.asarray(widths)) + fv * qd


def _motion(seed, duration=5.0, rate=200.0):
    """Two sines per joint about the middle of the SCARA's range: (t, q, qd, qdd)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    centre, amplitude = np.array([0.0, 0.0, 0.1, 0.0]), np.array([0.6, 0.6, 0.035, 1.0])
    w, phase = rng.uniform(1.5, 3.0, (4, 2)), rng.uniform(0.0, 2 * np.pi, (4, 2))
    arg = w[None] * t[:, None, None] + phase[None]
    a = amplitude[:, None] / w
    q = centre + (a * np.sin(arg)).sum(2)
    qd, qdd = (a * w * np.cos(arg)).sum(2), -(a * w**2 * np.sin(arg)).sum(2)
    return t, q, qd, qdd


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    folder = tmp_path_factory.mktemp("widths")
    uniform = model_document()  # one width, 0.05 (as every file written so far)
    per_joint = copy.deepcopy(uniform)
    per_joint["drive"]["coulomb_velocity"] = list(WIDTHS)
    for name, document in (("uniform.json", uniform), ("per_joint.json", per_joint)):
        (folder / name).write_text(model_text(document))
    loaded = read_calibrated_model(folder / "per_joint.json")
    recordings = []
    for seed in (0, 1):
        t, q, qd, qdd = _motion(seed)
        tau = _truth(loaded.robot, per_joint, q, qd, qdd, WIDTHS)
        tau = tau + np.random.default_rng(10 + seed).normal(scale=0.005, size=tau.shape)
        recordings.append(Recording(t=t, q=q, tau=tau, name=f"scara{seed}"))
        save_recording(recordings[-1], folder / f"scara{seed}.csv")
    return folder, loaded, CalibratedModel(uniform), recordings


@pytest.fixture(autouse=True)
def _robot_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # load_robot's copies of the robot texts


def test_predict_smooths_each_joint_over_its_own_width(case):
    _, loaded, uniform, _ = case
    t, q, qd, qdd = _motion(2)
    document = loaded.calibrated.document
    np.testing.assert_array_equal(loaded.calibrated.coulomb_widths, WIDTHS)
    want = _truth(loaded.robot, document, q, qd, qdd, WIDTHS)
    np.testing.assert_allclose(loaded.calibrated.predict(loaded.model, q, qd, qdd), want, atol=1e-9)
    assert np.abs(uniform.predict(loaded.model, q, qd, qdd) - want).max() > 0.1  # one width predicts otherwise


def test_one_number_predicts_as_the_same_width_listed_per_joint(case):
    _, loaded, uniform, _ = case
    listed = copy.deepcopy(uniform.document)
    listed["drive"]["coulomb_velocity"] = [uniform.document["drive"]["coulomb_velocity"]] * 4
    _, q, qd, qdd = _motion(3)
    np.testing.assert_array_equal(CalibratedModel(listed).predict(loaded.model, q, qd, qdd),
                                  uniform.predict(loaded.model, q, qd, qdd))  # fmt: skip


def test_validate_and_the_diagnosis_nominal_predict_the_files_widths(case, capsys):
    folder, loaded, uniform, (train, held) = case
    rmse = {}
    for name in ("per_joint", "uniform"):
        assert main(["validate", str(folder / f"{name}.json"), str(folder / "scara1.csv"), "--json"]) == 0
        rmse[name] = np.array(json.loads(capsys.readouterr().out)["recordings"][0]["rmse"])
    own = validation_rmse(loaded.calibrated, loaded.model, held)[0]
    np.testing.assert_allclose(rmse["per_joint"], own, rtol=1e-9)
    assert rmse["per_joint"].max() < 0.05  # the filter's share at the sharpest reversals (joint 1)
    assert np.all(rmse["uniform"][1:] > 5 * rmse["per_joint"][1:])
    quick = DiagnosisOptions(rigid_body="prior", library=SpringTerm() + TorqueOffsetTerm(), sparse=False, cv_folds=0)
    options = model_file_options(loaded.calibrated, quick)
    assert options.coulomb_velocity == tuple(WIDTHS)
    robot = calibrated_robot(loaded.calibrated, loaded.robot)
    nominal = diagnose(robot, train, held, options, model=loaded.model)
    np.testing.assert_allclose(nominal.rmse_before, own, rtol=0.05)  # its friction refitted: the file's, per joint


@needs_cc
@pytest.mark.needs_cc
def test_the_generated_c_smooths_each_joint_over_its_own_width(case, tmp_path):
    from codegen.build import build_library
    from codegen.calibrated import build_calibrated_functions, header_note
    from codegen.export import export_c

    _, loaded, uniform, _ = case
    functions = build_calibrated_functions(loaded.calibrated, loaded.model, loaded.robot)
    library = build_library(export_c(functions, tmp_path / "out"), flags=("-O1",))
    _, q, qd, qdd = _motion(4, duration=1.0)
    mapped = library.function("psdm_inverse_dynamics").map(q.shape[0])
    tau = np.array(mapped(q.T, qd.T, qdd.T), dtype=float).T
    predicted = loaded.calibrated.predict(loaded.model, q, qd, qdd)
    np.testing.assert_allclose(tau, predicted, rtol=0, atol=1e-9 * np.abs(predicted).max())
    assert np.abs(tau - uniform.predict(loaded.model, q, qd, qdd)).max() > 0.1
    note = header_note(loaded.calibrated)
    assert "fc_j tanh(qd_j / v_j)" in note and "v2 = 0.10000000000000001" in note


@pytest.mark.parametrize("widths", [[0.02, 0.1, 0.01], [0.02, -0.1, 0.01, 0.15], "wide"], ids=["3", "negative", "text"])
def test_a_wrong_width_list_is_an_exit_2_error_naming_the_field(case, widths, tmp_path, capsys):
    folder, _, uniform, _ = case
    document = copy.deepcopy(uniform.document)
    document["drive"]["coulomb_velocity"] = widths
    (tmp_path / "bad.json").write_text(model_text(document))
    with pytest.raises(ModelFileError, match=r"bad\.json: drive\.coulomb_velocity must be one positive number"):
        read_calibrated_model(tmp_path / "bad.json")
    assert main(["validate", str(tmp_path / "bad.json"), str(folder / "scara1.csv")]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "drive.coulomb_velocity" in err and "one per joint" in err


def test_a_fit_with_a_width_per_joint_writes_them_and_predicts_the_truth(case, tmp_path):
    folder, loaded, _, (train, held) = case
    robot, model = loaded.robot, loaded.model
    rmse = {}
    for name, widths in (("per_joint", tuple(WIDTHS)), ("uniform", 0.05)):
        options = TrajectoryOptions(friction=("fc", "fv"), coulomb_velocity=widths, drive_inertia=False,
                                    consistency=False)  # the least-squares fit: the widths' part, no Ipopt  # fmt: skip
        fit = identify_trajectories(robot, model, [train], options)
        assert fit.coulomb_velocity == widths
        written = CalibratedModel.from_fit(robot, model, fit, robot_source="scara").save(
            tmp_path / f"{name}.json", allow_inconsistent=True
        )
        again = read_calibrated_model(written).calibrated
        assert again.document["version"] == (WIDTH_VERSION if name == "per_joint" else 2)
        assert again.document["drive"]["coulomb_velocity"] == (WIDTHS if name == "per_joint" else 0.05)
        rmse[name] = validation_rmse(again, model, held)[0]
    assert np.all(rmse["per_joint"][1:] * 5 < rmse["uniform"][1:]), rmse
    assert rmse["per_joint"].max() < 0.05, rmse


def test_one_width_repeated_is_one_width_and_a_wrong_one_names_the_option(case):
    _, loaded, _, (train, _) = case
    assert TrajectoryOptions(coulomb_velocity=(0.05,) * 4).coulomb_velocity == 0.05  # written as before: version 2
    with pytest.raises(ParameterError, match="TrajectoryOptions.coulomb_velocity must be a positive width"):
        TrajectoryOptions(coulomb_velocity=(0.05, -0.1))
    with pytest.raises(ParameterError, match=r"TrajectoryOptions.coulomb_velocity must be .* or 4, one per joint"):
        identify_trajectories(loaded.robot, loaded.model, [train], TrajectoryOptions(coulomb_velocity=(0.02, 0.05)))


def test_the_command_line_takes_a_width_per_joint(case, tmp_path, capsys):
    folder, _, _, _ = case
    argv = ["identify", "scara", "--data", str(folder / "scara0.csv"), "--friction", "coulomb-viscous",
            "--offset", "off", "--no-drive-inertia", "--no-consistency"]  # fmt: skip
    asked = ["--coulomb-velocity", ",".join(map(str, WIDTHS)), "--out", str(tmp_path / "m.json"), "--json"]
    assert main([*argv, *asked]) == 0
    columns = json.loads(capsys.readouterr().out)["columns"]
    assert columns["request"]["coulomb_velocity"] == WIDTHS
    assert (
        columns["smoothing"] == "Coulomb smoothing: tanh(qd / 0.02, 0.1, 0.01, 0.15 rad/s (joints 1 to 4)) (as asked)"
    )
    assert read_calibrated_model(tmp_path / "m.json").calibrated.document["drive"]["coulomb_velocity"] == WIDTHS
    for bad in ("0.02,0.1", "0.02,0.1,0,0.15", "fast"):
        assert main([*argv, "--coulomb-velocity", bad, "--out", str(tmp_path / "no.json")]) == 2
        err = capsys.readouterr().err
        assert "--coulomb-velocity must be a velocity > 0" in err and "one per joint separated by commas" in err
        assert not (tmp_path / "no.json").exists()
