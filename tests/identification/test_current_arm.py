"""The virtual current-logging arm (``identification.virtual.current_arm``): its file, its motion, its currents.

Truth: the arm's own parameters. The file's drives read the currents with ``gear * motor_kt * kt_error``; the motion
stays within half the limits and starts and ends at rest; with the right constants the logged currents are the
joint torque the simulation recorded, up to the stated current noise.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from identification.virtual.current_arm import CurrentRun, faded_sines, write_current_recordings
from psdm_casadi.robot import load_robot
from tests.identification.torque_scale_data import GEAR, MOTOR_KT, PAYLOAD, cobot


def test_the_faded_sines_stay_within_half_the_limits_and_rest_at_both_ends():
    arm = cobot()
    t, q = faded_sines(arm.truth, 6.0, np.random.default_rng(4))
    assert t[0] == 0.0 and t[-1] == pytest.approx(6.0) and np.allclose(np.diff(t), 1e-3)
    assert np.all(np.abs(q) <= 0.5 * arm.truth.q_max + 1e-12)
    qd = np.gradient(q, t, axis=0)
    assert np.all(np.abs(qd).max(axis=0) <= 0.5 * arm.truth.qd_max * 1.01)
    assert (
        np.allclose(q[0], 0.0)
        and np.allclose(q[-1], 0.0, atol=1e-9)
        and np.all(np.abs(qd[[0, -1]]) < 1e-3 * arm.truth.qd_max)
    )
    assert np.all(np.ptp(q, axis=0) > 0.05)  # every joint moves


def test_the_file_states_the_constants_times_their_error_and_the_currents_are_the_true_torque(tmp_path):
    arm = cobot()
    error = (1.0, 1.15, 1.0, 0.9)
    (tmp_path / "arm.toml").write_text(arm.robot_file(error))
    robot = load_robot(tmp_path / "arm.toml")
    assert [j.name for j in robot.joints] == ["j1", "j2", "j3", "j4"]
    stated = np.array(GEAR) * np.array(MOTOR_KT) * np.array(error)
    assert np.allclose([d.kt for d in robot.drives], stated, rtol=1e-12)
    assert np.allclose([link.mass for link in robot.links], arm.file_mass)
    runs = (CurrentRun("still", 1.0), CurrentRun("loaded", 2.0, PAYLOAD))
    paths = write_current_recordings(tmp_path, arm, runs, np.random.default_rng(0))
    assert [p.name for p in paths] == ["still.csv", "loaded.csv"]
    assert not (tmp_path / "still.payload.json").exists()
    assert json.loads((tmp_path / "loaded.payload.json").read_text()) == PAYLOAD
    header = paths[1].read_text().splitlines()[0].split(",")
    assert header == ["timestamp", "q_1", "q_2", "q_3", "q_4", "i_1", "i_2", "i_3", "i_4"]
    again = write_current_recordings(tmp_path / "again", arm, runs, np.random.default_rng(0))
    assert again[1].read_bytes() == paths[1].read_bytes()  # seeded
