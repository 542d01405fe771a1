"""The Stribeck friction shape of the recordings route: known truth recovered, validation improved, export equal.

The truth is written here independently of the fit: the Denso's rigid body by Pinocchio plus the
Stribeck friction ``(fc + (fs - fc) exp(-(qd/vs)^2)) tanh(qd/eps) + fv qd`` evaluated in numpy on the
exact states of a sine excitation, with white torque noise.
"""

import shutil

import casadi as ca
import numpy as np
import pytest

from identification.calibration.stribeck import StribeckColumns, stribeck_step
from identification.calibration.trajectory_data import drive_columns, friction_term, stribeck_derivative
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories, predict_torque
from psdm_casadi.errors import ParameterError
from psdm_casadi.oracle import PinocchioOracle
from tests.identification.friction_signal import exact_recording

needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
RATE, DURATION, NOISE, EPS, CUTOFF = 400.0, 12.0, 0.1, 0.05, 40.0
FC = np.array([2.0, 2.5, 1.5, 0.6, 0.5, 0.3])
FS = 1.8 * FC
VS = np.array([0.1, 0.15, 0.08, 0.2, 0.12, 0.1])
FV = np.array([1.0, 1.5, 0.8, 0.3, 0.2, 0.1])


def _stribeck_truth(qd):
    return (FC + (FS - FC) * np.exp(-((qd / VS) ** 2))) * np.tanh(qd / EPS) + FV * qd


def _recording(robot, seed):
    return exact_recording(robot, seed, _stribeck_truth, duration=DURATION, rate=RATE, noise=NOISE,
                           name=f"stribeck{seed}")  # fmt: skip


@pytest.fixture(scope="module")
def stribeck_data(denso, denso_model):
    """Training and validation recordings with Stribeck friction, and the fits of both shapes on the first."""
    train, valid = _recording(denso, 21), _recording(denso, 22)
    fits = {
        shape: identify_trajectories(denso, denso_model, [train], TrajectoryOptions(friction=terms, cutoff_hz=CUTOFF))
        for shape, terms in (("coulomb-viscous", ("fc", "fv")), ("stribeck", ("fc", "fs", "fv")))
    }
    return train, valid, fits


def _drive(fit, prefix, values="drive"):
    array = getattr(fit, values)
    return np.array([array[fit.drive_names.index(f"{prefix}{j + 1}")] for j in range(len(FC))])


@pytest.mark.slow
def test_stribeck_fit_recovers_the_static_friction_and_velocity_within_sigma(stribeck_data):
    _, _, fits = stribeck_data
    fit = fits["stribeck"]
    assert fit.consistent and fit.friction_terms == ("fc", "fs", "fv")
    fs, fs_std = _drive(fit, "fs", "drive_ols"), _drive(fit, "fs", "drive_std")
    assert np.all(fs_std > 0) and np.all(np.abs(fs - FS) < 3 * fs_std), np.round((fs - FS) / fs_std, 2)
    # the consistent fit keeps the same Stribeck velocities; its fs stays within the same band
    assert np.all(np.abs(_drive(fit, "fs") - FS) < 3 * fs_std)
    vs, vs_std = np.array(fit.stribeck_velocity), np.array(fit.stribeck_velocity_std)
    assert np.all(vs > 0) and np.all(np.abs(vs - VS) < 3 * vs_std), np.round((vs - VS) / vs_std, 2)


@pytest.mark.slow
def test_stribeck_lowers_the_validation_rmse_of_coulomb_viscous(stribeck_data, denso_model):
    from identification.calibration.trajectory_data import prepare_recording
    from identification.metrics import rmse

    _, valid, fits = stribeck_data
    ready, _, _ = prepare_recording(valid, None, CUTOFF)
    x = (ready.q, ready.qd, ready.qdd)
    errors = {shape: np.asarray(rmse(ready.tau, predict_torque(denso_model, fit, *x))) for shape, fit in fits.items()}
    assert np.all(errors["stribeck"] < errors["coulomb-viscous"]), errors
    assert errors["stribeck"].max() < 2 * NOISE  # what is left is about the noise (filtered)


@pytest.mark.slow
@pytest.mark.needs_cc
@needs_cc
def test_exported_c_of_a_stribeck_model_equals_predict(stribeck_data, denso, denso_model, tmp_path, monkeypatch):
    from codegen.build import build_library
    from codegen.calibrated import build_calibrated_functions, header_note
    from codegen.export import export_c
    from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
    from tests.conftest import DENSO_FILE

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    _, _, fits = stribeck_data
    path = CalibratedModel.from_fit(denso, denso_model, fits["stribeck"], robot_source=DENSO_FILE).save(
        tmp_path / "stribeck.json"
    )
    calibrated = load_calibrated_model(path)
    assert calibrated.document["drive"]["friction_shape"] == "stribeck"
    library = build_library(export_c(build_calibrated_functions(calibrated, denso_model, denso), tmp_path / "c"),
                            flags=("-O1",))  # fmt: skip
    rng = np.random.default_rng(7)
    q = rng.uniform(denso.q_min, denso.q_max, (300, denso.n_dof))
    qd = rng.normal(scale=0.2, size=q.shape)  # around the Stribeck velocities, where the shape matters
    qdd = rng.normal(size=q.shape)
    inverse = library.function("psdm_inverse_dynamics").map(q.shape[0])
    tau = np.array(inverse(q.T, qd.T, qdd.T), dtype=float).T
    predicted = calibrated.predict(denso_model, q, qd, qdd)
    np.testing.assert_allclose(predicted, predict_torque(denso_model, fits["stribeck"], q, qd, qdd), rtol=1e-12)
    error = np.max(np.abs(tau - predicted).max(axis=0) / np.abs(predicted).max(axis=0))
    assert error < 1e-9, error
    # and predict is the Stribeck formula: the fitted parameters in the independent numpy expression
    fit = fits["stribeck"]
    vs = np.array(fit.stribeck_velocity)
    fc, fs, fv = (_drive(fit, name) for name in ("fc", "fs", "fv"))
    friction = (fc + (fs - fc) * np.exp(-((qd / vs) ** 2))) * np.tanh(qd / fit.coulomb_velocity) + fv * qd
    rigid = PinocchioOracle(denso, fit.standard).rnea(q, qd, qdd)
    np.testing.assert_allclose(predicted, rigid + friction, rtol=1e-9, atol=1e-9)
    assert "vs1 = " in header_note(calibrated)


def test_stribeck_columns_are_one_definition_for_numbers_and_casadi():
    qd = np.linspace(-0.5, 0.5, 11)
    symbol, velocity = ca.SX.sym("qd"), ca.SX.sym("vs")
    for term in ("fc", "fs"):
        function = ca.Function("f", [symbol, velocity], [friction_term(term, symbol, EPS, velocity)])
        np.testing.assert_allclose(
            [float(function(v, 0.12)) for v in qd], friction_term(term, qd, EPS, 0.12), rtol=1e-14, atol=1e-15
        )
    # the two columns split the Coulomb level: fc (1 - g) s + fs g s = fc s + (fs - fc) g s
    g_s = np.exp(-((qd / 0.12) ** 2)) * np.tanh(qd / EPS)
    np.testing.assert_allclose(friction_term("fs", qd, EPS, 0.12), g_s, rtol=1e-14)
    np.testing.assert_allclose(friction_term("fc", qd, EPS, 0.12) + g_s, np.tanh(qd / EPS), rtol=1e-14, atol=1e-16)
    # the derivative column against a central difference in vs
    step = 1e-6
    difference = (friction_term("fs", qd, EPS, 0.12 + step) - friction_term("fs", qd, EPS, 0.12 - step)) / (2 * step)
    np.testing.assert_allclose(stribeck_derivative(qd, EPS, 0.12), difference, rtol=1e-6, atol=1e-9)
    with pytest.raises(ParameterError, match="needs stribeck_velocity"):
        friction_term("fs", qd, EPS)


def test_the_gauss_newton_step_is_the_velocity_change_of_the_linearised_column():
    """Fitting fc, fs and the derivative coefficient on a column with vs0 gives c / (fs - fc) ~ vs - vs0."""
    rng = np.random.default_rng(2)
    qd = rng.uniform(-1, 1, size=(4000, 1))
    vs_true, vs0 = np.array([0.15]), np.array([0.14])
    y = 1.0 * friction_term("fc", qd, EPS, vs_true) + 2.0 * friction_term("fs", qd, EPS, vs_true)
    columns = np.concatenate(
        [drive_columns(qd, qd, ("fc", "fs"), (), EPS, vs0), StribeckColumns(EPS, vs0).columns(qd, qd, qd)], axis=2
    )[:, 0, :]
    x = np.linalg.lstsq(columns, y[:, 0], rcond=None)[0]
    change = stribeck_step(x, 0, ["fc1", "fs1"], vs0)
    assert abs(vs0[0] + change[0] - vs_true[0]) < 0.1 * abs(vs_true[0] - vs0[0])


def test_the_stribeck_options_are_checked():
    with pytest.raises(ParameterError, match="'fc' with 'fs'"):
        TrajectoryOptions(friction=("fs", "fv"))
    with pytest.raises(ParameterError, match="stribeck_velocity must be > 0"):
        TrajectoryOptions(friction=("fc", "fs"), stribeck_velocity=0.0)


def test_the_stribeck_velocities_are_logged_as_the_model_s_only_when_the_shape_is_chosen(caplog):
    """The column choice fits the Stribeck shape as a candidate before it decides; on a virtual SCARA with Coulomb +
    viscous friction it chooses Coulomb-viscous, and the log said "Stribeck velocities ... after N Gauss-Newton
    steps" as if the model had them. The trial is now named a trial; the line the fit of the chosen Stribeck shape
    logs is kept."""
    from identification.calibration.identify_route import identify_recordings
    from psdm_casadi import derive_psdm, load_robot
    from tests.identification.test_model_file_offsets import recording

    robot = load_robot("scara")
    model = derive_psdm(robot)
    train, held = recording(robot, 0), recording(robot, 1)
    with caplog.at_level("INFO", logger="identification.calibration"):
        result = identify_recordings(robot, model, [train], validation=[held], counterbalance=False)
    assert result.calibrated.document["drive"]["friction_shape"] == "coulomb-viscous"
    lines = [r.getMessage() for r in caplog.records]
    assert not any("Stribeck velocities" in m for m in lines), lines
    tried = [m for m in lines if m.startswith("identify: the Stribeck shape tried for the column choice")]
    assert len(tried) == 1 and "kept only if it is chosen" in tried[0], lines
    caplog.clear()
    with caplog.at_level("INFO", logger="identification.calibration"):
        fit = identify_trajectories(robot, model, [train], TrajectoryOptions(friction=("fc", "fs", "fv")))
    lines = [r.getMessage() for r in caplog.records]
    shown = ", ".join(f"{v:.3g}" for v in fit.stribeck_velocity)
    assert any(m.startswith(f"identify: Stribeck velocities {shown} rad/s after") for m in lines), lines
