"""Synthetic train/validation recordings for the diagnosis tests (known hidden effects)."""

import numpy as np

from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment


def recording_pair(robot, extras, seed, train_s=10.0, val_s=5.0):
    """A training and a validation recording of ``robot`` carrying ``extras``, torque-sensor style."""
    out = []
    for k, duration in enumerate((train_s, val_s)):
        rng = np.random.default_rng(100 * seed + k)
        rec, _ = simulate_recording(
            robot,
            sine_experiment(robot, duration=duration, rng=rng).reference(),
            SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1),
            rng,
            extras=extras,
        )
        out.append(rec)
    return out
