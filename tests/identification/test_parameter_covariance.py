"""The base and drive parameters' covariance in the calibrated-model file (``parameter_covariance``) and the flange
payload check's +- from it (``payload_check.model_columns``).

Reference: the synthetic truth of the virtual Denso. Each calibration is a least-squares fit (``consistency=False``:
the written parameters are the estimate whose covariance the file states) of one 4 s training motion with its own
draw of 0.1 N m torque noise (20 draws; the virtual robot without friction, so that the model's error is the noise's
alone); each of two validation recordings carries a 1 kg body at the flange the model does not have. The check's
z-score is (mass - 1 kg) / its stated standard deviation, whether or not it would name the load (``MIN_Z`` and
``MIN_DROP`` lifted). With the file's covariance the z-scores have an RMS near 1 and hold the truth within 2 sd in
>= 90 % (measured: RMS 1.13, 37 of 40; 1.04 and 57 of 60 with 30 draws); with the standard deviations alone (a file
written before the block, the parameters taken as independent) the same checks state their +- too wide (RMS 0.75).
The consistent fits of two 8 s recordings, with friction, over 5 x 6 cases: the slow ``test_payload_check_coverage``.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from identification.calibration import payload_check
from identification.calibration.calibrated_model import CalibratedModel, load_calibrated_model
from identification.calibration.finding_value import validation_rmse
from identification.calibration.parameter_covariance import stated_covariance
from identification.calibration.payload_check import model_columns, new_payload
from identification.calibration.trajectory_fit import TrajectoryOptions, identify_trajectories
from identification.data.recording import Recording
from identification.virtual.effects import Payload as VirtualPayload
from identification.virtual.simulation import SimulationOptions, simulate_recording
from psdm_casadi.errors import ModelFileError
from tests.conftest import DENSO_FILE
from trajopt.experiments import sine_experiment

LOAD = VirtualPayload(mass=1.0, com=(0.03, 0.0, 0.06))
NOISE = 0.1  # [N m] on every joint's torque
CALIBRATIONS = 20  # noise draws on the one training motion
VALIDATIONS = (51, 52)


def _record(robot, seed, extras=(), noise=NOISE):
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():  # the sine experiment may graze a limit: irrelevant here
        warnings.simplefilter("ignore")
        reference = sine_experiment(robot, duration=4.0, rng=rng).reference()
    options = SimulationOptions(record_tau=True, record_current=False, tau_noise_std=noise, friction=False)
    return simulate_recording(robot, reference, options, rng, extras=extras)[0]


def _calibrated(denso, denso_model, recording):
    fit = identify_trajectories(denso, denso_model, [recording], TrajectoryOptions(consistency=False))
    return fit, CalibratedModel.from_fit(denso, denso_model, fit, robot_source=DENSO_FILE)


@pytest.fixture(scope="module")
def training(denso):
    """The noiseless torques of one 4 s training motion; each calibration adds its own noise."""
    return _record(denso, 31, noise=0.0)


def _noisy(recording, seed):
    rng = np.random.default_rng(seed)
    tau = recording.tau + rng.normal(scale=NOISE, size=recording.tau.shape)
    return Recording(t=recording.t, q=recording.q, tau=tau, name=f"train{seed}")


@pytest.fixture(scope="module")
def z_scores(denso, denso_model, training):
    """(z with the file's covariance, z with its standard deviations alone) per calibration x recording."""
    validations = [_record(denso, seed, (LOAD,)) for seed in VALIDATIONS]
    with_covariance, independent = [], []
    with pytest.MonkeyPatch.context() as patch:  # every estimate, named or not
        patch.setattr(payload_check, "MIN_Z", 0.0)
        patch.setattr(payload_check, "MIN_DROP", -1.0)
        for seed in range(CALIBRATIONS):
            _, calibrated = _calibrated(denso, denso_model, _noisy(training, seed))
            for recording in validations:
                _, _, prepared, predicted = validation_rmse(calibrated, denso_model, recording)
                columns, covariance = model_columns(calibrated, denso_model, prepared)
                for out, own in ((with_covariance, covariance), (independent, np.diag(np.diag(covariance)))):
                    check = new_payload(denso, prepared, predicted, own=(columns, own))
                    out.append(np.nan if check is None else (check.mass - LOAD.mass) / check.mass_std)
    return np.array(with_covariance), np.array(independent)


def test_the_flange_checks_plus_minus_from_the_covariance_covers_the_true_mass_as_stated(z_scores):
    z, independent = z_scores
    assert 0.8 < np.sqrt(np.nanmean(z**2)) < 1.25, z.round(2)
    assert np.mean(np.abs(z) <= 2.0) >= 0.9, z.round(2)  # a load the recording cannot weigh (NaN) counts as missed
    assert np.sqrt(np.nanmean(independent**2)) < 0.8, independent.round(2)  # what the covariance mends: too wide


def test_the_file_states_the_fits_covariance_and_an_old_file_falls_back_to_the_standard_deviations(
    denso, denso_model, training, tmp_path
):
    fit, calibrated = _calibrated(denso, denso_model, _noisy(training, 0))
    path = calibrated.save(tmp_path / "model.json", allow_inconsistent=True)
    document = json.loads(path.read_text())
    n = denso_model.n_base + len(fit.drive_names)
    stated = stated_covariance(document, n)
    assert stated.shape == (n, n) and np.array_equal(stated, stated.T)
    np.testing.assert_allclose(stated, fit.covariance, rtol=0.0, atol=1e-10 * np.abs(fit.covariance).max())
    std = np.concatenate([document["base"]["std"], document["drive"]["std"]]).astype(float)
    np.testing.assert_allclose(np.sqrt(np.diag(stated)), np.nan_to_num(std), rtol=1e-12)
    assert np.max(np.abs(stated - np.diag(np.diag(stated)))) > 0.1 * np.max(np.diag(stated))  # correlated
    recording = _record(denso, VALIDATIONS[0], (LOAD,))
    loaded = load_calibrated_model(path)
    prepared = validation_rmse(loaded, denso_model, recording)[2]
    np.testing.assert_allclose(model_columns(loaded, denso_model, prepared)[1], stated, rtol=1e-12)
    del document["covariance"]  # a file written before the block: read as before, the standard deviations alone
    (tmp_path / "old.json").write_text(json.dumps(document))
    old = load_calibrated_model(tmp_path / "old.json")
    assert stated_covariance(old.document, n) is None
    np.testing.assert_allclose(model_columns(old, denso_model, prepared)[1], np.diag(np.nan_to_num(std) ** 2))


def test_a_covariance_block_of_another_size_is_refused_naming_the_field(denso, denso_model, training, tmp_path):
    _, calibrated = _calibrated(denso, denso_model, _noisy(training, 0))
    document = json.loads(calibrated.save(tmp_path / "model.json", allow_inconsistent=True).read_text())
    document["covariance"]["lower"] = document["covariance"]["lower"][:-1]
    (tmp_path / "bad.json").write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r"covariance\.lower must be a list of \d+ numbers"):
        load_calibrated_model(tmp_path / "bad.json")
