"""The pull towards the robot file as a Gaussian prior weighed against the data's independent samples (prior_pull).

Checked against what can be computed independently: the weight from counted samples and correlation times, and, on a
virtual Denso whose robot file is wrong (masses 30 % off, centres of mass moved), that the well-excited fit stays on
the truth (no closer to the wrong file than the weak pull of before). That a link the data hardly fix is held by the
file is checked on the Kinova Gen3 (test_kinova_gen3, slow: links 2 and 5 off their mass bounds).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from identification.calibration.prior_pull import PriorPull
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.io import save_recording
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.cli import main
from psdm_casadi.errors import ParameterError
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment


def test_the_weight_is_one_over_the_uncertainty_squared_times_the_independent_samples():
    count, correlation = np.array([400, 400, 200]), np.array([4.0, 2.0, 0.5])  # below 1 counts as white
    pull = PriorPull.of(TrajectoryOptions(prior_uncertainty=0.5, prior_weight=None), count, correlation)
    assert pull.effective_samples == pytest.approx(100 + 200 + 200)
    assert pull.weight == pytest.approx(1.0 / (0.25 * 500)) and pull.given is None
    assert PriorPull.of(TrajectoryOptions(prior_weight=None), count).effective_samples == pytest.approx(1000)
    given = PriorPull.of(TrajectoryOptions(prior_weight=1e-4), count, correlation)
    assert given.weight == 1e-4 and given.note()[0][1]["given"] and "given" in given.describe()
    assert PriorPull.from_note(pull.note()[0][1]) == PriorPull(0.5, 500.0, None, np.log(4.0) / 4)
    old = {k: v for k, v in pull.note()[0][1].items() if k != "mass_uncertainty"}  # a file written before
    assert PriorPull.from_note(old) == PriorPull(0.5, 500.0)


def test_the_masses_are_known_as_the_mass_bounds_state_them():
    """The default bounds 0.5-2 x state each mass to ln(4) / 4 = 35 % (both bounds 1.4-2.9 standard deviations away);
    bounds that say less (none, 0 or inf, wider than the stated uncertainty) leave the masses at the stated
    uncertainty, as does a given per-sample weight."""
    from identification.calibration.prior_pull import mass_uncertainty

    assert mass_uncertainty(TrajectoryOptions()) == pytest.approx(0.3466, abs=1e-4)
    assert mass_uncertainty(TrajectoryOptions(mass_ratio=(0.25, 4.0))) == pytest.approx(np.log(16) / 4)
    for options in (TrajectoryOptions(envelope=False), TrajectoryOptions(mass_ratio=(0.0, 2.0)),
                    TrajectoryOptions(mass_ratio=(0.5, np.inf)), TrajectoryOptions(prior_uncertainty=0.3),
                    TrajectoryOptions(mass_ratio=(0.01, 100.0))):  # fmt: skip
        assert mass_uncertainty(options) is None, options
    assert PriorPull.of(TrajectoryOptions(prior_weight=1e-4), [100]).mass is None
    pull = PriorPull.of(TrajectoryOptions(), [400], [4.0])
    assert "the links' masses to 35 %, as the mass bounds state" in pull.describe()


def test_a_mass_off_the_file_costs_its_relative_error_over_the_mass_uncertainty_squared():
    """The pull evaluated against its formula: a link's mass 40 % above the file's costs ``(0.4 / 0.347)^2 / N_eff``,
    its centre of mass's first moment (in the file's size, known to ``u``) ``(0.4 / 2)^2 / N_eff``."""
    import casadi as ca

    prior = np.zeros((2, 11))
    prior[:, 0], prior[:, 3], prior[:, [4, 6, 9]] = [2.0, 0.5], [0.2, 0.05], 0.01
    pull = PriorPull.of(TrajectoryOptions(), [400], [4.0])  # 100 independent samples
    moved = prior.copy()
    moved[0, 0] *= 1.4
    value = float(pull.expression(ca.DM(moved.reshape(-1)), prior))
    assert value == pytest.approx((0.4 / (np.log(4) / 4)) ** 2 / 100)
    moved = prior.copy()
    moved[1, 3] *= 1.4
    assert float(pull.expression(ca.DM(moved.reshape(-1)), prior)) == pytest.approx((0.4 / 2) ** 2 / 100)


@pytest.mark.parametrize("field, value", [("prior_uncertainty", 0.0), ("prior_uncertainty", np.nan),
                                          ("prior_weight", -1.0)])  # fmt: skip
def test_an_out_of_range_prior_option_is_refused_naming_it(field, value):
    with pytest.raises(ParameterError, match=f"TrajectoryOptions.{field} must"):
        TrajectoryOptions(**{field: value})


@pytest.fixture(scope="module")
def wrong_file(denso):
    """The Denso as truth, and a robot file whose masses are 30 % off (alternately high and low) with centres of
    mass moved by 2 cm: CAD numbers of a real arm."""
    links = [replace(link, mass=link.mass * (1.3 if i % 2 else 0.7), com=np.asarray(link.com) + 0.02)
             for i, link in enumerate(denso.links)]  # fmt: skip
    return denso.with_links(links)


def _recording(robot, duration, seed=3):
    rng = np.random.default_rng(seed)
    reference = sine_experiment(robot, duration=duration, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=0.1, friction=False)
    return simulate_recording(robot, reference, options, rng)[0]


def test_a_well_excited_fit_stays_on_the_truth_and_not_on_a_wrong_file(denso, denso_model, wrong_file):
    """The base parameters' error stays at the estimate's own noise (0.8 standard deviations RMS, as with the weak
    pull of before), 50 times smaller than the file's."""
    recording = _recording(denso, 8.0)
    fit = identify_trajectories(wrong_file, denso_model, [recording], TrajectoryOptions(prior_weight=None))
    weak = identify_trajectories(wrong_file, denso_model, [recording], TrajectoryOptions(prior_weight=1e-4))
    truth = denso_model.base_parameters(denso.nominal_dynamic_parameters())
    file = denso_model.base_parameters(wrong_file.nominal_dynamic_parameters())
    error, weak_error, file_error = (np.linalg.norm(theta - truth) for theta in (fit.theta, weak.theta, file))
    assert error < 0.05 * file_error and error < 1.2 * weak_error, (error, weak_error, file_error)
    z = (fit.theta - truth) / fit.theta_std
    assert np.sqrt(np.mean(z**2)) < 1.2 and np.abs(z).max() < 3.5, z
    prior = dict(fit.envelope_bounds)["prior"]
    assert not prior["given"] and prior["effective_samples"] < 0.5 * 6 * fit.n_samples


def test_identify_states_the_pull_once_and_stores_it_in_the_model_file(denso, tmp_path, capsys):
    save_recording(_recording(denso, 8.0), tmp_path / "train.csv")
    argv = ["identify", str(DENSO_FILE), "--data", str(tmp_path / "train.csv"), "--out", str(tmp_path / "m.json")]
    assert main([*argv, "--prior-uncertainty", "0.5"]) == 0
    out, err = capsys.readouterr()
    assert "pull towards the robot file: its inertial parameters known to 0.5 times their size" in out
    # stated once, in identify's report: not logged again by every consistent fit (column choice, refits)
    assert (out + err).count("pull towards the robot file") == 1, out + err
    stored = json.loads((tmp_path / "m.json").read_text())["standard"]["envelope"]["prior"]
    assert stored["uncertainty"] == 0.5 and not stored["given"]
    assert PriorPull.from_note(stored).weight == pytest.approx(1.0 / (0.25 * stored["effective_samples"]))
    assert main([*argv, "--overwrite", "--prior-uncertainty", "0"]) == 2
    err = capsys.readouterr().err
    assert "--prior-uncertainty must be > 0" in err and "Traceback" not in err
