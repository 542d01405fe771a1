"""``identification.virtual.recording_pair``: a training and a validation recording, reproduced from the seed alone."""

from __future__ import annotations

import warnings

import numpy as np

from identification.virtual.recording_pair import recording_pair
from trajopt.experiments import sine_experiment


def test_a_pair_is_reproduced_from_its_seed_and_its_two_motions_differ(denso):
    def sine(duration, rng):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the sine experiment may graze a limit
            return sine_experiment(denso, duration=duration, rng=rng).reference()

    train, validation = recording_pair(denso, [], 2, sine, (2.0, 1.0))
    assert train.t[-1] - train.t[0] == np.float64(2.0) and validation.t[-1] - validation.t[0] == np.float64(1.0)
    again = recording_pair(denso, [], 2, sine, (2.0, 1.0))
    for one, other in zip((train, validation), again):
        np.testing.assert_array_equal(one.q, other.q)
        np.testing.assert_array_equal(one.tau, other.tau)  # the noise drawn from the same generators too
    assert not np.allclose(train.q[: validation.q.shape[0]], validation.q)  # each recording its own motion
    other_seed, _ = recording_pair(denso, [], 3, sine, (2.0, 1.0))
    assert not np.allclose(other_seed.q, train.q)
    quiet, _ = recording_pair(denso, [], 2, sine, (2.0, 1.0), noise=0.0)
    np.testing.assert_array_equal(quiet.q, train.q)  # the same motion; only the torque sensors' noise differs
    assert 0.05 < np.std(train.tau - quiet.tau) < 0.2  # 0.1 N m by default
