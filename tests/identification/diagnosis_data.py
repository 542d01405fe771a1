"""Synthetic train/validation recordings for the diagnosis tests (known hidden effects)."""

import numpy as np

from identification.data.preprocessing import PreprocessOptions, preprocess
from identification.diagnosis.context import build_context
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


def rigid_recording(robot, extras, seed=3, duration=8.0):
    """An 8 s sine-experiment recording of ``robot`` carrying ``extras``, torque sensors with 0.1 N m noise and no
    friction: what the rigid body and its envelope see."""
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    recording, _ = simulate_recording(robot, reference, options, rng, extras=extras)
    return recording


def sine_context(robot, model, seed, duration=3.0):
    """The diagnosis context of a noise-free sine-experiment recording of ``robot`` (torque sensors), filtered at
    15 Hz on a 100 Hz grid: the candidates' columns are evaluated on it."""
    rng = np.random.default_rng(seed)
    rec, _ = simulate_recording(
        robot,
        sine_experiment(robot, duration=duration, rng=rng).reference(),
        SimulationOptions(record_tau=True, record_current=False),
        rng,
    )
    return build_context(robot, model, preprocess(rec, PreprocessOptions(cutoff_hz=15.0)), rate_hz=100.0)
