"""Pipeline inputs (data directory layout), options, the identify command; the full run is slow."""

from __future__ import annotations

import numpy as np
import pytest

from identification.calibration.pipeline import IdentificationPipeline, PipelineOptions
from identification.data.dataset import CalibrationData, load_calibration_data, save_calibration_data
from identification.data.payload import Payload
from identification.data.recording import Recording
from psdm_casadi.errors import ParameterError, RecordingError


def _rec(n_dof, name, seed=0):
    t = np.linspace(0.0, 1.0, 20)
    q = np.random.default_rng(seed).standard_normal((20, n_dof))
    return Recording(t=t, q=q, current=q, name=name)


def test_calibration_data_round_trip(tmp_path):
    data = CalibrationData(
        payload=Payload(mass=1.5, com=(0.1, 0.0, 0.0)),
        motor=((0, _rec(2, "a"), _rec(2, "b", 1)),),
        gravity=(_rec(2, "g"),),
        friction=(
            (
                1,
                _rec(2, "f"),
            ),
        ),
        excitation=(_rec(2, "e"),),
        friction_validation=((1, _rec(2, "fv", 2)),),
    )
    save_calibration_data(data, tmp_path)
    back = load_calibration_data(tmp_path, n_dof=2)
    assert back.payload == data.payload
    assert back.motor[0][0] == 0 and back.friction[0][0] == 1
    assert len(back.friction) == 1 and back.friction_validation[0][0] == 1
    np.testing.assert_allclose(back.friction_validation[0][1].q, data.friction_validation[0][1].q)
    np.testing.assert_allclose(back.motor[0][2].current, data.motor[0][2].current)
    with pytest.raises(FileExistsError):
        save_calibration_data(data, tmp_path)


def test_data_directory_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="--data"):
        load_calibration_data(tmp_path / "missing")
    with pytest.raises(FileNotFoundError, match="payload.json"):
        load_calibration_data(tmp_path)
    (tmp_path / "payload.json").write_text('{"mass": 2.0, "com": [0, 0, 0.05]}')
    with pytest.raises(RecordingError, match="motor_j"):
        load_calibration_data(tmp_path)
    (tmp_path / "payload.json").write_text('{"weight": 2.0}')
    with pytest.raises(ParameterError, match="mass"):
        load_calibration_data(tmp_path)
    with pytest.raises(RecordingError, match="gravity"):
        CalibrationData(
            payload=Payload(mass=1.0),
            motor=((0, _rec(2, "a"), _rec(2, "b")),),
            gravity=(),
            friction=((0, _rec(2, "f")),),
            excitation=(_rec(2, "e"),),
        )


def test_pipeline_option_and_input_errors(denso, denso_model):
    with pytest.raises(ParameterError, match="split_fraction"):
        PipelineOptions(split_fraction=1.2)
    with pytest.raises(ParameterError, match="friction_rate_hz"):
        PipelineOptions(friction_rate_hz=0.0)
    with pytest.raises(ParameterError, match="friction_cutoff_hz"):
        PipelineOptions(friction_cutoff_hz=-40.0)
    with pytest.raises(ParameterError, match="gravity_inertia"):
        PipelineOptions(gravity_inertia="cad")
    with pytest.raises(ParameterError, match="gravity_friction"):
        PipelineOptions(gravity_friction="lugre")
    with pytest.raises(ParameterError, match="friction_coupling"):
        PipelineOptions(friction_coupling="identified")
    assert PipelineOptions().friction_cutoff_hz is None  # friction data are used unfiltered at 1 kHz
    with pytest.raises(ParameterError, match="model"):
        IdentificationPipeline(denso, None).fit("x")
    with pytest.raises(ParameterError, match="CalibrationData"):
        IdentificationPipeline(denso, denso_model).fit(42)


def test_identified_friction_is_removed_from_torques_or_currents():
    """The second gravity pass subtracts the LuGre torque from tau, or torque / Kt from the currents."""
    from identification.calibration.preparation import without_torque

    t = np.linspace(0.0, 1.0, 11)
    q = np.zeros((11, 2))
    torque = np.outer(np.sin(t), [2.0, -1.0])
    kt = np.array([4.0, 0.5])
    with_current = without_torque(Recording(t=t, q=q, current=np.ones((11, 2)), name="c"), torque, kt)
    np.testing.assert_allclose(with_current.joint_torque(kt), kt * 1.0 - torque)
    with_tau = without_torque(Recording(t=t, q=q, tau=np.ones((11, 2)), name="t"), torque, kt)
    np.testing.assert_allclose(with_tau.tau, 1.0 - torque)


def test_virtual_calibration_options_errors():
    from trajopt.calibration_plan import CalibrationPlan

    with pytest.raises(ParameterError, match="friction_design"):
        CalibrationPlan(friction_design=(1e-3, 0.1))
    with pytest.raises(ParameterError, match="gravity_speed"):
        CalibrationPlan(gravity_speed=0.0)


def test_identify_command_is_registered():
    from psdm_casadi.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["identify", "robot.toml", "--data", "d", "--out", "o", "--json"])
    assert args.handler.__name__ == "_run_identify" and args.json


@pytest.mark.slow
def test_full_pipeline_on_virtual_denso(denso, denso_model, tmp_path):
    """Noise-free short calibration: Kt within 1 %, all R^2 >= 0.98, consistent mass matrix, saved model loads."""
    from identification.calibration.result import load_identified
    from identification.virtual.calibration import VirtualCalibrationOptions, simulate_calibration
    from identification.virtual.simulation import SimulationOptions
    from trajopt.calibration_plan import CalibrationPlan
    from trajopt.friction_design import FrictionDesign

    plan = CalibrationPlan(gravity_duration=30.0, excitation_duration=20.0, friction_design=FrictionDesign.quick())
    options = VirtualCalibrationOptions(
        quiet=True,
        simulation=SimulationOptions(encoder_resolution=None, current_resolution=None, current_noise_std=0.0),
    )
    data = simulate_calibration(denso, plan, options, np.random.default_rng(0))
    assert len(data.friction_validation) == denso.n_dof
    pipeline = IdentificationPipeline(denso, denso_model, PipelineOptions(quiet=True)).fit(data)
    result = pipeline.result_
    kt = np.array([d.kt for d in denso.drives])
    assert np.abs(result.kt / kt - 1).max() < 0.01
    assert result.report.min_r2("all") > 0.98
    assert result.consistency.consistent
    assert result.report.min_r2("friction") > 0.98
    assert "gravity_friction" in pipeline.timings_  # step 2 again without the identified friction
    back = load_identified(result.save(tmp_path / "out"))
    np.testing.assert_array_equal(back.theta, result.theta)
