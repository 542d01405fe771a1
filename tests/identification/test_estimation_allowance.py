"""The two parts of the robot-file check's margin on a short recording: the paired bootstrap's noise and what
estimating the rigid body costs (``paired_margin``, ``calibration.estimation_allowance``).

References: the measured RMSE difference itself (the bootstrap's draws must centre on it, whichever stretch of the
recording it sits in); the Gaussian identity that a block's covariance given the others is the inverse of its
precision block; the uniform rule's closed form.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from identification.calibration.estimation_allowance import (
    joint_allowance,
    rigid_body_covariance,
    uniform_allowance,
)
from identification.paired_margin import block_length, paired_rmse_draws


def test_the_bootstrap_draws_centre_on_a_difference_that_sits_at_the_recordings_end():
    """A smooth residual and a model 0.3 N m off over the last tenth of a 300-sample recording: the blocks are long (a
    slow difference), and blocks that stopped at the end drew its last samples rarely (their draws' median was 0.009
    against the measured 0.032); wrapping around, every sample is drawn about equally often."""
    t = np.arange(300)
    before = 0.1 * np.sin(2 * np.pi * t / 150.0)
    after = before + np.where(t >= 270, 0.3, 0.0)
    rmse_before, rmse_after, draws = paired_rmse_draws(before[:, None], after[:, None])
    measured = float(rmse_after[0] - rmse_before[0])
    assert block_length(after**2 - before**2) >= 30
    assert np.median(draws) == pytest.approx(measured, rel=0.15)
    assert np.mean(draws) == pytest.approx(measured, rel=0.15)


def test_the_rigid_body_covariance_given_the_drive_is_the_inverse_of_its_precision_block():
    """For a Gaussian, the covariance of the first block given the second is the inverse of the first block of the
    precision; a drive parameter held (a zero row and column: not estimated) conditions nothing."""
    rng = np.random.default_rng(4)
    n_base, n_drive = 5, 3
    root = rng.normal(size=(n_base + n_drive, n_base + n_drive))
    covariance = root @ root.T + 0.1 * np.eye(n_base + n_drive)
    model = SimpleNamespace(n_base=n_base)
    fit = SimpleNamespace(covariance=covariance, drive_names=("fc1", "fv1", "offset1"))
    given = rigid_body_covariance(model, fit)
    np.testing.assert_allclose(given, np.linalg.inv(np.linalg.inv(covariance)[:n_base, :n_base]), rtol=1e-8)
    held = np.zeros((n_base + n_drive + 1,) * 2)  # a fourth drive column held: its row and column are 0
    held[: n_base + n_drive, : n_base + n_drive] = covariance
    fit_held = SimpleNamespace(covariance=held, drive_names=("fc1", "fv1", "offset1", "fc2"))
    np.testing.assert_allclose(rigid_body_covariance(model, fit_held), given, rtol=1e-8)
    assert rigid_body_covariance(model, SimpleNamespace(covariance=None, drive_names=())) is None
    assert rigid_body_covariance(model, SimpleNamespace(covariance=np.eye(3), drive_names=())) is None  # other size


def test_the_allowance_adds_the_variance_in_quadrature_and_the_uniform_rule_is_its_closed_form():
    before, variance = np.array([0.3, 0.4, 0.0]), np.array([0.16, 0.0, 0.01])
    np.testing.assert_allclose(joint_allowance(before, variance), [0.2, 0.0, 0.1], atol=1e-12)
    assert uniform_allowance(43, 45.4) == pytest.approx(np.sqrt(1 + 43 / 45.4) - 1)
    assert uniform_allowance(3, 0.0) == pytest.approx(1.0)  # at least one sample
