"""The consistent fit's covariance (``consistent_covariance``): the least squares' with the pull's precision added.

References: the information form ``(C^-1 + H^T (P S P^T)^-1 H)^-1`` inverted directly (the module computes the Kalman
form, which needs neither inverse), and the consistent fit itself: on a virtual Denso 4 s recording whose solution
presses no bound, the Laplace mean of the same prior, ``x_ls + K (theta_file - theta_ls)``, is where Ipopt's
consistent fit ends (median 0.05, at most 0.7 of the stated standard deviations), so the precision the covariance adds
is the one the fit was pulled with. The coverage of the flange check's +- on 4 s recordings is the slow
``test_payload_check_coverage``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from identification.calibration import trajectory_fit
from identification.calibration.consistent_covariance import consistent_covariance
from identification.calibration.consistent_fit import link_is_free, prior_standard
from identification.calibration.prior_pull import PriorPull
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.virtual.simulation import SimulationOptions, simulate_recording
from trajopt.experiments import sine_experiment


def _prior_map(model, robot, pull) -> np.ndarray:
    """``P S^(1/2)`` over the fit's variables (free links' ten parameters, every rotor), written out again here."""
    sd = pull.standard_deviations(prior_standard(robot))
    rows = []
    for i in range(robot.n_dof):
        for k in range(11):
            if k == 10 or link_is_free(model, i):
                rows.append((i * 11 + k, sd[i, k]))
    return np.column_stack([model.parameter_map[:, c] * s for c, s in rows])


def test_it_is_the_information_form_of_the_pull_added_to_the_least_squares(denso, denso_model):
    rng = np.random.default_rng(0)
    n = denso_model.n_base + 5
    root = rng.normal(size=(n, n))
    covariance = root @ root.T / n + 1e-3 * np.eye(n)
    pull = PriorPull(uncertainty=2.0, effective_samples=400.0, mass=0.35)
    mapped = _prior_map(denso_model, denso, pull)
    information = np.linalg.inv(covariance)
    information[: denso_model.n_base, : denso_model.n_base] += np.linalg.inv(mapped @ mapped.T)
    expected = np.linalg.inv(information)
    got = consistent_covariance(covariance, denso_model, denso, pull)
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-10 * np.abs(expected).max())
    assert np.all(np.linalg.eigvalsh(covariance - got) > -1e-12)  # never wider than the least squares'
    weaker = consistent_covariance(covariance, denso_model, denso, PriorPull(2.0, 400.0, given=1e-20))
    np.testing.assert_allclose(weaker, covariance, rtol=1e-5, atol=1e-9)  # a vanishing pull adds nothing


@pytest.fixture(scope="module")
def short_fit(denso, denso_model):
    """A consistent fit of one 4 s recording of the virtual Denso (friction on) and what its covariance came from."""
    rng = np.random.default_rng(13)
    with warnings.catch_warnings():  # the sine experiment may graze a limit: irrelevant here
        warnings.simplefilter("ignore")
        reference = sine_experiment(denso, duration=4.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=True)
    recording = simulate_recording(denso, reference, options, rng)[0]
    seen = {}
    original = trajectory_fit.consistent_covariance

    def spy(covariance, model, robot, pull, held_links=()):
        seen.update(covariance=np.array(covariance), model=model, robot=robot, pull=pull)
        return original(covariance, model, robot, pull, held_links)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(trajectory_fit, "consistent_covariance", spy)
        fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(envelope=False))
    return fit, seen


def test_the_consistent_fit_ends_at_the_laplace_mean_of_the_prior_its_covariance_states(short_fit):
    fit, seen = short_fit
    c, model, robot, pull = seen["covariance"], seen["model"], seen["robot"], seen["pull"]
    n_base = model.n_base
    x_ls = np.concatenate([fit.theta_ols, fit.drive_ols])
    x_fit = np.concatenate([fit.theta, fit.drive])
    mapped = _prior_map(model, robot, pull)
    theta_file = model.parameter_map @ prior_standard(robot).reshape(-1)
    gain = c[:, :n_base] @ np.linalg.inv(c[:n_base, :n_base] + mapped @ mapped.T)
    x_laplace = x_ls + gain @ (theta_file - x_ls[:n_base])
    sd_fit, sd_ls = (np.sqrt(np.diag(m)) for m in (fit.covariance, c))
    off = np.abs(x_fit - x_laplace) / sd_fit
    assert np.median(off) < 0.15 and off.max() < 1.0, off.round(2)
    moved = np.abs(x_fit - x_ls) / sd_ls  # the pull moved the fit by about a least-squares standard deviation
    assert np.median(moved) > 0.5, moved.round(2)
    np.testing.assert_allclose(fit.covariance, consistent_covariance(c, model, robot, pull), rtol=1e-12)
    ratio = sd_fit / sd_ls
    assert np.all(ratio <= 1 + 1e-9) and np.median(ratio) < 0.8 and ratio.min() < 0.2, ratio.round(2)
