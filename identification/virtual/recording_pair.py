"""A training and a validation recording of the virtual robot with hidden effects: the diagnosis's usual test case.

:func:`recording_pair` simulates ``robot`` (torque sensors, Gaussian noise) twice along motions it is given, each from
its own seeded generator, so a case is reproduced from ``seed`` alone and its two recordings never share a motion.
The motion's designer is ``trajopt`` (e.g. ``sine_experiment``), which this package does not import: the caller
passes ``reference(duration, rng)``. The diagnosis tests (``tests/identification/diagnosis_data``) and the
pre-sliding-or-elasticity benchmark draw their sine-experiment pairs from it.
"""

from __future__ import annotations

import numpy as np

from identification.virtual.simulation import SimulationOptions, simulate_recording

__all__ = ["recording_pair"]


def recording_pair(robot, extras, seed: int, reference, durations=(10.0, 5.0), noise: float = 0.1) -> list:
    """``[training, validation]`` recordings of ``robot`` carrying ``extras`` (``effects``, ``transmission_effects``).

    Recording ``k`` (0 training, 1 validation) lasts ``durations[k]`` [s] along ``reference(duration, rng)`` (a
    reference ``simulate_recording`` tracks) with ``rng = numpy.random.default_rng(100 seed + k)``, which then draws
    the sensor noise too: torque sensors of ``noise`` [N m] standard deviation, no currents.
    """
    out = []
    for k, duration in enumerate(durations):
        rng = np.random.default_rng(100 * seed + k)
        options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=noise)
        recording, _ = simulate_recording(robot, reference(duration, rng), options, rng, extras=extras)
        out.append(recording)
    return out
