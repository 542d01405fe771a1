"""Identification from exciting trajectories: the consistency chart, the normal equations, known truth, real data."""

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from identification.calibration.pseudo_inertia import (
    link_from_log_cholesky,
    link_from_pseudo_inertia,
    log_cholesky_from_link,
    pseudo_inertia,
    pseudo_inertia_eigenvalues,
)
from identification.calibration.trajectory_data import NormalEquations, choose_filter, drive_columns
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.description import physical_to_dynamic
from psdm_casadi.errors import ModelFileError, ParameterError
from psdm_casadi.oracle import PinocchioOracle
from trajopt.experiments import sine_experiment


def _box_link(mass, com, sides):
    """Standard parameters of a solid box (an independent, textbook consistent body)."""
    a, b, c = sides
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return physical_to_dynamic(mass, com, inertia)


def test_the_chart_covers_consistent_links_and_only_them():
    rng = np.random.default_rng(0)
    for _ in range(20):
        link = _box_link(rng.uniform(0.1, 5), rng.normal(size=3) * 0.2, rng.uniform(0.01, 0.5, size=3))
        assert pseudo_inertia_eigenvalues(np.append(link, 0.0)[None])[0] > 0
        np.testing.assert_allclose(link_from_pseudo_inertia(pseudo_inertia(link)), link, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(link_from_log_cholesky(log_cholesky_from_link(link)), link, rtol=1e-10,
                                   atol=1e-13)  # fmt: skip
        phi = rng.normal(size=10)  # any point of the chart is a consistent link ...
        assert np.linalg.eigvalsh(pseudo_inertia(link_from_log_cholesky(phi)))[0] > 0
        symbol = ca.SX.sym("phi", 10)  # ... and the CasADi form is the same function
        casadi_link = ca.Function("link", [symbol], [link_from_log_cholesky(symbol, margin=1e-3)])(phi)
        np.testing.assert_allclose(np.asarray(casadi_link).ravel(), link_from_log_cholesky(phi, margin=1e-3),
                                   rtol=1e-12)  # fmt: skip
    # a body whose principal moments break the triangle inequality (Izz > Ixx + Iyy) is not consistent,
    # although its mass and inertia matrix are positive
    impossible = physical_to_dynamic(1.0, np.zeros(3), np.diag([0.1, 0.1, 0.3]))
    assert pseudo_inertia_eigenvalues(np.append(impossible, 0.0)[None])[0] < 0
    with pytest.raises(ParameterError, match="positive-definite pseudo-inertia"):
        log_cholesky_from_link(impossible)
    assert np.linalg.eigvalsh(pseudo_inertia(link_from_log_cholesky(log_cholesky_from_link(impossible, 1e-4))))[0] > 0


def test_normal_equations_in_chunks_equal_the_stacked_least_squares():
    rng = np.random.default_rng(1)
    columns, tau = rng.normal(size=(500, 3, 4)), rng.normal(size=(500, 3))
    whole, parts = NormalEquations(3, 4), NormalEquations(3, 4)
    whole.add(columns, tau)
    for sl in (slice(0, 123), slice(123, 400), slice(400, 500)):
        parts.add(columns[sl], tau[sl])
    np.testing.assert_allclose(parts.gram, whole.gram, rtol=1e-12)
    weights = np.array([1.0, 4.0, 0.25])
    gram, moment, _ = parts.weighted(weights)
    stacked = (columns * np.sqrt(weights)[None, :, None]).reshape(-1, 4)
    target = (tau * np.sqrt(weights)).reshape(-1)
    np.testing.assert_allclose(np.linalg.solve(gram, moment), np.linalg.lstsq(stacked, target, rcond=None)[0],
                               rtol=1e-10)  # fmt: skip
    x = rng.normal(size=4)
    np.testing.assert_allclose(parts.residual_sum(x), ((columns @ x - tau) ** 2).sum(axis=0), rtol=1e-10)


def test_filter_choice_follows_the_sampling_rate():
    assert choose_filter(1000.0) == (10.0, 10)
    assert choose_filter(5000.0) == (10.0, 50)
    assert choose_filter(50.0) == (5.0, 1)
    with pytest.raises(ParameterError, match="cutoff_hz must be in"):
        choose_filter(100.0, cutoff_hz=60.0)
    qd = np.array([[-1.0, 0.0], [1.0, 2.0]])
    cols = drive_columns(qd, np.ones_like(qd), ("fc", "fv"), (1,), coulomb_velocity=0.05)
    assert cols.shape == (2, 2, 5) and cols[1, 1, 3] == 2.0 and cols[0, 1, 4] == 1.0 and cols[0, 0, 0] < -0.99


@pytest.fixture(scope="module")
def denso_fit(denso, denso_model):
    """The virtual Denso (rigid body and drive inertia, no friction) along one 20 s sine trajectory."""
    rng = np.random.default_rng(3)
    reference = sine_experiment(denso, duration=20.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(denso, reference, options, rng)
    return identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())


def test_known_truth_lies_within_three_reported_sigma(denso, denso_model, denso_fit):
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    z = (denso_fit.theta_ols - truth) / denso_fit.theta_std
    assert np.abs(z).max() < 3.0, np.round(z, 2)
    assert np.abs((denso_fit.theta - truth) / denso_fit.theta_std).max() < 3.0
    assert denso_fit.condition_number < 100 and np.all(denso_fit.relative_sigma_percent[: denso_model.n_base] > 0)
    # no friction was simulated: the bounded friction estimates stay small against the torque noise
    assert np.all(denso_fit.drive >= 0) and np.abs(denso_fit.drive).max() < 0.05


def test_the_identified_model_is_consistent_and_predicts_what_it_reports(denso, denso_model, denso_fit):
    assert denso_fit.consistent and denso_fit.min_pseudo_inertia_eigenvalue >= 1e-6 * (1 - 1e-6)
    oracle = PinocchioOracle(denso, denso_fit.standard)
    rng = np.random.default_rng(0)
    q = rng.uniform(denso.q_min, denso.q_max, size=(500, denso.n_dof))
    assert min(np.linalg.eigvalsh(m)[0] for m in oracle.crba(q)) > 0
    qd, qdd = rng.normal(size=(2, 50, denso.n_dof))
    # the reported torque is Pinocchio's rigid body of the standard parameters plus the drive terms
    drive = drive_columns(qd, qdd, denso_fit.friction_terms, denso_fit.inertia_joints, denso_fit.coulomb_velocity)
    expected = oracle.rnea(q[:50], qd, qdd) + drive @ denso_fit.drive
    np.testing.assert_allclose(predict_torque(denso_model, denso_fit, q[:50], qd, qdd), expected, rtol=1e-9, atol=1e-9)


def test_without_consistency_no_standard_parameters_are_reported(denso, denso_model):
    rng = np.random.default_rng(4)
    reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(denso, reference, options, rng)
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(consistency=False))
    assert not fit.consistent and not fit.checked and np.all(np.isnan(fit.standard))
    np.testing.assert_array_equal(fit.theta, fit.theta_ols)


def test_the_robot_copies_of_a_model_file_go_where_the_model_cache_goes(
    tmp_path, monkeypatch, denso, denso_model, denso_fit
):
    """One setting moves every cache: $PSDM_CACHE_DIR holds the robot texts a model file writes back, not ~/.cache."""
    from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

    monkeypatch.setenv("PSDM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    written = CalibratedModel.from_fit(
        denso, denso_model, denso_fit, robot_source=BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
    )
    loaded = load_calibrated_model(written.save(tmp_path / "denso.json"))
    main = loaded.robot_file()
    assert (tmp_path / "cache" / "robots") in main.parents
    assert main.read_text() == (BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml").read_text()
    assert loaded.load_robot().joint_names == denso.joint_names
    assert not (tmp_path / "xdg").exists() and not (tmp_path / "home").exists()


def test_the_calibrated_model_file_round_trips_and_predicts_the_fit(tmp_path, denso, denso_model, denso_fit):
    from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

    written = CalibratedModel.from_fit(
        denso, denso_model, denso_fit, robot_source=BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
    )
    path = written.save(tmp_path / "denso.json")
    loaded = load_calibrated_model(path)
    assert loaded.document["standard"]["names"][:3] == ["m1", "mx1", "my1"] and loaded.consistent
    assert loaded.document["drive"]["names"][:2] == ["fc1", "fv1"]
    robot = loaded.load_robot(cache_dir=tmp_path / "cache")
    assert robot.joint_names == denso.joint_names
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.normal(size=(3, 20, denso.n_dof))
    expected = predict_torque(denso_model, denso_fit, q, qd, qdd)
    np.testing.assert_allclose(loaded.predict(denso_model, q, qd, qdd), expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(FileExistsError):
        written.save(path)


def test_a_model_file_needs_the_robot_file(denso, denso_model, denso_fit):
    from identification.calibration.calibrated_model import CalibratedModel

    with pytest.raises(ParameterError, match="robot_source is None.*robot file"):
        CalibratedModel.from_fit(denso, denso_model, denso_fit, robot_source=None)


def test_an_inconsistent_model_is_written_only_when_asked_and_then_marked(tmp_path, denso, denso_model, denso_fit):
    import dataclasses
    import json

    from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
    from psdm_casadi.errors import ModelFileError
    from psdm_casadi.robot import BUILTIN_ROBOTS_DIR

    bad = dataclasses.replace(denso_fit, consistent=False, min_pseudo_inertia_eigenvalue=-0.5)
    model_file = CalibratedModel.from_fit(
        denso, denso_model, bad, robot_source=BUILTIN_ROBOTS_DIR / "denso_vs6556g.toml"
    )
    with pytest.raises(ModelFileError, match="allow-inconsistent"):
        model_file.save(tmp_path / "bad.json")
    assert not (tmp_path / "bad.json").exists()
    model_file.save(tmp_path / "bad.json", allow_inconsistent=True)
    assert load_calibrated_model(tmp_path / "bad.json").document["standard"]["consistent"] is False
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ModelFileError, match="format must be"):
        load_calibrated_model(tmp_path / "other.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(ModelFileError, match="not a calibrated-model file"):
        load_calibrated_model(tmp_path / "broken.json")


def test_a_locked_urdf_robot_is_rebuilt_with_its_locks(tmp_path):
    from identification.calibration.calibrated_model import CalibratedModel, _robot_block
    from psdm_casadi.robot import load_robot
    from tests.conftest import example_robot_urdf

    urdf = example_robot_urdf("ur_description/urdf/ur5_robot.urdf")
    robot = load_robot(urdf, locked_joints=(("elbow_joint", 0.7),))
    rebuilt = CalibratedModel({"robot": _robot_block(robot, urdf)}).load_robot(cache_dir=tmp_path)
    assert rebuilt.joint_names == robot.joint_names and rebuilt.n_dof == 5
    assert dict(rebuilt.locked_joints)["elbow_joint"] == pytest.approx(0.7)


def test_one_friction_term_definition_serves_numbers_and_casadi():
    from identification.calibration.trajectory_data import friction_term

    qd = np.linspace(-0.2, 0.2, 7)
    symbol = ca.SX.sym("qd")
    for term in ("fc", "fv", "offset"):
        function = ca.Function("f", [symbol], [friction_term(term, symbol, 0.05)])
        np.testing.assert_allclose([float(function(v)) for v in qd], friction_term(term, qd, 0.05), rtol=1e-15)
    with pytest.raises(ParameterError, match="friction_term.term must be one of"):
        friction_term("stribeck", qd, 0.05)


def test_a_fit_stopped_at_the_iteration_cap_is_kept_consistent_and_marked(denso, denso_model, monkeypatch, caplog):
    import identification.calibration.trajectory_fit as trajectory_fit

    rng = np.random.default_rng(3)
    reference = sine_experiment(denso, duration=6.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(denso, reference, options, rng)
    import identification.calibration.barrier_path as barrier_path

    monkeypatch.setitem(trajectory_fit.IPOPT_OPTIONS, "ipopt.max_iter", 2)
    monkeypatch.setitem(barrier_path.BARRIER_OPTIONS, "ipopt.max_iter", 2)  # the convex path fails: the chart's cap
    with caplog.at_level("WARNING", logger="identification.calibration.consistent_fit"):
        fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions())
    assert fit.solver_status == "Maximum_Iterations_Exceeded"
    assert "iteration cap" in caplog.text and "not proven optimal" in caplog.text
    assert fit.consistent and fit.min_pseudo_inertia_eigenvalue > 0  # every iterate of the chart is consistent


def test_a_robot_file_whose_urdf_lies_elsewhere_is_rebuilt_from_the_model_file(tmp_path):
    from identification.calibration.calibrated_model import CalibratedModel, _robot_block
    from psdm_casadi.robot import load_robot
    from tests.conftest import example_robot_urdf

    urdf_text = example_robot_urdf("ur_description/urdf/ur5_robot.urdf").read_text()
    (tmp_path / "data" / "urdf").mkdir(parents=True)
    (tmp_path / "data" / "urdf" / "ur5.urdf").write_text(urdf_text)
    (tmp_path / "robots").mkdir()
    main = tmp_path / "robots" / "ur5.toml"
    main.write_text(
        '[urdf]\npath = "../data/urdf/ur5.urdf"\n\n[transmission]\ngear_ratios = [100, 100, 100, 50, 50, 50]\n'
    )
    robot = load_robot(main)
    block = _robot_block(robot, main)
    assert set(block["files"]) == {"ur5.toml", "../data/urdf/ur5.urdf"}
    rebuilt = CalibratedModel({"robot": block}).load_robot(cache_dir=tmp_path / "cache")
    assert rebuilt.joint_names == robot.joint_names
    np.testing.assert_array_equal(rebuilt.transmission.gear_ratios, [100, 100, 100, 50, 50, 50])
    assert (tmp_path / "cache").resolve() in Path(rebuilt.urdf_path).resolve().parents  # inside the cache
    escaping = dict(block, files={**block["files"], str(tmp_path / "outside.urdf"): "x"})
    with pytest.raises(ModelFileError, match="must lie beside the robot file or below it"):
        CalibratedModel({"robot": escaping}).robot_file(cache_dir=tmp_path / "cache2")


def test_a_urdf_reached_through_a_symlinked_folder_is_stored_where_the_robot_file_s_path_reaches_it(tmp_path):
    from identification.calibration.calibrated_model import CalibratedModel, _robot_block
    from psdm_casadi.robot import load_robot
    from tests.conftest import example_robot_urdf

    real = tmp_path / "disk" / "datasets" / "ur5"  # the real folder, deeper than the link that names it
    real.mkdir(parents=True)
    (real / "ur5.urdf").write_text(example_robot_urdf("ur_description/urdf/ur5_robot.urdf").read_text())
    (tmp_path / "project" / "robots").mkdir(parents=True)
    (tmp_path / "project" / "shared").symlink_to(real, target_is_directory=True)
    main = tmp_path / "project" / "robots" / "ur5.toml"
    main.write_text('[urdf]\npath = "../shared/ur5.urdf"\n')
    robot = load_robot(main)
    block = _robot_block(robot, main)
    assert set(block["files"]) == {"ur5.toml", "../shared/ur5.urdf"}  # as the robot file writes it
    rebuilt = CalibratedModel({"robot": block}).load_robot(cache_dir=tmp_path / "cache")
    assert rebuilt.joint_names == robot.joint_names
    assert (tmp_path / "cache").resolve() in Path(rebuilt.urdf_path).resolve().parents
