"""The recorded torque's scale against the robot file's (``plausibility.check_torque_scale``), on the virtual Denso.

A torque constant given without its gear ratio scales every joint's torque by about 1/100; identify then fitted
for many minutes instead of refusing. The truth here is a simulated recording (rigid body, rotors, friction, noise) of
a known robot: scaled by 1/100 it is refused at once, unscaled or recorded by a robot whose link is twice as heavy as
the file says it is not, and one joint's scale alone is a warning naming that joint.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.trajectory_data import prepare_recording, prepare_recordings
from identification.data.io import save_recording
from identification.data.plausibility import PlausibilityThresholds, check_torque_scale, torque_scale
from identification.data.recording import Recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError, RecordingError
from psdm_casadi.said_once import SAID
from trajopt.experiments import sine_experiment


def _simulated(truth, seed: int = 3) -> Recording:
    rng = np.random.default_rng(seed)
    reference = sine_experiment(truth, duration=8.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1)
    return simulate_recording(truth, reference, options, rng)[0]


@pytest.fixture(scope="module")
def recorded(denso) -> Recording:
    return _simulated(denso)


def _scaled(recording: Recording, factors) -> Recording:
    return Recording(t=recording.t, q=recording.q, tau=recording.tau * np.asarray(factors), name="scaled.csv")


def test_the_least_squares_scale_is_the_factor_applied(rng):
    predicted = rng.standard_normal((500, 3))
    found = torque_scale(predicted * [0.01, 1.0, 300.0], predicted)
    np.testing.assert_allclose(found.scale, [0.01, 1.0, 300.0], rtol=1e-12)
    np.testing.assert_allclose(found.correlation, 1.0, rtol=1e-12)
    alike = torque_scale(predicted * 0.01, predicted)
    assert alike.overall == pytest.approx(0.01, rel=1e-12) and alike.rms_ratio == pytest.approx(0.01, rel=1e-12)


def test_torques_a_hundredth_of_the_truth_are_refused_naming_recording_factor_and_causes(denso, recorded):
    with pytest.raises(RecordingError) as info:
        prepare_recordings(denso, [_scaled(recorded, 0.01)])
    message = str(info.value)
    factor = float(message.split("the recorded torque is about ")[1].split(" times")[0])
    assert factor == pytest.approx(0.01, rel=0.3)  # the rotors and friction are in the truth, not in the factor
    assert "scaled.csv" in message and "torque's unit" in message and "gear ratio" in message


def test_currents_with_the_motors_kt_name_the_forgotten_gear_ratio(denso, recorded):
    current = Recording(t=recorded.t, q=recorded.q, current=recorded.tau / 101.0, name="currents.csv")
    ready, *_ = prepare_recording(current, np.ones(denso.n_dof))  # kt = 1: the motor's kt given for the joint's 101
    with pytest.raises(RecordingError, match=r"currents.csv: .* did you give the motor's kt without the gear ratio"):
        check_torque_scale(ready, denso, currents=True)


def test_the_right_scale_and_a_link_twice_as_heavy_as_the_file_pass(denso, recorded):
    ready, *_ = prepare_recording(recorded)
    found = check_torque_scale(ready, denso)
    assert 0.5 < found.overall < 2.0 and found.global_factor(PlausibilityThresholds()) is None  # friction, noise
    for link in (1, 2):  # the file says half of link 2's (or link 3's) mass and inertia
        links = list(denso.links)
        links[link] = replace(links[link], mass=2.0 * links[link].mass, inertia=2.0 * np.asarray(links[link].inertia))
        found = check_torque_scale(prepare_recording(_simulated(denso.with_links(links), seed=4))[0], denso)
        assert 0.5 < found.overall < 3.0


def test_one_joint_off_is_a_warning_naming_it_not_a_refusal(denso, recorded, caplog):
    SAID.clear()
    factors = np.ones(denso.n_dof)
    factors[1] = 0.01  # joint 2's torque constant given without its gear ratio
    ready, *_ = prepare_recording(_scaled(recorded, factors))
    with caplog.at_level(logging.WARNING):
        check_torque_scale(ready, denso)
    (warning,) = [
        r.getMessage() for r in caplog.records if "times the torque the robot file predicts" in r.getMessage()
    ]
    assert "joint 2" in warning and "scaled.csv" in warning and "torque constant" in warning


def test_identify_refuses_a_hundredth_of_the_torque_within_seconds(recorded, tmp_path, capsys):
    path = tmp_path / "scaled.csv"
    save_recording(_scaled(recorded, 0.01), path)
    start = time.perf_counter()
    code = main(["identify", "denso_vs6556g", "--data", str(path), "--out", str(tmp_path / "m.json")])
    seconds = time.perf_counter() - start
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    assert "scaled.csv" in err and "the recorded torque is about" in err
    assert seconds < 60.0  # before any fit (it ran for many minutes before)


def test_the_torque_thresholds_are_checked():
    with pytest.raises(ParameterError, match="torque_factor"):
        PlausibilityThresholds(torque_factor=0.0)
