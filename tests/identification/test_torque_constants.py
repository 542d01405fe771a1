"""The torque constants a recording of currents is read with (``identification.data.torque_constants``).

Truth: the virtual robot's own joint torque. It logs the currents of that torque through the robot file's drives
(``tau = kt i``), so the currents read with :func:`recording_kt` give back the torque it logged beside them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from identification.data.torque_constants import drive_kt, recording_kt
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment


def test_currents_read_with_the_drives_constants_are_the_torque_logged_beside_them(denso):
    rng = np.random.default_rng(3)
    reference = sine_experiment(denso, duration=8.0, rng=rng).reference()
    exact = SimulationOptions(record_tau=True, record_current=True, tau_noise_std=0.0, current_noise_std=0.0,
                              current_resolution=None)  # fmt: skip
    both, _ = simulate_recording(denso, reference, exact, rng)
    currents, torques = both.with_signals(tau=None), both.with_signals(current=None)
    kt = recording_kt(denso, currents)
    np.testing.assert_allclose(currents.joint_torque(kt), both.tau, rtol=1e-9, atol=1e-9)
    assert np.array_equal(kt, drive_kt(denso)) and kt.dtype == float
    # nothing to read: every recording holds torques; one of currents among them needs the constants
    assert recording_kt(denso, torques) is None and recording_kt(denso, both) is None
    assert np.array_equal(recording_kt(denso, torques, currents), kt)
    # a robot file without drives has none to give
    bare = dataclasses.replace(denso, drives=None)
    assert drive_kt(bare) is None and recording_kt(bare, currents) is None
