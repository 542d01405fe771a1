"""The samples a fit used, per joint: a recording with a dead torque channel gives that joint fewer rows, and the
count identify prints and the robot-file check's allowance use each joint's own (the Kinova's RunTrajectory1 has a
dead joint-1 channel; identify printed joint 1's count as the fit's and shared the samples evenly).

Reference: two recordings of the same timing, one with joint 1's torque zero in every sample: joint 1 has exactly
half the rows of every other joint.
"""

import logging
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.identify_route import identify_recordings
from identification.calibration.prior_pull import PriorPull
from identification.calibration.trajectory_data import samples_text
from tests.identification.test_column_choice import synthetic


@pytest.fixture(scope="module")
def dead_channel(denso, denso_model):
    """The Denso identified on a 4 s recording and the same with joint 1's torque channel dead, checked on another."""
    record = logging.getLogger("identification.calibration.trajectory_fit")
    lines = []
    handler = logging.Handler()
    handler.emit = lambda r: lines.append(r.getMessage())
    record.addHandler(handler)
    level = record.level
    record.setLevel(logging.INFO)
    try:
        train = synthetic(denso, 3, duration=4.0)
        dead = replace(train, tau=np.column_stack([np.zeros(train.t.size), train.tau[:, 1:]]), name="dead")
        held = [synthetic(denso, 4, duration=4.0)]
        result = identify_recordings(denso, denso_model, [train, dead], validation=held, counterbalance=False)
    finally:
        record.removeHandler(handler)
        record.setLevel(level)
    return result, lines


def test_a_dead_channel_gives_its_joint_half_the_rows_and_the_fit_counts_the_samples_it_used(dead_channel):
    result, lines = dead_channel
    fit = result.fit
    rows = np.array(fit.joint_samples)
    assert rows.size == 6 and np.all(rows[1:] == rows[1]) and 2 * rows[0] == rows[1]
    assert fit.n_samples == rows[1]  # the samples used: the most any joint has, not joint 1's
    said = f"identify: {rows[1]} samples (joint 1: {rows[0]}) of 2 recording(s)"
    assert any(line.startswith(said) for line in lines), lines
    assert result.calibrated.document["identification"]["joint_samples"] == rows.tolist()


def test_the_robot_file_checks_samples_per_joint_are_each_joints_own_share(dead_channel):
    result, _ = dead_channel
    check, fit = result.file_check, result.fit
    samples, rows = np.array(check.samples), np.array(fit.joint_samples)
    note = dict(result.calibrated.document["standard"].get("envelope", {})).get("prior")
    # the pull's independent samples shared as the joints' own rows, or (no pull stated) each joint's rows
    total = rows.sum() if note is None else PriorPull.from_note(note).effective_samples
    np.testing.assert_allclose(samples, total * rows / rows.sum(), rtol=1e-12)
    assert samples[0] == pytest.approx(0.5 * samples[1], rel=1e-12)
    assert check.to_dict()["independent_samples_per_joint"] == pytest.approx(samples.tolist())


def test_the_samples_text_names_the_joints_with_fewer():
    assert samples_text([986, 986, 986]) == "986 samples"
    assert samples_text([461, 986, 986, 980]) == "986 samples (joint 1: 461, joint 4: 980)"
