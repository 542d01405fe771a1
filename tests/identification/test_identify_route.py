"""``psdm identify``'s route as a library call (``calibration.identify_route``): Python users get the command line's
model, with the data's choices (Coulomb smoothing, drive columns, counterbalance) stated.

Reference: the command line's own model file on the same recording (the command line is a thin caller of the route),
and the virtual Denso's hidden truth (its Coulomb-viscous friction moved ten times slower than its exciting
trajectory, where the default smoothing velocity of 0.05 rad/s is too soft).
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np

from identification.calibration.identify_route import identify_recordings
from identification.calibration.prior_pull import PRIOR_UNCERTAINTY
from identification.data.io import load_recording, save_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from trajopt.experiments import sine_experiment


def _slow_recording(robot, path):
    """A 20 s recording of the Denso's 2 s exciting trajectory run ten times slower (250 Hz, torque noise 0.1 N m)."""
    rng = np.random.default_rng(7)
    t, q = sine_experiment(robot, duration=2.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, rate=250.0)
    save_recording(simulate_recording(robot, (10.0 * t, q), options, rng)[0], path)
    return load_recording(path, robot.n_dof)


def test_python_users_get_the_command_lines_model_with_the_smoothing_the_data_choose(denso, denso_model, tmp_path):
    """``identify_recordings`` on a slow recording chooses a sharper Coulomb sign than 0.05 rad/s, fits with it and
    says so; ``psdm identify`` on the same file writes the same choice and the same parameters."""
    path = tmp_path / "slow.npz"
    recording = _slow_recording(denso, path)
    result = identify_recordings(denso, denso_model, [recording])
    smoothing = result.choice.smoothing
    assert smoothing.changed and result.fit.coulomb_velocity == smoothing.velocity < 0.01
    assert result.calibrated.document["drive"]["coulomb_velocity"] == smoothing.velocity
    assert smoothing.sentence() in result.describe()
    assert result.pull.uncertainty == PRIOR_UNCERTAINTY and result.pull.describe() in result.describe()  # once
    stored = result.calibrated.document["identification"]
    assert stored["column_choice"] == result.choice.to_dict() and "counterbalance" in stored
    out = tmp_path / "model.json"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["identify", str(denso.source), "--data", str(path), "--out", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["identification"]["column_choice"] == json.loads(json.dumps(stored["column_choice"]))
    assert document["identification"]["counterbalance"] == json.loads(json.dumps(stored["counterbalance"]))
    np.testing.assert_allclose(document["base"]["values"], result.fit.theta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(document["drive"]["values"], result.fit.drive, rtol=1e-9, atol=1e-12)
